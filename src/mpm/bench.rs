//! Benchmark: the a = 1 column at table 4.3 resolution (2 mm cells, 16 PPC, Mohr–Coulomb,
//! Δt = 1e-6 s). The issue asks for 40,000 points: a 100 mm × 100 mm column (50 × 50 cells,
//! 200 × 200 points) gives exactly that. Released from rest, stress free (no geostatic stage),
//! so the steps timed are flow steps. Per-phase times come from the solver's counters.

use super::column::{self, ColumnSpec};
use super::params::MpmParams;
use super::solver::PhaseTimes;
use crate::math::Real;

/// Benchmark outcome.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchResult {
    /// Threads used.
    pub threads: usize,
    /// Material points.
    pub points: usize,
    /// Timed steps.
    pub steps: u64,
    /// Wall-clock time of the timed steps [s].
    pub wall_s: Real,
    /// points × steps / wall_s.
    pub point_steps_per_s: Real,
    /// Per-phase times of the timed steps.
    pub phases: PhaseTimes,
}

impl BenchResult {
    /// P2G time [s] (including reset_grid).
    pub fn p2g_s(&self) -> Real {
        (self.phases.p2g + self.phases.reset_grid).as_secs_f64()
    }
    /// Stress update time [s].
    pub fn stress_s(&self) -> Real {
        self.phases.update_stress.as_secs_f64()
    }
    /// G2P time [s].
    pub fn g2p_s(&self) -> Real {
        self.phases.g2p.as_secs_f64()
    }
}

/// Run the benchmark column on a pool of `threads` threads: `steps` steps, or with
/// `steps = None`, blocks of 100 steps until at least `min_s` seconds have been timed (a
/// measurement under a second is too short to be stable on a shared machine).
pub fn run(threads: usize, steps: Option<u64>, min_s: f64) -> BenchResult {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build()
        .expect("thread pool");
    pool.install(|| {
        let params = MpmParams::default();
        let mut col = column::build(&params, ColumnSpec::from_area(1.0, 0.01)).expect("bench column");
        column::release(&mut col);
        let dt = col.solver.dt(&col.state);
        for _ in 0..5 {
            col.solver.step(&mut col.state, dt).expect("bench warm-up");
        }
        col.solver.times = PhaseTimes::default();
        let clock = std::time::Instant::now();
        let mut done = 0u64;
        loop {
            let k = steps.map_or(100, |s| s - done);
            for _ in 0..k {
                col.solver.step(&mut col.state, dt).expect("bench step");
            }
            done += k;
            if steps.is_some() || clock.elapsed().as_secs_f64() >= min_s {
                break;
            }
        }
        let steps = done;
        let wall_s = clock.elapsed().as_secs_f64();
        let points = col.state.points.len();
        BenchResult {
            threads: threads.max(1),
            points,
            steps,
            wall_s,
            point_steps_per_s: points as Real * steps as Real / wall_s,
            phases: col.solver.times,
        }
    })
}

/// Cost growth: the a = 1 benchmark column (same material, cells, 16 PPC) sized to about
/// `points` points (area = points / 4e6 m²), released, `steps` steps timed after 5 warm-up
/// steps. Returns (points, seconds per step).
pub fn scaling_point(points: usize, threads: usize, steps: u64) -> (usize, f64) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build()
        .expect("thread pool");
    pool.install(|| {
        let params = MpmParams::default();
        let mut col = column::build(&params, ColumnSpec::from_area(1.0, points as Real / 4e6)).expect("scaling column");
        column::release(&mut col);
        let dt = col.solver.dt(&col.state);
        for _ in 0..5 {
            col.solver.step(&mut col.state, dt).expect("scaling warm-up");
        }
        let clock = std::time::Instant::now();
        for _ in 0..steps {
            col.solver.step(&mut col.state, dt).expect("scaling step");
        }
        (
            col.state.points.len(),
            clock.elapsed().as_secs_f64() / steps.max(1) as f64,
        )
    })
}

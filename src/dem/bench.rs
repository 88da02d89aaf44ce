//! Benchmark: the LAMMPS reference scene of `shared/bench/lammps` (2924 disks, diameters
//! uniform in [0.92, 1.38] mm, hex lattice of pitch 1.38 mm in L_0 = 61.4 mm, settled,
//! right wall removed, Δt = 1e-6 s as in `common.lmp`), timed over `steps` steps of the
//! collapse. Set-up (lattice + soft settling, ≈ 5 s) is not timed.
//!
//! Cases: `Full` = table 4.2 physics with implicit rolling resistance and the ledger;
//! `NoRollingNoLedger` = the LAMMPS `gran/hooke/history` physics (compare with LAMMPS).

use crate::dem::error::DemError;
use crate::dem::params::DemParams;
use crate::dem::prep::{SplitMix64, box_walls, lattice_column, quench, settle};
use crate::dem::timers::PhaseTimers;
use crate::dem::world::World;
use crate::math::Real;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Benchmark case.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BenchCase {
    /// Rolling resistance (implicit dashpot) + energy ledger.
    Full,
    /// No rolling resistance, no ledger (same physics as the LAMMPS reference).
    NoRollingNoLedger,
}

/// One benchmark measurement (the lead prints it as a JSON line).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BenchResult {
    /// Case.
    pub case: BenchCase,
    /// Rayon threads.
    pub threads: usize,
    /// Grains.
    pub grains: usize,
    /// Timed steps.
    pub steps: u64,
    /// Wall time of the timed steps [s].
    pub wall_s: f64,
    /// grains × steps / wall_s.
    pub particle_steps_per_s: f64,
    /// Best of 5 equal blocks of the timed steps (robust on a shared machine, like the
    /// LAMMPS reference's "best of three").
    pub best_block_particle_steps_per_s: f64,
    /// Mean grain–grain contacts per grain at the end.
    pub contacts_per_grain: f64,
    /// Listed (Verlet) pairs per grain at the end.
    pub pairs_per_grain: f64,
    /// Neighbour-list builds during the timed steps.
    pub rebuilds: u64,
    /// Per-phase time of the timed steps [s].
    pub timers: PhaseTimers,
    /// Process CPU time during the timed steps [s] (Linux /proc; 0 elsewhere). On a
    /// loaded machine cpu_s/wall_s < threads shows how much CPU the run actually got
    /// (LAMMPS prints the same as "% CPU use").
    pub cpu_s: f64,
}

/// Process user + system CPU time [s] from /proc/self/stat (clock ticks of 1/100 s).
fn process_cpu_s() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else { return 0.0 };
    let Some(rest) = stat.rsplit(')').next() else { return 0.0 };
    let f: Vec<&str> = rest.split_whitespace().collect();
    // after the command name: state is field 3, utime 14, stime 15 (1-based) → 11, 12 here
    let tick = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (tick(11) + tick(12)) / 100.0
}

/// Scene parameters of the reference (Δt = 1e-6 s as LAMMPS; table 4.2 otherwise).
pub fn bench_params(case: BenchCase) -> DemParams {
    let mut p = DemParams { dt: 1e-6, ..DemParams::default() };
    p.watchdog.every = 0;
    match case {
        BenchCase::Full => {}
        BenchCase::NoRollingNoLedger => {
            p.rolling.enabled = false;
            p.ledger = false;
        }
    }
    p
}

/// The settled reference column with its gate still closed.
pub fn bench_scene(case: BenchCase) -> Result<World, DemError> {
    let n = 2924;
    let mut rng = SplitMix64(4242);
    let radii: Vec<Real> = (0..n).map(|_| 0.5 * (0.92e-3 + (1.38e-3 - 0.92e-3) * rng.next_f64())).collect();
    let l0 = 44.5 * 1.38e-3;
    let params = bench_params(case);
    let s = lattice_column(&radii, l0, 1.38e-3, params.density);
    // settle soft (k/100, Δt×10), then switch to the run stiffness
    let mut soft = params.softened(0.01);
    soft.ledger = false;
    let mut w = World::new(soft, s, box_walls(l0), None)?;
    settle(&mut w, 1e-5, 0.05, 0.15)?;
    let mut st = w.state.clone();
    st.stop();
    let mut w = World::new(params, st, box_walls(l0), None)?;
    quench(&mut w, 1e-8, 3000)?;
    w.run(1000)?;
    Ok(w)
}

/// Build the scene, open the gate and time `steps` steps on a pool of `threads` threads.
pub fn run(case: BenchCase, threads: usize, steps: u64) -> Result<BenchResult, DemError> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build().map_err(|e| DemError::Setup(e.to_string()))?;
    pool.install(|| {
        let mut w = bench_scene(case)?;
        for wall in w.walls.iter_mut() {
            if wall.name == "gate" { wall.active = false; }
        }
        w.run(200)?; // warm-up
        w.timers = PhaseTimers::default();
        let b0 = w.rebuilds();
        let c0 = process_cpu_s();
        let t0 = Instant::now();
        let block = (steps / 5).max(1);
        let mut done = 0;
        let mut best: f64 = 0.0;
        while done < steps {
            let k = block.min(steps - done);
            let tb = Instant::now();
            w.run(k)?;
            best = best.max(w.state.len() as f64 * k as f64 / tb.elapsed().as_secs_f64());
            done += k;
        }
        let wall_s = t0.elapsed().as_secs_f64();
        let cpu_s = process_cpu_s() - c0;
        let grains = w.state.len();
        Ok(BenchResult {
            case,
            threads,
            grains,
            steps,
            wall_s,
            particle_steps_per_s: grains as f64 * steps as f64 / wall_s,
            best_block_particle_steps_per_s: best,
            contacts_per_grain: 2.0 * w.contact_count() as f64 / grains as f64,
            rebuilds: w.rebuilds() - b0,
            pairs_per_grain: w.pair_count() as f64 / grains as f64,
            timers: w.timers,
            cpu_s,
        })
    })
}

//! Benchmark: the LAMMPS reference scene of `bench/lammps/column.lmp` (2924 disks, diameters
//! uniform in [0.92, 1.38] mm, hex lattice of pitch 1.38 mm in L_0 = 61.4 mm, settled,
//! right wall removed, Δt = 1e-6 s as there), timed over `steps` steps of the
//! collapse. Set-up (lattice + soft settling, ≈ 5 s) is not timed.
//!
//! Cases: `Full` = table 4.2 physics with implicit rolling resistance and the ledger;
//! `RollingNoLedger` = the same without the ledger (shows what the inline bookkeeping
//! costs); `NoRollingNoLedger` = the LAMMPS `gran/hooke/history` physics.
//!
//! Time step: [`bench_dt`], the LAMMPS reference's 1e-6 s when the pre-flight accepts it
//! for the case's physics, else the largest step it accepts (rounded down to two
//! significant digits); run LAMMPS at the same step for a ratio.

use crate::dem::error::DemError;
use crate::dem::params::DemParams;
use crate::dem::prep::{box_walls, lattice_column, quench, settle};
use crate::dem::timers::PhaseTimers;
use crate::dem::world::World;
use crate::math::Real;
use crate::sample::rng::SplitMix64;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Benchmark case.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BenchCase {
    /// Rolling resistance (implicit dashpot) + energy ledger.
    Full,
    /// Rolling resistance (implicit dashpot), no ledger.
    RollingNoLedger,
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
    /// Time step [s].
    pub dt: f64,
    /// Largest step the pre-flight accepts for this scene [s].
    pub preflight_limit_s: f64,
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
    /// blake3 of the final grain state, contact histories and ledger (bit patterns): equal
    /// digests at 1 and 2 threads, or from two binaries, show bit-identical runs.
    pub digest: String,
}

/// blake3 of every grain's x, y, v, ω, θ, the pair and wall histories and the ledger.
pub fn world_digest(w: &World) -> String {
    let mut h = blake3::Hasher::new();
    let s = &w.state;
    for v in [&s.x, &s.y, &s.vx, &s.vy, &s.w, &s.theta] {
        for x in v.iter() {
            h.update(&x.to_bits().to_le_bytes());
        }
    }
    let sh = w.saved_histories();
    for (a, b, c) in sh.pairs.iter().chain(sh.walls.iter()) {
        h.update(&a.to_le_bytes());
        h.update(&b.to_le_bytes());
        for x in [c.tangential, c.rolling, c.ft, c.mr] {
            h.update(&x.to_bits().to_le_bytes());
        }
    }
    let l = w.ledger;
    h.update(format!("{l:?}").as_bytes());
    h.finalize().to_hex()[..16].to_string()
}

/// Process user + system CPU time [s] from /proc/self/stat (clock ticks of 1/100 s).
fn process_cpu_s() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    let Some(rest) = stat.rsplit(')').next() else {
        return 0.0;
    };
    let f: Vec<&str> = rest.split_whitespace().collect();
    // after the command name: state is field 3, utime 14, stime 15 (1-based) → 11, 12 here
    let tick = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (tick(11) + tick(12)) / 100.0
}

impl BenchCase {
    /// Name in the JSON output.
    pub fn name(self) -> &'static str {
        match self {
            BenchCase::Full => "rolling+ledger",
            BenchCase::RollingNoLedger => "rolling-no-ledger",
            BenchCase::NoRollingNoLedger => "no-rolling-no-ledger",
        }
    }
}

/// Scene parameters of the reference at step `dt` (table 4.2 otherwise).
pub fn bench_params(case: BenchCase, dt: Real) -> DemParams {
    let mut p = DemParams {
        dt,
        ..DemParams::default()
    };
    p.watchdog.every = 0;
    match case {
        BenchCase::Full => {}
        BenchCase::RollingNoLedger => p.ledger = false,
        BenchCase::NoRollingNoLedger => {
            p.rolling.enabled = false;
            p.ledger = false;
        }
    }
    p
}

/// The LAMMPS reference's step.
pub const LAMMPS_DT: Real = 1e-6;

/// Radii of the reference scene (the same draw every time).
fn bench_radii() -> Vec<Real> {
    let mut rng = SplitMix64(4242);
    (0..2924)
        .map(|_| 0.5 * (0.92e-3 + (1.38e-3 - 0.92e-3) * rng.next_f64()))
        .collect()
}

/// The step of a case: 1e-6 s (LAMMPS) if the pre-flight accepts it, else its largest
/// accepted step rounded down to two significant digits. Returns (dt, pre-flight limit).
pub fn bench_dt(case: BenchCase) -> (Real, Real) {
    let r = bench_radii();
    let (lo, hi) = r
        .iter()
        .fold((Real::INFINITY, 0.0 as Real), |(a, b), &x| (a.min(x), b.max(x)));
    let mean = r.iter().sum::<Real>() / r.len() as Real;
    let sizes = crate::dem::preflight::SizeClasses {
        r_min: lo,
        r_mean: mean,
        r_max: hi,
    };
    let p = bench_params(case, LAMMPS_DT);
    let limit = crate::dem::preflight::time_scales(&p, sizes, true, LAMMPS_DT)
        .iter()
        .map(|t| t.limit)
        .fold(Real::INFINITY, Real::min);
    if LAMMPS_DT < limit {
        return (LAMMPS_DT, limit);
    }
    let e = limit.log10().floor() - 1.0;
    let q = 10f64.powf(e);
    let mut dt = (limit / q).floor() * q;
    if dt >= limit {
        dt -= q;
    }
    (dt, limit)
}

/// The settled reference column with its gate still closed.
///
/// With `GRANREPRO_BENCH_SCENE=FILE` the settled grains and contact histories are read
/// from FILE if it exists (else built and written there): for profiling under valgrind,
/// where the set-up would cost minutes. The timed steps are the same work either way.
pub fn bench_scene(case: BenchCase, dt: Real) -> Result<World, DemError> {
    let l0 = 44.5 * 1.38e-3;
    if let Some(path) = std::env::var_os("GRANREPRO_BENCH_SCENE") {
        let path = std::path::PathBuf::from(path);
        if let Ok(b) = std::fs::read(&path) {
            let (st, h): (crate::dem::state::State, crate::dem::world::SavedHistories) =
                serde_json::from_slice(&b).map_err(|e| DemError::Setup(format!("{}: {e}", path.display())))?;
            let mut w = World::new(bench_params(case, dt), st, box_walls(l0), None)?;
            w.restore_histories(&h);
            return Ok(w);
        }
        let w = build_scene(case, dt)?;
        let b = serde_json::to_vec(&(&w.state, w.saved_histories())).map_err(|e| DemError::Setup(e.to_string()))?;
        std::fs::write(&path, b).map_err(|e| DemError::Setup(format!("{}: {e}", path.display())))?;
        return Ok(w);
    }
    build_scene(case, dt)
}

fn build_scene(case: BenchCase, dt: Real) -> Result<World, DemError> {
    let radii = bench_radii();
    let l0 = 44.5 * 1.38e-3;
    let params = bench_params(case, dt);
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

/// Build the scene, open the gate and time `steps` steps on a pool of `threads` threads,
/// at step `dt` (None: [`bench_dt`]).
pub fn run(case: BenchCase, threads: usize, steps: u64, dt: Option<Real>) -> Result<BenchResult, DemError> {
    let (auto_dt, preflight_limit_s) = bench_dt(case);
    let dt = dt.unwrap_or(auto_dt);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build()
        .map_err(|e| DemError::Setup(e.to_string()))?;
    pool.install(|| {
        let mut w = bench_scene(case, dt)?;
        for wall in w.walls.iter_mut() {
            if wall.name == "gate" {
                wall.active = false;
            }
        }
        w.run(200)?; // warm-up
        w.timers = PhaseTimers::default();
        w.timing = true; // the phase table of `--phases`
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
            dt,
            preflight_limit_s,
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
            digest: world_digest(&w),
        })
    })
}

/// One point of the cost-growth measurement.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScalingPoint {
    /// Grains.
    pub grains: usize,
    /// Timed steps.
    pub steps: u64,
    /// Wall time per step [s].
    pub s_per_step: f64,
    /// Process CPU time per step [s] (Linux /proc, 10 ms ticks; 0 elsewhere): on a shared
    /// machine, cpu/wall below the thread count shows the cores the run did not get.
    pub cpu_s_per_step: f64,
    /// Listed pairs per grain at the end.
    pub pairs_per_grain: f64,
    /// Grain–grain contacts per grain at the end.
    pub contacts_per_grain: f64,
}

/// Memory order of the grains of a cost-growth scene ([`scaling_point`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GrainOrder {
    /// As the lattice was built and the copies tiled: grains that are neighbours in space
    /// are near in memory (a settled column's order).
    Lattice,
    /// The same grains shuffled (Fisher–Yates, [`SplitMix64`] with this seed), contact
    /// histories following their grains: the order a long mixed flow leaves.
    Shuffled(u64),
    /// Shuffled with this seed, then sorted by the world along its Hilbert curve
    /// ([`World::sort_now`]): the order a mixed flow has after a sort.
    Sorted(u64),
}

/// Seed of `bench scaling`'s shuffle.
pub const SCALING_SHUFFLE_SEED: u64 = 27;

/// A deterministic random permutation of `0..n` (Fisher–Yates, [`SplitMix64`] with `seed`).
pub fn shuffled_order(n: usize, seed: u64) -> Vec<usize> {
    let mut rng = SplitMix64(seed);
    let mut order: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        let j = ((rng.next_f64() * (i + 1) as Real) as usize).min(i);
        order.swap(i, j);
    }
    order
}

/// Cost growth of the DEM step with the chapter's physics (rolling resistance with the
/// implicit dashpot, ledger on, Δt = [`bench_dt`]): the settled reference column, cut to
/// its first `n` grains (its bottom layers) or repeated side by side (copies at L_0
/// spacing, contact histories kept) up to `n`, gate removed, the grains in `order`,
/// `steps` steps timed after 100 warm-up steps. The packing and the contact network per
/// grain are the same at every size, so the time per step should grow like n (neighbour
/// build, pair and grain loops are all O(n)).
pub fn scaling_point(
    base: &World,
    n: usize,
    threads: usize,
    steps: u64,
    order: GrainOrder,
) -> Result<ScalingPoint, DemError> {
    scaling_point_with(base, n, threads, steps, None, order)
}

/// [`scaling_point`] with the world's `team_min_grains` set (None: default): `Some(0)`
/// steps every size with a thread team when `threads` > 1 (no probing against one
/// thread), to measure the crossover.
pub fn scaling_point_with(
    base: &World,
    n: usize,
    threads: usize,
    steps: u64,
    team_min: Option<usize>,
    order: GrainOrder,
) -> Result<ScalingPoint, DemError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build()
        .map_err(|e| DemError::Setup(e.to_string()))?;
    pool.install(|| {
        let mut w = scaling_scene(base, n, order)?;
        if let Some(m) = team_min {
            w.team_min_grains = m;
            w.team_probe = false;
        }
        w.run(100)?;
        let c0 = process_cpu_s();
        let t0 = Instant::now();
        w.run(steps)?;
        let s_per_step = t0.elapsed().as_secs_f64() / steps.max(1) as f64;
        let cpu_s_per_step = (process_cpu_s() - c0) / steps.max(1) as f64;
        let grains = w.state.len();
        Ok(ScalingPoint {
            grains,
            steps,
            s_per_step,
            cpu_s_per_step,
            pairs_per_grain: w.pair_count() as f64 / grains as f64,
            contacts_per_grain: 2.0 * w.contact_count() as f64 / grains as f64,
        })
    })
}

/// The scene of [`scaling_point`]: the settled column `base` cut to `n` grains or tiled side
/// by side up to `n`, gate removed, contact histories kept, the grains in `order`.
pub fn scaling_scene(base: &World, n: usize, order: GrainOrder) -> Result<World, DemError> {
    let l0 = 44.5 * 1.38e-3;
    let nb = base.state.len();
    let copies = n.div_ceil(nb);
    let mut st = crate::dem::state::State::with_capacity(n);
    let mut hist = crate::dem::world::SavedHistories::default();
    let saved = base.saved_histories();
    for c in 0..copies {
        let off = c * nb;
        let take = (n - off).min(nb);
        let s = &base.state;
        for a in 0..take {
            st.x.push(s.x[a] + c as Real * l0);
            for (dst, src) in [
                (&mut st.y, &s.y),
                (&mut st.vx, &s.vx),
                (&mut st.vy, &s.vy),
                (&mut st.w, &s.w),
                (&mut st.theta, &s.theta),
                (&mut st.r, &s.r),
                (&mut st.m, &s.m),
                (&mut st.inv_m, &s.inv_m),
                (&mut st.inertia, &s.inertia),
                (&mut st.inv_i, &s.inv_i),
            ] {
                dst.push(src[a]);
            }
        }
        for &(a, b, h) in &saved.pairs {
            if (a as usize) < take && (b as usize) < take {
                hist.pairs.push((a + off as u32, b + off as u32, h));
            }
        }
        for &(wi, a, h) in &saved.walls {
            // floor contacts of every copy; the left wall only touches the first
            if (a as usize) < take && (wi == 0 || c == 0) {
                hist.walls.push((wi, a + off as u32, h));
            }
        }
    }
    if let GrainOrder::Shuffled(seed) | GrainOrder::Sorted(seed) = order {
        // grain order[p] becomes grain p; histories follow their grains
        let order = shuffled_order(st.len(), seed);
        let mut new_of = vec![0u32; order.len()];
        for (p, &a) in order.iter().enumerate() {
            new_of[a] = p as u32;
        }
        st = st.permuted(&order);
        for p in hist.pairs.iter_mut() {
            *p = p.2.renamed(new_of[p.0 as usize], new_of[p.1 as usize]);
        }
        for (_, a, _) in hist.walls.iter_mut() {
            *a = new_of[*a as usize];
        }
    }
    let mut walls = box_walls(copies as Real * l0);
    walls.retain(|w| w.name != "gate");
    let mut w = World::new(base.params.clone(), st, walls, None)?;
    w.restore_histories(&hist);
    if let GrainOrder::Sorted(_) = order {
        w.sort_min_grains = 0;
        w.sort_now();
    }
    Ok(w)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::state::State;

    #[test]
    fn shuffled_order_is_a_deterministic_permutation() {
        let a = shuffled_order(1000, SCALING_SHUFFLE_SEED);
        assert_eq!(a, shuffled_order(1000, SCALING_SHUFFLE_SEED));
        assert_ne!(a, shuffled_order(1000, SCALING_SHUFFLE_SEED + 1));
        let mut seen = vec![false; 1000];
        for &i in &a {
            assert!(!seen[i]);
            seen[i] = true;
        }
        // shuffled, not a near-identity
        assert!(a.iter().enumerate().filter(|&(p, &i)| p == i).count() < 20);
    }

    #[test]
    fn permuted_state_keeps_every_quantity_with_its_grain() {
        let mut s = State::new();
        for k in 0..50 {
            let id = s.insert(k as Real, 2.0 * k as Real, 1e-3 * (1.0 + k as Real), 2500.0);
            s.vx[id.0 as usize] = 3.0 * k as Real;
            s.vy[id.0 as usize] = 4.0 * k as Real;
            s.w[id.0 as usize] = 5.0 * k as Real;
            s.theta[id.0 as usize] = 6.0 * k as Real;
        }
        s.set_motion(7, crate::dem::state::Motion::Prescribed);
        let order = shuffled_order(50, 3);
        let p = s.permuted(&order);
        for (q, &a) in order.iter().enumerate() {
            for (u, v) in [
                (&p.x, &s.x),
                (&p.y, &s.y),
                (&p.vx, &s.vx),
                (&p.vy, &s.vy),
                (&p.w, &s.w),
                (&p.theta, &s.theta),
                (&p.r, &s.r),
                (&p.m, &s.m),
                (&p.inv_m, &s.inv_m),
                (&p.inertia, &s.inertia),
                (&p.inv_i, &s.inv_i),
            ] {
                assert_eq!(u[q].to_bits(), v[a].to_bits());
            }
        }
        // and back
        let mut inv = vec![0; 50];
        for (q, &a) in order.iter().enumerate() {
            inv[a] = q;
        }
        assert_eq!(p.permuted(&inv), s);
    }

    /// A small settling column with contacts and histories (a cheap `base`).
    fn small_base() -> World {
        let radii: Vec<Real> = bench_radii().into_iter().take(600).collect();
        let (dt, _) = bench_dt(BenchCase::Full);
        let l0 = 44.5 * 1.38e-3;
        let params = bench_params(BenchCase::Full, dt);
        let s = lattice_column(&radii, l0, 1.38e-3, params.density);
        let mut w = World::new(params, s, box_walls(l0), None).unwrap();
        w.run(20_000).unwrap();
        w
    }

    /// Grain p of the shuffled scene against grain order[p] of the lattice scene, bits.
    fn differing(a: &World, b: &World, order: &[usize]) -> usize {
        let (sa, sb) = (&a.state, &b.state);
        (0..order.len())
            .filter(|&p| {
                let q = order[p];
                [
                    (&sb.x, &sa.x),
                    (&sb.y, &sa.y),
                    (&sb.vx, &sa.vx),
                    (&sb.w, &sa.w),
                    (&sb.theta, &sa.theta),
                ]
                .iter()
                .any(|(u, v)| u[p].to_bits() != v[q].to_bits())
            })
            .count()
    }

    #[test]
    fn shuffled_scene_is_the_lattice_scene_relabelled() {
        let base = small_base();
        let a = scaling_scene(&base, 1000, GrainOrder::Lattice).unwrap();
        let b = scaling_scene(&base, 1000, GrainOrder::Shuffled(5)).unwrap();
        let order = shuffled_order(1000, 5);
        assert_eq!(differing(&a, &b, &order), 0);
        // the same contacts, histories following their grains
        let (ha, hb) = (a.saved_histories(), b.saved_histories());
        assert!(!ha.pairs.is_empty() && !ha.walls.is_empty());
        let mut mapped: Vec<_> = hb
            .pairs
            .iter()
            .map(|&(i, j, h)| h.renamed(order[i as usize] as u32, order[j as usize] as u32))
            .collect();
        mapped.sort_by_key(|p| (p.0, p.1));
        assert_eq!(mapped, ha.pairs);
        let mut walls: Vec<_> = hb
            .walls
            .iter()
            .map(|&(k, a, h)| (k, order[a as usize] as u32, h))
            .collect();
        walls.sort_by_key(|p| (p.0, p.1));
        assert_eq!(walls, ha.walls);
        // the same physics: without the rolling dashpot (whose Gauss–Seidel sweep follows
        // the grain indices) only round-off separates the two runs over a few steps. A
        // pair whose i and j swap keeps its rolling spring only if its sign turns over:
        // without that the ledgers differed by 3 % after one step.
        let (mut a, mut b) = (a, b);
        a.params.rolling.cr = 0.0;
        b.params.rolling.cr = 0.0;
        a.run(10).unwrap();
        b.run(10).unwrap();
        let (da, db) = (a.ledger.dissipated(), b.ledger.dissipated());
        assert!(da > 0.0 && (da - db).abs() <= 1e-12 * da, "ledger {da} vs {db}");
    }

    /// Measurement (run by hand with `--ignored --nocapture`): how far relabelling the
    /// grains moves a run. The engine's sums and its Gauss–Seidel dashpot sweep follow
    /// grain indices, so a memory reorder that renumbered the grains changes the results.
    /// On this 1000-grain column (2026-12-03): with the implicit rolling dashpot the
    /// ledger's dissipation differs by 3e-4 (relative) after one step — the sweep's order,
    /// not round-off — and 29 grains differ in some bit; with c_r = 0, 3 grains differ after
    /// one step and the ledgers agree to 1e-16 after 10 steps (round-off, then chaos: 940
    /// grains differ after 5000 steps either way).
    #[test]
    #[ignore]
    fn relabelled_grains_change_round_off() {
        let base = small_base();
        let mut a = scaling_scene(&base, 1000, GrainOrder::Lattice).unwrap();
        let mut b = scaling_scene(&base, 1000, GrainOrder::Shuffled(5)).unwrap();
        let order = shuffled_order(1000, 5);
        for k in [1u64, 10, 100, 1000, 5000] {
            let done = a.steps;
            a.run(k - done).unwrap();
            b.run(k - done).unwrap();
            let dmax = (0..1000)
                .map(|p| {
                    (b.state.x[p] - a.state.x[order[p]])
                        .abs()
                        .max((b.state.y[p] - a.state.y[order[p]]).abs())
                })
                .fold(0.0, Real::max);
            eprintln!(
                "after {k} steps: {} of 1000 grains differ in some bit; largest |Δx| {dmax:.3e} m; ledger {:?} vs {:?}",
                differing(&a, &b, &order),
                a.ledger.dissipated(),
                b.ledger.dissipated()
            );
        }
    }
}

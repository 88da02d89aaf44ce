//! The DEM world and its step, a list of named phases:
//!
//! `integrate(first half kick + drift)` → `refresh_neighbors` → `compute_contacts` (pair
//! pass) → `grain_pass` (per grain chunk: force gather, grain–wall contacts, second half
//! kick) → `integrate(rolling dashpot)` → `ledger` → `watchdog`. With the implicit
//! dashpot, the end of one step and the first half of the next (between two steps of one
//! `run`) are one phase, `step_boundary`: the spin work (sweeps, spin kick) on one thread
//! beside the translational kick and drift, and θ advances in the grain pass. The phase
//! timers keep the names contacts / gather / walls / integrate; the grain pass's wall time
//! is apportioned to them by each part's CPU time per chunk.
//!
//! Velocity Verlet (kick–drift–kick); contact forces at x^{n+1} use v^{n+½} (as LAMMPS
//! `fix nve/sphere`). Physics terms are picked once per [`World::run`] call by matching
//! the parameters to a monomorphised `step_with::<ROLLING, IMPLICIT, LEDGER>`.
//!
//! Parallelism (rayon, current pool): pairs are cut into fixed chunks of [`PAIR_CHUNK`],
//! grains into chunks of [`GRAIN_CHUNK`]; each pair's force is written to its own slot,
//! then each grain sums its pairs in increasing pair order, and scalar partials are summed
//! chunk by chunk in chunk order. Nothing depends on the thread count, so results are
//! bit-identical for any number of threads.

use crate::dem::contact_law::{BATCH, Law, LawCoeffs, PairBatch, PairBatchOut, PairIn, RollDashpot};
use crate::dem::energy::{Balance, Energies, Ledger};
use crate::dem::error::DemError;
use crate::dem::neighbors::NeighborList;
use crate::dem::params::{DemParams, RollingDamping, normal_damping};
use crate::dem::preflight::{Preflight, SizeClasses, preflight};
use crate::dem::state::{ContactState, State};
use crate::dem::timers::{Clock, PhaseTimers};
use crate::dem::walls::Wall;
use crate::dem::integrate::kick_range;
use crate::math::{Real, Vec2};
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Pairs per parallel work unit (fixed: the reduction order must not depend on threads).
pub const PAIR_CHUNK: usize = 512;
/// Grains per parallel work unit.
pub const GRAIN_CHUNK: usize = 256;
/// Steps for which [`World::run`] keeps its choice between stepping a world alone and with
/// a thread team, made by timing [`TEAM_PROBE`] steps each way.
pub const TEAM_SEGMENT: u64 = 4096;
/// See [`TEAM_SEGMENT`].
pub const TEAM_PROBE: u64 = 128;
/// Most walls a scene can have.
pub const MAX_WALLS: usize = 8;

#[derive(Clone, Copy)]
pub(crate) struct Ptr<T>(pub(crate) *mut T);
unsafe impl<T> Send for Ptr<T> {}
unsafe impl<T> Sync for Ptr<T> {}
impl<T> Ptr<T> {
    /// Write slot `i` without reading or dropping what was there.
    #[inline(always)]
    pub(crate) unsafe fn write(&self, i: usize, v: T) { unsafe { self.0.add(i).write(v) } }
}
impl<T: Copy> Ptr<T> {
    #[inline(always)]
    pub(crate) unsafe fn get(self, i: usize) -> T { unsafe { *self.0.add(i) } }
    #[inline(always)]
    pub(crate) unsafe fn set(self, i: usize, v: T) { unsafe { *self.0.add(i) = v } }
}

/// A slice indexed without bounds checks, for the hot loops whose indices come from the
/// neighbour list and gather tables (every entry < the number of grains / pairs they were
/// built for; a state that loses grains gets a new `World`, one that gains grains a
/// rebuild). Checked in debug builds.
#[derive(Clone, Copy)]
pub(crate) struct U<'a, T>(pub(crate) &'a [T]);
impl<T> std::ops::Index<usize> for U<'_, T> {
    type Output = T;
    #[inline(always)]
    fn index(&self, i: usize) -> &T {
        debug_assert!(i < self.0.len());
        // SAFETY: see the type's doc
        unsafe { self.0.get_unchecked(i) }
    }
}

/// Per-chunk partial results, summed in chunk order.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Partial {
    pub ledger: Ledger,
    pub max_overlap: Real,
    pub max_i: u32,
    pub max_j: u32,
    pub wall_force: [Vec2; MAX_WALLS],
    pub moved: bool,
    /// Rolling dashpots this chunk listed (pair pass), per wall (wall pass).
    pub n_roll: [u32; MAX_WALLS],
}

/// One implicit rolling dashpot for the integrator's sweep: grains `i`, `j` (`j =
/// u32::MAX`: a wall) and the dashpot.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct RollItem {
    pub i: u32,
    pub j: u32,
    pub d: RollDashpot,
}

/// The dashpots of the last force evaluation, compacted in sweep order: chunk `c` of the
/// pair pass wrote its dashpots to `items[c * PAIR_CHUNK..][..count[c]]` in pair order;
/// the grain chunk `c` of wall `wi` to `witems[wi * n + c * GRAIN_CHUNK..][..wcount[wi * nc + c]]`.
/// The sweep reads them in that order — pairs by (i, j), then walls by (wall, grain), as
/// before — without scanning the separated pairs and empty wall slots.
#[derive(Debug, Clone, Default)]
pub(crate) struct RollLists {
    pub items: Vec<RollItem>,
    pub count: Vec<u32>,
    pub witems: Vec<RollItem>,
    pub wcount: Vec<u32>,
}

impl Partial {
    pub(crate) fn merge(&mut self, o: &Partial) {
        self.ledger += o.ledger;
        if o.max_overlap > self.max_overlap {
            self.max_overlap = o.max_overlap;
            self.max_i = o.max_i;
            self.max_j = o.max_j;
        }
        for w in 0..MAX_WALLS {
            self.wall_force[w] += o.wall_force[w];
        }
        self.moved |= o.moved;
    }
}

/// What one chunk of the fused grain pass returns: the wall pass's partial, the kick's
/// partial (merged apart, in chunk order, exactly as the separate passes did) and the CPU
/// seconds of its three parts (gather, walls, kick), by which the pass's wall time is
/// apportioned to the phase timers.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct GrainChunk {
    pub walls: Partial,
    pub kick: Partial,
    pub secs: [f64; 3],
}

/// A new largest overlap fraction in a chunk: rare (a few times per chunk), so kept out of
/// the pair loop (the division is not evaluated for every contact).
#[cold]
#[inline(never)]
fn new_max_overlap(part: &mut Partial, overlap: Real, dmin: Real, i: usize, j: usize) {
    part.max_overlap = overlap / dmin;
    part.max_i = i as u32;
    part.max_j = j as u32;
}

/// Below this many grains a world steps on its calling thread (the team's threshold,
/// [`crate::dem::team::TEAM_MIN_GRAINS`]; the name the stage drivers refer to).
pub const PAR_MIN_ITEMS: usize = crate::dem::team::TEAM_MIN_GRAINS;

/// `f(lo, hi)` for each chunk of `chunk` items of `0..n`, results in chunk order in `out`:
/// shared out on the world's thread team inside a [`World::run`] that has one (see
/// [`crate::dem::team`]), else in order on this thread. The chunking — and so every
/// sum's order — is the same either way, so results do not depend on the thread count.
pub(crate) fn chunked<T: Send>(n: usize, chunk: usize, out: &mut Vec<T>, f: impl Fn(usize, usize) -> T + Sync + Send) {
    let nc = n.div_ceil(chunk);
    out.clear();
    out.reserve(nc);
    let dst = Ptr(out.as_mut_ptr());
    crate::dem::team::for_chunks(nc, &|c| {
        let v = f(c * chunk, ((c + 1) * chunk).min(n));
        // SAFETY: each chunk index is run exactly once, into reserved capacity
        unsafe { dst.write(c, v) };
    });
    // SAFETY: every slot 0..nc was written above (for_chunks returns when all are done)
    unsafe { out.set_len(nc) };
}

thread_local! {
    /// Lanes of the pair pass's batches, one set per thread (kept between chunks: filling
    /// 20 kB with zeros per chunk cost 2 % of the step).
    static PAIR_SCRATCH: std::cell::Cell<Option<Box<(PairBatch, PairBatchOut)>>> = const { std::cell::Cell::new(None) };
}

/// Contact histories of a settled state (see [`World::saved_histories`]).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SavedHistories {
    /// Grain pairs (i < j) and their history.
    pub pairs: Vec<(u32, u32, ContactState)>,
    /// Grain–wall contacts: (wall index, grain, history).
    pub walls: Vec<(u32, u32, ContactState)>,
}

/// Diagnostics of the last step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepInfo {
    /// Largest overlap / smaller diameter of the pair (or the grain at a wall).
    pub max_overlap_fraction: Real,
    /// Grains of that contact (j = u32::MAX for a wall).
    pub max_pair: (u32, u32),
    /// Force exerted by the grains on each wall [N/m] (index as in `walls`).
    pub wall_force: [Vec2; MAX_WALLS],
}

/// A DEM scene with its solver scratch.
#[derive(Debug, Clone)]
pub struct World {
    /// Parameters (read each step; change between `run` calls only).
    pub params: DemParams,
    /// Grain state.
    pub state: State,
    /// Walls (at most [`MAX_WALLS`]).
    pub walls: Vec<Wall>,
    /// Period along x [m], if the cell is periodic in x.
    pub periodic_x: Option<Real>,
    /// Simulated time [s].
    pub t: Real,
    /// Steps done.
    pub steps: u64,
    /// Cumulative dissipation (filled when `params.ledger`).
    pub ledger: Ledger,
    /// Total energy when the ledger was (re)started [J/m].
    pub e0: Real,
    /// Whether the watchdog's energy-rise check applies (off for driven scenes without ledger).
    pub energy_check: bool,
    /// Phase timers.
    pub timers: PhaseTimers,
    /// Optional physics paths taken (leave-out counters).
    pub paths: crate::dem::timers::PathCounts,
    /// Last step's diagnostics.
    pub info: StepInfo,
    /// Below this many grains the world steps on its calling thread even in a
    /// multi-thread pool (default [`crate::dem::team::TEAM_MIN_GRAINS`]; results are the
    /// same either way — `bench dem-crossover` sets it to measure the crossover).
    pub team_min_grains: usize,
    /// Whether `run` times steps alone against steps with the team and keeps the faster
    /// (default true; `bench dem-crossover` turns it off to time the team itself).
    pub team_probe: bool,
    /// Keep the phase timers (`timers`; default false: no clock calls in the steps).
    pub timing: bool,
    /// The probe's choice (team or alone) and the step until which it holds.
    pub(crate) team_on: bool,
    pub(crate) team_until: u64,
    /// Probes lost by the team in a row (a lost probe is retried after TEAM_SEGMENT / 16
    /// steps, doubling with every further loss up to TEAM_SEGMENT / 4).
    pub(crate) team_lost: u32,
    pub(crate) nl: NeighborList,
    pub(crate) wall_hist: Vec<ContactState>,
    pub(crate) wall_cn: Vec<Real>,
    pub(crate) fx: Vec<Real>,
    pub(crate) fy: Vec<Real>,
    pub(crate) tq: Vec<Real>,
    /// Per-pair output [f_x, f_y, torque_i, torque_j] (one cache line per two pairs).
    pub(crate) pout: Vec<[Real; 4]>,
    /// Implicit rolling dashpots of the last force evaluation, in sweep order.
    pub(crate) roll: RollLists,
    /// Per listed pair: 0 when its last evaluation found it separated, so that its
    /// history and output are zero and stay so while it stays separated (the pair pass
    /// then does nothing for it). Set to 1 for
    /// every pair by a rebuild or a history restore.
    pub(crate) plive: Vec<u8>,
    /// The same per grain–wall slot (`wall * n + grain`).
    pub(crate) wlive: Vec<u8>,
    pub(crate) partials: Vec<Partial>,
    /// Per-chunk results of the fused grain pass (gather + walls + second half kick).
    pub(crate) gpartials: Vec<GrainChunk>,
    pub(crate) forces_valid: bool,
    /// Inactive walls whose contact histories have been released.
    pub(crate) wall_cleared: [bool; MAX_WALLS],
    /// Walls as they were at the end of the last `run` (edits in between invalidate forces).
    pub(crate) walls_seen: Vec<Wall>,
}

impl World {
    /// A world from a state, walls and parameters. Validates the parameters.
    pub fn new(params: DemParams, state: State, walls: Vec<Wall>, periodic_x: Option<Real>) -> Result<Self, DemError> {
        let issues = params.validate();
        if !issues.is_empty() {
            let s: Vec<String> = issues.iter().map(|i| format!("{} = {} (allowed: {})", i.key, i.value, i.allowed)).collect();
            return Err(DemError::InvalidParams(s.join("; ")));
        }
        if walls.len() > MAX_WALLS {
            return Err(DemError::Setup(format!("{} walls given, at most {MAX_WALLS} supported", walls.len())));
        }
        if periodic_x.is_some_and(|l| !(l > 0.0)) {
            return Err(DemError::Setup("periodic period must be > 0".into()));
        }
        let mut w = World {
            params,
            state,
            walls,
            periodic_x,
            t: 0.0,
            steps: 0,
            ledger: Ledger::default(),
            e0: 0.0,
            energy_check: true,
            timers: PhaseTimers::default(),
            paths: Default::default(),
            info: StepInfo::default(),
            team_min_grains: crate::dem::team::TEAM_MIN_GRAINS,
            team_probe: true,
            timing: false,
            team_on: false,
            team_until: 0,
            team_lost: 0,
            nl: NeighborList::default(),
            wall_hist: Vec::new(),
            wall_cn: Vec::new(),
            fx: Vec::new(),
            fy: Vec::new(),
            tq: Vec::new(),
            pout: Vec::new(),
            wall_cleared: [false; MAX_WALLS],
            walls_seen: Vec::new(),
            roll: RollLists::default(),
            plive: Vec::new(),
            wlive: Vec::new(),
            partials: Vec::new(),
            gpartials: Vec::new(),
            forces_valid: false,
        };
        w.resize_scratch();
        w.rebuild();
        w.e0 = w.energies().total();
        Ok(w)
    }

    /// Call after appending grains or changing masses (histories of existing grains are
    /// kept; after removing grains build a new `World` instead).
    pub fn resize_scratch(&mut self) {
        let n = self.state.len();
        for v in [&mut self.fx, &mut self.fy, &mut self.tq] {
            v.clear();
            v.resize(n, 0.0);
        }
        self.roll.witems.clear();
        self.roll.witems.resize(MAX_WALLS * n, RollItem::default());
        self.roll.wcount.clear();
        self.roll.wcount.resize(MAX_WALLS * n.div_ceil(GRAIN_CHUNK), 0);
        // keep wall histories of grains that still exist (grains appended at the end)
        let old_n = self.wall_hist.len() / MAX_WALLS;
        let mut wh = vec![ContactState::default(); MAX_WALLS * n];
        for wi in 0..MAX_WALLS {
            for a in 0..old_n.min(n) {
                wh[wi * n + a] = self.wall_hist[wi * old_n + a];
            }
        }
        self.wall_hist = wh;
        self.wlive.clear();
        self.wlive.resize(MAX_WALLS * n, 1);
        let (z, kn) = (self.params.wall.damping_ratio(), self.params.wall.kn);
        self.wall_cn = self.state.m.iter().map(|&m| normal_damping(z, m, kn)).collect();
        // the list is rebuilt (positions changed); pair histories are kept by key
        self.nl.x0.clear();
        self.forces_valid = false;
    }

    /// Rebuild the neighbour list now.
    pub fn rebuild(&mut self) {
        let skin = self.params.skin_fraction * 2.0 * self.state.r.iter().cloned().fold(0.0, Real::max);
        let (z, kn) = (self.params.grain.damping_ratio(), self.params.grain.kn);
        let m = std::mem::take(&mut self.state.m);
        let mut s = std::mem::take(&mut self.state);
        s.m = Vec::new();
        self.nl.build(&mut s, skin, self.periodic_x, |i, j| normal_damping(z, m[i] * m[j] / (m[i] + m[j]), kn));
        s.m = m;
        self.state = s;
        let np = self.nl.len();
        self.pout.resize(np, [0.0; 4]);
        self.roll.items.resize(np, RollItem::default());
        self.roll.count.resize(np.div_ceil(PAIR_CHUNK), 0);
        self.plive.clear();
        self.plive.resize(np, 1);
    }

    /// Forces must be recomputed before the next kick (after external state edits that
    /// change positions, e.g. moving grains by hand).
    pub fn invalidate_forces(&mut self) { self.forces_valid = false; }

    /// Size classes of the current grains.
    pub fn size_classes(&self) -> SizeClasses {
        let (r_min, r_mean, r_max) = self.state.radius_stats();
        SizeClasses { r_min, r_mean, r_max }
    }

    /// Stability audit of this scene at `params.dt`.
    pub fn preflight(&self) -> Result<Preflight, DemError> {
        preflight(&self.params, self.size_classes(), !self.walls.is_empty(), self.params.dt)
    }

    /// Restart the ledger: zero dissipation, E_0 = current total energy.
    pub fn reset_ledger(&mut self) {
        self.ledger = Ledger::default();
        self.e0 = self.energies().total();
    }

    /// Add work done on the grains by an outside driver [J/m].
    pub fn add_external_work(&mut self, w: Real) { self.ledger.external_work += w; }

    /// One step.
    pub fn step(&mut self) -> Result<(), DemError> { self.run(1) }

    /// `n` steps; physics variant chosen once.
    pub fn run(&mut self, n: u64) -> Result<(), DemError> {
        if self.walls.len() > MAX_WALLS {
            return Err(DemError::Setup(format!("{} walls, at most {MAX_WALLS} supported", self.walls.len())));
        }
        let rolling = self.params.rolling.enabled;
        // no dashpot (c_r = 0): nothing to sweep; the explicit path is the same arithmetic
        let implicit = self.params.rolling.damping == RollingDamping::Implicit && self.params.rolling.cr > 0.0;
        let ledger = self.params.ledger;
        match (rolling, implicit, ledger) {
            (true, true, true) => self.run_with::<true, true, true>(n),
            (true, true, false) => self.run_with::<true, true, false>(n),
            (true, false, true) => self.run_with::<true, false, true>(n),
            (true, false, false) => self.run_with::<true, false, false>(n),
            (false, _, true) => self.run_with::<false, false, true>(n),
            (false, _, false) => self.run_with::<false, false, false>(n),
        }
    }

    /// Run until simulated time `t_end` (at most) [s].
    pub fn run_until(&mut self, t_end: Real) -> Result<(), DemError> {
        let n = ((t_end - self.t) / self.params.dt).round();
        if n > 0.0 { self.run(n as u64) } else { Ok(()) }
    }

    fn run_with<const R: bool, const IMP: bool, const L: bool>(&mut self, n: u64) -> Result<(), DemError> {
        // The hot loops index the grain arrays with the list's indices unchecked (`U`):
        // a state edited without `resize_scratch` (or resized without a rebuild) gets its
        // scratch and list brought up to date first. The library's own callers never
        // reach these branches (they resize and rebuild themselves), so no result moves.
        let ng = self.state.len();
        if self.fx.len() != ng || self.wall_cn.len() != ng {
            self.resize_scratch();
        }
        if self.nl.x0.len() != ng {
            self.rebuild();
        }
        if self.walls != self.walls_seen {
            // a wall was edited between runs (gate removed, wall shifted): the stored forces
            // are stale for the first half kick
            self.forces_valid = false;
        }
        if !self.forces_valid {
            self.compute_forces::<R, IMP, L, false>(0.0);
            self.forces_valid = true;
        }
        let team = ng >= self.team_min_grains && rayon::current_num_threads() > 1;
        let mut res = Ok(());
        let mut left = n;
        while left > 0 && res.is_ok() {
            if team && self.team_probe && self.steps >= self.team_until && left >= 2 * TEAM_PROBE {
                // Time TEAM_PROBE steps alone, then as many with the thread team, and keep
                // the faster for the next TEAM_SEGMENT steps (the machine's load changes;
                // results are the same either way).
                let t0 = Instant::now();
                res = self.steps_with::<R, IMP, L>(TEAM_PROBE);
                let solo = t0.elapsed();
                if res.is_err() { break; }
                let k = (left - 2 * TEAM_PROBE).min(TEAM_SEGMENT);
                let mut ran = 0;
                res = crate::dem::team::with_team(true, || {
                    // the first team steps wait for the helpers to wake and fill their
                    // caches: time the team after TEAM_PROBE / 4 of them
                    self.steps_with::<R, IMP, L>(TEAM_PROBE / 4)?;
                    let t1 = Instant::now();
                    self.steps_with::<R, IMP, L>(TEAM_PROBE - TEAM_PROBE / 4)?;
                    let team = t1.elapsed().as_secs_f64() / (TEAM_PROBE - TEAM_PROBE / 4) as f64;
                    // the team must be clearly faster: a short probe is noisy
                    self.team_on = team < 0.9 * solo.as_secs_f64() / TEAM_PROBE as f64;
                    // a lost probe is retried sooner: after 256 steps at first (a moment
                    // when the other core was busy, or noise, should not cost a whole
                    // segment), backing off to 1024 while the team keeps losing (a loaded
                    // machine, where every team probe is slow)
                    self.team_lost = if self.team_on { 0 } else { (self.team_lost + 1).min(3) };
                    self.team_until = self.steps + if self.team_on { TEAM_SEGMENT } else { (TEAM_SEGMENT / 16) << (self.team_lost - 1) };
                    if !self.team_on {
                        crate::dem::team::dismiss();
                    }
                    ran = k.min(self.team_until - self.steps);
                    self.steps_with::<R, IMP, L>(ran)
                });
                left -= 2 * TEAM_PROBE + ran;
            } else {
                let on = team && (!self.team_probe || self.team_on);
                // until the choice expires (then probe again), else to the end
                let k = if team && self.team_probe && self.team_until > self.steps { left.min(self.team_until - self.steps) } else { left };
                res = crate::dem::team::with_team(on, || self.steps_with::<R, IMP, L>(k));
                left -= k;
            }
        }
        self.walls_seen.clone_from(&self.walls);
        res
    }

    fn steps_with<const R: bool, const IMP: bool, const L: bool>(&mut self, n: u64) -> Result<(), DemError> {
        // between two steps of this call, the end of one and the start of the next run as
        // one team phase (`World::step_boundary`), except where the watchdog looks at the
        // state between them; on one thread the separate passes (one kick loop over
        // v and ω) are as fast
        let boundary = n >= 2 && crate::dem::team::active() && self.boundary_ok::<IMP>();
        let wd = self.params.watchdog.every;
        let mut first = None;
        for k in 0..n {
            let join = boundary && k + 1 < n && !(wd > 0 && (self.steps + 1) % wd == 0);
            first = self.step_with::<R, IMP, L>(first, join)?;
        }
        Ok(())
    }

    /// One step; `first`: its first half was done by the previous step's boundary (with
    /// whether the list must be rebuilt); `join`: end with [`World::step_boundary`] (the
    /// next step's first half, returned as its `first`).
    fn step_with<const R: bool, const IMP: bool, const L: bool>(&mut self, first: Option<bool>, join: bool) -> Result<Option<bool>, DemError> {
        let dt = self.params.dt;
        let on = self.timing;
        let t0 = Clock::now(on);
        let moved = match first {
            Some(m) => m,
            None => self.integrate_first_half::<IMP, L>(),
        };
        let t1 = Clock::now(on);
        self.timers.integrate += t0.to(t1);
        if moved { self.refresh_neighbors(); }
        let t2 = Clock::now(on);
        self.timers.neighbors += t1.to(t2);
        // contacts, walls and the second half kick (fused per grain chunk)
        self.compute_forces::<R, IMP, L, true>(dt);
        let t3 = Clock::now(on);
        if join {
            let next = self.step_boundary::<L>();
            self.t += dt;
            self.steps += 1;
            self.timers.integrate += t3.elapsed();
            return Ok(Some(next));
        }
        self.integrate_second_half::<IMP, L>();
        self.t += dt;
        self.steps += 1;
        let t4 = Clock::now(on);
        self.timers.integrate += t3.to(t4);
        let wd = self.params.watchdog.every;
        if wd > 0 && self.steps % wd == 0 {
            self.watchdog()?;
        }
        self.timers.watchdog += t4.elapsed();
        Ok(None)
    }

    fn refresh_neighbors(&mut self) { self.rebuild(); }

    /// Contact and wall forces at the current positions with the current velocities;
    /// histories advance by `dt` (0 for the priming evaluation). With `KICK`, the second
    /// half kick follows in the same per-chunk pass (see [`World::grain_pass`]).
    fn compute_forces<const R: bool, const IMP: bool, const L: bool, const KICK: bool>(&mut self, dt: Real) {
        let on = self.timing;
        let t0 = Clock::now(on);
        (self.paths.rolling_forces, self.paths.ledger) = (self.paths.rolling_forces + R as u64, self.paths.ledger + L as u64);
        let p = self.compute_contacts::<R, IMP, L>(dt);
        let t1 = Clock::now(on);
        self.timers.contacts += t0.to(t1);
        let (q, k) = self.grain_pass::<R, IMP, L, KICK>(dt);
        let t2 = Clock::now(on);
        self.ledger_phase::<L>(&p, &q);
        if KICK && L {
            // the kick's partial after the contacts', as when the kick was its own pass
            self.ledger += k.ledger;
        }
        self.timers.ledger += t2.elapsed();
    }

    fn ledger_phase<const L: bool>(&mut self, p: &Partial, q: &Partial) {
        let (fp, fq) = (p.max_overlap, q.max_overlap);
        self.info.max_overlap_fraction = fp.max(fq);
        self.info.max_pair = if fp >= fq { (p.max_i, p.max_j) } else { (q.max_i, u32::MAX) };
        self.info.wall_force = q.wall_force;
        if L {
            self.ledger += p.ledger;
            self.ledger += q.ledger;
        }
    }

    /// Pair forces in parallel, then a per-grain gather in fixed order.
    fn compute_contacts<const R: bool, const IMP: bool, const L: bool>(&mut self, dt: Real) -> Partial {
        let coeffs = LawCoeffs::new(&self.params.grain, &self.params.rolling);
        let s = &self.state;
        let nl = &mut self.nl;
        let np = nl.pi.len();
        let lx = self.periodic_x.unwrap_or(0.0);
        let (pi, pj, shift, cn, rr) = (U(&nl.pi[..]), U(&nl.pj[..]), U(&nl.shift[..]), U(&nl.cn[..]), U(&nl.r_roll[..]));
        let n_grains = s.len();
        debug_assert!(nl.pj.iter().all(|&j| (j as usize) < n_grains));
        let hist = Ptr(nl.hist.as_mut_ptr());
        let (pout, ritems) = (Ptr(self.pout.as_mut_ptr()), Ptr(self.roll.items.as_mut_ptr()));
        debug_assert_eq!(self.plive.len(), np);
        let live = Ptr(self.plive.as_mut_ptr());
        let (x, y, vx, vy, w, r) = (U(&s.x[..]), U(&s.y[..]), U(&s.vx[..]), U(&s.vy[..]), U(&s.w[..]), U(&s.r[..]));
        chunked(np, PAIR_CHUNK, &mut self.partials, move |lo, hi| {
            let mut part = Partial::default();
            // Pass 1, branch-free: the pairs with work to do (touching, or separated with a
            // history still to drop), in pair order. A separated pair found separated before
            // has nothing left to drop and is skipped: whether a pair touches follows no
            // pattern along the list, and as a branch it was mispredicted pair after pair.
            let mut todo = [0u16; PAIR_CHUNK];
            let mut n_todo = 0usize;
            for k in lo..hi {
                let (i, j) = (pi[k] as usize, pj[k] as usize);
                let dx = x[i] - (x[j] + shift[k] * lx);
                let dy = y[i] - y[j];
                let rsq = dx * dx + dy * dy;
                let radsum = r[i] + r[j];
                let touching = !(rsq >= radsum * radsum);
                let work = touching | unsafe { live.get(k) != 0 };
                todo[n_todo] = (k - lo) as u16;
                n_todo += usize::from(work);
            }
            // Pass 2: those pairs in order, with the same arithmetic as a single pass, in
            // batches: (a) gather each pair's inputs into lanes, (b) evaluate the law on
            // all lanes at once (`Law::eval_pairs`, SIMD), (c) store the results and book
            // the sums pair by pair. The ledger sums run in registers (same order of
            // additions as into `part`).
            let (mut led_n, mut led_t, mut led_r) = (0.0, 0.0, 0.0);
            let mut n_roll = 0usize;
            let mut scratch = PAIR_SCRATCH.take().unwrap_or_else(|| Box::new((PairBatch::default(), PairBatchOut::default())));
            let (b, bo) = &mut *scratch;
            for batch in todo[..n_todo].chunks(BATCH) {
                let nb = batch.len();
                // (a) gather
                for (l, &o) in batch.iter().enumerate() {
                    let k = lo + o as usize;
                    let (i, j) = (pi[k] as usize, pj[k] as usize);
                    let dx = x[i] - (x[j] + shift[k] * lx);
                    let dy = y[i] - y[j];
                    b.dx[l] = dx;
                    b.dy[l] = dy;
                    b.rsq[l] = dx * dx + dy * dy;
                    b.radsum[l] = r[i] + r[j];
                    b.dvx[l] = vx[i] - vx[j];
                    b.dvy[l] = vy[i] - vy[j];
                    b.w_i[l] = w[i];
                    b.w_j[l] = w[j];
                    b.r_i[l] = r[i];
                    b.r_j[l] = r[j];
                    b.r_roll[l] = rr[k];
                    b.cn[l] = cn[k];
                    let h = unsafe { hist.get(k) };
                    b.h[0][l] = h.tangential;
                    b.h[1][l] = h.rolling;
                    b.h[2][l] = h.ft;
                    b.h[3][l] = h.mr;
                }
                // (b) the law on every lane (separated lanes give unused numbers)
                Law::<R, IMP, L>::eval_pairs(&coeffs, b, bo, nb, dt);
                // (c) store, in pair order
                for (l, &o) in batch.iter().enumerate() {
                    let k = lo + o as usize;
                    let (i, j) = (pi[k] as usize, pj[k] as usize);
                    let radsum = b.radsum[l];
                    unsafe {
                        // separated → drop history (once)
                        if b.rsq[l] >= radsum * radsum {
                            live.set(k, 0);
                            let h = hist.get(k);
                            if h != ContactState::default() {
                                if L {
                                    let (et, er) = Law::<R, IMP, L>::released(&coeffs, &h);
                                    led_t += et;
                                    led_r += er;
                                }
                                hist.set(k, ContactState::default());
                            }
                            pout.set(k, [0.0; 4]);
                            continue;
                        }
                        let overlap = bo.overlap[l];
                        let dmin = 2.0 * r[i].min(r[j]);
                        if overlap > part.max_overlap * dmin {
                            new_max_overlap(&mut part, overlap, dmin, i, j);
                        }
                        live.set(k, 1);
                        hist.set(k, ContactState { tangential: b.h[0][l], rolling: b.h[1][l], ft: b.h[2][l], mr: b.h[3][l] });
                        pout.set(k, [bo.fx[l], bo.fy[l], bo.t_i[l], bo.t_j[l]]);
                        if IMP {
                            // written always, kept (counted) only with a dashpot: no branch
                            let d = RollDashpot { c: bo.roll[0][l], m_spring: bo.roll[1][l], m_max: bo.roll[2][l] };
                            ritems.set(lo + n_roll, RollItem { i: i as u32, j: j as u32, d });
                            n_roll += usize::from(d.c > 0.0);
                        }
                        if L {
                            led_n += bo.work[0][l];
                            led_t += bo.work[1][l];
                            led_r += bo.work[2][l];
                        }
                    }
                }
            }
            PAIR_SCRATCH.set(Some(scratch));
            part.ledger.normal_damping += led_n;
            part.ledger.tangential += led_t;
            part.ledger.rolling += led_r;
            part.n_roll[0] = n_roll as u32;
            part
        });
        let mut total = Partial::default();
        for (c, p) in self.partials.iter().enumerate() {
            total.merge(p);
            self.roll.count[c] = p.n_roll[0];
        }
        total
    }

    /// The per-grain pass after the pair pass, chunk by chunk (one fork-join, each chunk's
    /// grains stay in cache): (1) gather of the pair forces in increasing pair order plus
    /// gravity, (2) grain–wall contacts with the same law, walls in order, (3) with `KICK`
    /// the second half kick. Every grain's arithmetic and every partial sum is in the same
    /// order as when these were three passes (walls within a chunk: wall by wall, grains in
    /// order), so the results are bit-identical to them. Returns the wall partial (with the
    /// released inactive walls first) and the kick partial, each merged in chunk order.
    fn grain_pass<const R: bool, const IMP: bool, const L: bool, const KICK: bool>(&mut self, dt: Real) -> (Partial, Partial) {
        let on = self.timing;
        let clock = Clock::now(on);
        let mut total = Partial::default();
        self.release_inactive_walls::<R, IMP, L>(&mut total);
        let any_wall = self.walls.iter().any(|w| w.active);
        let coeffs = LawCoeffs::new(&self.params.wall, &self.params.rolling);
        let s = &mut self.state;
        let n = s.len();
        let walls = &self.walls[..];
        let g = self.params.gravity;
        let nl = &self.nl;
        let (istart, jstart, jlist) = (U(&nl.istart[..]), U(&nl.jstart[..]), &nl.jlist[..]);
        let pout = U(&self.pout[..]);
        let m = U(&s.m[..]);
        let (x, y, r) = (U(&s.x[..]), U(&s.y[..]), U(&s.r[..]));
        let (inv_m, inv_i) = (U(&s.inv_m[..]), U(&s.inv_i[..]));
        let (vx, vy, w) = (Ptr(s.vx.as_mut_ptr()), Ptr(s.vy.as_mut_ptr()), Ptr(s.w.as_mut_ptr()));
        let wcn = U(&self.wall_cn[..]);
        let hist = Ptr(self.wall_hist.as_mut_ptr());
        let (fx, fy, tq, witems) = (Ptr(self.fx.as_mut_ptr()), Ptr(self.fy.as_mut_ptr()), Ptr(self.tq.as_mut_ptr()), Ptr(self.roll.witems.as_mut_ptr()));
        let live = Ptr(self.wlive.as_mut_ptr());
        let h = 0.5 * self.params.dt;
        let dt_step = self.params.dt;
        let th = Ptr(s.theta.as_mut_ptr());
        chunked(n, GRAIN_CHUNK, &mut self.gpartials, move |lo, hi| {
            let t0 = Clock::now(on);
            if IMP && KICK {
                // θ ← θ + Δt ω of the step's first half (ω after the first dashpot sweep;
                // see `World::integrate_first_half`)
                // SAFETY: this chunk's grains only
                let (thp, wp) = (th, w);
                unsafe {
                    let (th, w) = (std::slice::from_raw_parts_mut(thp.0.add(lo), hi - lo), std::slice::from_raw_parts(wp.0.add(lo), hi - lo));
                    for a in 0..hi - lo {
                        th[a] += dt_step * w[a];
                    }
                }
            }
            // (1) gather per grain, in increasing pair order
            for a in lo..hi {
                let (mut ax, mut ay, mut at) = (0.0, -m[a] * g, 0.0);
                // pairs where a is i: contiguous, sequential reads
                for k in istart[a] as usize..istart[a + 1] as usize {
                    let o = &pout[k];
                    ax += o[0];
                    ay += o[1];
                    at += o[2];
                }
                // pairs where a is j
                for &k in &jlist[jstart[a] as usize..jstart[a + 1] as usize] {
                    let k = k as usize;
                    let o = &pout[k];
                    ax -= o[0];
                    ay -= o[1];
                    at += o[3];
                }
                unsafe {
                    fx.set(a, ax);
                    fy.set(a, ay);
                    tq.set(a, at);
                }
            }
            let t1 = Clock::now(on);
            // (2) grain–wall contacts, wall by wall
            let mut part = Partial::default();
            if any_wall {
                for (wi, wall) in walls.iter().enumerate() {
                    if !wall.active { continue; }
                    for a in lo..hi {
                        let hk = wi * n + a;
                        let p = Vec2::new(x[a], y[a]);
                        let overlap = r[a] - wall.distance(p);
                        if overlap <= 0.0 {
                            unsafe {
                                if live.get(hk) == 0 { continue; }
                                live.set(hk, 0);
                                let h = hist.get(hk);
                                if h != ContactState::default() {
                                    if L {
                                        let (et, er) = Law::<R, IMP, L>::released(&coeffs, &h);
                                        part.ledger.wall_tangential += et;
                                        part.ledger.rolling += er;
                                    }
                                    hist.set(hk, ContactState::default());
                                }
                            }
                            continue;
                        }
                        let frac = overlap / (2.0 * r[a]);
                        if frac > part.max_overlap {
                            part.max_overlap = frac;
                            part.max_i = a as u32;
                        }
                        unsafe {
                            let pin = PairIn {
                                n: wall.normal,
                                overlap,
                                v_rel: Vec2::new(vx.get(a), vy.get(a)) - wall.velocity,
                                w_i: w.get(a),
                                w_j: 0.0,
                                arm_i: r[a],
                                arm_j: 0.0,
                                r_roll: r[a],
                                cn: wcn[a],
                            };
                            live.set(hk, 1);
                            let mut h = hist.get(hk);
                            let o = Law::<R, IMP, L>::eval(&coeffs, &pin, &mut h, dt);
                            hist.set(hk, h);
                            fx.set(a, fx.get(a) + o.f.x);
                            fy.set(a, fy.get(a) + o.f.y);
                            tq.set(a, tq.get(a) + o.t_i);
                            if IMP && o.roll.c > 0.0 {
                                witems.set(wi * n + lo + part.n_roll[wi] as usize, RollItem { i: a as u32, j: u32::MAX, d: o.roll });
                                part.n_roll[wi] += 1;
                            }
                            part.wall_force[wi] -= o.f;
                            if L {
                                part.ledger.wall_normal += o.work.normal;
                                part.ledger.wall_tangential += o.work.tangential;
                                part.ledger.rolling += o.work.rolling;
                                part.ledger.external_work += o.f.dot(&wall.velocity) * dt;
                            }
                        }
                    }
                }
            }
            let t2 = Clock::now(on);
            // (3) second half kick with the complete forces
            let mut kpart = Partial::default();
            if KICK {
                // SAFETY: this chunk's grains, written above by this chunk only
                unsafe {
                    let f = |p: Ptr<Real>| std::slice::from_raw_parts(p.0.add(lo), hi - lo);
                    kick_range::<L>(lo, hi, h, (&inv_m.0[lo..hi], &inv_i.0[lo..hi]), (f(fx), f(fy), f(tq)), (vx, vy, w), &mut kpart);
                }
            }
            let t3 = Clock::now(on);
            GrainChunk { walls: part, kick: kpart, secs: [t0.to(t1), t1.to(t2), t2.to(t3)] }
        });
        let wall_s = clock.elapsed();
        let nc = self.gpartials.len();
        let mut kick = Partial::default();
        let mut cpu = [0.0; 3];
        for (c, p) in self.gpartials.iter().enumerate() {
            if any_wall {
                total.merge(&p.walls);
                for wi in 0..MAX_WALLS {
                    self.roll.wcount[wi * nc + c] = p.walls.n_roll[wi];
                }
            }
            kick.merge(&p.kick);
            for (s, x) in cpu.iter_mut().zip(p.secs) {
                *s += x;
            }
        }
        if !any_wall {
            self.roll.wcount.fill(0);
        }
        let sum = (cpu[0] + cpu[1] + cpu[2]).max(1e-12);
        self.timers.gather += wall_s * cpu[0] / sum;
        self.timers.walls += wall_s * cpu[1] / sum;
        self.timers.integrate += wall_s * cpu[2] / sum;
        (total, kick)
    }

    /// A wall that was switched off (removed gate) gives up its contacts once: stored
    /// spring energy is booked as dissipated and the history zeroed.
    fn release_inactive_walls<const R: bool, const IMP: bool, const L: bool>(&mut self, total: &mut Partial) {
        let n = self.state.len();
        let coeffs = LawCoeffs::new(&self.params.wall, &self.params.rolling);
        for (wi, wall) in self.walls.iter().enumerate() {
            if wall.active {
                self.wall_cleared[wi] = false;
                continue;
            }
            if self.wall_cleared[wi] { continue; }
            for h in &mut self.wall_hist[wi * n..(wi + 1) * n] {
                if L {
                    let (et, er) = Law::<R, IMP, L>::released(&coeffs, h);
                    total.ledger.wall_tangential += et;
                    total.ledger.rolling += er;
                }
                *h = ContactState::default();
            }
            self.wall_cleared[wi] = true;
        }
    }

    /// Energies of the current configuration (D06), elastic parts included.
    pub fn energies(&self) -> Energies {
        let s = &self.state;
        let g = self.params.gravity;
        let mut e = Energies::default();
        for i in 0..s.len() {
            e.ep += s.m[i] * g * s.y[i];
            e.ekx += 0.5 * s.m[i] * s.vx[i] * s.vx[i];
            e.eky += 0.5 * s.m[i] * s.vy[i] * s.vy[i];
            e.erot += 0.5 * s.inertia[i] * s.w[i] * s.w[i];
        }
        let (kn, kt, kr) = (self.params.grain.kn, self.params.grain.kt, if self.params.rolling.enabled { self.params.rolling.kr } else { 0.0 });
        let lx = self.periodic_x.unwrap_or(0.0);
        let nl = &self.nl;
        for k in 0..nl.len() {
            let (i, j) = (nl.pi[k] as usize, nl.pj[k] as usize);
            let dx = s.x[i] - (s.x[j] + nl.shift[k] * lx);
            let dy = s.y[i] - s.y[j];
            let ov = s.r[i] + s.r[j] - (dx * dx + dy * dy).sqrt();
            if ov > 0.0 {
                e.elastic_normal += 0.5 * kn * ov * ov;
            }
            let h = nl.hist[k];
            e.elastic_tangential += 0.5 * kt * h.tangential * h.tangential;
            e.elastic_rolling += 0.5 * kr * h.rolling * h.rolling;
        }
        let (kwn, kwt) = (self.params.wall.kn, self.params.wall.kt);
        let n = s.len();
        for (wi, wall) in self.walls.iter().enumerate() {
            for a in 0..n {
                let h = self.wall_hist[wi * n + a];
                e.elastic_tangential += 0.5 * kwt * h.tangential * h.tangential;
                e.elastic_rolling += 0.5 * kr * h.rolling * h.rolling;
                if wall.active {
                    let ov = s.r[a] - wall.distance(Vec2::new(s.x[a], s.y[a]));
                    if ov > 0.0 {
                        e.elastic_normal += 0.5 * kwn * ov * ov;
                    }
                }
            }
        }
        e
    }

    /// Energy balance now (meaningful with `params.ledger`).
    pub fn balance(&self) -> Balance {
        let energies = self.energies();
        let residual = self.e0 + self.ledger.external_work - (energies.total() + self.ledger.dissipated());
        Balance { e0: self.e0, energies, ledger: self.ledger, residual }
    }

    /// Number of grain–grain contacts (overlapping listed pairs) now.
    pub fn contact_count(&self) -> usize {
        let s = &self.state;
        let lx = self.periodic_x.unwrap_or(0.0);
        (0..self.nl.len()).filter(|&k| {
            let (i, j) = (self.nl.pi[k] as usize, self.nl.pj[k] as usize);
            let dx = s.x[i] - (s.x[j] + self.nl.shift[k] * lx);
            let dy = s.y[i] - s.y[j];
            let rs = s.r[i] + s.r[j];
            dx * dx + dy * dy < rs * rs
        }).count()
    }

    /// All listed grain pairs with their history (zero for pairs not in contact).
    pub fn contact_histories(&self) -> impl Iterator<Item = (crate::dem::state::ContactKey, ContactState)> + '_ {
        (0..self.nl.len()).map(|k| (crate::dem::state::ContactKey { i: self.nl.pi[k], j: self.nl.pj[k] }, self.nl.hist[k]))
    }

    /// Contact history between grains a and b, if listed.
    pub fn contact_history(&self, a: u32, b: u32) -> Option<ContactState> { self.nl.history(a, b) }

    /// Contact histories worth keeping across a restart: grain pairs and grain–wall
    /// contacts whose springs hold something.
    pub fn saved_histories(&self) -> SavedHistories {
        let n = self.state.len();
        let pairs = (0..self.nl.len())
            .filter(|&k| self.nl.hist[k] != ContactState::default())
            .map(|k| (self.nl.pi[k], self.nl.pj[k], self.nl.hist[k]))
            .collect();
        let walls = (0..self.walls.len())
            .flat_map(|wi| (0..n).map(move |a| (wi, a)))
            .filter(|&(wi, a)| self.wall_hist[wi * n + a] != ContactState::default())
            .map(|(wi, a)| (wi as u32, a as u32, self.wall_hist[wi * n + a]))
            .collect();
        SavedHistories { pairs, walls }
    }

    /// Restore contact histories saved by [`World::saved_histories`] on the same grains
    /// (a restarted column keeps its settled tangential and rolling springs). Pairs that
    /// are not listed now (moved apart) and walls that do not exist are skipped; returns
    /// how many histories were restored.
    pub fn restore_histories(&mut self, h: &SavedHistories) -> usize {
        let n = self.state.len();
        let mut restored = 0;
        for &(a, b, st) in &h.pairs {
            let key = crate::dem::state::ContactKey::new(a, b);
            let (Some(&lo), Some(&hi)) = (self.nl.istart.get(key.i as usize), self.nl.istart.get(key.i as usize + 1)) else { continue };
            if let Some(k) = (lo as usize..hi as usize).find(|&k| self.nl.pj[k] == key.j) {
                self.nl.hist[k] = st;
                restored += 1;
            }
        }
        for &(wi, a, st) in &h.walls {
            let (wi, a) = (wi as usize, a as usize);
            if wi < self.walls.len() && a < n {
                self.wall_hist[wi * n + a] = st;
                restored += 1;
            }
        }
        self.plive.fill(1);
        self.wlive.fill(1);
        self.forces_valid = false;
        restored
    }

    /// Total contact + gravity force on grain i from the last evaluation [N/m].
    pub fn force(&self, i: usize) -> Vec2 { Vec2::new(self.fx[i], self.fy[i]) }
    /// Total torque on grain i from the last evaluation [N·m/m].
    pub fn torque(&self, i: usize) -> Real { self.tq[i] }
    /// Number of listed (Verlet) pairs.
    pub fn pair_count(&self) -> usize { self.nl.len() }
    /// Number of neighbour-list builds so far.
    pub fn rebuilds(&self) -> u64 { self.nl.builds }
}

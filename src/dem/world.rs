//! The DEM world and its step, a list of named phases:
//!
//! `integrate(first half kick + drift)` → `refresh_neighbors` → `compute_contacts` (pair
//! pass) → `grain_pass` (per grain chunk: force gather, grain–wall contacts, second half
//! kick) → `integrate(rolling dashpot)` → `ledger` → `watchdog`; the chunk kernels are in
//! [`crate::dem::passes`]. On a thread team with the implicit dashpot, consecutive steps
//! of one `run` are *joined* ([`World::steps_with`]): a step's force evaluation is one
//! team phase without barriers inside (`World::staged_forces`) — the spin work left by
//! the previous step beside the pair filter, then the pair pass, then the grain pass,
//! which also does the next step's translational kick and drift. The phase timers keep
//! the names contacts / gather / walls / integrate / rolling; a phase's wall time is
//! apportioned to them by each part's CPU time per chunk.
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

mod data;

pub use crate::dem::scratch::{GRAIN_CHUNK, MAX_WALLS, PAIR_CHUNK, PAR_MIN_ITEMS};
pub use data::{SavedHistories, StepInfo, World};

use crate::dem::contact_law::{Law, LawCoeffs};
use crate::dem::energy::{Balance, Energies, Ledger};
use crate::dem::error::DemError;
use crate::dem::integrate::{SpinJob, SpinOut};
use crate::dem::neighbors::NeighborList;
use crate::dem::params::{DemParams, RollingDamping, normal_damping};
use crate::dem::passes::{GrainPass, PairPass, grain_chunk_deps};
use crate::dem::preflight::{Preflight, SizeClasses, preflight};
use crate::dem::scratch::{Flags, Partial, RollItem, RollLists, chunked, slots};
use crate::dem::state::{ContactState, State};
use crate::dem::team::wait_for;
use crate::dem::timers::Phase;
use crate::dem::timers::{Clock, PhaseTimers};
use crate::dem::walls::{NearWalls, Wall};
use crate::math::{Real, Vec2};
use crate::shared::SharedMut;
use std::sync::atomic::Ordering::Release;
use std::time::Instant;

/// [`World::run`] steps a world with a thread team while the team is clearly faster than
/// the world alone: it times [`TEAM_PROBE`] steps alone (the reference, taken again after
/// [`TEAM_REFRESH`] steps), then the team in blocks of [`TEAM_BLOCK`] steps; a team
/// slower than 0.9 × the reference rests for [`TEAM_REST`] steps (doubling with every
/// further loss, up to 4 × TEAM_REST) and is tried again. Results are the same either way.
pub const TEAM_PROBE: u64 = 128;
/// See [`TEAM_PROBE`].
pub const TEAM_BLOCK: u64 = 1024;
/// See [`TEAM_PROBE`].
pub const TEAM_REFRESH: u64 = 32768;
/// See [`TEAM_PROBE`].
pub const TEAM_REST: u64 = 256;
impl World {
    /// A world from a state, walls and parameters. Validates the parameters.
    pub fn new(params: DemParams, state: State, walls: Vec<Wall>, periodic_x: Option<Real>) -> Result<Self, DemError> {
        let issues = params.validate();
        if !issues.is_empty() {
            let s: Vec<String> = issues
                .iter()
                .map(|i| format!("{} = {} (allowed: {})", i.key, i.value, i.allowed))
                .collect();
            return Err(DemError::InvalidParams(s.join("; ")));
        }
        if walls.len() > MAX_WALLS {
            return Err(DemError::Setup(format!(
                "{} walls given, at most {MAX_WALLS} supported",
                walls.len()
            )));
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
            solo_ref: None,
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
            near: NearWalls::default(),
            partials: Vec::new(),
            gpartials: Vec::new(),
            todo: Vec::new(),
            filtered: Vec::new(),
            gdeps: Vec::new(),
            phase_id: 0,
            fdone: Flags::default(),
            pdone: Flags::default(),
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
        self.near.invalidate();
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
        self.nl.build(&mut s, skin, self.periodic_x, |i, j| {
            normal_damping(z, m[i] * m[j] / (m[i] + m[j]), kn)
        });
        s.m = m;
        self.state = s;
        let np = self.nl.len();
        self.pout.resize(np, [0.0; 4]);
        // (the dashpot lists keep their size until the next pair pass writes them: the
        // sweeps between a rebuild and that pass read the last evaluation's dashpots)
        self.todo.resize(np.div_ceil(PAIR_CHUNK) * PAIR_CHUNK, 0);
        self.gdeps = grain_chunk_deps(
            &self.nl.istart,
            &self.nl.jstart,
            &self.nl.jlist,
            self.state.len(),
            GRAIN_CHUNK,
        );
        self.all_pairs_live();
        self.near.invalidate();
    }

    /// Every listed pair live (its history unknown to the pair pass until evaluated).
    fn all_pairs_live(&mut self) {
        let np = self.nl.len();
        self.plive.clear();
        self.plive.resize(np.div_ceil(64), !0);
        if np % 64 != 0 {
            self.plive[np / 64] = (1u64 << (np % 64)) - 1;
        }
    }

    /// Make the near-wall lists again if they no longer hold (see [`NearWalls`]).
    pub(crate) fn ensure_near_walls(&mut self) {
        if !self.near.hold(&self.walls, self.state.len()) {
            self.near.make(
                &self.walls,
                (&self.nl.x0, &self.nl.y0),
                &self.state.r,
                self.nl.skin,
                &self.wlive,
                GRAIN_CHUNK,
            );
        }
    }

    /// Forces must be recomputed before the next kick (after external state edits that
    /// change positions, e.g. moving grains by hand).
    pub fn invalidate_forces(&mut self) {
        self.forces_valid = false;
    }

    /// Size classes of the current grains.
    pub fn size_classes(&self) -> SizeClasses {
        let (r_min, r_mean, r_max) = self.state.radius_stats();
        SizeClasses { r_min, r_mean, r_max }
    }

    /// Stability audit of this scene at `params.dt`.
    pub fn preflight(&self) -> Result<Preflight, DemError> {
        preflight(
            &self.params,
            self.size_classes(),
            !self.walls.is_empty(),
            self.params.dt,
        )
    }

    /// Restart the ledger: zero dissipation, E_0 = current total energy.
    pub fn reset_ledger(&mut self) {
        self.ledger = Ledger::default();
        self.e0 = self.energies().total();
    }

    /// Add work done on the grains by an outside driver [J/m].
    pub fn add_external_work(&mut self, w: Real) {
        self.ledger.external_work += w;
    }

    /// One step.
    pub fn step(&mut self) -> Result<(), DemError> {
        self.run(1)
    }

    /// `n` steps; physics variant chosen once.
    pub fn run(&mut self, n: u64) -> Result<(), DemError> {
        if self.walls.len() > MAX_WALLS {
            return Err(DemError::Setup(format!(
                "{} walls, at most {MAX_WALLS} supported",
                self.walls.len()
            )));
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
        // The hot loops index the grain arrays with the list's indices unchecked
        // (`crate::shared`):
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
        if !self.forces_valid && self.nl.needs_rebuild(&self.state) {
            // grains moved by hand since the last build (`invalidate_forces`): the pair
            // and near-wall lists assume no grain is more than skin/2 from its build
            // position
            self.rebuild();
        }
        if !self.forces_valid {
            self.compute_forces::<R, IMP, L, false>(0.0);
            self.forces_valid = true;
        }
        let team = ng >= self.team_min_grains && rayon::current_num_threads() > 1;
        let mut res = Ok(());
        let mut left = n;
        while left > 0 && res.is_ok() {
            if !(team && self.team_probe) {
                res = crate::dem::team::with_team(team, || self.steps_with::<R, IMP, L>(left));
                break;
            }
            let fresh = self.solo_ref.is_some_and(|(_, at)| self.steps < at + TEAM_REFRESH);
            if !fresh && left >= 2 * TEAM_PROBE {
                // the reference: TEAM_PROBE steps alone, then try the team
                let t0 = Instant::now();
                res = self.steps_with::<R, IMP, L>(TEAM_PROBE);
                self.solo_ref = Some((t0.elapsed().as_secs_f64() / TEAM_PROBE as f64, self.steps));
                left -= TEAM_PROBE;
            } else if self.solo_ref.is_some() && self.steps >= self.team_until {
                // with the team, in timed blocks, while it stays clearly faster than alone
                let mut ran = 0;
                res = crate::dem::team::with_team(true, || self.team_blocks::<R, IMP, L>(left, &mut ran));
                left -= ran;
            } else {
                // alone until the team's next try (timed: the reference for it; steps alone
                // are measured whenever they run)
                let k = if self.solo_ref.is_some() {
                    left.min(self.team_until - self.steps)
                } else {
                    left
                };
                let t0 = Instant::now();
                res = self.steps_with::<R, IMP, L>(k);
                if k >= TEAM_PROBE {
                    self.solo_ref = Some((t0.elapsed().as_secs_f64() / k as f64, self.steps));
                }
                left -= k;
            }
        }
        self.walls_seen.clone_from(&self.walls);
        res
    }

    /// Up to `left` steps with the team (`World::run_with`), in blocks timed against the
    /// reference alone (`solo_ref`): the first after TEAM_PROBE / 4 steps that wake the
    /// helpers and fill their caches, then TEAM_BLOCK steps each. Stops when a block is
    /// not clearly faster than the reference (the other core got busy, or the team does
    /// not pay on this scene: the team rests, and is tried again after TEAM_REST steps,
    /// doubling with every further loss up to 4 × TEAM_REST) or when the reference is
    /// older than TEAM_REFRESH steps. `ran`: steps done.
    fn team_blocks<const R: bool, const IMP: bool, const L: bool>(
        &mut self,
        left: u64,
        ran: &mut u64,
    ) -> Result<(), DemError> {
        let warm = (TEAM_PROBE / 4).min(left);
        self.steps_with::<R, IMP, L>(warm)?;
        *ran = warm;
        let mut block = TEAM_PROBE - warm;
        while *ran < left {
            let k = block.min(left - *ran);
            let t0 = Instant::now();
            self.steps_with::<R, IMP, L>(k)?;
            *ran += k;
            let (solo, at) = self.solo_ref.unwrap_or((f64::INFINITY, self.steps));
            // a short block is noisy: the team must be clearly faster
            if k >= TEAM_PROBE / 2 && !(t0.elapsed().as_secs_f64() / (k as f64) < 0.9 * solo) {
                self.team_lost = (self.team_lost + 1).min(3);
                self.team_until = self.steps + (TEAM_REST << (self.team_lost - 1));
                crate::dem::team::dismiss();
                return Ok(());
            }
            self.team_lost = 0;
            if self.steps >= at + TEAM_REFRESH {
                break;
            }
            block = TEAM_BLOCK;
        }
        Ok(())
    }

    /// `n` steps. On a thread team, two steps of this call are *joined* (except where the
    /// watchdog looks at the state between them): the grain pass of the first does the
    /// second's translational kick and drift on the grains it has just kicked (in cache,
    /// on the thread that computed their forces), and the spin work between them — this
    /// step's second dashpot sweep, the next one's spin kick and first sweep, serial —
    /// runs at the next step's start on one thread while the others filter its pairs
    /// (`World::staged_forces`). Every grain's arithmetic and every sum is that of the
    /// separate passes (`integrate_second_half`, `integrate_first_half`, `compute_contacts`),
    /// so results are bit-identical to them; on one thread the separate passes are as
    /// fast.
    fn steps_with<const R: bool, const IMP: bool, const L: bool>(&mut self, n: u64) -> Result<(), DemError> {
        let boundary = n >= 2 && crate::dem::team::active() && self.join_ok::<IMP>();
        let wd = self.params.watchdog.every;
        let mut first = None;
        for k in 0..n {
            let join = boundary && k + 1 < n && !(wd > 0 && (self.steps + 1) % wd == 0);
            first = self.step_with::<R, IMP, L>(first, join)?;
        }
        Ok(())
    }

    /// One step; `first`: the previous step joined this one (see [`World::steps_with`]):
    /// it did the translational first half of this one (with whether the list must be
    /// rebuilt) and left its spin work to this step's start; `join`: do the same for the
    /// next step (returned as its `first`).
    fn step_with<const R: bool, const IMP: bool, const L: bool>(
        &mut self,
        first: Option<bool>,
        join: bool,
    ) -> Result<Option<bool>, DemError> {
        let dt = self.params.dt;
        let on = self.timing;
        let t0 = Clock::now(on);
        let moved = match first {
            Some(m) => m,
            None => self.integrate_first_half::<IMP, L>(),
        };
        let t1 = Clock::now(on);
        self.timers.integrate += t0.to(t1);
        if moved {
            self.refresh_neighbors();
        }
        let t2 = Clock::now(on);
        self.timers.neighbors += t1.to(t2);
        // contacts, walls and the second half kick (fused per grain chunk); on a team, as
        // one phase with the spin work left by a joined previous step and, joined to the
        // next step, its translational kick and drift
        let moved_next = if first.is_some() || join {
            self.staged_forces::<R, IMP, L>(dt, first.is_some(), join)
        } else {
            self.compute_forces::<R, IMP, L, true>(dt);
            false
        };
        let t3 = Clock::now(on);
        if join {
            // the next step's walls (as `integrate_first_half`)
            for wall in self.walls.iter_mut() {
                wall.origin += wall.velocity * dt;
            }
            self.t += dt;
            self.steps += 1;
            self.timers.integrate += t3.elapsed();
            return Ok(Some(moved_next || self.nl.x0.len() != self.state.len()));
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

    fn refresh_neighbors(&mut self) {
        self.rebuild();
    }

    /// Contact and wall forces at the current positions with the current velocities;
    /// histories advance by `dt` (0 for the priming evaluation). With `KICK`, the second
    /// half kick follows in the same per-chunk pass (see [`World::grain_pass`]), and with
    /// `next` the translational first half of the next step too; returns whether that
    /// moved a grain past the skin. `filtered`: as in [`World::compute_contacts`].
    fn compute_forces<const R: bool, const IMP: bool, const L: bool, const KICK: bool>(&mut self, dt: Real) {
        let on = self.timing;
        let t0 = Clock::now(on);
        (self.paths.rolling_forces, self.paths.ledger) =
            (self.paths.rolling_forces + R as u64, self.paths.ledger + L as u64);
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

    /// A step's force evaluation (histories advance by `dt`, second half kick included) as
    /// one phase of the thread team, without a barrier inside, in three stages whose
    /// chunks wait for what they read (see [`crate::dem::team::for_stages`]):
    /// 1. the spin job (with `spin`: the spin work left by the previous, joined step — its
    ///    second dashpot sweep, this step's spin kick and first sweep, serial, in order),
    ///    beside the pair filter ([`crate::dem::passes::PairFilter`]: positions only) of every pair chunk;
    /// 2. the pair pass ([`PairPass`]) of each chunk, once the spins and its filter are done;
    /// 3. the grain pass ([`GrainPass`], with `next` the next step's translational kick and
    ///    drift) of each grain chunk, once the spins and every pair chunk holding one of
    ///    its grains are done (`World::gdeps`) — so no chunk moves a grain that a pair
    ///    chunk still reads.
    ///
    /// Each chunk writes its own slots and the partials are merged after the phase in
    /// chunk order, in the order of the separate passes (`integrate_second_half`,
    /// `integrate_first_half`, `compute_forces`): results are bit-identical to them.
    /// Returns whether the next step's drift moved a grain past the skin.
    fn staged_forces<const R: bool, const IMP: bool, const L: bool>(
        &mut self,
        dt: Real,
        spin: bool,
        next: bool,
    ) -> bool {
        let on = self.timing;
        let clock = Clock::now(on);
        (self.paths.rolling_forces, self.paths.ledger) =
            (self.paths.rolling_forces + R as u64, self.paths.ledger + L as u64);
        self.paths.rolling_dashpot += 2 * spin as u64;
        let mut total = Partial::default();
        self.release_inactive_walls::<R, IMP, L>(&mut total);
        let (n, np) = (self.state.len(), self.nl.len());
        let (npc, ngc) = (np.div_ceil(PAIR_CHUNK), n.div_ceil(GRAIN_CHUNK));
        self.phase_id += 1;
        let id = self.phase_id;
        self.fdone.ensure(1 + npc);
        self.pdone.ensure(npc);
        debug_assert_eq!(self.gdeps.len(), ngc);
        // the pair pass first: it may grow the dashpot list the spin job reads
        let pairs = PairPass::<R, IMP, L>::new(self, dt);
        let spin_job = spin.then(|| SpinJob::<L>::new(self));
        let grains = GrainPass::<R, IMP, L, true>::new(self, dt, next);
        let (fout, pout, gout) = (
            slots(&mut self.filtered, 1 + npc),
            slots(&mut self.partials, npc),
            slots(&mut self.gpartials, ngc),
        );
        let (fdone, pdone, gdeps) = (&self.fdone.0[..], &self.pdone.0[..], &self.gdeps[..]);
        let mut spin_out = SpinOut::default();
        let sp = SharedMut::new(std::slice::from_mut(&mut spin_out));
        let s0 = |c: usize| {
            let t0 = Clock::now(on);
            // SAFETY: every chunk writes its own slot once; the spin job is chunk 0 only
            unsafe {
                if c == 0 {
                    if let Some(j) = &spin_job {
                        sp.write(0, j.run());
                    }
                    fout.write(0, (0, 0.0));
                } else {
                    let lo = (c - 1) * PAIR_CHUNK;
                    let k = pairs.filter.run(lo, (lo + PAIR_CHUNK).min(np));
                    fout.write(c, (k as u32, t0.elapsed()));
                }
            }
            fdone[c].store(id, Release);
        };
        let s1 = |c: usize| {
            wait_for(&fdone[0], id);
            wait_for(&fdone[1 + c], id);
            let t0 = Clock::now(on);
            let lo = c * PAIR_CHUNK;
            // SAFETY: its filter is done (acquire above); one chunk per call
            unsafe {
                let mut p = pairs.chunk(lo, (lo + PAIR_CHUNK).min(np), Some(fout.get(1 + c).0 as usize));
                p.secs = t0.elapsed();
                pout.write(c, p);
            }
            pdone[c].store(id, Release);
        };
        let s2 = |c: usize| {
            wait_for(&fdone[0], id);
            let (a, b) = gdeps[c];
            for q in a as usize..b as usize {
                wait_for(&pdone[q], id);
            }
            let lo = c * GRAIN_CHUNK;
            // SAFETY: every pair of its grains is evaluated (acquire above); one chunk per call
            unsafe { gout.write(c, grains.chunk(lo, (lo + GRAIN_CHUNK).min(n))) };
        };
        crate::dem::team::for_stages(&[(1 + npc, &s0), (npc, &s1), (ngc, &s2)]);
        // SAFETY: every slot was written above (for_stages returns when all are done)
        unsafe {
            self.filtered.set_len(1 + npc);
            self.partials.set_len(npc);
            self.gpartials.set_len(ngc);
        }
        let wall_s = clock.elapsed();
        // the sums, in the order of the separate passes
        if L && spin {
            self.ledger += spin_out.ledger[0];
            self.ledger += spin_out.ledger[1];
            self.ledger += spin_out.ledger[2];
        }
        let p = self.pair_partials();
        let (q, k, cpu) = self.grain_partials(total);
        self.ledger_phase::<L>(&p, &q);
        if L {
            self.ledger += k.ledger;
        }
        if on {
            let filter_s: f64 = self.filtered[1..].iter().map(|f| f.1).sum();
            let pair_s: f64 = self.partials.iter().map(|p| p.secs).sum();
            self.apportion(
                wall_s,
                &[
                    (Phase::Rolling, spin_out.sweep_s),
                    (Phase::Integrate, spin_out.kick_s + cpu[2]),
                    (Phase::Contacts, filter_s + pair_s),
                    (Phase::Gather, cpu[0]),
                    (Phase::Walls, cpu[1]),
                ],
            );
        }
        k.moved
    }

    fn ledger_phase<const L: bool>(&mut self, p: &Partial, q: &Partial) {
        let (fp, fq) = (p.max_overlap, q.max_overlap);
        self.info.max_overlap_fraction = fp.max(fq);
        self.info.max_pair = if fp >= fq {
            (p.max_i, p.max_j)
        } else {
            (q.max_i, u32::MAX)
        };
        self.info.wall_force = q.wall_force;
        if L {
            self.ledger += p.ledger;
            self.ledger += q.ledger;
        }
    }

    /// Pair forces in parallel (each pair's to its own slot; [`PairPass`]), then a
    /// per-grain gather in fixed order.
    fn compute_contacts<const R: bool, const IMP: bool, const L: bool>(&mut self, dt: Real) -> Partial {
        let pass = PairPass::<R, IMP, L>::new(self, dt);
        let np = self.nl.len();
        // SAFETY: one chunk per call, the job made for this list just now
        chunked(np, PAIR_CHUNK, &mut self.partials, |lo, hi| unsafe {
            pass.chunk(lo, hi, None)
        });
        self.pair_partials()
    }

    /// The pair pass's partials merged in chunk order; the dashpot counts per chunk.
    fn pair_partials(&mut self) -> Partial {
        self.roll.count.resize(self.partials.len(), 0);
        let mut total = Partial::default();
        for (c, p) in self.partials.iter().enumerate() {
            total.merge(p);
            self.roll.count[c] = p.n_roll[0];
        }
        total
    }

    /// The per-grain pass after the pair pass ([`GrainPass`]), one fork-join: returns the
    /// wall partial (with the released inactive walls first) and the kick partial, each
    /// merged in chunk order.
    fn grain_pass<const R: bool, const IMP: bool, const L: bool, const KICK: bool>(
        &mut self,
        dt: Real,
    ) -> (Partial, Partial) {
        let clock = Clock::now(self.timing);
        let mut total = Partial::default();
        self.release_inactive_walls::<R, IMP, L>(&mut total);
        let pass = GrainPass::<R, IMP, L, KICK>::new(self, dt, false);
        // SAFETY: one chunk per call, after the pair pass, the job made just now
        chunked(self.state.len(), GRAIN_CHUNK, &mut self.gpartials, |lo, hi| unsafe {
            pass.chunk(lo, hi)
        });
        let (wall, kick, cpu) = self.grain_partials(total);
        self.apportion(
            clock.elapsed(),
            &[
                (Phase::Gather, cpu[0]),
                (Phase::Walls, cpu[1]),
                (Phase::Integrate, cpu[2]),
            ],
        );
        (wall, kick)
    }

    /// The grain pass's partials merged in chunk order into `total` (walls) and the kick
    /// partial; the wall dashpot counts per chunk; the CPU seconds of its three parts.
    fn grain_partials(&mut self, mut total: Partial) -> (Partial, Partial, [f64; 3]) {
        let any_wall = self.walls.iter().any(|w| w.active);
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
        (total, kick, cpu)
    }

    /// Add a phase's wall time `wall_s` to the phase timers in proportion to the CPU
    /// seconds of its parts.
    pub(crate) fn apportion(&mut self, wall_s: f64, parts: &[(Phase, f64)]) {
        let sum = parts.iter().map(|p| p.1).sum::<f64>().max(1e-12);
        for &(ph, cpu) in parts {
            let t = &mut self.timers;
            let slot = match ph {
                Phase::Contacts => &mut t.contacts,
                Phase::Gather => &mut t.gather,
                Phase::Walls => &mut t.walls,
                Phase::Integrate => &mut t.integrate,
                Phase::Rolling => &mut t.rolling,
            };
            *slot += wall_s * cpu / sum;
        }
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
            if self.wall_cleared[wi] {
                continue;
            }
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
        let (kn, kt, kr) = (
            self.params.grain.kn,
            self.params.grain.kt,
            if self.params.rolling.enabled {
                self.params.rolling.kr
            } else {
                0.0
            },
        );
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
        Balance {
            e0: self.e0,
            energies,
            ledger: self.ledger,
            residual,
        }
    }

    /// Number of grain–grain contacts (overlapping listed pairs) now.
    pub fn contact_count(&self) -> usize {
        let s = &self.state;
        let lx = self.periodic_x.unwrap_or(0.0);
        (0..self.nl.len())
            .filter(|&k| {
                let (i, j) = (self.nl.pi[k] as usize, self.nl.pj[k] as usize);
                let dx = s.x[i] - (s.x[j] + self.nl.shift[k] * lx);
                let dy = s.y[i] - s.y[j];
                let rs = s.r[i] + s.r[j];
                dx * dx + dy * dy < rs * rs
            })
            .count()
    }

    /// All listed grain pairs with their history (zero for pairs not in contact).
    pub fn contact_histories(&self) -> impl Iterator<Item = (crate::dem::state::ContactKey, ContactState)> + '_ {
        (0..self.nl.len()).map(|k| {
            (
                crate::dem::state::ContactKey {
                    i: self.nl.pi[k],
                    j: self.nl.pj[k],
                },
                self.nl.hist[k],
            )
        })
    }

    /// Contact history between grains a and b, if listed.
    pub fn contact_history(&self, a: u32, b: u32) -> Option<ContactState> {
        self.nl.history(a, b)
    }

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
            let (Some(&lo), Some(&hi)) = (
                self.nl.istart.get(key.i as usize),
                self.nl.istart.get(key.i as usize + 1),
            ) else {
                continue;
            };
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
        self.all_pairs_live();
        self.wlive.fill(1);
        self.near.invalidate();
        self.forces_valid = false;
        restored
    }

    /// Total contact + gravity force on grain i from the last evaluation [N/m].
    pub fn force(&self, i: usize) -> Vec2 {
        Vec2::new(self.fx[i], self.fy[i])
    }
    /// Total torque on grain i from the last evaluation [N·m/m].
    pub fn torque(&self, i: usize) -> Real {
        self.tq[i]
    }
    /// Number of listed (Verlet) pairs.
    pub fn pair_count(&self) -> usize {
        self.nl.len()
    }
    /// Number of neighbour-list builds so far.
    pub fn rebuilds(&self) -> u64 {
        self.nl.builds
    }
}

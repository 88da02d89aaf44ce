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
//!
//! The team scheduling of [`World::run`] (timed probes, blocks, rests) is in
//! `world/schedule.rs`; the scratch and the contact histories (saved, restored) in
//! `world/history.rs`; the world's fields in `world/data.rs`.

mod data;
mod history;
mod schedule;
mod sort;

pub use crate::dem::scratch::{GRAIN_CHUNK, MAX_WALLS, PAIR_CHUNK, PAR_MIN_ITEMS};
pub use data::{SavedHistories, StepInfo, World};
pub use schedule::{TEAM_BLOCK, TEAM_PROBE, TEAM_REFRESH, TEAM_REST};

use crate::dem::contact_law::{Law, LawCoeffs};
use crate::dem::energy::{Balance, Energies, Ledger};
use crate::dem::error::DemError;
use crate::dem::integrate::{SpinJob, SpinOut};
use crate::dem::neighbors::NeighborList;
use crate::dem::params::{DemParams, RollingDamping, normal_damping};
use crate::dem::passes::{GrainPass, PairPass, grain_chunk_deps};
use crate::dem::preflight::{Preflight, SizeClasses, preflight};
use crate::dem::scratch::{Flags, Partial, RollLists, chunked, slots};
use crate::dem::state::{ContactState, State};
use crate::dem::team::wait_for;
use crate::dem::timers::Phase;
use crate::dem::timers::{Clock, PhaseTimers};
use crate::dem::walls::{NearWalls, Wall};
use crate::math::{Real, Vec2};
use crate::shared::SharedMut;
use std::sync::atomic::Ordering::Release;

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
            grain_ids: Vec::new(),
            timers: PhaseTimers::default(),
            paths: Default::default(),
            info: StepInfo::default(),
            team_min_grains: crate::dem::team::TEAM_MIN_GRAINS,
            sort_min_grains: crate::dem::order::SORT_MIN_GRAINS,
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
            next_sort: 0,
            sorts: 0,
        };
        w.grain_ids = (0..w.state.len() as u32).collect();
        w.resize_scratch();
        w.rebuild();
        w.e0 = w.energies().total();
        Ok(w)
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
        if !np.is_multiple_of(64) {
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
        if wd > 0 && self.steps.is_multiple_of(wd) {
            self.watchdog()?;
        }
        self.timers.watchdog += t4.elapsed();
        Ok(None)
    }

    fn refresh_neighbors(&mut self) {
        if self.params.sort_every > 0 && self.steps >= self.next_sort {
            self.sort_grains();
        }
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
    pub(super) fn staged_forces<const R: bool, const IMP: bool, const L: bool>(
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

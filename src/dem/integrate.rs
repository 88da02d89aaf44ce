//! Velocity Verlet (kick–drift–kick) for disks, with the implicit rolling dashpot.
//!
//! Translation: v ← v + (h/m) F, h = Δt/2; x ← x + Δt v. Rotation: ω* = ω + (h/I) M with
//! the explicit moments (springs, friction, and the rolling dashpot when it is explicit).
//!
//! Implicit rolling dashpot ([`RollingDamping::Implicit`]): table 4.2's c_r = 0.1 N·m·s
//! relaxes a relative spin in I/c_r ≈ 1e-9 s (docs/definitions.md c.2), 100–1000× below any
//! usable step, so it is integrated by backward Euler. Two ways were open: solve
//! (I + hC_L)ω⁺ = Iω* with C_L the dashpot Laplacian of the contact network, or apply
//! pairwise backward-Euler impulses contact by contact. We take the pairwise impulses, in a
//! fixed order (pairs by (i, j), then walls by (wall, grain)), one sweep per half kick:
//! - each update is exact backward Euler of its pair, u⁺ = u/(1 + h c_r/I_eff) with
//!   u = ω_i − ω_j and I_eff = I_iI_j/(I_i + I_j) (I_eff = I_i at a wall), applied as an
//!   equal and opposite angular impulse J = −I_eff(u − u⁺): ΣIω is conserved to
//!   round-off and the pair's rotational energy can only fall, so E_rot never rises and
//!   no mode overshoots, whatever c_r h/I;
//! - the sweep is one Gauss–Seidel pass of the network system; with c_r h/I ≫ 1 every
//!   pass already locks each pair, so more passes change little, and it needs no
//!   assembly, no solver tolerance and no allocation;
//! - the cap of [`RollingModel::Capped`] clips J/h so that |M_spring + J/h| ≤ μ_r r F_n,
//!   which a linear solve could not express.
//! The sweep is sequential (deterministic at any thread count); it costs one pass over
//! the contacts, small against the force evaluation. The dissipation booked is the exact
//! drop of ½Iω² the impulses cause (plus the work a driver does on prescribed grains).
//!
//! Prescribed grains (1/m = 0) keep their velocity; the work their drivers do is booked
//! as external work.
//!
//! [`RollingDamping::Implicit`]: crate::dem::params::RollingDamping::Implicit
//! [`RollingModel::Capped`]: crate::dem::params::RollingModel::Capped

use crate::dem::contact_law::RollDashpot;
use crate::dem::energy::Ledger;
use crate::dem::scratch::{GRAIN_CHUNK, MAX_WALLS, PAIR_CHUNK, Partial, RollItem, RollLists, chunked};
use crate::dem::timers::Clock;
use crate::dem::world::World;
use crate::math::Real;
use crate::shared::{SharedMut, SharedRef, checked_assert};

impl World {
    /// First half kick and drift; returns whether the neighbour list must be rebuilt.
    pub(crate) fn integrate_first_half<const IMP: bool, const L: bool>(&mut self) -> bool {
        let dt = self.params.dt;
        for wall in self.walls.iter_mut() {
            wall.origin += wall.velocity * dt;
        }
        let force_rebuild = self.nl.x0.len() != self.state.len();
        let moved = if IMP {
            // the dashpot sweep changes spins only: x, y drift with the kick, θ after the
            // sweep — in the force evaluation's grain pass (`World::grain_pass`), per grain
            // chunk before that chunk's second half kick (ω is not changed in between)
            let moved = self.kick_pass::<L, true, false>();
            self.rolling_dashpot::<L, true>();
            moved
        } else {
            self.kick_pass::<L, true, true>()
        };
        moved || force_rebuild
    }

    /// After the second half kick (done per chunk by the grain pass of the force
    /// evaluation, `World::grain_pass`): the implicit rolling dashpot.
    pub(crate) fn integrate_second_half<const IMP: bool, const L: bool>(&mut self) {
        if IMP {
            self.rolling_dashpot::<L, false>();
        }
    }

    /// Half kick of every grain with the explicit forces and moments, then (if `DRIFT`)
    /// x ← x + Δt v, (if `THETA`) θ ← θ + Δt ω, and the skin check. Returns whether a grain
    /// moved more than skin/2 since the last build.
    fn kick_pass<const L: bool, const DRIFT: bool, const THETA: bool>(&mut self) -> bool {
        let dt = self.params.dt;
        let h = 0.5 * dt;
        let s = &mut self.state;
        let n = s.len();
        let (vx, vy, w) = (
            SharedMut::of(&mut s.vx),
            SharedMut::of(&mut s.vy),
            SharedMut::of(&mut s.w),
        );
        let (x, y, th) = (
            SharedMut::of(&mut s.x),
            SharedMut::of(&mut s.y),
            SharedMut::of(&mut s.theta),
        );
        let (inv_m, inv_i) = (&s.inv_m[..], &s.inv_i[..]);
        let (fx, fy, tq) = (&self.fx[..], &self.fy[..], &self.tq[..]);
        checked_assert!(
            s.inv_m.len() == n && s.inv_i.len() == n && self.fx.len() == n && self.fy.len() == n && self.tq.len() == n
        );
        let lim = 0.25 * self.nl.skin * self.nl.skin;
        let have_x0 = self.nl.x0.len() == n;
        let (x0, y0) = (&self.nl.x0[..], &self.nl.y0[..]);
        let x0y0 = have_x0.then_some((x0, y0));
        chunked(n, GRAIN_CHUNK, &mut self.partials, |lo, hi| {
            let mut part = Partial::default();
            // SAFETY: chunks are disjoint grain ranges of arrays of length n
            unsafe {
                let (vxn, vyn, wn) = kick_range::<L>(
                    lo,
                    hi,
                    h,
                    (&inv_m[lo..hi], &inv_i[lo..hi]),
                    (&fx[lo..hi], &fy[lo..hi], &tq[lo..hi]),
                    (vx, vy, w),
                    &mut part,
                );
                if DRIFT {
                    part.moved = drift_range::<THETA>(lo, dt, (vxn, vyn, wn), (x, y, th), x0y0, lim);
                }
            }
            part
        });
        let mut tot = Partial::default();
        for p in &self.partials {
            tot.merge(p);
        }
        if L {
            self.ledger += tot.ledger;
        }
        tot.moved
    }

    /// One sweep of pairwise backward-Euler rolling-dashpot impulses over a half step
    /// (module doc), grain pairs in list order, then grain–wall contacts. `FIRST`: the
    /// sweep after the first half kick, which books the splitting term ([`dashpot_sweep`]).
    fn rolling_dashpot<const L: bool, const FIRST: bool>(&mut self) {
        self.paths.rolling_dashpot += 1;
        let t0 = crate::dem::timers::Clock::now(self.timing);
        let h = 0.5 * self.params.dt;
        let s = &mut self.state;
        // SAFETY: the lists are not written during the sweep (made and used here, on this
        // thread)
        let led = unsafe {
            dashpot_sweep::<L, FIRST>(
                &Dashpots::of(&mut self.roll),
                self.walls.len(),
                h,
                &mut s.w[..],
                (&s.inv_i[..], &s.inertia[..]),
                &self.tq[..],
            )
        };
        if L {
            self.ledger += led;
        }
        // reported as its own phase (the caller's timer counts it under `integrate`)
        let el = t0.elapsed();
        self.timers.rolling += el;
        self.timers.integrate -= el;
    }

    /// Whether two steps may be joined ([`World::steps_with`]): the implicit dashpot is on
    /// and no grain is prescribed (1/m = 0: the kick books the driver's work from the
    /// velocities before it, which the joined translational kick changes meanwhile).
    pub(crate) fn join_ok<const IMP: bool>(&self) -> bool {
        IMP && self.state.inv_m.iter().all(|&v| v != 0.0)
    }
}

/// What the spin job returns: the ledger parts of its sweep, kick and sweep (in that
/// order), and the CPU seconds of its sweeps and of its kick.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct SpinOut {
    pub ledger: [Ledger; 3],
    pub sweep_s: f64,
    pub kick_s: f64,
}

/// The spin work left between two joined steps ([`World::steps_with`]): the first step's
/// second dashpot sweep, the second step's spin kick and its first sweep, in order (serial:
/// the sweep is Gauss–Seidel). The sweeps read the dashpots of the last force evaluation
/// (a rebuild in between keeps them, `World::rebuild`). Every grain's arithmetic and every
/// sum is that of `integrate_second_half` then `integrate_first_half` (no prescribed
/// grain: the kick books nothing), so results are bit-identical to them. A job of the
/// first stage of `World::staged_forces` (see [`crate::dem::passes`] for raw views).
pub(crate) struct SpinJob<const L: bool> {
    d: Dashpots,
    nwalls: usize,
    h: Real,
    on: bool,
    w: SharedMut<Real>,
    n: usize,
    inv_i: SharedRef<Real>,
    inertia: SharedRef<Real>,
    tq: SharedRef<Real>,
}

impl<const L: bool> SpinJob<L> {
    pub(crate) fn new(w: &mut World) -> Self {
        let n = w.state.len();
        checked_assert!(w.state.inv_i.len() == n && w.state.inertia.len() == n && w.tq.len() == n);
        // SAFETY: read only by `run`, whole (`0..n`, the lengths asserted above), while
        // nothing else touches the spins and torques (its caller's contract)
        unsafe {
            SpinJob {
                d: Dashpots::of(&mut w.roll),
                nwalls: w.walls.len(),
                h: 0.5 * w.params.dt,
                on: w.timing,
                w: SharedMut::of(&mut w.state.w),
                n,
                inv_i: SharedRef::new(&w.state.inv_i),
                inertia: SharedRef::new(&w.state.inertia),
                tq: SharedRef::of(&mut w.tq),
            }
        }
    }

    /// The spin work: sweep, spin kick, sweep.
    ///
    /// # Safety
    /// Nothing else touches the spins, torques or dashpot lists meanwhile.
    pub(crate) unsafe fn run(&self) -> SpinOut {
        let (n, h, on) = (self.n, self.h, self.on);
        // SAFETY: caller's contract
        let (w, inv_i, inertia, tq) = unsafe {
            (
                self.w.slice_mut(0, n),
                self.inv_i.slice(0, n),
                self.inertia.slice(0, n),
                self.tq.slice(0, n),
            )
        };
        let t0 = Clock::now(on);
        // SAFETY: caller's contract (nothing writes the lists meanwhile)
        let l2 = unsafe { dashpot_sweep::<L, false>(&self.d, self.nwalls, h, w, (inv_i, inertia), tq) };
        let t1 = Clock::now(on);
        // the spin part of `kick_range` (no prescribed grain: nothing booked; its
        // partials, merged in chunk order, are zero)
        for a in 0..n {
            w[a] += h * inv_i[a] * tq[a];
        }
        let t2 = Clock::now(on);
        // SAFETY: as the first sweep
        let l1 = unsafe { dashpot_sweep::<L, true>(&self.d, self.nwalls, h, w, (inv_i, inertia), tq) };
        SpinOut {
            ledger: [l2, Ledger::default(), l1],
            sweep_s: t0.to(t1) + t2.elapsed(),
            kick_s: t1.to(t2),
        }
    }
}

/// A shared view of the dashpot lists ([`RollLists`]) for a sweep.
#[derive(Clone, Copy)]
pub(crate) struct Dashpots {
    items: SharedRef<RollItem>,
    count: SharedRef<u32>,
    witems: SharedRef<RollItem>,
    wcount: SharedRef<u32>,
}

impl Dashpots {
    pub(crate) fn of(rl: &mut RollLists) -> Self {
        // SAFETY: read only by `dashpot_sweep`, as whole slices (its caller promises that
        // nothing writes the lists meanwhile)
        unsafe {
            Dashpots {
                items: SharedRef::of(&mut rl.items),
                count: SharedRef::new(&rl.count),
                witems: SharedRef::of(&mut rl.witems),
                wcount: SharedRef::new(&rl.wcount),
            }
        }
    }
}

/// One sweep of pairwise backward-Euler rolling-dashpot impulses over `h` on the spins
/// `w` (module doc): the dashpots `rl` listed by the last force evaluation, in sweep order
/// (pairs by (i, j), then walls by (wall, grain); see `RollLists`). Returns what it books.
///
/// `FIRST`: the sweep that follows the first half kick ω* = ω + h M/I, with `tq` the M of
/// that kick. The spring's work is booked by the contact law with the spin after this
/// sweep (the drift's), so the kick's work on the spin the sweep takes back, h Σ M·δω,
/// is booked nowhere else: it is booked here, in the rolling term (for a pair the dashpot
/// locks, δω ≈ −h M/I and the term is ≈ −h² M²/I). Without it the ledger drifts first
/// order in Δt (0.28 % of E_0 on a 4 τ_c column, 0.13 % at Δt/2: the test
/// `the_implicit_rolling_dashpot_books_no_splitting_error`). The second sweep needs no
/// such term: the next step's spring work starts from the spin after it, and the
/// ½ h² M²/I of the two kicks telescope as in plain velocity Verlet.
///
/// # Safety
/// Nothing writes the lists meanwhile.
unsafe fn dashpot_sweep<const L: bool, const FIRST: bool>(
    rl: &Dashpots,
    nwalls: usize,
    h: Real,
    w: &mut [Real],
    (inv_i, inertia): (&[Real], &[Real]),
    tq: &[Real],
) -> Ledger {
    let mut led = Ledger::default();
    // SAFETY: caller's contract; the counts index the lists as the passes wrote them
    let (count, items, wcount, witems) = unsafe {
        (
            rl.count.slice(0, rl.count.len()),
            rl.items.slice(0, rl.items.len()),
            rl.wcount.slice(0, rl.wcount.len()),
            rl.witems.slice(0, rl.witems.len()),
        )
    };
    for (c, &cnt) in count.iter().enumerate() {
        for it in &items[c * PAIR_CHUNK..c * PAIR_CHUNK + cnt as usize] {
            pair_impulse::<L, FIRST>(
                &it.d,
                h,
                w,
                (inv_i, inertia, tq),
                it.i as usize,
                Some(it.j as usize),
                &mut led,
            );
        }
    }
    let n = w.len();
    let nc = n.div_ceil(GRAIN_CHUNK);
    let nw = nwalls.min(MAX_WALLS);
    for wi in 0..nw {
        for c in 0..nc {
            let cnt = wcount[wi * nc + c] as usize;
            let at = wi * n + c * GRAIN_CHUNK;
            for it in &witems[at..at + cnt] {
                pair_impulse::<L, FIRST>(&it.d, h, w, (inv_i, inertia, tq), it.i as usize, None, &mut led);
            }
        }
    }
    led
}

/// Half kick of grains `lo..hi` with the chunk's 1/m, 1/I and forces (fx, fy, tq):
/// v ← v + (h/m) F, ω ← ω + (h/I) M, in loops without branches that run several grains
/// at once;
/// books a driver's work on prescribed grains (1/m = 0) in `part`, in grain order. Returns
/// the chunk's new (vx, vy, ω).
///
/// # Safety
/// `lo..hi` is in bounds of every array, and no other thread touches those indices of
/// `vx`, `vy`, `w` meanwhile.
#[inline(always)]
pub(crate) unsafe fn kick_range<'a, const L: bool>(
    lo: usize,
    hi: usize,
    h: Real,
    (im, ii): (&[Real], &[Real]),
    (fx, fy, tq): (&[Real], &[Real], &[Real]),
    (vx, vy, w): (SharedMut<Real>, SharedMut<Real>, SharedMut<Real>),
    part: &mut Partial,
) -> (&'a mut [Real], &'a mut [Real], &'a mut [Real]) {
    let n = hi - lo;
    let (im, ii) = (&im[..n], &ii[..n]);
    let (fx, fy, tq) = (&fx[..n], &fy[..n], &tq[..n]);
    // SAFETY: caller's contract
    let (vx, vy, w) = unsafe { (vx.slice_mut(lo, n), vy.slice_mut(lo, n), w.slice_mut(lo, n)) };
    if L {
        for a in 0..n {
            if im[a] == 0.0 {
                // driver keeps the prescribed velocity against contacts and gravity
                part.ledger.external_work -= h * (fx[a] * vx[a] + fy[a] * vy[a] + tq[a] * w[a]);
            }
        }
    }
    for a in 0..n {
        vx[a] += h * im[a] * fx[a];
        vy[a] += h * im[a] * fy[a];
        w[a] += h * ii[a] * tq[a];
    }
    (vx, vy, w)
}

/// Drift of the grains of a chunk starting at `lo` (new velocities `vx`, `vy`, `w`):
/// x ← x + Δt v, (if `THETA`) θ ← θ + Δt ω; returns
/// whether one moved more than √lim from its position at the last neighbour build.
///
/// # Safety
/// As [`kick_range`] for `x`, `y`, `th`.
#[inline(always)]
pub(crate) unsafe fn drift_range<const THETA: bool>(
    lo: usize,
    dt: Real,
    (vx, vy, w): (&mut [Real], &mut [Real], &mut [Real]),
    (x, y, th): (SharedMut<Real>, SharedMut<Real>, SharedMut<Real>),
    x0y0: Option<(&[Real], &[Real])>,
    lim: Real,
) -> bool {
    let n = vx.len();
    let vy = &vy[..n];
    // SAFETY: caller's contract
    let (x, y) = unsafe { (x.slice_mut(lo, n), y.slice_mut(lo, n)) };
    for a in 0..n {
        x[a] += dt * vx[a];
        y[a] += dt * vy[a];
    }
    if THETA {
        // SAFETY: caller's contract
        let th = unsafe { th.slice_mut(lo, n) };
        let w = &w[..n];
        for a in 0..n {
            th[a] += dt * w[a];
        }
    }
    match x0y0 {
        Some((x0, y0)) => {
            let (x0, y0) = (&x0[lo..lo + n], &y0[lo..lo + n]);
            let mut moved = false;
            for a in 0..n {
                let (dx, dy) = (x[a] - x0[a], y[a] - y0[a]);
                moved |= dx * dx + dy * dy > lim;
            }
            moved
        }
        None => false,
    }
}

/// Backward-Euler dashpot impulse between grain `i` and grain `j` (or a wall, spin 0,
/// infinite inertia) over `h`, clipped by the cap of `d`. `FIRST`: also books the
/// splitting term h M·δω of both grains ([`dashpot_sweep`]).
#[inline(always)]
fn pair_impulse<const L: bool, const FIRST: bool>(
    d: &RollDashpot,
    h: Real,
    w: &mut [Real],
    (inv_i, inertia, tq): (&[Real], &[Real], &[Real]),
    i: usize,
    j: Option<usize>,
    led: &mut Ledger,
) {
    let (wj, iij) = match j {
        Some(j) => (w[j], inv_i[j]),
        None => (0.0, 0.0),
    };
    let wi = w[i];
    let iii = inv_i[i];
    let inv_eff = iii + iij;
    if inv_eff == 0.0 {
        return;
    }
    let u = wi - wj;
    // u⁺ = u/(1 + h c/I_eff); J = −I_eff (u − u⁺) = −h c u⁺ (impulse on i)
    let mut jm = -h * d.c * u / (1.0 + h * d.c * inv_eff);
    // cap on spring + dashpot: M_spring + J/h ∈ [−M_max, M_max]
    if d.m_max.is_finite() {
        // |M_spring| < M_max below the cap, so 0 is inside: clipping never reverses J
        jm = jm.clamp(h * (-d.m_max - d.m_spring), h * (d.m_max - d.m_spring));
    }
    let wi_new = wi + iii * jm;
    w[i] = wi_new;
    if let Some(j) = j {
        let wj_new = wj - iij * jm;
        w[j] = wj_new;
        if L {
            led.rolling += 0.5 * inertia[j] * (wj * wj - wj_new * wj_new);
            if FIRST {
                led.rolling += h * tq[j] * (wj_new - wj);
            }
            if iij == 0.0 {
                // a driver holds j's spin against −J: its work is external, and dissipated
                led.external_work += jm * wj;
                led.rolling += jm * wj;
            }
        }
    }
    if L {
        if FIRST {
            led.rolling += h * tq[i] * (wi_new - wi);
        }
        if iii > 0.0 {
            led.rolling += 0.5 * inertia[i] * (wi * wi - wi_new * wi_new);
        } else {
            led.external_work -= jm * wi;
            led.rolling -= jm * wi;
        }
    }
}

/// Kinetic energy per grain (helper for the watchdog) [J/m].
pub(crate) fn grain_ke(s: &crate::dem::state::State, i: usize) -> Real {
    0.5 * s.m[i] * (s.vx[i] * s.vx[i] + s.vy[i] * s.vy[i]) + 0.5 * s.inertia[i] * s.w[i] * s.w[i]
}

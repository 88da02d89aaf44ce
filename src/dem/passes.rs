//! The chunk kernels of one force evaluation, as jobs a phase runs chunk by chunk:
//!
//! - [`PairFilter`] — pass 1 of the pair pass: which listed pairs of a chunk have work;
//! - [`PairPass`] — pass 2: the contact law on those pairs, in batches;
//! - [`GrainPass`] — per grain chunk: force gather, grain–wall contacts, second half kick
//!   (and, for a joined step, the next step's translational kick and drift).
//!
//! A job holds shared views of the world's arrays ([`SharedRef`], [`SharedMut`]; their
//! contract is [`crate::shared`]'s) rather than borrows, so that one phase can run several
//! of them at once on a thread team — a grain chunk may drift positions that the pair pass
//! of other chunks still reads, once those chunks are done (`World::staged_forces` orders
//! them). A job is valid while the world's arrays are not reallocated: for one phase, made
//! just before it. Its read views index with the neighbour list's and the gather tables'
//! indices, every entry < the number of grains or pairs they were built for (checked with
//! the `checked` feature).

use crate::dem::contact_law::{BATCH, Law, LawCoeffs, PairBatch, PairBatchOut, PairIn, RollDashpot};
use crate::dem::integrate::{drift_range, kick_range};
use crate::dem::scratch::{GRAIN_CHUNK, GrainChunk, MAX_WALLS, PAIR_CHUNK, Partial, RollItem};
use crate::dem::state::ContactState;
use crate::dem::timers::Clock;
use crate::dem::walls::Wall;
use crate::dem::world::World;
use crate::math::{Real, Vec2};
use crate::shared::{SharedMut, SharedRef, checked_assert};

/// Three methods of a chunk kernel: `$name`, which runs the kernel's body `$body` (an
/// `#[inline(always)]` method) built for the widest vector unit the CPU has, and the two
/// builds `$avx512` (AVX-512 with BMI1's `tzcnt`) and `$avx2`; else the baseline's SSE2.
/// A build is the whole chunk, the law's lanes inlined (`Law::eval_pairs`): one call per
/// chunk, no spills around the law, the gathers and stores built for the same unit. IEEE
/// add, multiply, divide and square root are exactly rounded at any width and nothing is
/// fused, so every build gives the same bits (the law's batch test runs each width).
/// `$name`'s `# Safety` section is the invocation's (its docs are passed in).
macro_rules! built_for_the_widest_unit {
    ($(#[$doc:meta])* $name:ident, $avx512:ident, $avx2:ident => $body:ident($($a:ident: $t:ty),*) -> $r:ty) => {
        $(#[$doc])*
        pub(crate) unsafe fn $name(&self, $($a: $t),*) -> $r {
            #[cfg(target_arch = "x86_64")]
            {
                if std::arch::is_x86_feature_detected!("avx512f") && std::arch::is_x86_feature_detected!("bmi1") {
                    // SAFETY: the CPU has the features; caller's contract
                    return unsafe { self.$avx512($($a),*) };
                }
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU has the feature; caller's contract
                    return unsafe { self.$avx2($($a),*) };
                }
            }
            // SAFETY: caller's contract
            unsafe { self.$body($($a),*) }
        }

        /// The kernel's body built for AVX-512 (with BMI1's `tzcnt`).
        ///
        /// # Safety
        /// The CPU has AVX-512F and BMI1, and the body's contract holds (as the dispatching
        /// method's).
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx512f,bmi1")]
        #[inline(never)]
        unsafe fn $avx512(&self, $($a: $t),*) -> $r {
            // SAFETY: caller's contract (the body's)
            unsafe { self.$body($($a),*) }
        }

        /// The kernel's body built for AVX2.
        ///
        /// # Safety
        /// The CPU has AVX2, and the body's contract holds (as the dispatching method's).
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2")]
        #[inline(never)]
        unsafe fn $avx2(&self, $($a: $t),*) -> $r {
            // SAFETY: caller's contract (the body's)
            unsafe { self.$body($($a),*) }
        }
    };
}

thread_local! {
    /// Lanes of the pair pass's batches, one set per thread (kept between chunks: filling
    /// 20 kB with zeros per chunk cost 2 % of the step).
    static PAIR_SCRATCH: std::cell::Cell<Option<Box<(PairBatch, PairBatchOut)>>> = const { std::cell::Cell::new(None) };
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

/// Pass 1 of the pair pass: which listed pairs of a chunk have work (touching, or
/// separated with a history still to drop), in pair order. A live pair (touching at its
/// last evaluation, `World::plive`) has work whatever it does now, so only the others are
/// checked, 64 pairs to a word of live bits: a separated pair found separated before has
/// nothing left to drop and has work only if it touches now (without a branch: whether a
/// pair touches follows no pattern along the list). Reads positions and radii only, so on
/// a thread team it runs beside the spin work of a joined step's start
/// (`World::staged_forces`).
#[derive(Clone, Copy)]
pub(crate) struct PairFilter {
    pi: SharedRef<u32>,
    pj: SharedRef<u32>,
    shift: SharedRef<Real>,
    x: SharedRef<Real>,
    y: SharedRef<Real>,
    r: SharedRef<Real>,
    lx: Real,
    live: SharedMut<u64>,
    todo: SharedMut<u16>,
}

impl PairFilter {
    pub(crate) fn new(w: &mut World) -> Self {
        let nl = &w.nl;
        checked_assert!(w.plive.len() == nl.len().div_ceil(64) && w.todo.len() >= nl.len());
        // SAFETY: read only by `run`/`run_to`, at the pairs of a chunk of this list and at
        // their grains (the list's indices are < the number of grains, `World::run_with`
        // rebuilds a stale list); the positions are written meanwhile only by grain chunks
        // whose pairs are done (`World::staged_forces`)
        unsafe {
            PairFilter {
                pi: SharedRef::new(&nl.pi),
                pj: SharedRef::new(&nl.pj),
                shift: SharedRef::new(&nl.shift),
                x: SharedRef::of(&mut w.state.x),
                y: SharedRef::of(&mut w.state.y),
                r: SharedRef::new(&w.state.r),
                lx: w.periodic_x.unwrap_or(0.0),
                live: SharedMut::of(&mut w.plive),
                todo: SharedMut::of(&mut w.todo),
            }
        }
    }

    /// Writes the offsets from `lo` of the pairs `lo..hi` with work to `todo[lo..]`, in
    /// increasing order; returns how many.
    ///
    /// # Safety
    /// `lo..hi` is one pair chunk of the list the filter was made for, whose `todo` and
    /// `live` entries no other thread touches meanwhile, nor the positions of its grains.
    pub(crate) unsafe fn run(&self, lo: usize, hi: usize) -> usize {
        // SAFETY: caller's contract (a chunk of the list: in bounds of `todo`)
        unsafe { self.run_widest(lo, hi, self.todo.slice_mut(lo, hi - lo).as_mut_ptr()) }
    }

    built_for_the_widest_unit! {
        /// [`PairFilter::run_to`] built for the CPU's vector unit (as the pair chunk that
        /// runs it unfiltered).
        ///
        /// # Safety
        /// As [`PairFilter::run_to`].
        run_widest, run_avx512, run_avx2 => run_to(lo: usize, hi: usize, dst: *mut u16) -> usize
    }

    /// As [`PairFilter::run`], the offsets to `dst[..hi - lo]`.
    ///
    /// # Safety
    /// As [`PairFilter::run`]; `dst` holds `hi - lo` entries.
    #[inline(always)]
    pub(crate) unsafe fn run_to(&self, lo: usize, hi: usize, dst: *mut u16) -> usize {
        let (pi, pj, shift, x, y, r, lx) = (self.pi, self.pj, self.shift, self.x, self.y, self.r, self.lx);
        checked_assert!(lo.is_multiple_of(64) && hi - lo <= PAIR_CHUNK);
        let mut n_todo = 0usize;
        for base in (lo..hi).step_by(64) {
            let valid = if hi - base >= 64 {
                !0u64
            } else {
                (1u64 << (hi - base)) - 1
            };
            // SAFETY: caller's contract (this chunk's words)
            let live = unsafe { self.live.get(base / 64) } & valid;
            let mut work = live;
            let mut rest = !live & valid;
            while rest != 0 {
                let b = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                let k = base + b;
                let (i, j) = (pi[k] as usize, pj[k] as usize);
                let dx = x[i] - (x[j] + shift[k] * lx);
                let dy = y[i] - y[j];
                let rsq = dx * dx + dy * dy;
                let radsum = r[i] + r[j];
                let touching = !(rsq >= radsum * radsum);
                work |= u64::from(touching) << b;
            }
            let o = base - lo;
            while work != 0 {
                let b = work.trailing_zeros() as usize;
                work &= work - 1;
                checked_assert!(n_todo < hi - lo);
                // SAFETY: caller's contract; at most hi - lo offsets
                unsafe { dst.add(n_todo).write((o + b) as u16) };
                n_todo += 1;
            }
        }
        n_todo
    }
}

/// Pass 2 of the pair pass: the contact law on the pairs the filter kept, each pair's
/// force to its own slot (`pout`), its history advanced, its dashpot listed.
#[derive(Clone, Copy)]
pub(crate) struct PairPass<const R: bool, const IMP: bool, const L: bool> {
    coeffs: LawCoeffs,
    dt: Real,
    lx: Real,
    pi: SharedRef<u32>,
    pj: SharedRef<u32>,
    shift: SharedRef<Real>,
    cn: SharedRef<Real>,
    rr: SharedRef<Real>,
    x: SharedRef<Real>,
    y: SharedRef<Real>,
    vx: SharedRef<Real>,
    vy: SharedRef<Real>,
    w: SharedRef<Real>,
    r: SharedRef<Real>,
    hist: SharedMut<ContactState>,
    pout: SharedMut<[Real; 4]>,
    ritems: SharedMut<RollItem>,
    live: SharedMut<u64>,
    /// The filter of this list; its `todo` holds the pairs to evaluate.
    pub(crate) filter: PairFilter,
}

impl<const R: bool, const IMP: bool, const L: bool> PairPass<R, IMP, L> {
    /// The pass over `w`'s list with histories advancing by `dt`. The dashpot list grows
    /// to the list's size here (never shrinks: the sweeps of a joined step read the last
    /// evaluation's dashpots in the same phase, `World::staged_forces`).
    pub(crate) fn new(w: &mut World, dt: Real) -> Self {
        let np = w.nl.len();
        if w.roll.items.len() < np {
            w.roll.items.resize(np, RollItem::default());
        }
        checked_assert!(w.plive.len() == np.div_ceil(64));
        checked_assert!(w.nl.pj.iter().all(|&j| (j as usize) < w.state.len()));
        let filter = PairFilter::new(w);
        let (nl, s) = (&mut w.nl, &mut w.state);
        // SAFETY: read only by `chunk`, at the pairs of a chunk of this list and at their
        // grains (as `PairFilter::new`); the positions, velocities and spins are written
        // meanwhile only by the spin job and grain chunks that the phase orders before or
        // after the pair chunks reading them (`World::staged_forces`)
        unsafe {
            PairPass {
                coeffs: LawCoeffs::new(&w.params.grain, &w.params.rolling),
                dt,
                lx: w.periodic_x.unwrap_or(0.0),
                pi: SharedRef::new(&nl.pi),
                pj: SharedRef::new(&nl.pj),
                shift: SharedRef::new(&nl.shift),
                cn: SharedRef::new(&nl.cn),
                rr: SharedRef::new(&nl.r_roll),
                x: SharedRef::of(&mut s.x),
                y: SharedRef::of(&mut s.y),
                vx: SharedRef::of(&mut s.vx),
                vy: SharedRef::of(&mut s.vy),
                w: SharedRef::of(&mut s.w),
                r: SharedRef::new(&s.r),
                hist: SharedMut::of(&mut nl.hist),
                pout: SharedMut::of(&mut w.pout),
                ritems: SharedMut::of(&mut w.roll.items),
                live: filter.live,
                filter,
            }
        }
    }

    built_for_the_widest_unit! {
        /// The pairs `lo..hi` (one chunk): the filter first, unless it has run and found
        /// `filtered` pairs with work. Returns the chunk's partial (`n_roll[0]`: dashpots it
        /// listed at `ritems[lo..]`).
        ///
        /// # Safety
        /// `lo..hi` is one pair chunk, its slots touched by no other thread meanwhile; nothing
        /// writes the positions, velocities or spins of its grains meanwhile; `filtered` is
        /// `None`, or `Some(k)` with `k` what the filter's `run` on this chunk returned.
        chunk, chunk_avx512, chunk_avx2 => chunk_body(lo: usize, hi: usize, filtered: Option<usize>) -> Partial
    }

    /// The body of [`PairPass::chunk`].
    ///
    /// # Safety
    /// As [`PairPass::chunk`].
    #[inline(always)]
    unsafe fn chunk_body(&self, lo: usize, hi: usize, filtered: Option<usize>) -> Partial {
        let mut part = Partial::default();
        let (pi, pj, shift, cn, rr, lx) = (self.pi, self.pj, self.shift, self.cn, self.rr, self.lx);
        let (x, y, vx, vy, w, r) = (self.x, self.y, self.vx, self.vy, self.w, self.r);
        let (hist, pout, ritems, live, coeffs, dt) =
            (self.hist, self.pout, self.ritems, self.live, &self.coeffs, self.dt);
        // Pass 1 (`PairFilter`): the pairs with work to do, in pair order; unfiltered, the
        // chunk filters into a buffer on the stack (in L1 for the pass; not zeroed: the
        // filter writes every entry it counts)
        let mut local = std::mem::MaybeUninit::<[u16; PAIR_CHUNK]>::uninit();
        let todo = match filtered {
            // SAFETY: caller's contract: the filter ran on this chunk and wrote `k` offsets
            // to `todo[lo..]`, which no other thread touches
            Some(k) => unsafe { self.filter.todo.slice(lo, k) },
            // SAFETY: caller's contract (`PairFilter::run_to`'s); `local` holds PAIR_CHUNK
            // ≥ hi − lo entries, of which the filter wrote the first `k`
            None => unsafe {
                let p = local.as_mut_ptr() as *mut u16;
                let k = self.filter.run_to(lo, hi, p);
                std::slice::from_raw_parts(p, k)
            },
        };
        // Pass 2: those pairs in order, with the same arithmetic as a single pass, in
        // batches: (a) gather each pair's inputs into lanes, (b) evaluate the law on
        // all lanes at once (`Law::eval_pairs`, SIMD), (c) store the results and book
        // the sums pair by pair. The ledger sums run in registers (same order of
        // additions as into `part`).
        let (mut led_n, mut led_t, mut led_r) = (0.0, 0.0, 0.0);
        let mut n_roll = 0usize;
        // the chunk's live bits after this evaluation: its touching pairs (a pair without
        // work stays separated, with no history)
        let mut now_live = [0u64; PAIR_CHUNK / 64];
        let mut scratch = PAIR_SCRATCH
            .take()
            .unwrap_or_else(|| Box::new((PairBatch::default(), PairBatchOut::default())));
        let (b, bo) = &mut *scratch;
        for batch in todo.chunks(BATCH) {
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
                // SAFETY: `k` is a pair of this chunk (caller's contract): its history is this
                // chunk's alone during the pass
                let h = unsafe { hist.get(k) };
                b.h[0][l] = h.tangential;
                b.h[1][l] = h.rolling;
                b.h[2][l] = h.ft;
                b.h[3][l] = h.mr;
            }
            // (b) the law on every lane (separated lanes give unused numbers)
            Law::<R, IMP, L>::eval_pairs(coeffs, b, bo, nb, dt);
            // (c) store, in pair order
            for (l, &o) in batch.iter().enumerate() {
                let k = lo + o as usize;
                let (i, j) = (pi[k] as usize, pj[k] as usize);
                let radsum = b.radsum[l];
                // SAFETY: `k` is a pair of this chunk and `lo + n_roll` ≤ `k` (caller's
                // contract): their history, force and dashpot slots are this chunk's alone
                unsafe {
                    // separated → drop history (once)
                    if b.rsq[l] >= radsum * radsum {
                        let h = hist.get(k);
                        if h != ContactState::default() {
                            if L {
                                let (et, er) = Law::<R, IMP, L>::released(coeffs, &h);
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
                    now_live[o as usize / 64] |= 1 << (o % 64);
                    hist.set(
                        k,
                        ContactState {
                            tangential: b.h[0][l],
                            rolling: b.h[1][l],
                            ft: b.h[2][l],
                            mr: b.h[3][l],
                        },
                    );
                    pout.set(k, [bo.fx[l], bo.fy[l], bo.t_i[l], bo.t_j[l]]);
                    if IMP {
                        // written always, kept (counted) only with a dashpot: no branch
                        let d = RollDashpot {
                            c: bo.roll[0][l],
                            m_spring: bo.roll[1][l],
                            m_max: bo.roll[2][l],
                        };
                        ritems.set(
                            lo + n_roll,
                            RollItem {
                                i: i as u32,
                                j: j as u32,
                                d,
                            },
                        );
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
        for (q, &v) in now_live[..(hi - lo).div_ceil(64)].iter().enumerate() {
            // SAFETY: this chunk's words
            unsafe { live.set(lo / 64 + q, v) };
        }
        part.ledger.normal_damping += led_n;
        part.ledger.tangential += led_t;
        part.ledger.rolling += led_r;
        part.n_roll[0] = n_roll as u32;
        part
    }
}

/// The per-grain pass after the pair pass, one grain chunk at a time (each chunk's grains
/// stay in cache): (1) gather of the pair forces in increasing pair order plus gravity,
/// (2) grain–wall contacts with the same law, walls in order, (3) with `KICK` the second
/// half kick, and with `next` the next step's translational half kick and drift (a joined
/// step). Every grain's arithmetic and every partial sum is in the same order as when
/// these were separate passes (walls within a chunk: wall by wall, grains in order), so
/// the results are bit-identical to them.
#[derive(Clone, Copy)]
pub(crate) struct GrainPass<const R: bool, const IMP: bool, const L: bool, const KICK: bool> {
    coeffs: LawCoeffs,
    /// Step of the histories (0 for a priming evaluation) and of the kicks and drift.
    dt: Real,
    step_dt: Real,
    g: Real,
    n: usize,
    next: bool,
    on: bool,
    lim: Real,
    walls: SharedRef<Wall>,
    any_wall: bool,
    /// The near-wall lists (`NearWalls`): grains and per (wall, chunk) starts.
    near: SharedRef<u32>,
    near_start: SharedRef<u32>,
    near_chunks: usize,
    istart: SharedRef<u32>,
    jstart: SharedRef<u32>,
    jlist: SharedRef<u32>,
    pout: SharedRef<[Real; 4]>,
    m: SharedRef<Real>,
    r: SharedRef<Real>,
    inv_m: SharedRef<Real>,
    inv_i: SharedRef<Real>,
    wcn: SharedRef<Real>,
    x0: Option<(SharedRef<Real>, SharedRef<Real>)>,
    x: SharedMut<Real>,
    y: SharedMut<Real>,
    th: SharedMut<Real>,
    vx: SharedMut<Real>,
    vy: SharedMut<Real>,
    w: SharedMut<Real>,
    fx: SharedMut<Real>,
    fy: SharedMut<Real>,
    tq: SharedMut<Real>,
    hist: SharedMut<ContactState>,
    live: SharedMut<u8>,
    witems: SharedMut<RollItem>,
}

impl<const R: bool, const IMP: bool, const L: bool, const KICK: bool> GrainPass<R, IMP, L, KICK> {
    /// The pass over `w`'s grains with contact histories advancing by `dt`; `next`: also
    /// the next step's translational first half (needs `KICK` and no prescribed grain).
    pub(crate) fn new(w: &mut World, dt: Real, next: bool) -> Self {
        let n = w.state.len();
        checked_assert!(!next || (KICK && w.state.inv_m.iter().all(|&v| v != 0.0)));
        w.ensure_near_walls();
        let s = &mut w.state;
        let nl = &w.nl;
        // SAFETY: read only by `chunk`, at the grains of a grain chunk (< n), their pairs'
        // force slots (`istart`, `jlist`: < the number of pairs), the near-wall lists'
        // entries (grains of the chunk) and starts (per wall and chunk); the arrays read
        // are written meanwhile only by the chunk that reads them or by pair chunks done
        // before it (`World::staged_forces`)
        unsafe {
            GrainPass {
                coeffs: LawCoeffs::new(&w.params.wall, &w.params.rolling),
                dt,
                step_dt: w.params.dt,
                g: w.params.gravity,
                n,
                next,
                on: w.timing,
                lim: 0.25 * nl.skin * nl.skin,
                walls: SharedRef::new(&w.walls),
                any_wall: w.walls.iter().any(|w| w.active),
                near: SharedRef::new(&w.near.grains),
                near_start: SharedRef::new(&w.near.start),
                near_chunks: w.near.chunks,
                istart: SharedRef::new(&nl.istart),
                jstart: SharedRef::new(&nl.jstart),
                jlist: SharedRef::new(&nl.jlist),
                pout: SharedRef::of(&mut w.pout),
                m: SharedRef::new(&s.m),
                r: SharedRef::new(&s.r),
                inv_m: SharedRef::new(&s.inv_m),
                inv_i: SharedRef::new(&s.inv_i),
                wcn: SharedRef::new(&w.wall_cn),
                x0: (nl.x0.len() == n).then(|| (SharedRef::new(&nl.x0), SharedRef::new(&nl.y0))),
                x: SharedMut::of(&mut s.x),
                y: SharedMut::of(&mut s.y),
                th: SharedMut::of(&mut s.theta),
                vx: SharedMut::of(&mut s.vx),
                vy: SharedMut::of(&mut s.vy),
                w: SharedMut::of(&mut s.w),
                fx: SharedMut::of(&mut w.fx),
                fy: SharedMut::of(&mut w.fy),
                tq: SharedMut::of(&mut w.tq),
                hist: SharedMut::of(&mut w.wall_hist),
                live: SharedMut::of(&mut w.wlive),
                witems: SharedMut::of(&mut w.roll.witems),
            }
        }
    }

    built_for_the_widest_unit! {
        /// Grains `lo..hi` (one chunk).
        ///
        /// # Safety
        /// `lo..hi` is one grain chunk, whose grains no other thread touches meanwhile, and
        /// every pair of its grains has been evaluated (`pout`).
        chunk, chunk_avx512, chunk_avx2 => chunk_body(lo: usize, hi: usize) -> GrainChunk
    }

    /// The body of [`GrainPass::chunk`].
    ///
    /// # Safety
    /// As [`GrainPass::chunk`].
    #[inline(always)]
    unsafe fn chunk_body(&self, lo: usize, hi: usize) -> GrainChunk {
        let (n, dt, step_dt, on) = (self.n, self.dt, self.step_dt, self.on);
        let h = 0.5 * step_dt;
        let (istart, jstart, jlist, pout, m, r, g) =
            (self.istart, self.jstart, self.jlist, self.pout, self.m, self.r, self.g);
        let (inv_m, inv_i, wcn) = (self.inv_m, self.inv_i, self.wcn);
        let (xp, yp, th, vx, vy, w) = (self.x, self.y, self.th, self.vx, self.vy, self.w);
        let (fx, fy, tq, hist, live, witems) = (self.fx, self.fy, self.tq, self.hist, self.live, self.witems);
        // SAFETY: not written during the phase
        let walls = unsafe { self.walls.slice(0, self.walls.len()) };
        let coeffs = &self.coeffs;
        let t0 = Clock::now(on);
        if IMP && KICK {
            // θ ← θ + Δt ω of the step's first half (ω after the first dashpot sweep;
            // see `World::integrate_first_half`)
            // SAFETY: this chunk's grains only
            unsafe {
                let (th, w) = (th.slice_mut(lo, hi - lo), w.slice(lo, hi - lo));
                for a in 0..hi - lo {
                    th[a] += step_dt * w[a];
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
            // SAFETY: the gather table is not written during the phase
            for &k in unsafe { jlist.slice(jstart[a] as usize, (jstart[a + 1] - jstart[a]) as usize) } {
                let k = k as usize;
                let o = &pout[k];
                ax -= o[0];
                ay -= o[1];
                at += o[3];
            }
            // SAFETY: `a` is this chunk's grain
            unsafe {
                fx.set(a, ax);
                fy.set(a, ay);
                tq.set(a, at);
            }
        }
        let t1 = Clock::now(on);
        // (2) grain–wall contacts, wall by wall, over the grains near each wall
        // (`NearWalls`: the others have no contact and nothing to drop)
        let mut part = Partial::default();
        if self.any_wall {
            checked_assert!(
                lo.is_multiple_of(GRAIN_CHUNK) && self.near_start.len() == walls.len() * (self.near_chunks + 1)
            );
            let c = lo / GRAIN_CHUNK;
            for (wi, wall) in walls.iter().enumerate() {
                if !wall.active {
                    continue;
                }
                let at = wi * (self.near_chunks + 1) + c;
                let (s, e) = (self.near_start[at] as usize, self.near_start[at + 1] as usize);
                // SAFETY: not written during the phase
                for &a in unsafe { self.near.slice(s, e - s) } {
                    let a = a as usize;
                    checked_assert!((lo..hi).contains(&a));
                    let hk = wi * n + a;
                    // SAFETY: this chunk's grain
                    let p = unsafe { Vec2::new(xp.get(a), yp.get(a)) };
                    let overlap = r[a] - wall.distance(p);
                    if overlap <= 0.0 {
                        // SAFETY: `a` is this chunk's grain, so its contact with wall `wi`
                        // (slot `hk`) is this chunk's alone
                        unsafe {
                            if live.get(hk) == 0 {
                                continue;
                            }
                            live.set(hk, 0);
                            let h = hist.get(hk);
                            if h != ContactState::default() {
                                if L {
                                    let (et, er) = Law::<R, IMP, L>::released(coeffs, &h);
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
                    // SAFETY: `a` is this chunk's grain, `hk` its contact with wall `wi`, and
                    // `wi * n + lo + n_roll[wi]` (n_roll[wi] < hi − lo) a dashpot slot of this
                    // chunk's range for that wall: all this chunk's alone
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
                        let o = Law::<R, IMP, L>::eval(coeffs, &pin, &mut h, dt);
                        hist.set(hk, h);
                        fx.set(a, fx.get(a) + o.f.x);
                        fy.set(a, fy.get(a) + o.f.y);
                        tq.set(a, tq.get(a) + o.t_i);
                        if IMP && o.roll.c > 0.0 {
                            witems.set(
                                wi * n + lo + part.n_roll[wi] as usize,
                                RollItem {
                                    i: a as u32,
                                    j: u32::MAX,
                                    d: o.roll,
                                },
                            );
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
                let f = |p: SharedMut<Real>| p.slice(lo, hi - lo);
                let (im, ii) = (inv_m.slice(lo, hi - lo), inv_i.slice(lo, hi - lo));
                let (vxs, vys, _) =
                    kick_range::<L>(lo, hi, h, (im, ii), (f(fx), f(fy), f(tq)), (vx, vy, w), &mut kpart);
                if self.next {
                    // the next step's translational half kick (`kick_range`'s arithmetic;
                    // no prescribed grain, nothing to book) and drift
                    let (fx, fy) = (f(fx), f(fy));
                    for a in 0..hi - lo {
                        vxs[a] += h * im[a] * fx[a];
                        vys[a] += h * im[a] * fy[a];
                    }
                    let x0y0 = self.x0.as_ref().map(|(x0, y0)| (x0.slice(0, n), y0.slice(0, n)));
                    kpart.moved = drift_range::<false>(
                        lo,
                        step_dt,
                        (vxs, vys, &mut []),
                        (xp, yp, SharedMut::new(&mut [])),
                        x0y0,
                        self.lim,
                    );
                }
            }
        }
        let t3 = Clock::now(on);
        GrainChunk {
            walls: part,
            kick: kpart,
            secs: [t0.to(t1), t1.to(t2), t2.to(t3)],
        }
    }
}

/// The grain chunk range `[first, last)` of pair chunks holding a pair of each grain chunk
/// (as i or as j): what its gather must wait for in a joined step. Empty for a chunk
/// without pairs.
pub(crate) fn grain_chunk_deps(
    istart: &[u32],
    jstart: &[u32],
    jlist: &[u32],
    n: usize,
    grain_chunk: usize,
) -> Vec<(u32, u32)> {
    (0..n.div_ceil(grain_chunk))
        .map(|c| {
            let (lo, hi) = (c * grain_chunk, ((c + 1) * grain_chunk).min(n));
            let (mut a, mut b) = (u32::MAX, 0u32);
            if istart[hi] > istart[lo] {
                a = istart[lo];
                b = istart[hi] - 1;
            }
            for &k in &jlist[jstart[lo] as usize..jstart[hi] as usize] {
                a = a.min(k);
                b = b.max(k);
            }
            if a == u32::MAX {
                (0, 0)
            } else {
                (a / PAIR_CHUNK as u32, b / PAIR_CHUNK as u32 + 1)
            }
        })
        .collect()
}

const _: () = assert!(MAX_WALLS <= 8);

#[cfg(test)]
mod tests;

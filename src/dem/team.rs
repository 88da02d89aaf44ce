//! In-step parallelism for one DEM world: a team of threads held for a whole
//! [`World::run`](crate::dem::World::run) call, sharing out each parallel phase's fixed
//! chunks without waking a pool per phase.
//!
//! Why not a rayon region per phase: at a few thousand grains a phase lasts 10–100 µs,
//! and a pool worker that went to sleep between two regions takes about as long to wake
//! (futex, and in a VM an inter-processor interrupt) — the 2-thread step was slower than
//! the 1-thread one. Here the run's thread (the *lead*) spawns one helper job per other
//! pool thread once per `run` call; a helper spins between phases (a few µs of serial
//! work: the rolling-dashpot sweep) instead of sleeping.
//!
//! Each phase publishes a job `f(c)` for chunks `c` in `0..nc` — or several, as stages run
//! one after the other without a barrier between them ([`for_stages`]). The lead claims
//! chunks from the front, helpers from the back (one atomic word per stage holds the phase
//! epoch and both ends), so each thread keeps about the same contiguous block of grains
//! and pairs from phase to phase and step to step (its cache), while an idle or slow
//! helper costs nothing: the lead takes whatever is left. The lead never waits for a helper to
//! *start*, only for chunks a helper has already claimed to finish, so a helper that is
//! never scheduled (busy pool, loaded machine) cannot stall the run. Every chunk writes
//! its own output slot and the lead reduces them in chunk order: results do not depend on
//! which thread ran which chunk, nor on the number of threads.
//!
//! A team only pays when its threads run at the same time: when there are more runnable
//! threads than cores (other processes), a helper descheduled while it holds a chunk
//! makes the lead wait a time slice at the phase's end, and the step runs slower than on
//! the lead alone. So [`World::run`](crate::dem::World::run) times steps alone (a
//! reference) and the team's steps in blocks, and keeps the team while it is clearly the
//! faster (see [`crate::dem::world::TEAM_PROBE`] and `World::run_with`).

use std::any::Any;
use std::cell::{Cell, UnsafeCell};
use std::panic::{AssertUnwindSafe, catch_unwind, resume_unwind};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering::*};

/// Below this many grains a world steps on its calling thread even in a multi-thread
/// pool (and leaves the other threads to other scenes). Measured crossover on the project's
/// 2-core machine, `bench dem-crossover` (docs/performance.md, "Session 5: DEM").
pub const TEAM_MIN_GRAINS: usize = 1000;

const BITS: u32 = 20;
const MASK: u64 = (1 << BITS) - 1;
const EPOCH: u64 = (1 << 24) - 1;
/// Most chunks a stage can have (larger phases run on the lead alone).
const MAX_CHUNKS: usize = MASK as usize;
/// Most stages a phase can have.
pub(crate) const MAX_STAGES: usize = 4;

type Job = *const (dyn Fn(usize) + Sync);

/// One stage of a phase: `f(c)` for chunks `c` in `0..n`.
pub(crate) type Stage<'a> = (usize, &'a (dyn Fn(usize) + Sync));

/// Shared state of one team (see the module doc).
pub(crate) struct Team {
    /// The current phase: epoch (24 bits) | number of stages << 24.
    phase: AtomicU64,
    /// Per stage: epoch (24 bits) | front (20) | back (20): chunks `front..back` are
    /// unclaimed. The epoch makes a claim on a stage of an earlier phase fail.
    stages: [AtomicU64; MAX_STAGES],
    /// Chunks finished by helpers in the current phase.
    done: AtomicUsize,
    /// Set when the lead's run is over: helpers return.
    quit: AtomicBool,
    /// The current phase's jobs; a job is read only by a thread that has claimed one of
    /// its chunks (the lead does not replace it before every claimed chunk is finished).
    jobs: UnsafeCell<[Option<Job>; MAX_STAGES]>,
    /// Divisor of the chunks left that one claim takes ([`Team::grab`]).
    share: usize,
    /// Set when a chunk panicked: chunks waiting for another's output stop waiting
    /// ([`wait_for`]), the phase runs out, and the lead raises the first panic again —
    /// instead of every thread waiting for a chunk that will never be done.
    failed: AtomicBool,
    /// The first panic's payload.
    failure: Mutex<Option<Box<dyn Any + Send>>>,
}

// SAFETY: `jobs` is written by the lead only while no chunk of the previous phase is
// claimed-but-unfinished and before the phase's stages are published (release stores);
// helpers read a job only after claiming one of its chunks (acquire CAS on its stage).
unsafe impl Sync for Team {}

#[inline(always)]
fn unpack(s: u64) -> (u64, usize, usize) {
    (s >> (2 * BITS), ((s >> BITS) & MASK) as usize, (s & MASK) as usize)
}

impl Team {
    fn new(threads: usize) -> Self {
        Team {
            phase: AtomicU64::new(0),
            stages: [const { AtomicU64::new(0) }; MAX_STAGES],
            done: AtomicUsize::new(0),
            quit: AtomicBool::new(false),
            jobs: UnsafeCell::new([None; MAX_STAGES]),
            share: 2 * threads.max(1),
            failed: AtomicBool::new(false),
            failure: Mutex::new(None),
        }
    }

    /// Chunks `cs` of job `f`; a panic is kept for the lead (see `failed`).
    #[inline(always)]
    fn chunks(&self, cs: impl Iterator<Item = usize>, f: &(dyn Fn(usize) + Sync)) {
        if let Err(p) = catch_unwind(AssertUnwindSafe(|| cs.for_each(f))) {
            let mut first = self.failure.lock().unwrap_or_else(|e| e.into_inner());
            first.get_or_insert(p);
            self.failed.store(true, Release);
        }
    }

    /// How many of `left` unclaimed chunks one claim takes: a share of what is left
    /// (guided scheduling), at least one. Every claim is a compare-exchange on the line
    /// both threads spin on, a cross-core transfer; claiming a few chunks at once halves
    /// them, and the last claims of a phase are still single chunks (the balance at its
    /// end is the same).
    #[inline(always)]
    fn grab(&self, left: usize) -> usize {
        (left / self.share).max(1)
    }

    /// Lead: run every stage's chunks on the team; returns when all are done. A thread
    /// goes on to the next stage as soon as the current one has no chunk left to claim,
    /// without waiting for the other threads' chunks of it: a chunk that needs another
    /// stage's output waits for it itself (its job checks), so the phase has no barrier
    /// inside. Without a team (or when the team has quit) the stages run in order on the
    /// lead, where every such wait is already satisfied.
    fn run(&self, stages: &[Stage<'_>]) {
        let total: usize = stages.iter().map(|s| s.0).sum();
        if stages.len() > MAX_STAGES || stages.iter().any(|s| s.0 > MAX_CHUNKS) || total < 2 || self.quit.load(Relaxed)
        {
            for &(n, f) in stages {
                (0..n).for_each(f);
            }
            return;
        }
        let e = ((self.phase.load(Relaxed) & EPOCH) + 1) & EPOCH;
        // SAFETY: the previous phase is finished (every claimed chunk done), and no new
        // claim can succeed before the stores below publish this phase. The lifetimes are
        // erased: every `f` outlives every use, which ends before this function returns.
        unsafe {
            let jobs = &mut *self.jobs.get();
            for (k, &(_, f)) in stages.iter().enumerate() {
                jobs[k] = Some(std::mem::transmute::<&(dyn Fn(usize) + Sync), Job>(f));
            }
        }
        self.done.store(0, Relaxed);
        for (k, &(n, _)) in stages.iter().enumerate() {
            self.stages[k].store((e << (2 * BITS)) | (n as u64), Release);
        }
        self.phase.store(e | ((stages.len() as u64) << 24), Release);
        let mut mine = 0;
        for (k, &(_, f)) in stages.iter().enumerate() {
            let st = &self.stages[k];
            loop {
                let s = st.load(Relaxed);
                let (_, front, back) = unpack(s);
                if front >= back {
                    break;
                }
                let c = self.grab(back - front);
                if st
                    .compare_exchange_weak(s, s + ((c as u64) << BITS), Acquire, Relaxed)
                    .is_ok()
                {
                    self.chunks(front..front + c, f);
                    mine += c;
                }
            }
        }
        // wait for the chunks helpers claimed
        let mut spins = 0u32;
        while self.done.load(Acquire) + mine < total {
            backoff(&mut spins);
        }
        if self.failed.load(Acquire) {
            let p = self.failure.lock().unwrap_or_else(|e| e.into_inner()).take();
            resume_unwind(p.unwrap_or_else(|| Box::new("a chunk of a DEM team phase panicked")));
        }
    }

    /// Helper: claim chunks from the back of each stage in turn, phase after phase, until
    /// the lead's run is over.
    fn help(&self) {
        MEMBER.with(|m| m.set(self as *const Team));
        let _member = Member;
        let mut spins = 0u32;
        let mut seen = 0u64;
        loop {
            let p = self.phase.load(Acquire);
            let e = p & EPOCH;
            if e != seen {
                let ns = ((p >> 24) as usize).min(MAX_STAGES);
                'stages: for k in 0..ns {
                    let st = &self.stages[k];
                    loop {
                        let s = st.load(Acquire);
                        let (se, front, back) = unpack(s);
                        // a newer phase has begun: this one is over
                        if se != e {
                            break 'stages;
                        }
                        if front >= back {
                            break;
                        }
                        let c = self.grab(back - front);
                        if st.compare_exchange_weak(s, s - c as u64, AcqRel, Relaxed).is_ok() {
                            // SAFETY: chunks of this stage are claimed, so its job is set
                            // and outlives this call (the lead waits for `done`).
                            let f = unsafe { &*(*self.jobs.get())[k].unwrap_unchecked() };
                            // from the back down, as one chunk per claim did
                            self.chunks((back - c..back).rev(), f);
                            self.done.fetch_add(c, Release);
                        }
                    }
                }
                seen = e;
                spins = 0;
                continue;
            }
            if self.quit.load(Acquire) {
                return;
            }
            backoff(&mut spins);
        }
    }
}

/// Spin (the next phase is µs away: a yield would hand the core to another process for a
/// whole time slice), and yield only after a long wait (~10 ms).
#[inline(always)]
pub(crate) fn backoff(spins: &mut u32) {
    if *spins < 1 << 22 {
        *spins += 1;
        std::hint::spin_loop();
    } else {
        std::thread::yield_now();
    }
}

thread_local! {
    /// The team this thread leads.
    static CURRENT: Cell<*const Team> = const { Cell::new(std::ptr::null()) };
    /// The team this thread helps (while in `Team::help`).
    static MEMBER: Cell<*const Team> = const { Cell::new(std::ptr::null()) };
}

/// Clears `MEMBER` when a helper leaves its team.
struct Member;
impl Drop for Member {
    fn drop(&mut self) {
        MEMBER.with(|m| m.set(std::ptr::null()));
    }
}

/// Wait until `flag` holds the stamp `id` (a chunk's output is visible, acquire) — or
/// until a chunk of this thread's team has panicked: the phase is then abandoned, and
/// its lead raises the panic when every claimed chunk has returned.
pub(crate) fn wait_for(flag: &AtomicU64, id: u64) {
    let mut spins = 0u32;
    while flag.load(Acquire) != id {
        if spins % 64 == 0 {
            let t = MEMBER.with(|m| m.get());
            let t = if t.is_null() { CURRENT.with(|c| c.get()) } else { t };
            // SAFETY: the team outlives its lead's and helpers' use of it (see `with_team`)
            if !t.is_null() && unsafe { &*t }.failed.load(Acquire) {
                return;
            }
        }
        backoff(&mut spins);
    }
}

struct Lead<'a>(&'a Team, *const Team);
impl Drop for Lead<'_> {
    fn drop(&mut self) {
        CURRENT.with(|c| c.set(self.1));
        self.0.quit.store(true, Release);
    }
}

/// Run `f` (a world's steps) with a team of the current rayon pool's threads when the pool
/// has more than one and `big` (the world has at least its `team_min_grains`, by default
/// [`TEAM_MIN_GRAINS`]); phases inside share their chunks through [`for_chunks`].
pub(crate) fn with_team<R: Send>(big: bool, f: impl FnOnce() -> R + Send) -> R {
    let threads = rayon::current_num_threads();
    if threads < 2 || !big || !CURRENT.with(|c| c.get().is_null()) {
        return f();
    }
    let team = Team::new(threads);
    rayon::scope(|s| {
        for _ in 1..threads {
            s.spawn(|_| team.help());
        }
        let prev = CURRENT.with(|c| c.replace(&team as *const Team));
        let _lead = Lead(&team, prev);
        f()
    })
}

/// Lead: send the current team's helpers away; the lead runs the rest of the team's scope
/// alone (same chunks, same results).
pub(crate) fn dismiss() {
    let t = CURRENT.with(|c| c.get());
    if !t.is_null() {
        // SAFETY: as in `for_chunks`
        unsafe { &*t }.quit.store(true, Release);
    }
}

/// Whether this thread leads a team whose helpers are still with it.
pub(crate) fn active() -> bool {
    let t = CURRENT.with(|c| c.get());
    // SAFETY: as in `for_chunks`
    !t.is_null() && !unsafe { &*t }.quit.load(Relaxed)
}

/// `f(c)` for every chunk `c` in `0..nc`: on the current team if there is one, else in
/// order on this thread.
pub(crate) fn for_chunks(nc: usize, f: &(dyn Fn(usize) + Sync)) {
    for_stages(&[(nc, f)])
}

/// Every stage's chunks, as one phase: on the current team if there is one (see
/// [`Team::run`]: a chunk that reads another stage's output must wait for it), else
/// stage after stage in order on this thread.
pub(crate) fn for_stages(stages: &[Stage<'_>]) {
    let t = CURRENT.with(|c| c.get());
    if t.is_null() {
        for &(n, f) in stages {
            (0..n).for_each(f);
        }
    } else {
        // SAFETY: set by `with_team` on this thread for the duration of the team's scope.
        unsafe { &*t }.run(stages);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    /// Two stages on a team of two, stage 1's chunk c waiting for stage 0's chunk c; chunk
    /// `bad` of stage 0 panics. Returns whether the run panicked, or None if it hung (the
    /// old team waited for ever for the chunk that would never be done).
    fn panicking_chunk(bad: usize) -> Option<bool> {
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
            let r = pool.install(|| {
                catch_unwind(|| {
                    with_team(true, || {
                        let done: Vec<AtomicU64> = (0..64).map(|_| AtomicU64::new(0)).collect();
                        let s0 = |c: usize| {
                            assert!(c != bad, "chunk {c} fails");
                            done[c].store(1, Release);
                        };
                        let s1 = |c: usize| wait_for(&done[c], 1);
                        for_stages(&[(64, &s0), (64, &s1)]);
                    })
                })
            });
            let _ = tx.send(r.is_err());
        });
        rx.recv_timeout(Duration::from_secs(60)).ok()
    }

    /// A chunk that panics makes the run panic (on the lead, when every claimed chunk has
    /// returned) instead of leaving the other thread waiting for its output for ever —
    /// whether the lead (first chunk) or, most likely, the helper (last chunk) ran it.
    #[test]
    fn a_panicking_chunk_panics_the_run_instead_of_hanging() {
        assert_eq!(panicking_chunk(0), Some(true), "first chunk");
        assert_eq!(panicking_chunk(63), Some(true), "last chunk");
    }
}

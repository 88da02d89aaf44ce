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
//! Each phase publishes a job `f(c)` for chunks `c` in `0..nc`. The lead claims chunks from
//! the front, helpers from the back (one atomic word holds the phase epoch and both
//! ends), so each thread keeps about the same contiguous block of grains and pairs from
//! phase to phase and step to step (its cache), while an idle or slow helper costs
//! nothing: the lead takes whatever is left. The lead never waits for a helper to
//! *start*, only for chunks a helper has already claimed to finish, so a helper that is
//! never scheduled (busy pool, loaded machine) cannot stall the run. Every chunk writes
//! its own output slot and the lead reduces them in chunk order: results do not depend on
//! which thread ran which chunk, nor on the number of threads.
//!
//! A team only pays when its threads run at the same time: when there are more runnable
//! threads than cores (other processes), a helper descheduled while it holds a chunk
//! makes the lead wait a time slice at the phase's end, and the step runs slower than on
//! the lead alone. So [`World::run`](crate::dem::World::run) times a few steps alone and a
//! few with the team, and keeps the faster (see `World::run_with`).

use std::cell::{Cell, UnsafeCell};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering::*};

/// Below this many grains a world steps on its calling thread even in a multi-thread
/// pool (and leaves the other threads to other scenes). Measured crossover on the project's
/// 2-core machine, `bench dem-crossover` (README "DEM speed, session 5").
pub const TEAM_MIN_GRAINS: usize = 1000;

const BITS: u32 = 20;
const MASK: u64 = (1 << BITS) - 1;
/// Most chunks a phase can have (larger phases run on the lead alone).
const MAX_CHUNKS: usize = MASK as usize;

type Job = *const (dyn Fn(usize) + Sync);

/// Shared state of one team (see the module doc).
pub(crate) struct Team {
    /// epoch (24 bits) | front (20) | back (20): chunks `front..back` are unclaimed.
    state: AtomicU64,
    /// Chunks finished by helpers in the current phase.
    done: AtomicUsize,
    /// Set when the lead's run is over: helpers return.
    quit: AtomicBool,
    /// The current phase's job; read only by a thread that has claimed one of its chunks
    /// (the lead does not replace it before every claimed chunk is finished).
    job: UnsafeCell<Option<Job>>,
    /// Divisor of the chunks left that one claim takes ([`Team::grab`]).
    share: usize,
}

// SAFETY: `job` is written by the lead only while no chunk of the previous phase is
// claimed-but-unfinished and before the phase is published (release store of `state`);
// helpers read it only after claiming a chunk (acquire CAS on `state`).
unsafe impl Sync for Team {}

#[inline(always)]
fn unpack(s: u64) -> (u64, usize, usize) { (s >> (2 * BITS), ((s >> BITS) & MASK) as usize, (s & MASK) as usize) }

impl Team {
    fn new(threads: usize) -> Self { Team { state: AtomicU64::new(0), done: AtomicUsize::new(0), quit: AtomicBool::new(false), job: UnsafeCell::new(None), share: 2 * threads.max(1) } }

    /// How many of `left` unclaimed chunks one claim takes: a share of what is left
    /// (guided scheduling), at least one. Every claim is a compare-exchange on the line
    /// both threads spin on, a cross-core transfer; claiming a few chunks at once halves
    /// them, and the last claims of a phase are still single chunks (the balance at its
    /// end is the same).
    #[inline(always)]
    fn grab(&self, left: usize) -> usize { (left / self.share).max(1) }

    /// Lead: run `f(c)` for every `c` in `0..nc` on the team; returns when all are done.
    fn run(&self, nc: usize, f: &(dyn Fn(usize) + Sync)) {
        if nc > MAX_CHUNKS || nc < 2 || self.quit.load(Relaxed) {
            (0..nc).for_each(f);
            return;
        }
        let (epoch, _, _) = unpack(self.state.load(Relaxed));
        // SAFETY: the previous phase is finished (every claimed chunk done), and no new
        // claim can succeed before the store below publishes this phase. The lifetime is
        // erased: `f` outlives every use, which ends before this function returns.
        unsafe { *self.job.get() = Some(std::mem::transmute::<&(dyn Fn(usize) + Sync), Job>(f)) };
        self.done.store(0, Relaxed);
        let e = (epoch + 1) & ((1 << 24) - 1);
        self.state.store((e << (2 * BITS)) | (nc as u64), Release);
        let mut mine = 0;
        loop {
            let s = self.state.load(Relaxed);
            let (_, front, back) = unpack(s);
            if front >= back { break; }
            let k = self.grab(back - front);
            if self.state.compare_exchange_weak(s, s + ((k as u64) << BITS), Acquire, Relaxed).is_ok() {
                (front..front + k).for_each(f);
                mine += k;
            }
        }
        // wait for the chunks helpers claimed
        let mut spins = 0u32;
        while self.done.load(Acquire) + mine < nc {
            backoff(&mut spins);
        }
    }

    /// Helper: claim chunks from the back until the lead's run is over.
    fn help(&self) {
        let mut spins = 0u32;
        loop {
            let s = self.state.load(Acquire);
            let (_, front, back) = unpack(s);
            if front < back {
                let k = self.grab(back - front);
                if self.state.compare_exchange_weak(s, s - k as u64, AcqRel, Relaxed).is_ok() {
                    // SAFETY: chunks of the current phase are claimed, so the job is set and
                    // outlives this call (the lead waits for `done`).
                    let f = unsafe { &*(*self.job.get()).unwrap_unchecked() };
                    // from the back down, as one chunk per claim did
                    (back - k..back).rev().for_each(f);
                    self.done.fetch_add(k, Release);
                }
                spins = 0;
                continue;
            }
            if self.quit.load(Acquire) { return; }
            backoff(&mut spins);
        }
    }
}

/// Spin (the next phase is µs away: a yield would hand the core to another process for a
/// whole time slice), and yield only after a long wait (~10 ms).
#[inline(always)]
fn backoff(spins: &mut u32) {
    if *spins < 1 << 22 {
        *spins += 1;
        std::hint::spin_loop();
    } else {
        std::thread::yield_now();
    }
}

thread_local! {
    static CURRENT: Cell<*const Team> = const { Cell::new(std::ptr::null()) };
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
    let t = CURRENT.with(|c| c.get());
    if t.is_null() {
        (0..nc).for_each(f);
    } else {
        // SAFETY: set by `with_team` on this thread for the duration of the team's scope.
        unsafe { &*t }.run(nc, f);
    }
}

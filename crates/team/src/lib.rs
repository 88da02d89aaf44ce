//! A team of threads that shares out a run's parallel phases, each a few fixed chunks,
//! without waking a pool per phase: the protocol behind granrepro's DEM step, in a crate
//! of its own so that loom can check it alone (`--cfg loom` rebuilds every dependency).
//!
//! The lead ([`Team::lead`]) runs the caller's code; each helper ([`Team::help`], on a
//! thread of its own) spins between phases. Each phase publishes a job `f(c)` for chunks
//! `c` in `0..n` — or several, as stages run one after the other without a barrier between
//! them ([`for_stages`]). The lead claims chunks from the front, helpers from the back (one
//! atomic word per stage holds the phase epoch and both ends), so each thread keeps about
//! the same contiguous block of chunks from phase to phase (its cache), while an idle or
//! slow helper costs nothing: the lead takes whatever is left.
//!
//! Contract:
//! - every chunk of a phase runs exactly once, on some member of the team; [`for_stages`]
//!   returns when all have run, and every chunk's writes happen before its return (so the
//!   lead may read every chunk's output slot and reduce them in chunk order: results do not
//!   depend on which thread ran which chunk, nor on the number of threads);
//! - the lead never waits for a helper to *start*, only for chunks a helper has already
//!   claimed to finish, so a helper that is never scheduled cannot stall the run;
//! - a claim on a stage of an earlier phase fails (the epoch in the stage's word);
//! - a chunk may wait for another chunk's output ([`wait_for`]) — of an earlier stage of
//!   the phase, or of an earlier chunk of its own stage: chunks are claimed in order;
//! - a chunk that panics does not hang the team: waits return, the phase runs out and the
//!   lead raises the first panic again when every claimed chunk has returned; the team is
//!   then whole again for the next phase (if the lead's code catches the panic).
//!
//! Without a team (or after [`dismiss`]) the same calls run every chunk in order on the
//! calling thread: same chunks, same results. `tests/loom.rs` model-checks the protocol
//! with 2 and 3 threads (`RUSTFLAGS="--cfg loom" cargo test -p granrepro-team --release
//! --test loom`); every access to shared state goes through [`sync`](self) (a private
//! facade: the standard library, or loom's types under `--cfg loom`).
#![warn(missing_docs)]

mod sync;

use std::any::Any;
use std::cell::Cell;
use std::panic::{AssertUnwindSafe, catch_unwind, resume_unwind};
use sync::Ordering::*;
use sync::{AtomicBool, AtomicU64, AtomicUsize, Mutex, UnsafeCell};

const BITS: u32 = 20;
const MASK: u64 = (1 << BITS) - 1;
const EPOCH: u64 = (1 << 24) - 1;
/// Most chunks a stage can have (larger phases run on the lead alone).
const MAX_CHUNKS: usize = MASK as usize;
/// Most stages one phase can have on a team (a phase with more runs on the lead alone).
pub const MAX_STAGES: usize = 4;

type Job = *const (dyn Fn(usize) + Sync);

/// One stage of a phase: `f(c)` for chunks `c` in `0..n`, as `(n, f)`.
pub type Stage<'a> = (usize, &'a (dyn Fn(usize) + Sync));

/// Shared state of one team (see the crate doc): made by the lead's thread, led once
/// ([`Team::lead`]) and helped by any number of other threads ([`Team::help`]) until the
/// lead is done.
pub struct Team {
    /// The current phase: epoch (24 bits) | number of stages << 24.
    phase: AtomicU64,
    /// Per stage: epoch (24 bits) | front (20) | back (20): chunks `front..back` are
    /// unclaimed. The epoch makes a claim on a stage of an earlier phase fail.
    stages: [AtomicU64; MAX_STAGES],
    /// Chunks finished by helpers in the current phase.
    done: AtomicUsize,
    /// Set when the lead's run is over: helpers return.
    quit: AtomicBool,
    /// Set by [`Team::lead`]: a team has one lead, once.
    led: AtomicBool,
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
// helpers read a job only after claiming one of its chunks (acquire CAS on its stage), and
// the lead returns from the phase (ending the jobs' borrows) only after every claimed
// chunk is done. There is one lead (`led`), and a phase started inside one of its chunks
// runs on the lead alone (`for_stages` hides the team from its chunks). The raw job
// pointers are nothing thread-bound: the team may move to another thread when idle.
unsafe impl Sync for Team {}
// SAFETY: as above.
unsafe impl Send for Team {}

#[inline(always)]
fn unpack(s: u64) -> (u64, usize, usize) {
    (s >> (2 * BITS), ((s >> BITS) & MASK) as usize, (s & MASK) as usize)
}

impl Team {
    /// A team for `threads` threads (the lead and its helpers; it sets how many chunks one
    /// claim takes, not how many threads may help).
    pub fn new(threads: usize) -> Self {
        Team {
            phase: AtomicU64::new(0),
            stages: std::array::from_fn(|_| AtomicU64::new(0)),
            done: AtomicUsize::new(0),
            quit: AtomicBool::new(false),
            led: AtomicBool::new(false),
            jobs: UnsafeCell::new([None; MAX_STAGES]),
            share: 2 * threads.max(1),
            failed: AtomicBool::new(false),
            failure: Mutex::new(None),
        }
    }

    /// Lead the team: `f` runs on this thread, and the phases it starts with
    /// [`for_chunks`] / [`for_stages`] are shared with the team's helpers. When `f` returns
    /// (or unwinds) the helpers are sent away.
    ///
    /// # Panics
    /// If the team was led before (a team has one lead, once), or is helped from this
    /// thread; and with the first panic of a chunk of a phase `f` starts.
    pub fn lead<R>(&self, f: impl FnOnce() -> R) -> R {
        assert!(!self.led.swap(true, Relaxed), "a team is led once");
        assert!(!in_team(), "a team's member cannot lead another team");
        let _lead = Lead::enter(self);
        f()
    }

    /// Help the team: claim chunks from the back of each stage in turn, phase after phase,
    /// until the lead is done (returns at once if it is). Run it on a thread of its own.
    pub fn help(&self) {
        let _member = Member::enter(self);
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
                            // (acquired with the claim) and outlives this call (the lead
                            // waits for `done`); the lead writes `jobs` only between phases.
                            let f = unsafe { &*self.jobs.with(|j| (*j)[k].unwrap_unchecked()) };
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
    /// inside. When the team has quit (or the phase does not fit a stage word) the stages
    /// run in order on the lead, where every such wait is already satisfied.
    fn run(&self, stages: &[Stage<'_>]) {
        let total: usize = stages.iter().map(|s| s.0).sum();
        if stages.len() > MAX_STAGES || stages.iter().any(|s| s.0 > MAX_CHUNKS) || total < 2 || self.quit.load(Relaxed)
        {
            serial(stages);
            return;
        }
        let e = ((self.phase.load(Relaxed) & EPOCH) + 1) & EPOCH;
        // SAFETY: the previous phase is finished (every claimed chunk done), and no new
        // claim can succeed before the stores below publish this phase. The lifetimes are
        // erased: every `f` outlives every use, which ends before this function returns.
        self.jobs.with_mut(|jobs| unsafe {
            for (k, &(_, f)) in stages.iter().enumerate() {
                (*jobs)[k] = Some(std::mem::transmute::<&(dyn Fn(usize) + Sync), Job>(f));
            }
        });
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
            // every chunk has returned: the next phase (if the caller catches this panic
            // and goes on) waits for its chunks again
            self.failed.store(false, Relaxed);
            let p = self.failure.lock().unwrap_or_else(|e| e.into_inner()).take();
            resume_unwind(p.unwrap_or_else(|| Box::new("a chunk of a team phase panicked")));
        }
    }
}

/// Every stage's chunks in order on this thread.
fn serial(stages: &[Stage<'_>]) {
    for &(n, f) in stages {
        (0..n).for_each(f);
    }
}

/// Spin (the next phase is µs away: a yield would hand the core to another process for a
/// whole time slice), and yield only after a long wait (~10 ms). Under loom every spin
/// yields to its scheduler, so a wait is explored as finitely many steps.
#[inline(always)]
fn backoff(spins: &mut u32) {
    if *spins < 1 << 22 {
        *spins += 1;
        sync::spin_loop(*spins);
    } else {
        sync::yield_now();
    }
}

sync::thread_local_const! {
    /// The team whose phases this thread starts: set by `Team::lead`, and hidden while
    /// one of its phases runs (a phase started inside a chunk runs on the thread alone).
    static CURRENT: Cell<*const Team> = Cell::new(std::ptr::null());
}
sync::thread_local_const! {
    /// The team this thread is a member of, as lead or helper (whose failure `wait_for`
    /// watches).
    static MEMBER: Cell<*const Team> = Cell::new(std::ptr::null());
}

/// Whether this thread is a member of a team (its lead or a helper): a team is not started
/// inside another.
#[inline]
pub fn in_team() -> bool {
    !MEMBER.with(|m| m.get()).is_null()
}

/// Makes this thread a helper of a team (`MEMBER`) until dropped.
struct Member(*const Team);
impl Member {
    fn enter(t: &Team) -> Self {
        Member(MEMBER.with(|m| m.replace(t)))
    }
}
impl Drop for Member {
    fn drop(&mut self) {
        MEMBER.with(|m| m.set(self.0));
    }
}

/// Makes this thread a team's lead (`CURRENT` and `MEMBER`) until dropped; then sends the
/// helpers away.
struct Lead<'a> {
    team: &'a Team,
    prev: *const Team,
    _member: Member,
}
impl<'a> Lead<'a> {
    fn enter(team: &'a Team) -> Self {
        let _member = Member::enter(team);
        let prev = CURRENT.with(|c| c.replace(team));
        Lead { team, prev, _member }
    }
}
impl Drop for Lead<'_> {
    fn drop(&mut self) {
        CURRENT.with(|c| c.set(self.prev));
        self.team.quit.store(true, Release);
    }
}

/// Spins between two looks at the team's failure flag in [`wait_for`] (a line other
/// threads write: not on every spin). Under loom every spin looks: each spin is a step
/// that loom explores, and 63 idle ones would multiply its executions for nothing.
const FAILED_EVERY: u32 = if cfg!(loom) { 1 } else { 64 };

/// Wait until `flag` holds the stamp `id` (a chunk's output is visible: acquire) — or
/// until a chunk of this thread's team has panicked: the phase is then abandoned, and
/// its lead raises the panic when every claimed chunk has returned.
///
/// `flag` is the standard library's `AtomicU64` (loom's under `--cfg loom`).
#[inline]
pub fn wait_for(flag: &AtomicU64, id: u64) {
    let mut spins = 0u32;
    while flag.load(Acquire) != id {
        if spins.is_multiple_of(FAILED_EVERY) {
            let t = MEMBER.with(|m| m.get());
            // SAFETY: `MEMBER` is set only while its team is borrowed by `Team::help` or
            // `Team::lead` on this thread (cleared by their guards), so it is alive.
            if !t.is_null() && unsafe { &*t }.failed.load(Acquire) {
                return;
            }
        }
        backoff(&mut spins);
    }
}

/// Lead: send the current team's helpers away; the lead runs the rest of [`Team::lead`]'s
/// `f` alone (same chunks, same results).
pub fn dismiss() {
    let t = CURRENT.with(|c| c.get());
    if !t.is_null() {
        // SAFETY: `CURRENT` is set only while `Team::lead` borrows its team on this thread
        // (restored by its guard), so it is alive.
        unsafe { &*t }.quit.store(true, Release);
    }
}

/// Whether this thread leads a team whose helpers are still with it (false inside a
/// chunk: a phase started there runs on the thread alone).
pub fn active() -> bool {
    let t = CURRENT.with(|c| c.get());
    // SAFETY: as in `dismiss`
    !t.is_null() && !unsafe { &*t }.quit.load(Relaxed)
}

/// `f(c)` for every chunk `c` in `0..nc`: on the team this thread leads if there is one,
/// else in order on this thread.
#[inline]
pub fn for_chunks(nc: usize, f: &(dyn Fn(usize) + Sync)) {
    for_stages(&[(nc, f)])
}

/// Every stage's chunks, as one phase: on the team this thread leads if there is one (a
/// chunk that reads another stage's output must [`wait_for`] it: no barrier between
/// stages), else stage after stage in order on this thread.
///
/// # Panics
/// With the first panic of a chunk, once every chunk claimed by a helper has returned.
#[inline]
pub fn for_stages(stages: &[Stage<'_>]) {
    let t = CURRENT.with(|c| c.replace(std::ptr::null()));
    if t.is_null() {
        serial(stages);
    } else {
        // The team is hidden from the phase's chunks (a phase started inside one runs on
        // this thread alone) and shown again after it, also when a chunk's panic unwinds.
        struct Restore(*const Team);
        impl Drop for Restore {
            fn drop(&mut self) {
                CURRENT.with(|c| c.set(self.0));
            }
        }
        let _restore = Restore(t);
        // SAFETY: as in `dismiss`
        unsafe { &*t }.run(stages);
    }
}

#[cfg(all(test, not(loom)))]
mod tests {
    use super::*;

    /// A team of `threads` on scoped threads, the lead running `f`.
    fn on_team<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
        let team = Team::new(threads);
        std::thread::scope(|s| {
            for _ in 1..threads {
                s.spawn(|| team.help());
            }
            team.lead(f)
        })
    }

    /// Every chunk of every phase runs once, whatever the thread count, including phases
    /// of two stages where a chunk waits for the previous stage's.
    #[test]
    fn every_chunk_runs_once_per_phase() {
        for threads in [1, 2, 3] {
            let runs: Vec<AtomicUsize> = (0..2 * 300).map(|_| AtomicUsize::new(0)).collect();
            let flags: Vec<AtomicU64> = (0..300).map(|_| AtomicU64::new(0)).collect();
            on_team(threads, || {
                for phase in 1..=50u64 {
                    let s0 = |c: usize| {
                        runs[c].fetch_add(1, Relaxed);
                        flags[c].store(phase, Release);
                    };
                    let s1 = |c: usize| {
                        wait_for(&flags[c], phase);
                        runs[300 + c].fetch_add(1, Relaxed);
                    };
                    for_stages(&[(300, &s0), (300, &s1)]);
                }
            });
            assert!(runs.iter().all(|r| r.load(Relaxed) == 50), "{threads} threads");
        }
    }

    /// A phase started inside a chunk runs on that thread alone (it would otherwise replace
    /// the jobs of the phase in progress), and the team is back after it.
    #[test]
    fn a_phase_inside_a_chunk_runs_on_its_thread() {
        let sum = AtomicUsize::new(0);
        on_team(2, || {
            for_chunks(8, &|_| {
                assert!(!active());
                for_chunks(4, &|c| {
                    sum.fetch_add(c, Relaxed);
                });
            });
            assert!(active());
        });
        assert_eq!(sum.load(Relaxed), 8 * 6);
    }

    #[test]
    #[should_panic(expected = "led once")]
    fn a_team_is_led_once() {
        let team = Team::new(1);
        team.lead(|| ());
        team.lead(|| ());
    }
}

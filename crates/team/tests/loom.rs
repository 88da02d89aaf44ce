//! Contract: loom explores the interleavings (up to a preemption bound) of the team's
//! production protocol — the crate's own `Team`, `for_stages`, `wait_for`, built against
//! loom's atomics, cells and thread-locals — with a lead and one or two helpers, and finds
//! in none of them a chunk that runs twice or not at all, a chunk output (or the team's
//! job table) read without being ordered after its write, a lost panic, or a hang. Cases:
//! (a) one phase runs to completion and the lead reduces the outputs in chunk order;
//! (b) a stage's chunk waits for another stage's chunk's output (`wait_for`);
//! (c) a chunk panics: the lead raises that panic, nothing waits for ever, no chunk reruns,
//!     and the next phase's chunks wait for their outputs again;
//! (d) two phases in a row: a helper's claim on the earlier phase fails once the next one
//!     is published.
//!
//! Run with `RUSTFLAGS="--cfg loom" cargo test -p granrepro-team --release --test loom`
//! (`.ci/run` does, in a target directory of its own). Without `--cfg loom` this file is
//! empty.
#![cfg(loom)]

use granrepro_team::{Team, for_chunks, for_stages, wait_for};
use loom::cell::UnsafeCell;
use loom::model::Builder;
use loom::sync::Arc;
use loom::sync::atomic::AtomicU64;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::atomic::Ordering::Release;

/// Preemptions per execution loom explores: bugs found in practice need two or three
/// (loom's docs). Three with one helper, two with two (whose interleavings are many more),
/// two for the panicking two-stage phase: each test then takes seconds to a couple of
/// minutes. `LOOM_MAX_PREEMPTIONS` overrides.
fn preemptions(default: usize) -> usize {
    std::env::var("LOOM_MAX_PREEMPTIONS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// The default bound for `threads` (see [`preemptions`]).
fn bound(threads: usize) -> usize {
    if threads <= 2 { 3 } else { 2 }
}

/// One output slot per chunk, each written by the chunk that owns it only: loom checks
/// every access against its happens-before order, so a read of a slot not ordered after
/// its write is reported as a data race (and the test fails).
struct Slots(Vec<UnsafeCell<u64>>);

// SAFETY: a slot is written by one chunk and read by other threads only after that
// chunk's completion is acquired — the property under test; loom reports any access that
// is not ordered so.
unsafe impl Sync for Slots {}

impl Slots {
    fn new(n: usize) -> Self {
        Slots((0..n).map(|_| UnsafeCell::new(0)).collect())
    }
    /// Adds `v` (a chunk that ran twice leaves 2v).
    fn add(&self, c: usize, v: u64) {
        // SAFETY: loom checks that no other access to this slot races with this one
        self.0[c].with_mut(|p| unsafe { *p += v });
    }
    fn get(&self, c: usize) -> u64 {
        // SAFETY: as in `add`
        self.0[c].with(|p| unsafe { *p })
    }
    fn all(&self) -> Vec<u64> {
        (0..self.0.len()).map(|c| self.get(c)).collect()
    }
}

/// Explores `lead`, up to `bound` preemptions, as the lead of a team of `threads` (the lead and `threads - 1` helpers
/// on loom threads, joined at the end: a helper that never returns is a hang, reported by
/// loom).
fn explore(threads: usize, bound: usize, lead: impl Fn() + Send + Sync + 'static) {
    let mut b = Builder::new();
    b.preemption_bound = Some(preemptions(bound));
    let lead = std::sync::Arc::new(lead);
    b.check(move || {
        let team = Arc::new(Team::new(threads));
        let helpers: Vec<_> = (1..threads)
            .map(|_| {
                let t = team.clone();
                loom::thread::spawn(move || t.help())
            })
            .collect();
        team.lead(|| lead());
        for h in helpers {
            h.join().unwrap();
        }
    });
}

/// (a) `n` chunks, chunk c adds c + 1 to its slot; the lead reduces in chunk order.
fn completion(threads: usize, n: usize) {
    explore(threads, bound(threads), move || {
        let out = Slots::new(n);
        for_chunks(n, &|c| out.add(c, c as u64 + 1));
        let expect: Vec<u64> = (1..=n as u64).collect();
        assert_eq!(out.all(), expect, "every chunk once, in its own slot");
        let digits = out.all().iter().fold(0, |h, &v| 10 * h + v);
        assert_eq!(
            digits,
            expect.iter().fold(0, |h, &v| 10 * h + v),
            "reduced in chunk order"
        );
    });
}

#[test]
fn a_every_chunk_runs_once_2_threads() {
    completion(2, 3);
}

#[test]
fn a_every_chunk_runs_once_3_threads() {
    completion(3, 3);
}

/// (b) two stages of `n` chunks: stage 1's chunk c reads stage 0's chunk c's output once
/// its flag holds the phase's stamp.
fn waiting(threads: usize, n: usize) {
    explore(threads, bound(threads), move || {
        let (out0, out1) = (Slots::new(n), Slots::new(n));
        let flags: Vec<AtomicU64> = (0..n).map(|_| AtomicU64::new(0)).collect();
        let s0 = |c: usize| {
            out0.add(c, c as u64 + 1);
            flags[c].store(1, Release);
        };
        let s1 = |c: usize| {
            wait_for(&flags[c], 1);
            out1.add(c, 10 * out0.get(c));
        };
        for_stages(&[(n, &s0), (n, &s1)]);
        assert_eq!(out1.all(), (1..=n as u64).map(|v| 10 * v).collect::<Vec<_>>());
    });
}

#[test]
fn b_a_chunk_waits_for_another_stages_output_2_threads() {
    waiting(2, 2);
}

#[test]
fn b_a_chunk_waits_for_another_stages_output_3_threads() {
    waiting(3, 2);
}

/// The payload of the deliberate panics (kept out of the test output).
struct ChunkPanic;

fn quiet_chunk_panics() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !info.payload().is::<ChunkPanic>() {
                default(info);
            }
        }));
    });
}

/// (c) as (b), but stage 0's chunk `bad` panics before it sets its flag: stage 1's chunk
/// `bad` would wait for ever without the team's failure flag.
fn panicking(threads: usize, n: usize, bad: usize) {
    quiet_chunk_panics();
    explore(threads, 2, move || {
        let (out0, out1) = (Slots::new(n), Slots::new(n));
        let flags: Vec<AtomicU64> = (0..n).map(|_| AtomicU64::new(0)).collect();
        let s0 = |c: usize| {
            if c == bad {
                std::panic::panic_any(ChunkPanic);
            }
            out0.add(c, 1);
            flags[c].store(1, Release);
        };
        let s1 = |c: usize| {
            wait_for(&flags[c], 1);
            out1.add(c, 1);
        };
        let r = catch_unwind(AssertUnwindSafe(|| for_stages(&[(n, &s0), (n, &s1)])));
        let p = r.expect_err("the lead raises the chunk's panic");
        assert!(p.is::<ChunkPanic>(), "the chunk's own payload");
        // every chunk ran at most once (stage 1's chunks may run before, or instead of
        // waiting for, the failed one) and the failed chunk wrote nothing
        assert!(out0.all().iter().chain(&out1.all()).all(|&v| v <= 1));
        assert_eq!(out0.get(bad), 0);
        // the panic caught, the team's next phase waits for its outputs again
        let (out0, out1) = (Slots::new(n), Slots::new(n));
        let s0 = |c: usize| {
            out0.add(c, 1);
            flags[c].store(2, Release);
        };
        let s1 = |c: usize| {
            wait_for(&flags[c], 2);
            out1.add(c, out0.get(c));
        };
        let r = catch_unwind(AssertUnwindSafe(|| for_stages(&[(n, &s0), (n, &s1)])));
        assert!(r.is_ok(), "the phase after a caught panic raised a panic of its own");
        assert_eq!(out1.all(), vec![1; n]);
    });
}

#[test]
fn c_a_panicking_chunk_panics_the_lead_2_threads() {
    panicking(2, 2, 0);
    panicking(2, 2, 1);
}

/// (c) with two helpers, in one stage (the two-stage case with two helpers takes loom more
/// than 4 minutes even at one preemption): chunk `bad` of `n` panics.
fn panicking_one_stage(threads: usize, n: usize, bad: usize) {
    quiet_chunk_panics();
    explore(threads, bound(threads), move || {
        let out = Slots::new(n);
        let f = |c: usize| {
            if c == bad {
                std::panic::panic_any(ChunkPanic);
            }
            out.add(c, 1);
        };
        let r = catch_unwind(AssertUnwindSafe(|| for_chunks(n, &f)));
        assert!(r.expect_err("the lead raises the chunk's panic").is::<ChunkPanic>());
        let expect: Vec<u64> = (0..n).map(|c| (c != bad) as u64).collect();
        assert_eq!(out.all(), expect, "every other chunk once, the failed one not");
    });
}

#[test]
fn c_a_panicking_chunk_panics_the_lead_3_threads() {
    panicking_one_stage(3, 3, 2);
}

/// (d) two phases of `n` chunks in a row, with different jobs: a helper still working
/// through the first must not claim (nor run the job of) the second under the first's
/// claim, and every chunk of each runs once.
fn two_phases(threads: usize, n: usize) {
    explore(threads, bound(threads), move || {
        let (first, second) = (Slots::new(n), Slots::new(n));
        for_chunks(n, &|c| first.add(c, 1));
        for_chunks(n, &|c| second.add(c, 2));
        assert_eq!(first.all(), vec![1; n]);
        assert_eq!(second.all(), vec![2; n]);
    });
}

#[test]
fn d_a_stale_claim_on_an_earlier_phase_fails_2_threads() {
    two_phases(2, 2);
}

#[test]
fn d_a_stale_claim_on_an_earlier_phase_fails_3_threads() {
    two_phases(3, 2);
}

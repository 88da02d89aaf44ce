//! In-step parallelism for one DEM world: a team of threads held for a whole
//! [`World::run`](crate::dem::World::run) call, sharing out each parallel phase's fixed
//! chunks without waking a pool per phase. The protocol (claims, waits, panics) is the
//! workspace crate `granrepro-team` (`crates/team`), model-checked with loom there; this
//! module spawns a team on the current rayon pool and re-exports what the step uses.
//!
//! Why not a rayon region per phase: at a few thousand grains a phase lasts 10–100 µs,
//! and a pool worker that went to sleep between two regions takes about as long to wake
//! (futex, and in a VM an inter-processor interrupt) — the 2-thread step was slower than
//! the 1-thread one. Here the run's thread (the *lead*) spawns one helper job per other
//! pool thread once per `run` call; a helper spins between phases (a few µs of serial
//! work: the rolling-dashpot sweep) instead of sleeping.
//!
//! Contract (the crate's): every chunk of a phase runs exactly once and writes its own
//! output slot, and the lead reduces them in chunk order, so results do not depend on
//! which thread ran which chunk, nor on the number of threads; a panicking chunk panics
//! the run instead of hanging it.
//!
//! A team only pays when its threads run at the same time: when there are more runnable
//! threads than cores (other processes), a helper descheduled while it holds a chunk
//! makes the lead wait a time slice at the phase's end, and the step runs slower than on
//! the lead alone. So [`World::run`](crate::dem::World::run) times steps alone (a
//! reference) and the team's steps in blocks, and keeps the team while it is clearly the
//! faster (see [`crate::dem::world::TEAM_PROBE`] and `World::run_with`).

pub(crate) use granrepro_team::{active, dismiss, for_chunks, for_stages, wait_for};

/// Below this many grains a world steps on its calling thread even in a multi-thread
/// pool (and leaves the other threads to other scenes). Measured crossover on the project's
/// 2-core machine, `bench dem-crossover` (docs/performance.md, "Session 5: DEM").
pub const TEAM_MIN_GRAINS: usize = 1000;

/// Run `f` (a world's steps) with a team of the current rayon pool's threads when the pool
/// has more than one and `big` (the world has at least its `team_min_grains`, by default
/// [`TEAM_MIN_GRAINS`]), and this thread is not already in a team; phases inside share
/// their chunks through [`for_chunks`] / [`for_stages`].
pub(crate) fn with_team<R: Send>(big: bool, f: impl FnOnce() -> R + Send) -> R {
    let threads = rayon::current_num_threads();
    if threads < 2 || !big || granrepro_team::in_team() {
        return f();
    }
    let team = granrepro_team::Team::new(threads);
    rayon::scope(|s| {
        for _ in 1..threads {
            s.spawn(|_| team.help());
        }
        team.lead(f)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::panic::catch_unwind;
    use std::sync::atomic::{AtomicU64, Ordering::Release};
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

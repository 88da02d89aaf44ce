//! The sync facade the team's protocol is written against: the standard library's
//! atomics, `UnsafeCell`, `Mutex`, spin hint, yield and thread-locals in a normal build,
//! and loom's model-checked twins under `--cfg loom` (`RUSTFLAGS="--cfg loom"`), so that
//! the loom tests run the production protocol itself, not a copy of it.
//!
//! Contract: in a normal build every item here is the standard library's own (re-exports,
//! or an `#[inline(always)]` wrapper that adds nothing), so the facade costs nothing in
//! the hot loops. Under loom, the spin hint yields to loom's scheduler and a wait's spins
//! past a small budget end loom's branching, so a spin loop is explored as a finite number
//! of steps; `UnsafeCell` accesses are checked against the
//! memory model (a read not ordered after the last write is reported).

#[cfg(not(loom))]
pub(crate) use std::sync::Mutex;
#[cfg(not(loom))]
pub(crate) use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize};

#[cfg(loom)]
pub(crate) use loom::sync::Mutex;
#[cfg(loom)]
pub(crate) use loom::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize};

// loom's atomics take the standard library's orderings.
pub(crate) use std::sync::atomic::Ordering;

/// One spin of a busy wait, the `spins`-th in a row of that wait: the CPU's pause hint;
/// under loom a yield to its scheduler (so the waiting thread lets the others run), and
/// past [`LOOM_SPIN_BUDGET`] spins of one wait the end of loom's branching in this
/// execution.
///
/// Why the budget: loom does not count a switch away from a thread that yielded as a
/// preemption, so two threads that wait at once (two helpers between phases) can hand the
/// processor to each other for ever, and loom explores ever longer such ping-pongs ("Model
/// exceeded maximum number of branches"). A spin that reads what it read before changes
/// nothing, so an execution whose wait spins longer is the same, step for step, as one
/// where it spun less — which loom explores. The execution still runs to its end (a wait
/// that can never end is still reported, as too many branches).
#[inline(always)]
pub(crate) fn spin_loop(spins: u32) {
    #[cfg(not(loom))]
    {
        let _ = spins;
        std::hint::spin_loop();
    }
    #[cfg(loom)]
    {
        if spins > LOOM_SPIN_BUDGET {
            loom::skip_branch();
        }
        loom::hint::spin_loop();
    }
}

/// Spins of one wait that loom explores alternatives around (see [`spin_loop`]).
#[cfg(loom)]
const LOOM_SPIN_BUDGET: u32 = 1;

/// Hand the core to another runnable thread.
#[inline(always)]
pub(crate) fn yield_now() {
    #[cfg(not(loom))]
    std::thread::yield_now();
    #[cfg(loom)]
    loom::thread::yield_now();
}

/// An `UnsafeCell` with loom's access API on both builds: the pointer is handed to a
/// closure, so that loom can check that the access does not race with another (the
/// standard library's `get` gives it no end to check). Handing out the pointer is safe;
/// dereferencing it is the caller's `unsafe`.
pub(crate) struct UnsafeCell<T> {
    #[cfg(not(loom))]
    cell: std::cell::UnsafeCell<T>,
    #[cfg(loom)]
    cell: loom::cell::UnsafeCell<T>,
}

impl<T> UnsafeCell<T> {
    /// A cell holding `v`.
    #[cfg_attr(loom, track_caller)]
    pub(crate) fn new(v: T) -> Self {
        UnsafeCell {
            #[cfg(not(loom))]
            cell: std::cell::UnsafeCell::new(v),
            #[cfg(loom)]
            cell: loom::cell::UnsafeCell::new(v),
        }
    }

    /// `f` with a pointer for reading the value (loom: a read access while `f` runs).
    #[inline(always)]
    #[cfg_attr(loom, track_caller)]
    pub(crate) fn with<R>(&self, f: impl FnOnce(*const T) -> R) -> R {
        #[cfg(not(loom))]
        return f(self.cell.get());
        #[cfg(loom)]
        return self.cell.with(f);
    }

    /// `f` with a pointer for writing the value (loom: a write access while `f` runs).
    #[inline(always)]
    #[cfg_attr(loom, track_caller)]
    pub(crate) fn with_mut<R>(&self, f: impl FnOnce(*mut T) -> R) -> R {
        #[cfg(not(loom))]
        return f(self.cell.get());
        #[cfg(loom)]
        return self.cell.with_mut(f);
    }
}

/// `thread_local!` with a constant initialiser: the standard library's (`const { … }`,
/// no lazy-initialisation check on access), or loom's, which keeps one value per modelled
/// thread and drops them when the modelled thread ends.
#[cfg(not(loom))]
macro_rules! thread_local_const {
    ($(#[$attr:meta])* static $name:ident: $t:ty = $init:expr;) => {
        std::thread_local! { $(#[$attr])* static $name: $t = const { $init }; }
    };
}
#[cfg(loom)]
macro_rules! thread_local_const {
    ($(#[$attr:meta])* static $name:ident: $t:ty = $init:expr;) => {
        loom::thread_local! { $(#[$attr])* static $name: $t = $init; }
    };
}
pub(crate) use thread_local_const;

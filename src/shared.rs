//! Shared views of arrays for the hand-written parallel kernels (the DEM passes and
//! integrator, the MPM scatter): [`SharedMut`] to write, [`SharedRef`] to read.
//!
//! A kernel phase runs chunk jobs on several threads at once, and the jobs of one phase
//! touch the same arrays: each chunk writes its own elements, and reads elements that other
//! chunks wrote earlier in the phase, once the phase's protocol says they are done (the
//! DEM's done flags, the MPM's band arrivals). Borrows cannot express "disjoint elements,
//! chosen at run time" nor "written before, by another thread", so the jobs hold raw views
//! instead, and the rules are this module's contract:
//!
//! - **What a view is.** A pointer and a length, copied freely; it does not own the
//!   memory and does not keep it alive. It is made from a live allocation (a `Vec`, its
//!   spare capacity, or a slice) just before the phase that uses it, and it is used only
//!   while that allocation is neither moved, reallocated nor dropped (for a DEM job: one
//!   phase; for the MPM scatter: one `p2g`).
//! - **Writing ([`SharedMut`]).** Between two synchronisation points (the start of a
//!   phase, a release/acquire hand-over, the end of a phase), an element that a thread
//!   reads or writes through a `SharedMut` is touched by no other thread: access to an
//!   element passes from thread to thread, it is never shared. Every accessor is
//!   `unsafe`, and that is its `# Safety` condition, together with `i < len`.
//! - **Reading ([`SharedRef`]).** Nothing writes the elements a view reads while they are
//!   read, unless the write happens-before the read (same thread earlier, or a release
//!   store the reader acquired). Many threads may read the same element at once. Its
//!   indexing is safe to call, so making the view is what is `unsafe`: whoever makes one
//!   promises that every index the kernels use with it is in bounds (the neighbour list's
//!   and gather tables' indices, each < the number of grains or pairs they were built for).
//! - **Threads.** `SharedMut<T>` is `Send + Sync` for `T: Send`, as `&mut [T]` split
//!   between threads (rayon's `par_chunks_mut`) moves elements' access, never shares it;
//!   `SharedRef<T>` for `T: Sync`, as `&[T]`. A view of a `T` that must stay on its thread
//!   (`Rc`, a raw pointer) cannot be sent to another.
//! - **Bounds.** The views carry their length. Without the `checked` cargo feature the
//!   accessors do not check it (the generated code is that of raw pointer arithmetic);
//!   with `checked` (`cargo test --features checked`, which CI runs), or with debug
//!   assertions on, every accessor `assert!`s `i < len` (or `lo + len <= len` for a
//!   range), and so do the kernels' other preconditions ([`checked_assert!`]).
//!
//! Known limits: the views do not check the protocol itself (which thread touches which
//! element when); the thread team's ordering is checked by its own tests.

/// `assert!` when the `checked` feature (or debug assertions) is on; otherwise nothing,
/// not even the evaluation of the condition. For the bounds and preconditions of the hot
/// loops' unchecked accesses (see [`crate::shared`]).
macro_rules! checked_assert {
    ($($arg:tt)*) => {
        if cfg!(any(feature = "checked", debug_assertions)) {
            assert!($($arg)*);
        }
    };
}
pub(crate) use checked_assert;

/// A view through which chunk jobs on several threads write (and read back) disjoint
/// elements of one array (module doc: the contract).
pub(crate) struct SharedMut<T> {
    p: *mut T,
    n: usize,
}

impl<T> Clone for SharedMut<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for SharedMut<T> {}

// SAFETY: the view gives access to an element to one thread at a time (module doc,
// "Writing"), so sending it, or sharing it, moves `T`s between threads and never shares
// one: `T: Send` is what that needs, as for `&mut [T]` split between threads.
unsafe impl<T: Send> Send for SharedMut<T> {}
// SAFETY: as for `Send`: through `&SharedMut<T>` a thread gets the same element access as
// through a copy of it.
unsafe impl<T: Send> Sync for SharedMut<T> {}

impl<T> SharedMut<T> {
    /// A view of all of `v` (from `Vec::as_mut_ptr`, which makes no reference to the
    /// elements, so several views of one array coexist).
    pub(crate) fn of(v: &mut Vec<T>) -> Self {
        SharedMut {
            p: v.as_mut_ptr(),
            n: v.len(),
        }
    }

    /// A view of all of `v`.
    pub(crate) fn new(v: &mut [T]) -> Self {
        SharedMut {
            p: v.as_mut_ptr(),
            n: v.len(),
        }
    }

    /// A view of `v`'s spare capacity (`v.len()..v.capacity()`): slots to [`SharedMut::write`]
    /// before `v.set_len` takes them in.
    pub(crate) fn spare(v: &mut Vec<T>) -> Self {
        let s = v.spare_capacity_mut();
        SharedMut {
            p: s.as_mut_ptr().cast(),
            n: s.len(),
        }
    }

    /// Write element `i` without reading or dropping what was there (an uninitialised
    /// slot of [`SharedMut::spare`]).
    ///
    /// # Safety
    /// `i < len`; no other thread touches element `i` meanwhile (module doc).
    #[inline(always)]
    pub(crate) unsafe fn write(self, i: usize, v: T) {
        checked_assert!(
            i < self.n,
            "SharedMut::write: index {i} out of range for length {}",
            self.n
        );
        // SAFETY: caller's contract: in bounds of the live allocation, not raced
        unsafe { self.p.add(i).write(v) }
    }

    /// `len` elements from `lo`, to read.
    ///
    /// # Safety
    /// `lo + len <= self.len()`; no other thread writes them while the slice is used.
    #[inline(always)]
    pub(crate) unsafe fn slice<'a>(self, lo: usize, len: usize) -> &'a [T] {
        checked_assert!(
            lo <= self.n && len <= self.n - lo,
            "SharedMut::slice: {lo}..+{len} out of range for length {}",
            self.n
        );
        // SAFETY: caller's contract: in bounds, initialised, not written meanwhile
        unsafe { std::slice::from_raw_parts(self.p.add(lo), len) }
    }

    /// `len` elements from `lo`, to write.
    ///
    /// # Safety
    /// `lo + len <= self.len()`; no other thread touches them while the slice is used.
    #[inline(always)]
    pub(crate) unsafe fn slice_mut<'a>(self, lo: usize, len: usize) -> &'a mut [T] {
        checked_assert!(
            lo <= self.n && len <= self.n - lo,
            "SharedMut::slice_mut: {lo}..+{len} out of range for length {}",
            self.n
        );
        // SAFETY: caller's contract: in bounds, initialised, touched by this thread only
        unsafe { std::slice::from_raw_parts_mut(self.p.add(lo), len) }
    }
}

impl<T: Copy> SharedMut<T> {
    /// Element `i`.
    ///
    /// # Safety
    /// `i < len`, element `i` initialised; no other thread writes it meanwhile.
    #[inline(always)]
    pub(crate) unsafe fn get(self, i: usize) -> T {
        checked_assert!(
            i < self.n,
            "SharedMut::get: index {i} out of range for length {}",
            self.n
        );
        // SAFETY: caller's contract
        unsafe { *self.p.add(i) }
    }

    /// Set element `i` (initialised: a `Copy` value has nothing to drop).
    ///
    /// # Safety
    /// `i < len`; no other thread touches element `i` meanwhile.
    #[inline(always)]
    pub(crate) unsafe fn set(self, i: usize, v: T) {
        checked_assert!(
            i < self.n,
            "SharedMut::set: index {i} out of range for length {}",
            self.n
        );
        // SAFETY: caller's contract
        unsafe { *self.p.add(i) = v }
    }
}

/// A read-only view of an array that chunk jobs on several threads read at once, indexed
/// without bounds checks unless `checked` is on (module doc: the contract).
pub(crate) struct SharedRef<T> {
    p: *const T,
    n: usize,
}

impl<T> Clone for SharedRef<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for SharedRef<T> {}

// SAFETY: the view only reads, from any number of threads at once (module doc,
// "Reading"): `T: Sync`, as for `&[T]`.
unsafe impl<T: Sync> Send for SharedRef<T> {}
// SAFETY: as for `Send`.
unsafe impl<T: Sync> Sync for SharedRef<T> {}

impl<T> SharedRef<T> {
    /// A view of an array that nothing writes while the view is used.
    ///
    /// # Safety
    /// Every index the view is read at ([`std::ops::Index`], [`SharedRef::slice`]) is
    /// `< v.len()`, and the view is used only while `v` is alive and not reallocated.
    pub(crate) unsafe fn new(v: &[T]) -> Self {
        SharedRef {
            p: v.as_ptr(),
            n: v.len(),
        }
    }

    /// A view of an array that a job of the same phase writes (other elements, or the
    /// same ones before or after, in an order the phase enforces); from `Vec::as_mut_ptr`,
    /// so the writers' views of `v` stay valid beside it.
    ///
    /// # Safety
    /// As [`SharedRef::new`], and every write to an element read happens-before the read
    /// or after it (module doc).
    pub(crate) unsafe fn of(v: &mut Vec<T>) -> Self {
        SharedRef {
            p: v.as_mut_ptr(),
            n: v.len(),
        }
    }

    /// Number of elements.
    pub(crate) fn len(&self) -> usize {
        self.n
    }

    /// `len` elements from `lo`.
    ///
    /// # Safety
    /// No write to them while the slice is used; `lo + len <= self.len()`.
    #[inline(always)]
    pub(crate) unsafe fn slice(&self, lo: usize, len: usize) -> &[T] {
        checked_assert!(
            lo <= self.n && len <= self.n - lo,
            "SharedRef::slice: {lo}..+{len} out of range for length {}",
            self.n
        );
        // SAFETY: caller's contract
        unsafe { std::slice::from_raw_parts(self.p.add(lo), len) }
    }
}

impl<T> std::ops::Index<usize> for SharedRef<T> {
    type Output = T;
    #[inline(always)]
    fn index(&self, i: usize) -> &T {
        checked_assert!(i < self.n, "SharedRef: index {i} out of range for length {}", self.n);
        // SAFETY: whoever made the view promised `i < len` and no racing write
        // (`SharedRef::new`)
        unsafe { &*self.p.add(i) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // The thread bounds (module doc, "Threads"): the views of `f64` cross threads, the
    // views of a `T` that must stay on its thread do not (a compile error if they did:
    // the call below is ambiguous exactly when the type is `Send`, or `Sync`).
    trait AmbiguousIfSend<A> {
        fn check() {}
    }
    impl<T: ?Sized> AmbiguousIfSend<()> for T {}
    impl<T: ?Sized + Send> AmbiguousIfSend<u8> for T {}
    trait AmbiguousIfSync<A> {
        fn check() {}
    }
    impl<T: ?Sized> AmbiguousIfSync<()> for T {}
    impl<T: ?Sized + Sync> AmbiguousIfSync<u8> for T {}
    fn send_sync<T: Send + Sync>() {}
    const _: fn() = || {
        send_sync::<SharedMut<f64>>();
        send_sync::<SharedRef<f64>>();
        // `Rc` is neither `Send` nor `Sync`; `Cell` is `Send` but not `Sync`
        <SharedMut<std::rc::Rc<u8>> as AmbiguousIfSend<_>>::check();
        <SharedMut<std::rc::Rc<u8>> as AmbiguousIfSync<_>>::check();
        <SharedRef<std::cell::Cell<u8>> as AmbiguousIfSend<_>>::check();
        <SharedRef<std::cell::Cell<u8>> as AmbiguousIfSync<_>>::check();
        send_sync::<SharedMut<std::cell::Cell<u8>>>();
    };

    /// In bounds, the views read and write the array they were made of.
    #[test]
    fn views_read_and_write_their_array() {
        let mut v = vec![1.0, 2.0, 3.0, 4.0];
        let m = SharedMut::of(&mut v);
        // SAFETY: in bounds, one thread
        unsafe {
            m.set(1, m.get(1) + 10.0);
            m.slice_mut(2, 2)[1] = 7.0;
            assert_eq!(m.slice(0, 4), &[1.0, 12.0, 3.0, 7.0]);
        }
        let mut slots: Vec<u32> = Vec::new();
        slots.reserve(3);
        let s = SharedMut::spare(&mut slots);
        for i in 0..3 {
            // SAFETY: in the reserved capacity, one thread
            unsafe { s.write(i, 5 * i as u32) };
        }
        // SAFETY: slots 0..3 written above
        unsafe { slots.set_len(3) };
        assert_eq!(slots, [0, 5, 10]);
        // SAFETY: every index read below is < 4; `v` outlives the view, unwritten meanwhile
        let r = unsafe { SharedRef::new(&v) };
        assert_eq!((r.len(), r[3]), (4, 7.0));
    }

    /// With `checked`, each accessor stops an index past the end before it touches memory.
    #[cfg(feature = "checked")]
    #[test]
    fn checked_stops_every_accessor_past_the_end() {
        let caught = |f: &dyn Fn()| {
            let e = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).expect_err("not caught");
            let msg = e.downcast_ref::<String>().cloned().unwrap_or_default();
            assert!(msg.contains("out of range"), "{msg}");
        };
        let mut v = vec![0.0f64; 4];
        let m = SharedMut::of(&mut v);
        // Each `unsafe` call below breaks its contract on purpose (an index past the end):
        // `checked` must stop it before the access.
        // SAFETY: none, see above
        caught(&|| unsafe { m.write(4, 1.0) });
        // SAFETY: none, see above
        caught(&|| unsafe { m.set(4, 1.0) });
        // SAFETY: none, see above
        caught(&|| unsafe { _ = m.get(4) });
        // SAFETY: none, see above
        caught(&|| unsafe { _ = m.slice(3, 2) });
        // SAFETY: none, see above
        caught(&|| unsafe { _ = m.slice_mut(5, 0) });
        let mut slots: Vec<u8> = Vec::with_capacity(2);
        let s = SharedMut::spare(&mut slots);
        let cap = slots.capacity();
        // SAFETY: none, see above
        caught(&|| unsafe { s.write(cap, 1) });
        // SAFETY: none for the reads below, see above; `v` outlives the view
        let r = unsafe { SharedRef::new(&v) };
        caught(&|| _ = r[4]);
        // SAFETY: none, see above
        caught(&|| unsafe { _ = r.slice(0, 5) });
    }
}

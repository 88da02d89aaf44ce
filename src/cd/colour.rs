//! NLGS on both cores, deterministically: the contacts in colour classes, no two contacts
//! of a class sharing a body that moves, so the contacts of one class can be solved at
//! once and in any order with the same result (each reads and writes only its own two
//! bodies). A sweep visits the classes in order; a class is cut into fixed chunks of
//! [`CHUNK`] contacts shared out on a thread team held for the whole solve (the DEM's,
//! [`crate::dem::team`]: a class lasts microseconds, too short to wake a pool thread), and
//! the sweep's sums are added chunk by chunk in chunk order. Nothing depends on the thread
//! count.
//!
//! The colouring is greedy, in key order: each contact takes the first colour neither of
//! its bodies has yet (bodies that never move — walls, imposed components on every axis —
//! are not coloured and never written). Disks in 2D touch at most six neighbours of their
//! size, so a handful of classes hold every contact; contacts that find none of the first
//! 63 colours free go to a last class swept on one thread.
//!
//! The order of the updates differs from the key-order sweep (a Gauss–Seidel sweep is a
//! sequence of updates): the two are the same solver with the same convergence tests, not
//! the same bits (measured in `src/cd/colour_tests.rs` and docs/performance.md).

use crate::cd::body::Body;
use crate::cd::contacts::Row;
use crate::cd::solver::{BodyStore, Settings, SolveInfo, change, residual, solve, update_row};
use crate::dem::scratch::chunked;
use crate::math::Real;
use crate::shared::SharedMut;

/// Contacts per work unit of a class.
pub const CHUNK: usize = 64;
/// Below this many contacts a solve runs on its calling thread (the same chunks, the same
/// result).
pub const TEAM_MIN_CONTACTS: usize = 1000;
/// The class of contacts that found no free colour (swept on one thread).
const LAST: usize = 63;

/// Colour classes of a contact list: class `c` holds the rows `order[start[c]..start[c +
/// 1]]`, in key order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Colouring {
    /// Row indices, class by class.
    pub order: Vec<u32>,
    /// Start of each class in `order` (64 classes + 1).
    pub start: Vec<u32>,
}

impl Colouring {
    /// Number of classes that hold a contact.
    pub fn classes(&self) -> usize {
        (0..self.start.len() - 1)
            .filter(|&c| self.start[c + 1] > self.start[c])
            .count()
    }
}

/// Whether a body ever moves (some inverse mass or inertia is not zero).
fn moves(b: &Body) -> bool {
    b.inv != [0.0; 3]
}

/// Greedy colouring of `rows` in their order (see the module doc).
pub fn colour(rows: &[Row], bodies: &[Body]) -> Colouring {
    let mut mask = vec![0u64; bodies.len()];
    let mut class = Vec::with_capacity(rows.len());
    let mut count = [0u32; LAST + 1];
    for r in rows {
        let (a, b) = (r.a as usize, r.b as usize);
        // bit LAST is never set, so a contact always finds some class
        let c = ((!(mask[a] | mask[b])).trailing_zeros() as usize).min(LAST);
        if c < LAST {
            for i in [a, b] {
                if moves(&bodies[i]) {
                    mask[i] |= 1 << c;
                }
            }
        }
        class.push(c as u8);
        count[c] += 1;
    }
    let mut start = vec![0u32; LAST + 2];
    for c in 0..=LAST {
        start[c + 1] = start[c] + count[c];
    }
    let mut fill = start.clone();
    let mut order = vec![0u32; rows.len()];
    for (k, &c) in class.iter().enumerate() {
        order[fill[c as usize] as usize] = k as u32;
        fill[c as usize] += 1;
    }
    Colouring { order, start }
}

/// The bodies as a class's chunks see them: each chunk writes only the bodies of its own
/// contacts, which no other contact of the class touches; bodies that never move are read
/// by many and written by none.
struct SharedBodies(SharedMut<Body>);

impl BodyStore for SharedBodies {
    #[inline(always)]
    fn body(&self, i: u32) -> Body {
        // SAFETY: a moving body is touched by one contact of the class only (the
        // colouring); a still one is never written
        unsafe { self.0.get(i as usize) }
    }
    #[inline(always)]
    fn put_v(&mut self, i: u32, v: [Real; 3]) {
        // SAFETY: as `body`
        unsafe {
            let mut b = self.0.get(i as usize);
            if moves(&b) {
                b.v = v;
                self.0.set(i as usize, b);
            }
        }
    }
}

/// The `gauss_seidel` phase with colour-class sweeps: as [`crate::cd::solver::gauss_seidel`]
/// (the same arguments, tests and cap), the contacts visited class by class.
pub fn gauss_seidel(
    rows: &mut [Row],
    bodies: &mut [Body],
    s: &Settings,
    roll: Option<(&mut [Real], &[Real], Real)>,
) -> SolveInfo {
    solve(rows, bodies, s, roll, sweeps::<false>, sweeps::<true>)
}

/// NLGS sweeps class by class (same convergence tests and cap as the key-order sweep).
fn sweeps<const ROLL: bool>(
    rows: &mut [Row],
    bodies: &mut [Body],
    s: &Settings,
    mr: &mut [Real],
    re: &[Real],
    mu_r: Real,
) -> SolveInfo {
    let mut info = SolveInfo::default();
    let col = colour(rows, bodies);
    // the rows (and rolling moments) laid out class by class, so that a chunk reads its
    // contacts in one run of memory; copied back after the solve
    let mut crow: Vec<Row> = col.order.iter().map(|&k| rows[k as usize]).collect();
    let mut cmr: Vec<Real> = if ROLL {
        col.order.iter().map(|&k| mr[k as usize]).collect()
    } else {
        Vec::new()
    };
    let cre: Vec<Real> = if ROLL {
        col.order.iter().map(|&k| re[k as usize]).collect()
    } else {
        Vec::new()
    };
    let omega = s.relaxation;
    let (nr, nb) = (rows.len(), bodies.len());
    let (rs, ms, bs) = (
        SharedMut::new(&mut crow),
        SharedMut::new(&mut cmr),
        SharedMut::new(bodies),
    );
    let cre = &cre[..];
    let chunk_sums = |lo: usize, hi: usize| {
        let mut sums = (0.0, 0.0);
        let mut store = SharedBodies(bs);
        // SAFETY: rows lo..hi (and their rolling moments) belong to this chunk alone
        let r = unsafe { rs.slice_mut(lo, hi - lo) };
        if ROLL {
            let m = unsafe { ms.slice_mut(lo, hi - lo) };
            for (k, r) in r.iter_mut().enumerate() {
                update_row::<true, _>(r, &mut m[k], cre[lo + k], mu_r, omega, &mut store, &mut sums);
            }
        } else {
            for r in r.iter_mut() {
                update_row::<false, _>(r, &mut 0.0, 1.0, 0.0, omega, &mut store, &mut sums);
            }
        }
        sums
    };
    let big = nr >= TEAM_MIN_CONTACTS;
    let col_ref = &col;
    let info = crate::dem::team::with_team(big, move || {
        let col = col_ref;
        let mut parts: Vec<(Real, Real)> = Vec::new();
        for it in 1..=s.max_iterations {
            let mut total = (0.0, 0.0);
            for c in 0..=LAST {
                let (lo, hi) = (col.start[c] as usize, col.start[c + 1] as usize);
                if lo == hi {
                    continue;
                }
                if c == LAST {
                    parts.clear();
                    parts.push(chunk_sums(lo, hi));
                } else {
                    chunked(hi - lo, CHUNK, &mut parts, |a, b| chunk_sums(lo + a, lo + b));
                }
                for p in &parts {
                    total.0 += p.0;
                    total.1 += p.1;
                }
            }
            info.iterations = it;
            info.change = change(total.0, total.1);
            if info.change <= s.tolerance {
                // SAFETY: no chunk runs now
                let (rows, bodies) = unsafe { (rs.slice_mut(0, nr), bs.slice_mut(0, nb)) };
                info.residual = residual(rows, bodies);
                if info.residual <= s.residual_tolerance {
                    info.converged = true;
                    return info;
                }
            }
        }
        // SAFETY: no chunk runs now
        let (rows, bodies) = unsafe { (rs.slice_mut(0, nr), bs.slice_mut(0, nb)) };
        info.residual = residual(rows, bodies);
        info
    });
    for (p, &k) in col.order.iter().enumerate() {
        rows[k as usize] = crow[p];
        if ROLL {
            mr[k as usize] = cmr[p];
        }
    }
    info
}

#[cfg(test)]
#[path = "colour_tests.rs"]
mod tests;

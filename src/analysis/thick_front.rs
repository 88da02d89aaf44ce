//! One front rule for grains and material points, during the flow and at rest
//! (issue 25, item 2; docs/definitions.md D01).
//!
//! **Meaning.** The front is the farthest x up to which the deposit, connected to the main
//! mass, is at least `threshold` thick (default one mean grain diameter d̄). Thickness is a
//! physical length, so the front does not move with the number of bodies that sample the
//! material (points per cell, cell size): a one-point MPM film thinner than d̄ is not
//! deposit, and neither is a chain of grains finer than d̄; a separate blob ahead is not
//! connected and does not count.
//!
//! **Construction.** Each body occupies the square of half-width `half` around its centre:
//! a grain its bounding square (radius), a material point its cell-area-equivalent square
//! (GIMP half-width l_p = spacing/2, so undeformed points tile the material). The x axis is
//! cut into bins of width d̄ from x = 0 (the left wall; from the leftmost edge if a body lies
//! left of it). A bin's thickness is the length of the union of the y-extents
//! [y − half, y + half] of the bodies whose x-extent overlaps the bin: the column height of
//! the body there, gaps between bodies not counted. The main mass sits in the thickest bin
//! (first on ties); what is connected to it is the run of contiguous non-empty bins through
//! it (an empty bin, a gap wider than d̄, separates), and the front is the last bin of that
//! run whose thickness is ≥ threshold. A thin spot inside the flowing layer therefore does
//! not cut off the thick flow beyond it (a front that must be thick all the way back to the
//! column jumped back by up to 3.5 L_0 at a = 6 when one bin thinned). L is the right edge
//! of that bin, cut back to the farthest body edge in it (so a sharp face, such as the column
//! at release, gives its exact position); H is the highest top edge from the first connected
//! bin to that one.
//!
//! Deterministic: bins are fixed by x = 0 and d̄, the per-bin intervals are sorted with a
//! total order, and the result does not depend on the input order.

use super::front::{Body, Front};
use super::gathered_front::{bins_of, profile};
use serde::{Deserialize, Serialize};

/// Stage setting `front` of the column runs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ThickRule {
    /// Least deposit thickness at the front [d̄]. 1 (one mean grain diameter); 0.5 and 2
    /// for the sensitivity.
    pub threshold_d: f64,
}

impl Default for ThickRule {
    fn default() -> Self {
        Self { threshold_d: 1.0 }
    }
}

impl ThickRule {
    /// Whether this is the default (for `skip_serializing_if`).
    pub fn is_default(&self) -> bool {
        *self == Self::default()
    }
    /// Problem with the value, if any: (key, value, what is allowed).
    pub fn issue(&self) -> Option<(&'static str, f64, &'static str)> {
        (!(self.threshold_d.is_finite() && self.threshold_d > 0.0 && self.threshold_d <= 100.0))
            .then_some(("front.threshold_d", self.threshold_d, "in (0, 100] [d̄]"))
    }
    /// The front of `body` with mean grain diameter `d` [m].
    pub fn front(&self, body: &Body, d: f64) -> Front {
        thick_front(body, d, self.threshold_d * d)
    }
}

/// The deposit front of `body` (see the module comment): bins of width `bin` [m] (d̄),
/// least thickness `threshold` [m]. `n_main` and `mass_fraction` count the bodies that
/// overlap the bins from the first connected one to the front's. An empty body gives
/// zeros; if no bin reaches the threshold, the front is in the thickest bin. The per-bin
/// thickness, top and right edge are [`super::gathered_front::profile`]'s.
pub fn thick_front(body: &Body, bin: f64, threshold: f64) -> Front {
    assert!(bin > 0.0 && bin.is_finite(), "thick_front: bin must be positive");
    let n = body.x.len();
    let zero = Front {
        length: 0.0,
        height: 0.0,
        n_main: 0,
        mass_fraction: 0.0,
    };
    if n == 0 {
        return zero;
    }
    let p = profile(body, bin);
    let (x0, nb, thick, top, right) = (p.x0, p.thickness.len(), &p.thickness, &p.top, &p.right);
    let x1 = right.iter().cloned().fold(x0, f64::max);
    // A layer of exactly the threshold passes despite rounding in the union.
    let passes = |t: f64| t >= threshold * (1.0 - 1e-9);
    let mut main = 0usize;
    for b in 1..nb {
        if thick[b] > thick[main] {
            main = b;
        }
    }
    let (mut first, mut end, mut last) = (main, main, main);
    while end + 1 < nb && thick[end + 1] > 0.0 {
        end += 1;
        if passes(thick[end]) {
            last = end;
        }
    }
    while first > 0 && thick[first - 1] > 0.0 {
        first -= 1;
    }
    // right[last] is finite unless every body has zero size and the thickest bin is empty.
    let length = if right[last].is_finite() {
        (x0 + (last + 1) as f64 * bin).min(right[last])
    } else {
        x1
    };
    let height = top[first..=last].iter().cloned().fold(0.0, f64::max);
    let (mut m_main, mut m_all, mut n_main) = (0.0, 0.0, 0usize);
    for i in 0..n {
        m_all += body.mass[i];
        let (lo, hi) = bins_of(body, i, x0, bin, nb);
        if lo <= last && hi >= first {
            m_main += body.mass[i];
            n_main += 1;
        }
    }
    Front {
        length,
        height,
        n_main,
        mass_fraction: if m_all > 0.0 { m_main / m_all } else { 0.0 },
    }
}

#[cfg(test)]
#[path = "thick_front_tests.rs"]
mod tests;

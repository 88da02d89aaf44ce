//! The front rule for grains and material points (issue 25, item 2): the **gathered
//! length**. Every column records it at every sample; the MPM columns take it as their L(t),
//! run-out and stop front (`run.front_rule: gathered`), and the DEM columns publish it
//! beside the chapter's contact rule (`runout_gathered_norm`), so the two methods are
//! compared on one rule (docs/definitions.md D01).
//!
//! **Meaning.** The run-out is the length the deposit connected to the main mass would
//! cover if every part thinner than one layer (`layer`, one mean grain diameter d̄) were
//! gathered into a layer of that thickness: a bin at least one layer thick counts with its
//! covered length, a thinner bin with its covered length times its thickness over `layer`.
//! A thin film therefore counts by the material it holds, not by how far it has spread: a
//! film of a tenth of a layer over 10 d̄ adds 1 d̄, wherever its tip is. The same rule
//! applies to grains (a monolayer of grains is one layer thick, so the chapter's "farthest
//! grain in contact with the main mass" is recovered at rest up to the gaps between
//! grains) and to material points.
//!
//! **Why it differs from the threshold rule** ([`super::thick_front`]). A front that is the
//! last bin at least one layer thick jumps back by the length of a sheet whenever the sheet
//! thins below the threshold (up to 1 L_0 at a = 6). The gathered length is a sum of
//! bounded, continuous terms: a sheet that thins shortens it by the thinning, not by its
//! length. [`gathered_front`] still jumps when a part detaches (an empty bin opens), by
//! what lies beyond the gap; [`gathered_length`] counts every bin, so it moves only as the
//! material moves, at the price of counting a detached toe by its material. Measured on the
//! quick sweep (docs/definitions.md D01): the largest backward jump of L(t) is 0.12 L_0 with
//! [`gathered_length`], against up to 2.7 L_0 with [`gathered_front`] and 1.9 with the grid
//! links.
//!
//! **Construction.** Bins of width `bin` from x = 0 (from the leftmost edge if a body lies
//! left of it). A body occupies the square of half-size `half` around its centre. Per bin:
//! the thickness h_k, the length of the union of the y-extents of the bodies overlapping it,
//! and the covered length c_k, the length of the union of their x-extents inside the bin.
//! The main mass sits in the thickest bin (first on ties); the deposit connected to it is
//! the run of contiguous non-empty bins through it. L = x_first + Σ c_k · min(1, h_k/layer)
//! over that run, with x_first the left edge of its first covered stretch. Deterministic: the
//! per-bin intervals are sorted with a total order.

use super::front::Body;

/// Per-bin profile of a body set: thickness and covered length.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    /// Left edge of bin 0 [m].
    pub x0: f64,
    /// Bin width [m].
    pub bin: f64,
    /// Union length of the y-extents of the bodies overlapping each bin [m].
    pub thickness: Vec<f64>,
    /// Union length of their x-extents inside each bin [m].
    pub covered: Vec<f64>,
    /// Left edge of the covered part of each bin [m] (+∞ where empty).
    pub left: Vec<f64>,
    /// Highest top edge of the bodies overlapping each bin [m] (−∞ where empty).
    pub top: Vec<f64>,
    /// Farthest right edge of the bodies overlapping each bin [m] (−∞ where empty).
    pub right: Vec<f64>,
}

/// Largest number of bins (a body flung far away cannot make the profile huge).
const MAX_BINS: usize = 1 << 20;

/// Union length of intervals sorted by their start.
pub(crate) fn union_length(iv: &[(f64, f64)]) -> f64 {
    let Some(&(mut lo, mut hi)) = iv.first() else {
        return 0.0;
    };
    let mut sum = 0.0;
    for &(a, b) in &iv[1..] {
        if a > hi {
            sum += hi - lo;
            lo = a;
        }
        hi = hi.max(b);
    }
    sum + (hi - lo)
}

/// The profile of `body` on bins of width `bin` [m].
pub fn profile(body: &Body, bin: f64) -> Profile {
    assert!(bin > 0.0 && bin.is_finite(), "profile: bin must be positive");
    let n = body.x.len();
    assert!(
        body.y.len() == n && body.half.len() == n && body.mass.len() == n,
        "Body slices differ in length"
    );
    let x0 = (0..n).map(|i| body.x[i] - body.half[i]).fold(0.0, f64::min);
    let x1 = (0..n).map(|i| body.x[i] + body.half[i]).fold(x0, f64::max);
    let nb = (((x1 - x0) / bin).ceil() as usize).clamp(1, MAX_BINS);
    // (bin, y-interval, x-interval clipped to the bin) for each body and bin it overlaps
    let mut rows: Vec<(usize, (f64, f64), (f64, f64))> = Vec::with_capacity(2 * n);
    for i in 0..n {
        let (xa, xb) = (body.x[i] - body.half[i], body.x[i] + body.half[i]);
        let (lo, hi) = bins_of(body, i, x0, bin, nb);
        for k in lo..=hi {
            let (ba, bb) = (x0 + k as f64 * bin, x0 + (k + 1) as f64 * bin);
            let (ca, cb) = (xa.max(ba), xb.min(bb));
            // a body that only touches the bin's edge does not overlap it
            if cb > ca {
                rows.push((k, (body.y[i] - body.half[i], body.y[i] + body.half[i]), (ca, cb)));
            }
        }
    }
    let mut thickness = vec![0.0; nb];
    let mut covered = vec![0.0; nb];
    let mut left = vec![f64::INFINITY; nb];
    let mut top = vec![f64::NEG_INFINITY; nb];
    let mut right = vec![f64::NEG_INFINITY; nb];
    for i in 0..n {
        let (lo, hi) = bins_of(body, i, x0, bin, nb);
        for k in lo..=hi {
            top[k] = top[k].max(body.y[i] + body.half[i]);
            right[k] = right[k].max(body.x[i] + body.half[i]);
        }
    }
    rows.sort_by(|a, b| {
        a.0.cmp(&b.0)
            .then(a.1.0.total_cmp(&b.1.0))
            .then(a.1.1.total_cmp(&b.1.1))
    });
    let mut s = 0;
    while s < rows.len() {
        let k = rows[s].0;
        let mut e = s;
        while e < rows.len() && rows[e].0 == k {
            e += 1;
        }
        let ys: Vec<(f64, f64)> = rows[s..e].iter().map(|r| r.1).collect();
        let mut xs: Vec<(f64, f64)> = rows[s..e].iter().map(|r| r.2).collect();
        xs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        thickness[k] = union_length(&ys);
        covered[k] = union_length(&xs);
        left[k] = xs.first().map_or(f64::INFINITY, |x| x.0);
        s = e;
    }
    Profile {
        x0,
        bin,
        thickness,
        covered,
        left,
        top,
        right,
    }
}

/// The bins (first, last) body `i` overlaps, of `nb` bins of width `bin` from `x0`; a body
/// that only touches a bin's edge does not overlap it.
pub(crate) fn bins_of(body: &Body, i: usize, x0: f64, bin: f64, nb: usize) -> (usize, usize) {
    let lo = ((body.x[i] - body.half[i] - x0) / bin).floor().max(0.0) as usize;
    let hi = ((body.x[i] + body.half[i] - x0) / bin).ceil() as usize;
    let lo = lo.min(nb - 1);
    (lo, hi.saturating_sub(1).clamp(lo, nb - 1))
}

/// The rule that gives a column's L(t), its run-out and the front its stop rule watches
/// (docs/definitions.md D01), for grains and material points alike.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FrontRule {
    /// The right edge of the main mass by the method's links (grains: the chapter's contact
    /// rule; material points: shared grid nodes or an edge gap).
    #[default]
    Links,
    /// The gathered length over every body ([`gathered_length`], bins and layer of one d̄).
    Gathered,
}

impl FrontRule {
    /// Whether this is the default (serde's `skip_serializing_if`, so that cache keys of
    /// stages that do not set it are unchanged).
    pub fn is_links(&self) -> bool {
        matches!(self, FrontRule::Links)
    }
}

/// The gathered length at the D01 scales: bins and layer of one mean grain diameter `d` [m].
pub fn gathered_d(body: &Body, d: f64) -> f64 {
    gathered_length(body, d, d)
}

/// The gathered front of `body` (see the module comment): bins of width `bin` [m], one layer
/// `layer` [m] thick. Returns L [m]; 0 for no body.
pub fn gathered_front(body: &Body, bin: f64, layer: f64) -> f64 {
    gathered(body, bin, layer, true)
}

/// The gathered length of every bin from the first covered one, connected or not: every
/// body counts by what it holds (the variant without jumps). To count a main mass only,
/// pass the bodies [`super::front::main_mass`] selects.
pub fn gathered_length(body: &Body, bin: f64, layer: f64) -> f64 {
    gathered(body, bin, layer, false)
}

fn gathered(body: &Body, bin: f64, layer: f64, connected: bool) -> f64 {
    assert!(
        layer > 0.0 && layer.is_finite(),
        "gathered_front: layer must be positive"
    );
    if body.x.is_empty() {
        return 0.0;
    }
    let p = profile(body, bin);
    let nb = p.thickness.len();
    let mut main = 0;
    for k in 1..nb {
        if p.thickness[k] > p.thickness[main] {
            main = k;
        }
    }
    let (mut first, mut end) = (main, main);
    if connected {
        while first > 0 && p.covered[first - 1] > 0.0 {
            first -= 1;
        }
        while end + 1 < nb && p.covered[end + 1] > 0.0 {
            end += 1;
        }
    } else {
        first = (0..nb).find(|&k| p.covered[k] > 0.0).unwrap_or(0);
        end = nb - 1;
    }
    let start = if p.left[first].is_finite() { p.left[first] } else { p.x0 };
    start
        + (first..=end)
            .map(|k| p.covered[k] * (p.thickness[k] / layer).min(1.0))
            .sum::<f64>()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bodies from (x, y, half) triples, unit mass.
    fn bodies(v: &[(f64, f64, f64)]) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
        (
            v.iter().map(|b| b.0).collect(),
            v.iter().map(|b| b.1).collect(),
            v.iter().map(|b| b.2).collect(),
            vec![1.0; v.len()],
        )
    }

    /// `rule` applied to bodies given as (x, y, half) triples of unit mass.
    fn measure(rule: fn(&Body, f64, f64) -> f64, v: &[(f64, f64, f64)], bin: f64, layer: f64) -> f64 {
        let (x, y, h, m) = bodies(v);
        rule(
            &Body {
                x: &x,
                y: &y,
                half: &h,
                mass: &m,
            },
            bin,
            layer,
        )
    }

    fn gathered(v: &[(f64, f64, f64)], bin: f64, layer: f64) -> f64 {
        measure(gathered_front, v, bin, layer)
    }

    fn length(v: &[(f64, f64, f64)], bin: f64, layer: f64) -> f64 {
        measure(gathered_length, v, bin, layer)
    }

    /// A block of squares of side 2·half tiling [0, w] × [0, t].
    fn block(x_from: f64, w: f64, t: f64, half: f64) -> Vec<(f64, f64, f64)> {
        let (nx, ny) = ((w / (2.0 * half)).round() as usize, (t / (2.0 * half)).round() as usize);
        (0..nx)
            .flat_map(|i| (0..ny).map(move |j| (x_from + (2 * i + 1) as f64 * half, (2 * j + 1) as f64 * half, half)))
            .collect()
    }

    #[test]
    fn a_sharp_face_is_measured_exactly_even_between_bin_edges() {
        // a 0.37 m wide, 0.5 m high block, bins of 0.1, layer 0.1: L = 0.37
        let b = block(0.0, 0.37, 0.5, 0.005);
        assert!((gathered(&b, 0.1, 0.1) - 0.37).abs() < 1e-6);
    }

    #[test]
    fn a_stretched_film_counts_by_what_it_holds_not_by_its_tip() {
        // thick deposit to x = 1 (0.4 thick, layer 0.1), then a 0.01-thick film to x = 3:
        // the film adds 2 × 0.01/0.1 = 0.2, not 2. The contact and shared-node rules put
        // the front at its tip (3), the threshold rule at 1.
        let mut b = block(0.0, 1.0, 0.4, 0.005);
        b.extend((0..200).map(|i| (1.005 + i as f64 * 0.01, 0.005, 0.005)));
        let l = gathered(&b, 0.1, 0.1);
        assert!((l - 1.2).abs() < 1e-6, "L = {l}");
        // and it does not move when the same film is stretched twice as far and half as thick
        let mut c = block(0.0, 1.0, 0.4, 0.005);
        c.extend((0..800).map(|i| (1.0025 + i as f64 * 0.005, 0.0025, 0.0025)));
        let l2 = gathered(&c, 0.1, 0.1);
        assert!((l2 - 1.2).abs() < 1e-6, "L = {l2}");
    }

    #[test]
    fn a_detached_toe_is_not_the_front() {
        // main deposit to x = 1, a separate blob at 1.5–1.7 beyond an empty bin
        let mut b = block(0.0, 1.0, 0.4, 0.005);
        b.extend(block(1.5, 0.2, 0.4, 0.005));
        assert!((gathered(&b, 0.1, 0.1) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn a_layer_thick_sheet_counts_to_its_end_and_thinning_it_shortens_it_continuously() {
        // deposit to x = 1, then a sheet to x = 2 one layer thick: L = 2
        let mut b = block(0.0, 1.0, 0.4, 0.005);
        b.extend(block(1.0, 1.0, 0.1, 0.005));
        assert!((gathered(&b, 0.1, 0.1) - 2.0).abs() < 1e-6);
        // the same sheet at 0.09 and at 0.11 thick: L moves by 0.1 and by nothing, where a
        // threshold at one layer jumps from 2 back to 1
        let mut thin = block(0.0, 1.0, 0.4, 0.005);
        thin.extend(block(1.0, 1.0, 0.09, 0.005));
        assert!((gathered(&thin, 0.1, 0.1) - 1.9).abs() < 1e-6);
        let mut thick = block(0.0, 1.0, 0.4, 0.005);
        thick.extend(block(1.0, 1.0, 0.11, 0.005));
        assert!((gathered(&thick, 0.1, 0.1) - 2.0).abs() < 1e-6);
    }

    #[test]
    fn without_connectivity_a_detached_toe_adds_what_it_holds_not_its_far_edge() {
        // main deposit to x = 1 and a 0.2 × 0.05 blob at 1.5–1.7 (half a layer thick): the
        // connected front stays at 1, the unconnected length adds 0.2 × 0.5 = 0.1; neither
        // is the toe's far edge (1.7), where the contact rule with a large gap would put it
        let mut b = block(0.0, 1.0, 0.4, 0.005);
        b.extend(block(1.5, 0.2, 0.05, 0.005));
        assert!((gathered(&b, 0.1, 0.1) - 1.0).abs() < 1e-6);
        assert!((length(&b, 0.1, 0.1) - 1.1).abs() < 1e-6);
    }

    #[test]
    fn without_connectivity_a_sheet_breaking_up_moves_the_length_by_what_it_loses() {
        // a one-layer sheet from 1 to 2 broken into five pieces 0.08 long, one in every
        // other bin: the connected front falls back to the first piece (1.08, a jump of the
        // whole sheet), the unconnected length by the emptied part only (1.4)
        let mut b = block(0.0, 1.0, 0.4, 0.005);
        for k in (0..10).step_by(2) {
            b.extend(block(1.01 + 0.1 * k as f64, 0.08, 0.1, 0.005));
        }
        assert!((gathered(&b, 0.1, 0.1) - 1.08).abs() < 1e-6);
        assert!((length(&b, 0.1, 0.1) - 1.4).abs() < 1e-6);
    }

    #[test]
    fn the_result_does_not_depend_on_the_input_order() {
        let mut b = block(0.0, 1.0, 0.4, 0.005);
        b.extend((0..100).map(|i| (1.0 + 0.0025 + i as f64 * 0.007, 0.004, 0.004)));
        let l = gathered(&b, 0.1, 0.1);
        b.reverse();
        assert_eq!(gathered(&b, 0.1, 0.1).to_bits(), l.to_bits());
    }
}

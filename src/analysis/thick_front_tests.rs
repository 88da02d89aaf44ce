//! Tests of the thick-deposit front (issue 25, item 2). Every case is built for both
//! representations where it makes sense — grains (disks of radius r) and material points
//! (squares of half-width l_p = s/2 on the lattice of spacing s) — and set against today's
//! two MPM rules: grid links (points sharing a background node, uGIMP support h + l_p) and
//! edge gaps (edges within 0.5 d̄).

use super::*;
use crate::analysis::front::{Link, front};

/// Mean grain diameter of the project's columns [m].
const D: f64 = 1.15e-3;

/// Bodies with their masses (struct of arrays).
#[derive(Default, Clone)]
struct Set {
    x: Vec<f64>,
    y: Vec<f64>,
    half: Vec<f64>,
    mass: Vec<f64>,
}

impl Set {
    fn push(&mut self, x: f64, y: f64, half: f64) {
        self.x.push(x);
        self.y.push(y);
        self.half.push(half);
        self.mass.push(half * half);
    }
    fn body(&self) -> Body<'_> {
        Body {
            x: &self.x,
            y: &self.y,
            half: &self.half,
            mass: &self.mass,
        }
    }
    /// Material points of spacing `s` filling the rectangle [x0, x0 + nx s] × [0, ny s].
    fn points(&mut self, x0: f64, nx: usize, ny: usize, s: f64) {
        for i in 0..nx {
            for j in 0..ny {
                self.push(x0 + (i as f64 + 0.5) * s, (j as f64 + 0.5) * s, 0.5 * s);
            }
        }
    }
    /// Material points of spacing `s` sampling the deposit of thickness `h(x)` from x = 0:
    /// a point wherever its centre lies inside the material.
    fn sample(&mut self, s: f64, x_end: f64, h: impl Fn(f64) -> f64) {
        for i in 0..(x_end / s).ceil() as usize {
            let xc = (i as f64 + 0.5) * s;
            let mut j = 0;
            while (j as f64 + 0.5) * s < h(xc) {
                self.push(xc, (j as f64 + 0.5) * s, 0.5 * s);
                j += 1;
            }
        }
    }
    /// Grains of diameter `d` on a square lattice filling [x0, x0 + nx d] × [0, ny d].
    fn grains(&mut self, x0: f64, nx: usize, ny: usize, d: f64) {
        for i in 0..nx {
            for j in 0..ny {
                self.push(x0 + (i as f64 + 0.5) * d, (j as f64 + 0.5) * d, 0.5 * d);
            }
        }
    }
}

/// Today's grid-link rule for 2 mm cells (or `h`) and the point half-width `lp`.
fn grid_rule(set: &Set, h: f64, lp: f64) -> f64 {
    front(&set.body(), Link::SharedNode { h, support: h + lp }).length
}

/// Today's edge-gap rule (0.5 d̄).
fn gap_rule(set: &Set) -> f64 {
    front(&set.body(), Link::Contact { gap: 0.5 * D }).length
}

fn new_rule(set: &Set, threshold_d: f64) -> Front {
    ThickRule { threshold_d }.front(&set.body(), D)
}

#[test]
fn a_column_at_release_is_measured_exactly() {
    // 50 × 20 mm, material points at 1 mm and grains of d̄: L = L_0, H = H_0, all the mass.
    let mut mp = Set::default();
    mp.points(0.0, 50, 20, 1e-3);
    let f = new_rule(&mp, 1.0);
    assert!((f.length - 50e-3).abs() < 1e-12 && (f.height - 20e-3).abs() < 1e-12);
    assert_eq!((f.n_main, f.mass_fraction), (1000, 1.0));
    let mut gr = Set::default();
    gr.grains(0.0, 40, 15, D);
    let f = new_rule(&gr, 1.0);
    assert!((f.length - 40.0 * D).abs() < 1e-12 && (f.height - 15.0 * D).abs() < 1e-12);
}

#[test]
fn stretched_film_ends_where_the_deposit_is_thick() {
    // (a) Material points (2 mm cells, 4 PPC: s = 1 mm, l_p = 0.5 mm): a 50 × 20 mm mass
    // and a one-point film (1 mm < d̄ thick) stretched to 1.5 mm spacing out to 80 mm. Both
    // of today's rules follow the film (its points share grid nodes; their edges are 0.5 mm
    // < 0.5 d̄ apart) and put the front at its tip; the new rule puts it at the mass.
    let (s, lp, h) = (1e-3, 0.5e-3, 2e-3);
    let mut mp = Set::default();
    mp.points(0.0, 50, 20, s);
    for k in 0..20 {
        mp.push(51e-3 + 1.5e-3 * k as f64, 0.5 * s, lp);
    }
    let tip = 51e-3 + 1.5e-3 * 19.0 + lp;
    assert!((grid_rule(&mp, h, lp) - tip).abs() < 1e-12, "grid rule: film tip");
    assert!((gap_rule(&mp) - tip).abs() < 1e-12, "edge-gap rule: film tip");
    let f = new_rule(&mp, 1.0);
    assert!(
        (f.length - 50e-3).abs() <= D,
        "new rule: the mass end, got {}",
        f.length
    );
    assert!(tip - f.length > 25.0 * D);
    // Grains: a touching chain of fine grains (0.6 d̄) along the base ahead of a mass of d̄
    // grains. The chapter's contact rule counts the chain; the new rule stops at the mass.
    let mut gr = Set::default();
    gr.grains(0.0, 40, 15, D);
    for k in 0..20 {
        gr.push(40.0 * D + (k as f64 + 0.5) * 0.6 * D, 0.3 * D, 0.3 * D);
    }
    let chain_tip = 40.0 * D + 20.0 * 0.6 * D;
    // The DEM column stages' contact rule: edges within 0.5 d̄ (stages/col-dem.yaml).
    let contact = front(&gr.body(), Link::Contact { gap: 0.5 * D }).length;
    assert!((contact - chain_tip).abs() < 1e-12, "contact rule: chain tip");
    let f = new_rule(&gr, 1.0);
    assert!((f.length - 40.0 * D).abs() <= D, "got {}", f.length / D);
}

#[test]
fn a_thin_spot_in_the_flowing_layer_does_not_cut_the_front() {
    // A 50 × 20 mm mass and a 2-point (2 mm) layer out to 90 mm that has thinned to one point
    // (1 mm < d̄) between 60 and 63 mm. The layer beyond is still connected through material
    // and thick: the front is its end, not the thin spot (requiring thickness all the way back
    // to the mass made L(t) jump back by 3.5 L_0 in the quick a = 6 run).
    let s = 1e-3;
    let mut mp = Set::default();
    mp.points(0.0, 50, 20, s);
    mp.points(50e-3, 10, 2, s);
    mp.points(60e-3, 3, 1, s);
    mp.points(63e-3, 27, 2, s);
    let f = new_rule(&mp, 1.0);
    assert!((f.length - 90e-3).abs() < 1e-12, "got {} mm", f.length * 1e3);
    // At 2.5 d̄ (2.9 mm) the 2 mm layer is thin everywhere: the front is the mass.
    assert!((new_rule(&mp, 2.5).length - 50e-3).abs() <= D);
}

#[test]
fn detached_toe_is_not_the_front() {
    // (b) Material points: a 51 × 20 mm mass and a 5 × 5 mm blob whose near edge is 2.5 mm
    // (2.2 d̄) ahead of it. The blob's first points and the mass's last ones reach the same
    // grid node (x = 52 mm, support h + l_p = 2.5 mm), so the grid rule makes it one mass
    // with the blob's far edge as the front; the new rule (and the edge-gap rule) do not.
    let (s, lp, h) = (1e-3, 0.5e-3, 2e-3);
    let mut mp = Set::default();
    mp.points(0.0, 51, 20, s);
    mp.points(53.5e-3, 5, 5, s);
    assert!((grid_rule(&mp, h, lp) - 58.5e-3).abs() < 1e-12, "grid rule: blob tip");
    assert!((gap_rule(&mp) - 51e-3).abs() < 1e-12);
    let f = new_rule(&mp, 1.0);
    assert!((f.length - 51e-3).abs() < 1e-12, "got {}", f.length);
    assert_eq!(f.n_main, 51 * 20);
    // Grains: a 4 × 4 blob of d̄ grains 3 d̄ ahead — the contact rule and the new one agree.
    let mut gr = Set::default();
    gr.grains(0.0, 40, 15, D);
    gr.grains(43.0 * D, 4, 4, D);
    let contact = front(&gr.body(), Link::Contact { gap: 0.5 * D }).length;
    let f = new_rule(&gr, 1.0);
    assert!((contact - 40.0 * D).abs() < 1e-12 && (f.length - 40.0 * D).abs() < 1e-12);
}

#[test]
fn thin_spreading_layer_ends_at_the_threshold_thickness() {
    // (c) A layer thinning linearly from 10 mm at the wall to nothing at X = 60 mm, sampled
    // by points of 0.5 mm (1 mm cells, 4 PPC). Where it is `t` thick: x* = X (1 − t/10 mm).
    // The front follows the threshold to within one bin plus the thickness resolution
    // (s over the slope); both old rules go to the last point, ~5 d̄ farther.
    let (s, lp, h, hh, xx) = (0.5e-3, 0.25e-3, 1e-3, 10e-3, 60e-3);
    let mut mp = Set::default();
    mp.sample(s, xx, |x| hh * (1.0 - x / xx));
    let tol = D + s * xx / hh;
    for k in [0.5, 1.0, 2.0] {
        let x_star = xx * (1.0 - k * D / hh);
        let f = new_rule(&mp, k);
        assert!(
            (f.length - x_star).abs() <= tol,
            "threshold {k} d̄: {} mm vs {} mm",
            f.length * 1e3,
            x_star * 1e3
        );
    }
    let x_star = xx * (1.0 - D / hh);
    for (name, old) in [("grid", grid_rule(&mp, h, lp)), ("edge gap", gap_rule(&mp))] {
        assert!(
            old - x_star > tol,
            "{name} rule {} mm is within the tolerance",
            old * 1e3
        );
    }
    // Grains of d̄ in whole layers under the same surface: the front is where one layer
    // (d̄ thick) remains; at 2 d̄ where two do.
    let mut gr = Set::default();
    for i in 0..(xx / D) as usize {
        let xc = (i as f64 + 0.5) * D;
        for j in 0..((hh * (1.0 - xc / xx)) / D).floor() as usize {
            gr.push(xc, (j as f64 + 0.5) * D, 0.5 * D);
        }
    }
    for k in [1.0, 2.0] {
        let x_star = xx * (1.0 - k * D / hh);
        let f = new_rule(&gr, k);
        assert!((f.length - x_star).abs() <= 2.0 * D, "grains, {k} d̄: {}", f.length / D);
    }
}

#[test]
fn the_same_continuum_gives_the_same_front_at_two_resolutions() {
    // A deposit 20 mm thick to 20 mm, thinning to nothing at 60 mm, with a 0.6 mm film to
    // 90 mm; sampled by points at 1 mm (2 mm cells, 4 PPC) and 0.5 mm (1 mm cells).
    let h = |x: f64| {
        if x < 20e-3 {
            20e-3
        } else if x < 60e-3 {
            20e-3 * (60e-3 - x) / 40e-3
        } else if x < 90e-3 {
            0.6e-3
        } else {
            0.0
        }
    };
    let (mut coarse, mut fine) = (Set::default(), Set::default());
    coarse.sample(1e-3, 90e-3, h);
    fine.sample(0.5e-3, 90e-3, h);
    for k in [1.0, 2.0] {
        let (a, b) = (new_rule(&coarse, k).length, new_rule(&fine, k).length);
        assert!((a - b).abs() <= D, "threshold {k} d̄: {} vs {} mm", a * 1e3, b * 1e3);
        assert!(a < 60e-3, "the film is not the front");
    }
    // Both old rules give the film tip at both resolutions.
    assert!((grid_rule(&coarse, 2e-3, 0.5e-3) - 90e-3).abs() < 1e-9);
    assert!((grid_rule(&fine, 1e-3, 0.25e-3) - 90e-3).abs() < 1e-9);
}

#[test]
fn a_film_drifting_apart_does_not_make_the_front_jump_back() {
    // A quick-sweep-like L(t) (L_0 = 50 mm): a mass whose one-point film lengthens and whose
    // points drift apart (spacing 1.2 → 3 mm). The edge-gap rule loses the film once its
    // edges are more than 0.5 d̄ apart: a jump back of ~1 L_0. The new rule never follows the
    // film and moves forward with the mass.
    use crate::analysis::runout::max_backward_jump;
    let (s, lp, l0) = (1e-3, 0.5e-3, 50e-3);
    let (mut new, mut old) = (Vec::new(), Vec::new());
    for k in 0..20 {
        let mut mp = Set::default();
        let nx = 50 + k;
        mp.points(0.0, nx, 20 - k / 2, s);
        let gap = 1.2e-3 + 0.1e-3 * k as f64;
        for m in 0..(20 + 4 * k) {
            mp.push(nx as f64 * s + lp + 0.2e-3 + gap * m as f64, 0.5 * s, lp);
        }
        new.push(new_rule(&mp, 1.0).length);
        old.push(gap_rule(&mp));
    }
    assert!(
        max_backward_jump(&old, l0) > 0.5,
        "old: {}",
        max_backward_jump(&old, l0)
    );
    assert!(max_backward_jump(&new, l0) <= D / l0, "new: {:?}", new);
}

#[test]
fn input_order_does_not_matter() {
    let mut mp = Set::default();
    mp.sample(1e-3, 60e-3, |x| 15e-3 * (1.0 - x / 60e-3));
    let f = new_rule(&mp, 1.0);
    let mut rev = mp.clone();
    for v in [&mut rev.x, &mut rev.y, &mut rev.half, &mut rev.mass] {
        v.reverse();
    }
    let g = new_rule(&rev, 1.0);
    assert_eq!((g.length, g.height, g.n_main), (f.length, f.height, f.n_main));
    assert_eq!(thick_front(&Set::default().body(), D, D).length, 0.0);
    assert!(ThickRule { threshold_d: 0.0 }.issue().is_some());
    assert!(ThickRule::default().issue().is_none());
}

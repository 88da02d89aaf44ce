//! uGIMP weighting functions (chapter 3 §"GIMP method", Bardenhagen & Kober 2004): linear
//! grid basis convolved with a piecewise-constant particle characteristic function of
//! half-width l_p (undeformed: "uGIMP", l_p fixed at h/(2√PPC)). With l_p ≤ h/2 a point
//! touches at most 3 nodes per direction, so the 2D stencil is 3 × 3 nodes.
//!
//! 1D, with r = x_p − x_i:
//! - |r| < l_p:              φ = 1 − (r² + l_p²)/(2 h l_p)
//! - l_p ≤ |r| < h − l_p:    φ = 1 − |r|/h
//! - h − l_p ≤ |r| < h + l_p: φ = (h + l_p − |r|)²/(4 h l_p)
//! - otherwise 0
//!
//! (the thesis writes the same with the full width l = 2 l_p).

use crate::math::Real;

/// 1D weight φ(r) and its derivative dφ/dx_p for node distance r = x_p − x_i.
#[inline(always)]
pub fn gimp_1d(r: Real, h: Real, lp: Real) -> (Real, Real) {
    let a = r.abs();
    let s = if r < 0.0 { -1.0 } else { 1.0 };
    if a < lp {
        (1.0 - (r * r + lp * lp) / (2.0 * h * lp), -r / (h * lp))
    } else if a < h - lp {
        (1.0 - a / h, -s / h)
    } else if a < h + lp {
        let d = h + lp - a;
        (d * d / (4.0 * h * lp), -s * d / (2.0 * h * lp))
    } else {
        (0.0, 0.0)
    }
}

/// The 3 × 3 nodal stencil of one point.
#[derive(Debug, Clone, Copy, Default)]
pub struct Stencil {
    /// Index of the first node in x (the stencil covers i0, i0+1, i0+2).
    pub i0: usize,
    /// Index of the first node in y.
    pub j0: usize,
    /// 1D weights in x.
    pub wx: [Real; 3],
    /// 1D weights in y.
    pub wy: [Real; 3],
    /// 1D derivatives in x.
    pub dx: [Real; 3],
    /// 1D derivatives in y.
    pub dy: [Real; 3],
}

/// First node index (per axis) of the stencil of a point at local coordinate `u` = (x − x_origin)/h.
#[inline(always)]
pub fn first_node(u: Real, lp_over_h: Real) -> isize {
    // floor without the libm call (not inlined on x86-64 without SSE4.1).
    let v = u - lp_over_h;
    let i = v as isize;
    if (i as Real) > v { i - 1 } else { i }
}

impl Stencil {
    /// Stencil of a point at (x, y) on a grid with origin (ox, oy), cell h, half-width lp.
    /// The caller guarantees that the point is inside the grid with a margin of one cell
    /// (checked by `relocate`).
    ///
    /// Per axis, with t = (x − x_{i0})/h ∈ [l, 1 + l) and l = l_p/h ≤ ½, node i0 is in the
    /// linear or the outer region, node i0+2 in the outer region or outside, and node i0+1
    /// follows from the partition of unity (weights) and its derivative (gradients sum to 0):
    /// one branch per axis instead of three piecewise evaluations.
    #[inline(always)]
    pub fn new(x: Real, y: Real, ox: Real, oy: Real, h: Real, lp: Real) -> Self {
        let inv_h = 1.0 / h;
        let l = lp * inv_h;
        let ux = (x - ox) * inv_h;
        let uy = (y - oy) * inv_h;
        let i0 = first_node(ux, l);
        let j0 = first_node(uy, l);
        let (wx, dx) = axis(ux - i0 as Real, l, inv_h);
        let (wy, dy) = axis(uy - j0 as Real, l, inv_h);
        Stencil {
            i0: i0.max(0) as usize,
            j0: j0.max(0) as usize,
            wx,
            wy,
            dx,
            dy,
        }
    }
}

impl Stencil {
    /// Stencil with its first node already known (`base` from [`Stencil::new`] or
    /// [`first_node`] at the same position): no float-to-int conversion.
    #[inline(always)]
    pub fn at(x: Real, y: Real, base: [u32; 2], ox: Real, oy: Real, h: Real, lp: Real) -> Self {
        let inv_h = 1.0 / h;
        let l = lp * inv_h;
        let tx = (x - ox) * inv_h - base[0] as Real;
        let ty = (y - oy) * inv_h - base[1] as Real;
        let (wx, dx) = axis(tx, l, inv_h);
        let (wy, dy) = axis(ty, l, inv_h);
        Stencil {
            i0: base[0] as usize,
            j0: base[1] as usize,
            wx,
            wy,
            dx,
            dy,
        }
    }
}

/// Weights and derivatives of the three nodes of one axis; `t` = distance from the first node
/// in cells, `l` = l_p/h.
#[inline(always)]
fn axis(t: Real, l: Real, inv_h: Real) -> ([Real; 3], [Real; 3]) {
    let (w0, d0, w2, d2) = if t < 1.0 - l {
        (1.0 - t, -inv_h, 0.0, 0.0)
    } else {
        let k = 0.25 / l;
        let q = 1.0 + l - t;
        let s = t - 1.0 + l;
        (k * q * q, -2.0 * k * q * inv_h, k * s * s, 2.0 * k * s * inv_h)
    };
    ([w0, 1.0 - w0 - w2, w2], [d0, -d0 - d2, d2])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mpm::params::{MpmParams, Shape};

    /// Positions (in cells) across a few cells: exact nodes, cell midpoints, the GIMP region
    /// boundaries for l = ¼ and irregular offsets (0.3141 and 0.7071 are arbitrary offsets,
    /// not π/10 and √½).
    #[allow(clippy::approx_constant)]
    fn positions() -> Vec<Real> {
        let mut u = Vec::new();
        for i in 2..5 {
            for f in [0.0, 0.25, 0.5, 0.75, 0.0625, 0.3141, 0.7071, 0.999, 1e-9] {
                u.push(i as Real + f);
            }
        }
        u
    }

    #[test]
    fn partition_of_unity_and_zero_gradient_sum_for_gimp_and_linear() {
        let h = 2e-3;
        let (ox, oy) = (-0.01, 0.003);
        for (shape, ppc) in [
            (Shape::Gimp, 1),
            (Shape::Gimp, 4),
            (Shape::Gimp, 16),
            (Shape::Linear, 4),
            (Shape::Linear, 16),
        ] {
            let p = MpmParams {
                shape,
                ppc,
                cell_size: h,
                ..MpmParams::default()
            };
            let lp = p.shape_half_width();
            match shape {
                Shape::Gimp => assert_eq!(lp, h / (2.0 * (ppc as Real).sqrt())),
                Shape::Linear => assert_eq!(lp, 0.0),
            }
            // the point's size used by the front (D01) does not depend on the shape functions
            assert_eq!(p.half_width(), h / (2.0 * (ppc as Real).sqrt()));
            for &ux in &positions() {
                for &uy in &[2.5, 3.0 + 0.37] {
                    let (x, y) = (ox + ux * h, oy + uy * h);
                    let st = Stencil::new(x, y, ox, oy, h, lp);
                    let sw: Real = st.wx.iter().sum::<Real>() * st.wy.iter().sum::<Real>();
                    assert!((sw - 1.0).abs() < 1e-12, "{shape:?} ppc {ppc} u = {ux}: Σφ = {sw}");
                    // Σ_i ∇φ_i = Σ_ij (dx_i wy_j, wx_i dy_j) = 0
                    let gx: Real = (0..3)
                        .flat_map(|i| (0..3).map(move |j| (i, j)))
                        .map(|(i, j)| st.dx[i] * st.wy[j])
                        .sum();
                    let gy: Real = (0..3)
                        .flat_map(|i| (0..3).map(move |j| (i, j)))
                        .map(|(i, j)| st.wx[i] * st.dy[j])
                        .sum();
                    assert!(
                        gx.abs() * h < 1e-12 && gy.abs() * h < 1e-12,
                        "{shape:?} ppc {ppc} u = {ux}: Σ∇φ = ({gx}, {gy})"
                    );
                    // every node's weight (and away from nodes its derivative) is the 1D
                    // function itself; nodes outside the stencil carry no weight
                    for n in -1..6isize {
                        let node = st.i0 as isize + n - 1;
                        let r = x - (ox + node as Real * h);
                        let (w, d) = gimp_1d(r, h, lp);
                        let k = n - 1;
                        if (0..3).contains(&k) {
                            let k = k as usize;
                            assert!(
                                (st.wx[k] - w).abs() < 1e-12,
                                "{shape:?} ppc {ppc} u = {ux} node {k}: {} vs {w}",
                                st.wx[k]
                            );
                            if (r / h - (r / h).round()).abs() > 1e-6 {
                                assert!(
                                    (st.dx[k] - d).abs() * h < 1e-9,
                                    "{shape:?} ppc {ppc} u = {ux} node {k}: {} vs {d}",
                                    st.dx[k]
                                );
                            }
                            assert!(st.wx[k] >= -1e-15, "negative weight");
                        } else {
                            assert_eq!(
                                w, 0.0,
                                "{shape:?} ppc {ppc} u = {ux}: node {node} outside the stencil has weight {w}"
                            );
                        }
                    }
                    if shape == Shape::Linear {
                        // the linear hat: two nodes, φ = 1 − |r|/h, dφ/dx = ∓1/h
                        let t = ux - ux.floor();
                        assert_eq!(st.i0 as isize, ux.floor() as isize, "u = {ux}");
                        assert!(
                            (st.wx[0] - (1.0 - t)).abs() < 1e-12 && (st.wx[1] - t).abs() < 1e-12 && st.wx[2] == 0.0,
                            "u = {ux}: {:?}",
                            st.wx
                        );
                        assert!(
                            (st.dx[0] + 1.0 / h).abs() * h < 1e-12
                                && (st.dx[1] - 1.0 / h).abs() * h < 1e-12
                                && st.dx[2] == 0.0,
                            "u = {ux}: {:?}",
                            st.dx
                        );
                    }
                }
            }
        }
    }
}

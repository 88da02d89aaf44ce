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
        Stencil { i0: i0.max(0) as usize, j0: j0.max(0) as usize, wx, wy, dx, dy }
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
        Stencil { i0: base[0] as usize, j0: base[1] as usize, wx, wy, dx, dy }
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

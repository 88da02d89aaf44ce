//! Grid transfers of the GIMP step, per point: the scatter of a band of points onto the
//! grid (p2g) and the gather of nodal velocities at the points (g2p, velocity gradient).
//!
//! Two implementations of the same arithmetic: a scalar one, and on x86-64 with AVX2
//! (detected at run time) one that works on four nodal components at once — the node's
//! [p.x, p.y, f.x, f.y] in the scatter, [v.x, v.y, Δv.x, Δv.y] and the four entries of the
//! velocity gradient in the gather. Every lane performs exactly the scalar operations, in the
//! scalar order, on the scalar operands (lanes that have nothing to add are blended out, no
//! fused multiply-add), so both give bit-identical results; `transfer_simd_matches_scalar`
//! in the tests checks it.

use super::grid::Node;
use super::particles::Point;
use super::shape::Stencil;
use crate::math::{Mat2, Real, Vec2};

/// Grid geometry the transfers need, plus whether the AVX2 path is used.
#[derive(Debug, Clone, Copy)]
pub(super) struct Geom {
    pub ox: Real,
    pub oy: Real,
    pub h: Real,
    pub lp: Real,
    pub ny: usize,
    pub simd: bool,
}

/// Whether this CPU runs the AVX2 transfers.
pub(super) fn simd_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

impl Geom {
    #[inline(always)]
    fn stencil(&self, p: &Point) -> Stencil {
        Stencil::at(p.x.x, p.x.y, p.base, self.ox, self.oy, self.h, self.lp)
    }

    /// Scatter the points `idx` (in that order) onto `chunk`, the node columns from `col0` on.
    /// `FULL`: mass, momentum, internal force −V σ ∇φ and gravity `g`; otherwise momentum only.
    pub fn scatter<const FULL: bool>(
        &self,
        chunk: &mut [Node],
        col0: usize,
        points: &[Point],
        idx: impl Iterator<Item = usize>,
        g: Real,
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.simd {
            // SAFETY: `simd` is only set when the CPU has AVX2 (`simd_available`).
            unsafe { avx2::scatter::<FULL>(self, chunk, col0, points, idx, g) };
            return;
        }
        let ny = self.ny;
        for pi in idx {
            let p = &points[pi];
            let st = self.stencil(p);
            let m = p.mass;
            let mv = p.v * m;
            let (vxx, vyy, vxy) = (-p.vol * p.stress.xx, -p.vol * p.stress.yy, -p.vol * p.stress.xy);
            let mg = -m * g;
            for a in 0..3 {
                let base = (st.i0 + a - col0) * ny + st.j0;
                let (wa, da) = (st.wx[a], st.dx[a]);
                let column = &mut chunk[base..base + 3];
                for (bb, n) in column.iter_mut().enumerate() {
                    let w = wa * st.wy[bb];
                    let gx = da * st.wy[bb];
                    let gy = wa * st.dy[bb];
                    n.p += mv * w;
                    if FULL {
                        n.m += w * m;
                        n.f.x += vxx * gx + vxy * gy;
                        n.f.y += vxy * gx + vyy * gy + w * mg;
                    }
                }
            }
        }
    }

    /// Gather at every point of `points`. `VEL`: FLIP/PIC velocity update with fraction
    /// `flip` and the step displacement Δx = Δt Σ φ v*; `GRAD`: the velocity gradient
    /// L = Σ v* ⊗ ∇φ.
    pub fn gather<const VEL: bool, const GRAD: bool>(
        &self,
        points: &mut [Point],
        nodes: &[Node],
        flip: Real,
        dt: Real,
    ) {
        #[cfg(target_arch = "x86_64")]
        if self.simd {
            // SAFETY: `simd` is only set when the CPU has AVX2 (`simd_available`).
            unsafe { avx2::gather::<VEL, GRAD>(self, points, nodes, flip, dt) };
            return;
        }
        let ny = self.ny;
        for p in points {
            let st = self.stencil(p);
            let mut vg = Vec2::zeros();
            let mut dv = Vec2::zeros();
            let mut l = Mat2::zeros();
            for a in 0..3 {
                let base = (st.i0 + a) * ny + st.j0;
                for (b, n) in nodes[base..base + 3].iter().enumerate() {
                    if VEL {
                        let w = st.wx[a] * st.wy[b];
                        vg += n.v * w;
                        dv += n.dv * w;
                    }
                    if GRAD {
                        let gx = st.dx[a] * st.wy[b];
                        let gy = st.wx[a] * st.dy[b];
                        l[(0, 0)] += n.v.x * gx;
                        l[(0, 1)] += n.v.x * gy;
                        l[(1, 0)] += n.v.y * gx;
                        l[(1, 1)] += n.v.y * gy;
                    }
                }
            }
            finish::<VEL, GRAD>(p, vg, dv, l, flip, dt);
        }
    }
}

/// Point update from the gathered sums (shared by both paths).
#[inline(always)]
fn finish<const VEL: bool, const GRAD: bool>(p: &mut Point, vg: Vec2, dv: Vec2, l: Mat2, flip: Real, dt: Real) {
    if VEL {
        p.v = (p.v + dv) * flip + vg * (1.0 - flip);
        p.dx = vg * dt;
    }
    if GRAD {
        p.grad_v = l;
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{Geom, Node, Point, Real, finish};
    use crate::math::{Mat2, Vec2};
    use std::arch::x86_64::*;

    // Offsets (in f64) of the node fields; `Node` is `repr(C)`: m, p, f, v, Δv.
    const P: usize = 1;
    const V: usize = 5;
    const _: () = assert!(std::mem::size_of::<Node>() == 9 * 8);
    const _: () = assert!(std::mem::offset_of!(Node, p) == P * 8 && std::mem::offset_of!(Node, f) == (P + 2) * 8);
    const _: () = assert!(std::mem::offset_of!(Node, v) == V * 8 && std::mem::offset_of!(Node, dv) == (V + 2) * 8);

    /// Lanes: [p.x, p.y, f.x, f.y] += [mv.x w, mv.y w, vxx gx + vxy gy, (vxy gx + vyy gy) + w mg],
    /// m += w m; the products and sums of the scalar code, each in its order.
    ///
    /// # Safety
    /// The CPU has AVX2 (the node accesses are bounds-checked here, once per stencil).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn scatter<const FULL: bool>(
        geo: &Geom,
        chunk: &mut [Node],
        col0: usize,
        points: &[Point],
        idx: impl Iterator<Item = usize>,
        g: Real,
    ) {
        let ny = geo.ny;
        for pi in idx {
            let p = &points[pi];
            let st = geo.stencil(p);
            let m = p.mass;
            let mv = p.v * m;
            let (vxx, vyy, vxy) = (-p.vol * p.stress.xx, -p.vol * p.stress.yy, -p.vol * p.stress.xy);
            let mg = -m * g;
            let q = _mm256_setr_pd(mv.x, mv.y, vxx, vxy);
            let s = _mm256_setr_pd(0.0, 0.0, vxy, vyy);
            let mgv = _mm256_setr_pd(0.0, 0.0, 0.0, mg);
            let wy = [
                _mm256_set1_pd(st.wy[0]),
                _mm256_set1_pd(st.wy[1]),
                _mm256_set1_pd(st.wy[2]),
            ];
            let dy = [
                _mm256_set1_pd(st.dy[0]),
                _mm256_set1_pd(st.dy[1]),
                _mm256_set1_pd(st.dy[2]),
            ];
            // One bounds check for the whole 3 × 3 stencil (columns ny nodes apart).
            let base = (st.i0 - col0) * ny + st.j0;
            assert!(base + 2 * ny + 3 <= chunk.len(), "stencil outside the band's nodes");
            let n0 = chunk.as_mut_ptr() as *mut Real;
            for a in 0..3 {
                // SAFETY: column a's 3 nodes lie inside `chunk` (checked above).
                let np = unsafe { n0.add(9 * (base + a * ny)) };
                let wxa = _mm256_set1_pd(st.wx[a]);
                // [w, w, gx, gx] = [wx_a, wx_a, dx_a, dx_a] · wy_b
                let aw = _mm256_setr_pd(st.wx[a], st.wx[a], st.dx[a], st.dx[a]);
                for b in 0..3 {
                    // SAFETY: node b of column a (bounds checked above); P..P+4 and 0 lie
                    // inside the node (offsets asserted above).
                    unsafe {
                        let n = np.add(9 * b);
                        let w4 = _mm256_mul_pd(aw, wy[b]);
                        let mut inc = _mm256_mul_pd(q, w4);
                        if FULL {
                            let gy = _mm256_mul_pd(wxa, dy[b]);
                            let ww = _mm256_mul_pd(wxa, wy[b]);
                            inc = _mm256_blend_pd::<0b1100>(inc, _mm256_add_pd(inc, _mm256_mul_pd(s, gy)));
                            inc = _mm256_blend_pd::<0b1000>(inc, _mm256_add_pd(inc, _mm256_mul_pd(mgv, ww)));
                            let cur = _mm256_loadu_pd(n.add(P));
                            _mm256_storeu_pd(n.add(P), _mm256_add_pd(cur, inc));
                            *n += _mm_cvtsd_f64(_mm256_castpd256_pd128(ww)) * m;
                        } else {
                            let cur = _mm_loadu_pd(n.add(P));
                            _mm_storeu_pd(n.add(P), _mm_add_pd(cur, _mm256_castpd256_pd128(inc)));
                        }
                    }
                }
            }
        }
    }

    /// Lanes: [vg.x, vg.y, Δv.x, Δv.y] += [v.x, v.y, Δv.x, Δv.y] w and
    /// [L00, L01, L10, L11] += [v.x, v.x, v.y, v.y] [gx, gy, gx, gy].
    ///
    /// # Safety
    /// The CPU has AVX2 (the node accesses are bounds-checked here, once per stencil).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn gather<const VEL: bool, const GRAD: bool>(
        geo: &Geom,
        points: &mut [Point],
        nodes: &[Node],
        flip: Real,
        dt: Real,
    ) {
        let ny = geo.ny;
        for p in points {
            let st = geo.stencil(p);
            let wy = [
                _mm256_set1_pd(st.wy[0]),
                _mm256_set1_pd(st.wy[1]),
                _mm256_set1_pd(st.wy[2]),
            ];
            let yd = [
                _mm256_setr_pd(st.wy[0], st.dy[0], st.wy[0], st.dy[0]),
                _mm256_setr_pd(st.wy[1], st.dy[1], st.wy[1], st.dy[1]),
                _mm256_setr_pd(st.wy[2], st.dy[2], st.wy[2], st.dy[2]),
            ];
            let mut acc = _mm256_setzero_pd();
            let mut lacc = _mm256_setzero_pd();
            let base = st.i0 * ny + st.j0;
            assert!(base + 2 * ny + 3 <= nodes.len(), "stencil outside the grid");
            let n0 = nodes.as_ptr() as *const Real;
            for a in 0..3 {
                // SAFETY: column a's 3 nodes lie inside `nodes` (checked above).
                let np = unsafe { n0.add(9 * (base + a * ny)) };
                let wxa = _mm256_set1_pd(st.wx[a]);
                let da = _mm256_setr_pd(st.dx[a], st.wx[a], st.dx[a], st.wx[a]);
                for b in 0..3 {
                    // SAFETY: node b of column a (checked above); V..V+4 lies inside the node.
                    let nv = unsafe { _mm256_loadu_pd(np.add(9 * b + V)) };
                    if VEL {
                        let w = _mm256_mul_pd(wxa, wy[b]);
                        acc = _mm256_add_pd(acc, _mm256_mul_pd(nv, w));
                    }
                    if GRAD {
                        let gr = _mm256_mul_pd(da, yd[b]);
                        let vv = _mm256_permute4x64_pd::<0b01_01_00_00>(nv);
                        lacc = _mm256_add_pd(lacc, _mm256_mul_pd(vv, gr));
                    }
                }
            }
            let mut s = [0.0; 4];
            let mut l = [0.0; 4];
            // SAFETY: four f64 each.
            unsafe {
                _mm256_storeu_pd(s.as_mut_ptr(), acc);
                _mm256_storeu_pd(l.as_mut_ptr(), lacc);
            }
            finish::<VEL, GRAD>(
                p,
                Vec2::new(s[0], s[1]),
                Vec2::new(s[2], s[3]),
                Mat2::new(l[0], l[1], l[2], l[3]),
                flip,
                dt,
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mpm::shape::first_node;
    use rand::{RngExt, SeedableRng};

    fn bits(x: &[Real]) -> Vec<u64> {
        x.iter().map(|v| v.to_bits()).collect()
    }

    /// Random points (some with exactly zero or −0 velocity and stress) on a 12 × 12 grid,
    /// random nodal velocities; scatter and gather with both paths, compare every bit.
    #[test]
    fn transfer_simd_matches_scalar() {
        if !simd_available() {
            eprintln!("no AVX2: nothing to compare");
            return;
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (h, ny, nx) = (2e-3, 12usize, 12usize);
        for lp in [h / 8.0, h / 4.0, 0.0] {
            let scalar = Geom {
                ox: -0.004,
                oy: 0.001,
                h,
                lp,
                ny,
                simd: false,
            };
            let simd = Geom { simd: true, ..scalar };
            let mut pts: Vec<Point> = (0..300)
                .map(|i| {
                    let x = Vec2::new(
                        scalar.ox + h * (2.0 + 7.0 * rng.random::<Real>()),
                        scalar.oy + h * (2.0 + 7.0 * rng.random::<Real>()),
                    );
                    let mut p = Point::new(i, x, 0.25 * h * h, 2500.0);
                    let mut r = |k: u32| match (i + k) % 5 {
                        0 => 0.0,
                        1 => -0.0,
                        _ => rng.random::<Real>() * 2.0 - 1.0,
                    };
                    p.v = Vec2::new(r(0), r(1));
                    p.stress.xx = 1e3 * r(2);
                    p.stress.yy = 1e3 * r(3);
                    p.stress.xy = 1e3 * r(4);
                    p.vol *= 1.0 + 0.01 * r(0);
                    let l = lp / h;
                    p.base = [
                        first_node((x.x - scalar.ox) / h, l) as u32,
                        first_node((x.y - scalar.oy) / h, l) as u32,
                    ];
                    p
                })
                .collect();
            let idx: Vec<usize> = (0..pts.len()).rev().collect();
            for full in [true, false] {
                let mut grids = [vec![Node::default(); nx * ny], vec![Node::default(); nx * ny]];
                for (grid, geo) in grids.iter_mut().zip([scalar, simd]) {
                    if full {
                        geo.scatter::<true>(grid, 0, &pts, idx.iter().copied(), 9.81);
                    } else {
                        geo.scatter::<false>(grid, 0, &pts, idx.iter().copied(), 9.81);
                    }
                }
                let flat = |g: &[Node]| {
                    g.iter()
                        .flat_map(|n| [n.m, n.p.x, n.p.y, n.f.x, n.f.y])
                        .collect::<Vec<_>>()
                };
                assert_eq!(
                    bits(&flat(&grids[0])),
                    bits(&flat(&grids[1])),
                    "scatter, lp {lp}, full {full}"
                );
                assert!(grids[0].iter().any(|n| n.f.y != 0.0) == full);
            }
            let mut nodes = vec![Node::default(); nx * ny];
            for (k, n) in nodes.iter_mut().enumerate() {
                let mut r = || if k % 7 == 0 { -0.0 } else { rng.random::<Real>() - 0.5 };
                n.v = Vec2::new(r(), r());
                n.dv = Vec2::new(r(), r());
            }
            let run = |geo: Geom, pts: &mut Vec<Point>, mode: u8| match mode {
                0 => geo.gather::<true, true>(pts, &nodes, 0.99, 1e-6),
                1 => geo.gather::<true, false>(pts, &nodes, 0.99, 1e-6),
                _ => geo.gather::<false, true>(pts, &nodes, 0.99, 1e-6),
            };
            for mode in 0..3 {
                let (mut a, mut b) = (pts.clone(), pts.clone());
                run(scalar, &mut a, mode);
                run(simd, &mut b, mode);
                let flat = |ps: &[Point]| {
                    ps.iter()
                        .flat_map(|p| {
                            [
                                p.v.x,
                                p.v.y,
                                p.dx.x,
                                p.dx.y,
                                p.grad_v[(0, 0)],
                                p.grad_v[(0, 1)],
                                p.grad_v[(1, 0)],
                                p.grad_v[(1, 1)],
                            ]
                        })
                        .collect::<Vec<_>>()
                };
                assert_eq!(bits(&flat(&a)), bits(&flat(&b)), "gather, lp {lp}, mode {mode}");
                assert_ne!(flat(&a), flat(&pts), "gather changed nothing");
            }
            pts.truncate(0);
        }
    }
}

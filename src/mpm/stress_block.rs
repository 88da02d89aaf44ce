//! The constitutive update of the frictional models (Mohr–Coulomb and μ(I)) for a block of
//! material points at once, several points per vector instruction (SIMD across points).
//!
//! Per point the update is the one of `material` — kinematics J ← J det(I + Δt L), V = V_0 J,
//! density-scaled moduli, Jaumann elastic trial, the cheap elastic test, and the principal
//! return mapping of [`material::mohr_coulomb_plastic`] — rewritten without a branch on the
//! point's data: every candidate of the return (main face, the edge on the side the face
//! return overshot, apex, tension cut-off) is evaluated and the result is chosen by selects.
//! In a granular flow most points are plastic (79 % per step in the MPM benchmark, 61 % of
//! them to the compression edge) and the face-or-edge decision is close to random from point
//! to point, so the branchy return mispredicts about once per point and cannot overlap the
//! chains of divisions and square roots of consecutive points; here the points of a block
//! are loaded into lanes (structure of arrays) and one loop without branches runs over the
//! lanes, which the compiler turns into vector code.
//!
//! Bit-identical to the per-point functions: every lane performs the same IEEE operations in
//! the same order (no fused multiply–add; add, multiply, divide and square root are exactly
//! rounded at any vector width), so the build for AVX-512, AVX2 or the baseline's SSE2 gives
//! the same bits. `tests::block_update_is_bit_identical_to_the_per_point_update` checks it on
//! random points for every model and surface option.

use super::material::{Elastic, McSurface};
use super::params::Model;
use super::particles::Point;
use crate::math::Real;

/// Points per block (lanes of the loop).
pub(crate) const LANES: usize = 64;

/// `if c { a } else { b }` for floats, as a select (no branch): through the bit patterns,
/// which LLVM keeps a blend, where a float select of a division may become a branch again.
#[inline(always)]
fn sel(c: bool, a: Real, b: Real) -> Real {
    let m = (c as u64).wrapping_neg();
    Real::from_bits((a.to_bits() & m) | (b.to_bits() & !m))
}

/// Which friction law sets a point's surface.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Friction {
    /// Fixed φ (Mohr–Coulomb).
    Fixed,
    /// μ = μ_min + b I.
    Linear { mu_min: Real, b: Real },
    /// μ = μ_s + (μ_2 − μ_s)/(I_0/I + 1) (Jop et al.).
    Jop { mu_s: Real, mu_2: Real, i0: Real },
}

/// Everything a lane needs besides its point: the step, the undeformed moduli, the surface
/// and the μ(I) constants.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Consts {
    dt: Real,
    el: Elastic,
    mc: McSurface,
    friction: Friction,
    /// Mean grain diameter and grain density (inertial number).
    d: Real,
    rho_s: Real,
    i_max: Real,
}

impl Consts {
    /// Constants of the update of a frictional `model`; `None` for the elastic model.
    pub(crate) fn new(dt: Real, el: Elastic, mc: McSurface, model: &Model, d: Real, rho_s: Real, i_max: Real) -> Option<Self> {
        let friction = match *model {
            Model::MohrCoulomb => Friction::Fixed,
            Model::MuILinear { mu_min, b } => Friction::Linear { mu_min, b },
            Model::MuIJop { mu_s, mu_2, i0 } => Friction::Jop { mu_s, mu_2, i0 },
            Model::Elastic => return None,
        };
        Some(Self { dt, el, mc, friction, d, rho_s, i_max })
    }
}

/// One block of points in lanes (structure of arrays). Inputs: J, V_0, the velocity
/// gradient L and the stress; outputs in place (J, stress, ε_p, plastic work) and V, μ, I.
#[derive(Clone)]
struct Lanes {
    j: [Real; LANES],
    vol0: [Real; LANES],
    l: [[Real; LANES]; 4],
    s: [[Real; LANES]; 4],
    eps_p: [Real; LANES],
    work_p: [Real; LANES],
    vol: [Real; LANES],
    mu: [Real; LANES],
    inertial: [Real; LANES],
}

impl Default for Lanes {
    fn default() -> Self {
        // Unused lanes of a short block hold a point at rest with J = 1 (finite throughout).
        let (z, one) = ([0.0; LANES], [1.0; LANES]);
        Self { j: one, vol0: one, l: [z; 4], s: [z; 4], eps_p: z, work_p: z, vol: z, mu: z, inertial: z }
    }
}

/// Update the stress of `points` (kinematics and constitutive law) over the step of `k`.
pub(crate) fn update(points: &mut [Point], k: &Consts) {
    update_with(points, k, run)
}

/// [`update`] with a given build of the lane loop.
#[inline(always)]
fn update_with(points: &mut [Point], k: &Consts, run: impl Fn(&mut Lanes, &Consts)) {
    let mut b = Lanes::default();
    for block in points.chunks_mut(LANES) {
        for (i, p) in block.iter().enumerate() {
            b.j[i] = p.j;
            b.vol0[i] = p.vol0;
            b.l[0][i] = p.grad_v[(0, 0)];
            b.l[1][i] = p.grad_v[(0, 1)];
            b.l[2][i] = p.grad_v[(1, 0)];
            b.l[3][i] = p.grad_v[(1, 1)];
            b.s[0][i] = p.stress.xx;
            b.s[1][i] = p.stress.yy;
            b.s[2][i] = p.stress.xy;
            b.s[3][i] = p.stress.zz;
            b.eps_p[i] = p.eps_p;
            b.work_p[i] = p.work_p;
        }
        run(&mut b, k);
        let mui = k.friction != Friction::Fixed;
        for (i, p) in block.iter_mut().enumerate() {
            p.j = b.j[i];
            p.vol = b.vol[i];
            p.stress.xx = b.s[0][i];
            p.stress.yy = b.s[1][i];
            p.stress.xy = b.s[2][i];
            p.stress.zz = b.s[3][i];
            p.eps_p = b.eps_p[i];
            p.work_p = b.work_p[i];
            if mui {
                p.mu = b.mu[i];
                p.inertial = b.inertial[i];
            }
        }
    }
}

/// The lane loop, built for the widest vector unit the CPU has.
#[inline]
fn run(b: &mut Lanes, k: &Consts) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU has the feature
            return unsafe { run_avx512(b, k) };
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has the feature
            return unsafe { run_avx2(b, k) };
        }
    }
    run_lanes(b, k)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline(never)]
unsafe fn run_avx512(b: &mut Lanes, k: &Consts) {
    run_lanes(b, k)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline(never)]
unsafe fn run_avx2(b: &mut Lanes, k: &Consts) {
    run_lanes(b, k)
}

/// Plain `for` loops: an iterator adaptor (`for_each`) is a call to a generic `fold` that
/// is not built with the caller's target features, and the loop would stay scalar.
#[inline(always)]
fn run_lanes(b: &mut Lanes, k: &Consts) {
    match k.friction {
        Friction::Fixed => {
            for i in 0..LANES {
                lane::<0>(b, i, k);
            }
        }
        Friction::Linear { .. } => {
            for i in 0..LANES {
                lane::<1>(b, i, k);
            }
        }
        Friction::Jop { .. } => {
            for i in 0..LANES {
                lane::<2>(b, i, k);
            }
        }
    }
}

#[inline(always)]
fn dot3(a: [Real; 3], b: [Real; 3]) -> Real {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The update of lane `i`. `F`: 0 fixed friction, 1 linear μ(I), 2 Jop μ(I). Each
/// expression is written as in `material` (and `solver::Kernel::update_stress`), so the
/// operations and their order are those of the per-point code.
#[inline(always)]
fn lane<const F: u8>(b: &mut Lanes, i: usize, k: &Consts) {
    let dt = k.dt;
    let (l00, l01, l10, l11) = (b.l[0][i], b.l[1][i], b.l[2][i], b.l[3][i]);
    let (sxx, syy, sxy, szz) = (b.s[0][i], b.s[1][i], b.s[2][i], b.s[3][i]);

    // Kinematics: J ← J det(I + Δt L) (nalgebra's 2 × 2 determinant m11 m22 − m21 m12),
    // V = V_0 J, moduli scaled by 1/J.
    let (m11, m12, m21, m22) = (1.0 + l00 * dt, 0.0 + l01 * dt, 0.0 + l10 * dt, 1.0 + l11 * dt);
    let j = b.j[i] * (m11 * m22 - m21 * m12);
    b.j[i] = j;
    b.vol[i] = b.vol0[i] * j;
    let kj = 1.0 / j;
    let (g, lambda, inv_young) = (k.el.g * kj, k.el.lambda * kj, k.el.inv_young * j);

    // Friction of the point: fixed, or μ(I) from the inertial number of the stress at the
    // start of the step (`material::shear_rate`, `inertial_number`, `mu_of_i`,
    // `McSurface::with_mu`).
    let (sf, cf) = if F == 0 {
        (k.mc.sin_phi, k.mc.cos_phi)
    } else {
        let dxx = l00;
        let dyy = l11;
        let dxy = 0.5 * (l01 + l10);
        let m = (dxx + dyy) / 3.0;
        let dd = (dxx - m) * (dxx - m) + (dyy - m) * (dyy - m) + m * m + 2.0 * dxy * dxy;
        let gd = (2.0 * dd).sqrt();
        let p = -(sxx + syy + szz) / 3.0;
        let ip = gd * k.d / (p / k.rho_s).sqrt();
        let ip = sel(ip < k.i_max, ip, k.i_max); // f64::min, NaN → i_max as well
        let inertial = sel(p <= 0.0, sel(gd > 0.0, k.i_max, 0.0), ip);
        let mu = match k.friction {
            Friction::Linear { mu_min, b } => mu_min + b * inertial,
            Friction::Jop { mu_s, mu_2, i0 } => sel(inertial > 0.0, mu_s + (mu_2 - mu_s) / (i0 / inertial + 1.0), mu_s),
            Friction::Fixed => 0.0,
        };
        b.inertial[i] = inertial;
        b.mu[i] = mu;
        let r = 1.0 / (1.0 + mu * mu).sqrt();
        (mu * r, r)
    };
    let yield_fn = |s1: Real, s3: Real| (s1 - s3) + (s1 + s3) * sf - 2.0 * k.mc.cohesion * cf;

    // Jaumann elastic trial (`material::elastic_trial`).
    let exx = l00 * dt;
    let eyy = l11 * dt;
    let exy = 0.5 * (l01 + l10) * dt;
    let w = 0.5 * (l10 - l01) * dt;
    let tr = exx + eyy;
    let txx = sxx - 2.0 * w * sxy + lambda * tr + 2.0 * g * exx;
    let tyy = syy + 2.0 * w * sxy + lambda * tr + 2.0 * g * eyy;
    let txy = sxy + w * (sxx - syy) + 2.0 * g * exy;
    let tzz = szz + lambda * tr;

    // Cheap elastic test (`material::mc_elastic_test`).
    let c0 = 0.5 * (txx + tyy);
    let hd = 0.5 * (txx - tyy);
    let r = (hd * hd + txy * txy).sqrt();
    let (a, bb, z) = (c0 + r, c0 - r, tzz);
    let (s1, s3) = (sel(a > z, a, z), sel(bb < z, bb, z));
    let elastic_trial = (yield_fn(s1, s3) <= 0.0) & (s1 <= k.mc.tension_cutoff);

    // Return mapping (`material::mohr_coulomb_plastic`), every candidate. Sorted trial:
    // z ≥ a → (z, a, b); z ≥ b → (a, z, b); else (a, b, z).
    let z_top = z >= a;
    let z_mid = !z_top & (z >= bb);
    let z_up = z_top | z_mid;
    let st = [sel(z_top, z, a), sel(z_top, a, sel(z_mid, z, bb)), sel(z_up, bb, z)];
    let (abs0, abs2) = (st[0].abs(), st[2].abs());
    let scale = sel(abs0 > abs2, abs0, abs2);
    let scale = sel(scale > k.mc.cohesion, scale, k.mc.cohesion) + 1e-300;
    let tol = 1e-12 * scale;
    let fa = yield_fn(st[0], st[2]);
    let elastic_ret = fa <= tol;
    let sp = k.mc.sin_psi;
    let d_times = |n: [Real; 3]| {
        let t = lambda * (n[0] + n[1] + n[2]);
        [t + 2.0 * g * n[0], t + 2.0 * g * n[1], t + 2.0 * g * n[2]]
    };
    // Main plane (1, 3).
    let nf_a = [1.0 + sf, 0.0, -(1.0 - sf)];
    let da = d_times([1.0 + sp, 0.0, -(1.0 - sp)]);
    let gam = fa / dot3(nf_a, da);
    let face = [st[0] - gam * da[0], st[1] - gam * da[1], st[2] - gam * da[2]];
    let on_face = (face[0] >= face[1]) & (face[1] >= face[2]);
    // Edge: σ2 overtook σ1 → edge σ1 = σ2, plane (2, 3); else σ2 = σ3, plane (1, 2).
    let comp = face[1] > face[0];
    let nf_b = [sel(comp, 0.0, 1.0 + sf), sel(comp, 1.0 + sf, -(1.0 - sf)), sel(comp, -(1.0 - sf), 0.0)];
    let ng_b = [sel(comp, 0.0, 1.0 + sp), sel(comp, 1.0 + sp, -(1.0 - sp)), sel(comp, -(1.0 - sp), 0.0)];
    let fb = yield_fn(sel(comp, st[1], st[0]), sel(comp, st[2], st[1]));
    let db = d_times(ng_b);
    let (a11, a12, a21, a22) = (dot3(nf_a, da), dot3(nf_a, db), dot3(nf_b, da), dot3(nf_b, db));
    let det = a11 * a22 - a12 * a21;
    let ga = (a22 * fa - a12 * fb) / det;
    let gb = (a11 * fb - a21 * fa) / det;
    let edge = [
        st[0] - ga * da[0] - gb * db[0],
        st[1] - ga * da[1] - gb * db[1],
        st[2] - ga * da[2] - gb * db[2],
    ];
    let edge_ok = (ga >= 0.0) & (gb >= 0.0) & (edge[0] >= edge[2] - tol) & (det.abs() > 0.0);
    // Apex c cot φ (0 without cohesion).
    let apex = sel(k.mc.cohesion == 0.0, 0.0, k.mc.cohesion * cf / sf);
    let pick = |n: usize| sel(on_face, face[n], sel(edge_ok, edge[n], apex));
    let is_apex = !elastic_ret & !on_face & !edge_ok;
    let mut so = [sel(elastic_ret, st[0], pick(0)), sel(elastic_ret, st[1], pick(1)), sel(elastic_ret, st[2], pick(2))];
    // Rankine tension cut-off (round-off above it clipped silently).
    let t = k.mc.tension_cutoff;
    let clip = so[0] > t;
    let tension = clip & (so[0] - t > tol) & !is_apex;
    for v in so.iter_mut() {
        *v = sel(clip & (*v > t), t, *v);
    }
    // What the per-point return calls elastic (the trial is kept, even if clipped within
    // round-off), and whether it returned to the main face.
    let unchanged = elastic_ret & !tension;
    let is_face = !elastic_ret & on_face & !tension;
    // Plastic strain increment: on the face γ n_g; otherwise from the stress correction.
    let pw_face = gam * ((1.0 + sp) * so[0] - (1.0 - sp) * so[2]);
    let ep_face = gam * k.mc.face_eq;
    let (d0, d1, d2) = (st[0] - so[0], st[1] - so[1], st[2] - so[2]);
    let trd = d0 + d1 + d2;
    let nu = k.el.poisson;
    let de = [
        inv_young * ((1.0 + nu) * d0 - nu * trd),
        inv_young * ((1.0 + nu) * d1 - nu * trd),
        inv_young * ((1.0 + nu) * d2 - nu * trd),
    ];
    let m = (de[0] + de[1] + de[2]) / 3.0;
    let dev2 = (de[0] - m) * (de[0] - m) + (de[1] - m) * (de[1] - m) + (de[2] - m) * (de[2] - m);
    let (pw_gen, ep_gen) = (dot3(so, de), (2.0 / 3.0 * dev2).sqrt());
    let plastic_work = sel(unchanged, 0.0, sel(is_face, pw_face, pw_gen));
    let d_eps_p = sel(unchanged, 0.0, sel(is_face, ep_face, ep_gen));
    // Back to the (a, b, z) order and the in-plane frame (coaxial with the trial).
    let s = [sel(z_top, so[1], so[0]), sel(z_up, so[2], so[1]), sel(z_top, so[0], sel(z_mid, so[1], so[2]))];
    let ir = 1.0 / r;
    let pos = r > 0.0;
    let (c2, s2) = (sel(pos, hd * ir, 1.0), sel(pos, txy * ir, 0.0));
    let cn = 0.5 * (s[0] + s[1]);
    let rn = 0.5 * (s[0] - s[1]);
    let keep = elastic_trial | unchanged;
    b.s[0][i] = sel(keep, txx, cn + rn * c2);
    b.s[1][i] = sel(keep, tyy, cn - rn * c2);
    b.s[2][i] = sel(keep, txy, rn * s2);
    b.s[3][i] = sel(keep, tzz, s[2]);
    // Points that passed the elastic test keep ε_p and the work untouched; the others add
    // the increment (zero when the return found them elastic), as the per-point code does.
    let vol = b.vol[i];
    b.eps_p[i] = sel(elastic_trial, b.eps_p[i], b.eps_p[i] + d_eps_p);
    b.work_p[i] = sel(elastic_trial, b.work_p[i], b.work_p[i] + plastic_work * vol);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Mat2, Vec2};
    use crate::mpm::material::{self, Elastic, McSurface};
    use crate::mpm::particles::Stress;
    use rand::{RngExt, SeedableRng};

    /// The per-point update as `solver::Kernel::update_stress` did it before blocks:
    /// kinematics, μ(I) surface, elastic trial, `material::mohr_coulomb`.
    fn per_point(p: &mut Point, k: &Consts, model: &Model) -> material::Region {
        let j = p.j * (Mat2::identity() + p.grad_v * k.dt).determinant();
        p.j = j;
        p.vol = p.vol0 * j;
        let el = k.el.scaled_by_jacobian(j);
        let mut surf = k.mc;
        if !matches!(model, Model::MohrCoulomb) {
            let gd = material::shear_rate(&p.grad_v);
            let i = material::inertial_number(gd, p.stress.pressure(), k.d, k.rho_s, k.i_max);
            let mu = material::mu_of_i(model, i).unwrap_or(0.0);
            p.inertial = i;
            p.mu = mu;
            surf = surf.with_mu(mu);
        }
        let tr = material::elastic_trial(&p.stress, &p.grad_v, k.dt, &el);
        let (elastic, _) = material::mc_elastic_test(&tr, &surf);
        let u = material::mohr_coulomb(tr, &el, &surf);
        p.stress = u.stress;
        if !elastic {
            p.eps_p += u.d_eps_p;
            p.work_p += u.plastic_work * p.vol;
        }
        u.region
    }

    type Build = fn(&mut Lanes, &Consts);

    /// The builds of the lane loop: baseline, and AVX2 and AVX-512 where the CPU has them.
    fn builds() -> Vec<(&'static str, Build)> {
        let mut v: Vec<(&'static str, Build)> = vec![("baseline", run_lanes)];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: only called on a CPU with the feature
                v.push(("avx2", |b, k| unsafe { run_avx2(b, k) }));
            }
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: only called on a CPU with the feature
                v.push(("avx512", |b, k| unsafe { run_avx512(b, k) }));
            }
        }
        v
    }

    fn bits(p: &Point) -> Vec<u64> {
        [p.j, p.vol, p.stress.xx, p.stress.yy, p.stress.xy, p.stress.zz, p.eps_p, p.work_p, p.mu, p.inertial]
            .iter()
            .map(|v| v.to_bits())
            .collect()
    }

    #[test]
    fn block_update_is_bit_identical_to_the_per_point_update() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let el = Elastic::new(1e6, 0.3);
        let models = [
            Model::MohrCoulomb,
            Model::MuILinear { mu_min: 0.4, b: 1.0 },
            Model::MuIJop { mu_s: 0.38, mu_2: 0.64, i0: 0.279 },
        ];
        let surfaces = [
            McSurface::from_degrees(30.0, 0.0, 0.0, 0.0),
            McSurface::from_degrees(25.0, 5.0, 0.0, 0.0),
            McSurface::from_degrees(35.0, 0.0, 200.0, 50.0),
            McSurface::from_degrees(30.0, 10.0, 50.0, Real::INFINITY),
        ];
        use material::Region;
        let mut regions = std::collections::HashMap::<String, usize>::new();
        for model in &models {
            for mc in &surfaces {
                let k = Consts::new(1e-5, el, *mc, model, 1e-3, 2500.0, 1.0).unwrap();
                // 4000 random points (not a multiple of the block), stresses from tension to
                // compression, gradients from quasi-static to violent, some exactly at rest.
                let mut pts: Vec<Point> = (0..4000)
                    .map(|n| {
                        let mut p = Point::new(n, Vec2::zeros(), 1e-6, 2000.0);
                        let s = 10f64.powf(rng.random_range(1.0..4.0));
                        p.stress = Stress {
                            xx: s * rng.random_range(-1.0..0.3),
                            yy: s * rng.random_range(-1.0..0.3),
                            xy: s * rng.random_range(-0.6..0.6),
                            zz: s * rng.random_range(-1.0..0.3),
                        };
                        let g = 10f64.powf(rng.random_range(-2.0..2.5));
                        p.grad_v = Mat2::new(
                            g * rng.random_range(-1.0..1.0),
                            g * rng.random_range(-1.0..1.0),
                            g * rng.random_range(-1.0..1.0),
                            g * rng.random_range(-1.0..1.0),
                        );
                        p.j = rng.random_range(0.8..1.5);
                        p.eps_p = rng.random_range(0.0..0.1);
                        p.work_p = rng.random_range(0.0..1e-3);
                        if n % 97 == 0 {
                            p.grad_v = Mat2::zeros();
                            p.stress = Stress::default();
                        }
                        p
                    })
                    .collect();
                let mut want = pts.clone();
                for p in &mut want {
                    *regions.entry(format!("{:?}", per_point(p, &k, model))).or_default() += 1;
                }
                // every build of the lane loop this CPU can run, and the dispatching one
                for (name, build) in builds() {
                    let mut got = pts.clone();
                    update_with(&mut got, &k, build);
                    for (n, (p, w)) in got.iter().zip(&want).enumerate() {
                        assert_eq!(bits(p), bits(w), "{name}: {model:?} {mc:?} point {n}: {p:?} vs {w:?}");
                    }
                }
                update(&mut pts, &k);
                for (n, (p, w)) in pts.iter().zip(&want).enumerate() {
                    assert_eq!(bits(p), bits(w), "update: {model:?} {mc:?} point {n}: {p:?} vs {w:?}");
                }
            }
        }
        // the random set exercises every region of the return
        for r in [Region::Elastic, Region::Face, Region::EdgeCompression, Region::EdgeExtension, Region::Apex, Region::Tension] {
            assert!(regions.get(&format!("{r:?}")).copied().unwrap_or(0) >= 100, "{r:?} rarely reached: {regions:?}");
        }
    }
}

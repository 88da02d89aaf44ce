//! The constitutive update of the frictional models (Mohr–Coulomb and μ(I)) for a block of
//! material points at once, several points per vector instruction (SIMD across points).
//!
//! Per point the update is the one of `material` — kinematics J ← J det(I + Δt L), V = V_0 J,
//! density-scaled moduli, Jaumann elastic trial, the cheap elastic test and the return
//! mapping [`material::mohr_coulomb_plastic`], which has no branch on the point's data
//! (every candidate evaluated, the result chosen by selects). The points of a block are
//! loaded into lanes (structure of arrays) and one loop without branches calls those
//! functions lane by lane, which the compiler turns into vector code.
//!
//! Bit-identical to one call per point: every lane performs the same IEEE operations in the
//! same order (no fused multiply–add; add, multiply, divide and square root are exactly
//! rounded at any vector width), so the build for AVX-512, AVX2 or the baseline's SSE2 gives
//! the same bits. `tests::block_update_is_bit_identical_to_the_per_point_update` checks it on
//! random points for every model and surface option.

use super::material::{self, Elastic, McSurface};
use super::params::Model;
use super::particles::Point;
use super::particles::Stress;
use crate::math::{Mat2, Real, select};

/// Points per block (lanes of the loop).
pub(crate) const LANES: usize = 64;

/// Everything a lane needs besides its point: the step, the undeformed moduli, the surface
/// and the μ(I) constants.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Consts {
    dt: Real,
    el: Elastic,
    mc: McSurface,
    model: Model,
    /// Mean grain diameter and grain density (inertial number).
    d: Real,
    rho_s: Real,
    i_max: Real,
}

impl Consts {
    /// Constants of the update of a frictional `model`; `None` for the elastic model.
    pub(crate) fn new(
        dt: Real,
        el: Elastic,
        mc: McSurface,
        model: &Model,
        d: Real,
        rho_s: Real,
        i_max: Real,
    ) -> Option<Self> {
        match model {
            Model::Elastic => None,
            _ => Some(Self {
                dt,
                el,
                mc,
                model: *model,
                d,
                rho_s,
                i_max,
            }),
        }
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
        Self {
            j: one,
            vol0: one,
            l: [z; 4],
            s: [z; 4],
            eps_p: z,
            work_p: z,
            vol: z,
            mu: z,
            inertial: z,
        }
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
        let mui = k.model != Model::MohrCoulomb;
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

/// [`run_lanes`] built for AVX-512.
///
/// # Safety
/// The CPU has AVX-512F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline(never)]
unsafe fn run_avx512(b: &mut Lanes, k: &Consts) {
    run_lanes(b, k)
}

/// [`run_lanes`] built for AVX2.
///
/// # Safety
/// The CPU has AVX2.
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
    match k.model {
        Model::MohrCoulomb => {
            for i in 0..LANES {
                lane::<0>(b, i, k);
            }
        }
        Model::MuILinear { .. } => {
            for i in 0..LANES {
                lane::<1>(b, i, k);
            }
        }
        Model::MuIJop { .. } => {
            for i in 0..LANES {
                lane::<2>(b, i, k);
            }
        }
        Model::Elastic => {}
    }
}

/// The update of lane `i`: the per-point `material` functions (all branch-free or reduced
/// to selects), so the lanes compute exactly what one call per point computes. `F`: 0 fixed
/// friction, 1 linear μ(I), 2 Jop μ(I).
#[inline(always)]
fn lane<const F: u8>(b: &mut Lanes, i: usize, k: &Consts) {
    let dt = k.dt;
    let l = Mat2::new(b.l[0][i], b.l[1][i], b.l[2][i], b.l[3][i]);
    let s = Stress {
        xx: b.s[0][i],
        yy: b.s[1][i],
        xy: b.s[2][i],
        zz: b.s[3][i],
    };
    // Kinematics: J ← J det(I + Δt L), V = V_0 J, moduli scaled by 1/J.
    let j = b.j[i] * (Mat2::identity() + l * dt).determinant();
    b.j[i] = j;
    b.vol[i] = b.vol0[i] * j;
    let el = k.el.scaled_by_jacobian(j);
    // Friction of the point: fixed, or μ(I) from the inertial number of the stress at the
    // start of the step.
    let surf = if F == 0 {
        k.mc
    } else {
        let gd = material::shear_rate(&l);
        let inertial = material::inertial_number(gd, s.pressure(), k.d, k.rho_s, k.i_max);
        let mu = material::mu_of_i(&k.model, inertial).unwrap_or(0.0);
        b.inertial[i] = inertial;
        b.mu[i] = mu;
        k.mc.with_mu(mu)
    };
    let tr = material::elastic_trial(&s, &l, dt, &el);
    let (elastic, r) = material::mc_elastic_test(&tr, &surf);
    let u = material::mohr_coulomb_plastic(tr, &el, &surf, r);
    b.s[0][i] = select(elastic, tr.xx, u.stress.xx);
    b.s[1][i] = select(elastic, tr.yy, u.stress.yy);
    b.s[2][i] = select(elastic, tr.xy, u.stress.xy);
    b.s[3][i] = select(elastic, tr.zz, u.stress.zz);
    // Points that passed the elastic test keep ε_p and the work untouched; the others add
    // the increment (zero when the return found them elastic), as the per-point code does.
    let vol = b.vol[i];
    b.eps_p[i] = select(elastic, b.eps_p[i], b.eps_p[i] + u.d_eps_p);
    b.work_p[i] = select(elastic, b.work_p[i], b.work_p[i] + u.plastic_work * vol);
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
        [
            p.j, p.vol, p.stress.xx, p.stress.yy, p.stress.xy, p.stress.zz, p.eps_p, p.work_p, p.mu, p.inertial,
        ]
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
            Model::MuIJop {
                mu_s: 0.38,
                mu_2: 0.64,
                i0: 0.279,
            },
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
        for r in [
            Region::Elastic,
            Region::Face,
            Region::EdgeCompression,
            Region::EdgeExtension,
            Region::Apex,
            Region::Tension,
        ] {
            assert!(
                regions.get(&format!("{r:?}")).copied().unwrap_or(0) >= 100,
                "{r:?} rarely reached: {regions:?}"
            );
        }
    }
}

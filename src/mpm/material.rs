//! Constitutive update of one material point (pure functions, no solver state).
//!
//! - Objective rate: Jaumann (σ̇ = C:D + Wσ − σW), plane strain (D_zz = 0, σ_zz evolves).
//! - Linear isotropic elasticity (E, ν).
//! - Mohr–Coulomb, perfectly plastic, non-associated (ψ ≤ φ, chapter: ψ = 0), return mapping
//!   in principal stress space (de Souza Neto, Perić & Owen 2008, box 8.1, with the 3 × 3
//!   principal elastic matrix): main face → edge (two active planes) → apex, then a Rankine
//!   tension cut-off. With c = 0 the apex is the stress-free state; no regularisation is used.
//! - μ(I): the MC friction of each point is set each step from its inertial number
//!   I = γ̇ d̄/√(p/ρ_s), γ̇ = √(2 D':D') (3D deviator of the plane-strain rate), p = −tr σ/3
//!   (three-dimensional mean stress of the plane-strain state; docs/definitions.md D08).
//!
//! Tension positive throughout; principal values sorted σ1 ≥ σ2 ≥ σ3 (σ3 most compressive).
//! Yield function f = (σ1 − σ3) + (σ1 + σ3) sin φ − 2c cos φ.

use super::params::{Material, Model};
use super::particles::Stress;
use crate::math::{Mat2, Real, select};

/// Elastic constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Elastic {
    /// Young's modulus [Pa].
    pub young: Real,
    /// Poisson's ratio [-].
    pub poisson: Real,
    /// Shear modulus G [Pa].
    pub g: Real,
    /// Lamé λ [Pa].
    pub lambda: Real,
    /// 1/E [1/Pa].
    pub inv_young: Real,
}

impl Elastic {
    /// From E and ν.
    pub fn new(young: Real, poisson: Real) -> Self {
        let g = young / (2.0 * (1.0 + poisson));
        let lambda = young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
        Self {
            young,
            poisson,
            g,
            lambda,
            inv_young: 1.0 / young,
        }
    }
    /// Moduli divided by the Jacobian `j` (density-scaled moduli, see `solver.rs`).
    #[inline(always)]
    pub fn scaled_by_jacobian(&self, j: Real) -> Self {
        let k = 1.0 / j;
        Self {
            young: self.young * k,
            poisson: self.poisson,
            g: self.g * k,
            lambda: self.lambda * k,
            inv_young: self.inv_young * j,
        }
    }
    /// Moduli multiplied by `k` (ν unchanged).
    #[inline]
    pub fn scaled(&self, k: Real) -> Self {
        Self {
            young: self.young * k,
            poisson: self.poisson,
            g: self.g * k,
            lambda: self.lambda * k,
            inv_young: self.inv_young / k,
        }
    }
    /// Elastic strain of a principal stress triple: ε_i = ((1+ν)σ_i − ν tr σ)/E.
    #[inline(always)]
    pub fn strain_of(&self, s: [Real; 3]) -> [Real; 3] {
        let tr = s[0] + s[1] + s[2];
        let k = self.inv_young;
        [
            k * ((1.0 + self.poisson) * s[0] - self.poisson * tr),
            k * ((1.0 + self.poisson) * s[1] - self.poisson * tr),
            k * ((1.0 + self.poisson) * s[2] - self.poisson * tr),
        ]
    }
    /// Elastic energy density ½ σ:C⁻¹:σ [J/m³] of a plane-strain stress.
    #[inline]
    pub fn energy_density(&self, s: &Stress) -> Real {
        let tr = s.xx + s.yy + s.zz;
        let sq = s.xx * s.xx + s.yy * s.yy + s.zz * s.zz + 2.0 * s.xy * s.xy;
        0.5 * ((1.0 + self.poisson) * sq - self.poisson * tr * tr) * self.inv_young
    }
    #[inline(always)]
    fn d_times(&self, n: [Real; 3]) -> [Real; 3] {
        let t = self.lambda * (n[0] + n[1] + n[2]);
        [
            t + 2.0 * self.g * n[0],
            t + 2.0 * self.g * n[1],
            t + 2.0 * self.g * n[2],
        ]
    }
}

/// Mohr–Coulomb surface constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct McSurface {
    /// sin φ.
    pub sin_phi: Real,
    /// cos φ.
    pub cos_phi: Real,
    /// sin ψ.
    pub sin_psi: Real,
    /// Cohesion c [Pa].
    pub cohesion: Real,
    /// Largest principal stress allowed [Pa].
    pub tension_cutoff: Real,
    /// √(2/3 |dev n_g|²) of the face flow direction n_g = (1 + sin ψ, 0, −(1 − sin ψ)):
    /// equivalent plastic strain per unit plastic multiplier on the main face.
    pub face_eq: Real,
}

impl McSurface {
    /// From angles in degrees.
    pub fn from_degrees(phi_deg: Real, psi_deg: Real, cohesion: Real, tension_cutoff: Real) -> Self {
        let (p, s) = (phi_deg.to_radians(), psi_deg.to_radians());
        let sp = s.sin();
        let face_eq = (4.0 / 3.0 + 4.0 * sp * sp / 9.0).sqrt();
        Self {
            sin_phi: p.sin(),
            cos_phi: p.cos(),
            sin_psi: sp,
            cohesion,
            tension_cutoff,
            face_eq,
        }
    }
    /// From a friction coefficient μ = tan φ (μ(I) models).
    #[inline(always)]
    pub fn with_mu(&self, mu: Real) -> Self {
        let r = 1.0 / (1.0 + mu * mu).sqrt();
        Self {
            sin_phi: mu * r,
            cos_phi: r,
            ..*self
        }
    }
    /// Yield function of principal values sorted descending.
    #[inline(always)]
    pub fn yield_fn(&self, s1: Real, s3: Real) -> Real {
        (s1 - s3) + (s1 + s3) * self.sin_phi - 2.0 * self.cohesion * self.cos_phi
    }
    /// Apex stress c·cot φ [Pa] (0 for c = 0).
    #[inline(always)]
    pub fn apex(&self) -> Real {
        select(self.cohesion == 0.0, 0.0, self.cohesion * self.cos_phi / self.sin_phi)
    }
}

/// Which part of the yield surface the return mapping used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Region {
    /// Trial stress admissible.
    Elastic,
    /// Return to the main plane (σ1, σ3).
    Face,
    /// Return to the edge σ1 = σ2 (triaxial compression meridian).
    EdgeCompression,
    /// Return to the edge σ2 = σ3 (triaxial extension meridian).
    EdgeExtension,
    /// Return to the apex (c cot φ, hydrostatic).
    Apex,
    /// The Rankine tension cut-off clipped a principal stress.
    Tension,
}

#[inline]
fn dot3(a: [Real; 3], b: [Real; 3]) -> Real {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Mohr–Coulomb return mapping of a principal trial stress (any order; the result keeps the
/// order of the input). Returns the admissible principal stresses and the region used.
pub fn mohr_coulomb_return(trial: [Real; 3], el: &Elastic, mc: &McSurface) -> ([Real; 3], Region) {
    // Sort descending: o[k] is the input index of the k-th largest.
    let mut o = [0usize, 1, 2];
    if trial[o[0]] < trial[o[1]] {
        o.swap(0, 1);
    }
    if trial[o[1]] < trial[o[2]] {
        o.swap(1, 2);
    }
    if trial[o[0]] < trial[o[1]] {
        o.swap(0, 1);
    }
    let Returned { out, region, .. } = return_sorted([trial[o[0]], trial[o[1]], trial[o[2]]], el, mc);
    let mut res = [0.0; 3];
    for k in 0..3 {
        res[o[k]] = out[k];
    }
    (res, region)
}

/// Outcome of [`return_sorted`].
#[derive(Debug, Clone, Copy)]
struct Returned {
    /// Admissible principal stresses (sorted order).
    out: [Real; 3],
    region: Region,
    /// Plastic multiplier of the main-face return (meaningful on the face only).
    gam: Real,
    /// The trial is kept (elastic within round-off, even if clipped within round-off).
    unchanged: bool,
    /// Returned to the main face.
    face: bool,
}

/// The return mapping proper, for principal values sorted σ1 ≥ σ2 ≥ σ3.
///
/// Without a branch on the data: every candidate (main face, the edge on the side the face
/// return overshot, apex, tension cut-off) is evaluated and the result chosen by selects.
/// In a granular flow most points are plastic and the face-or-edge decision is close to
/// random from point to point, so a branchy return mispredicts about once per point; this
/// one is also what a solver runs over several points per vector instruction
/// (`stress_block`). Divisions of candidates not chosen may give ±∞ or NaN: they are
/// selected away.
#[inline(always)]
fn return_sorted(s: [Real; 3], el: &Elastic, mc: &McSurface) -> Returned {
    let scale = s[0].abs().max(s[2].abs()).max(mc.cohesion) + 1e-300;
    let tol = 1e-12 * scale;
    let fa = mc.yield_fn(s[0], s[2]);
    let elastic = fa <= tol;
    let (sf, sp) = (mc.sin_phi, mc.sin_psi);
    // Main plane (1, 3): flow direction n_g, normal n_f.
    let nf_a = [1.0 + sf, 0.0, -(1.0 - sf)];
    let da = el.d_times([1.0 + sp, 0.0, -(1.0 - sp)]);
    let gam = fa / dot3(nf_a, da);
    let face = [s[0] - gam * da[0], s[1] - gam * da[1], s[2] - gam * da[2]];
    let on_face = (face[0] >= face[1]) & (face[1] >= face[2]);
    // Edge, a second plane active: σ2 overtook σ1 → edge σ1 = σ2, plane (2, 3); else σ2 fell
    // below σ3 → edge σ2 = σ3, plane (1, 2).
    let comp = face[1] > face[0];
    let nf_b = [
        select(comp, 0.0, 1.0 + sf),
        select(comp, 1.0 + sf, -(1.0 - sf)),
        select(comp, -(1.0 - sf), 0.0),
    ];
    let ng_b = [
        select(comp, 0.0, 1.0 + sp),
        select(comp, 1.0 + sp, -(1.0 - sp)),
        select(comp, -(1.0 - sp), 0.0),
    ];
    let fb = mc.yield_fn(select(comp, s[1], s[0]), select(comp, s[2], s[1]));
    let db = el.d_times(ng_b);
    let (a11, a12, a21, a22) = (dot3(nf_a, da), dot3(nf_a, db), dot3(nf_b, da), dot3(nf_b, db));
    let det = a11 * a22 - a12 * a21;
    let ga = (a22 * fa - a12 * fb) / det;
    let gb = (a11 * fb - a21 * fa) / det;
    let edge = [
        s[0] - ga * da[0] - gb * db[0],
        s[1] - ga * da[1] - gb * db[1],
        s[2] - ga * da[2] - gb * db[2],
    ];
    let edge_ok = (ga >= 0.0) & (gb >= 0.0) & (edge[0] >= edge[2] - tol) & (det.abs() > 0.0);
    // Apex (c cot φ, hydrostatic).
    let apex = mc.apex();
    let pick = |k: usize| select(elastic, s[k], select(on_face, face[k], select(edge_ok, edge[k], apex)));
    let mut out = [pick(0), pick(1), pick(2)];
    let is_apex = !elastic & !on_face & !edge_ok;
    // Rankine tension cut-off (round-off above it is clipped silently).
    let t = mc.tension_cutoff;
    let clip = out[0] > t;
    let tension = clip & (out[0] - t > tol) & !is_apex;
    for v in out.iter_mut() {
        *v = select(clip & (*v > t), t, *v);
    }
    let region = if tension {
        Region::Tension
    } else if elastic {
        Region::Elastic
    } else if on_face {
        Region::Face
    } else if edge_ok {
        if comp {
            Region::EdgeCompression
        } else {
            Region::EdgeExtension
        }
    } else {
        Region::Apex
    };
    Returned {
        out,
        region,
        gam,
        unchanged: elastic & !tension,
        face: !elastic & on_face & !tension,
    }
}

/// Result of one point stress update.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StressUpdate {
    /// New stress.
    pub stress: Stress,
    /// Return-mapping region.
    pub region: Region,
    /// Plastic work density σ:Δε^p [J/m³] of the step.
    pub plastic_work: Real,
    /// Equivalent plastic shear strain increment √(2/3 Δε^p_dev:Δε^p_dev) [-].
    pub d_eps_p: Real,
}

/// Elastic trial (Jaumann-rotated) stress for a velocity gradient `l` over `dt`.
#[inline(always)]
pub fn elastic_trial(s: &Stress, l: &Mat2, dt: Real, el: &Elastic) -> Stress {
    let exx = l[(0, 0)] * dt;
    let eyy = l[(1, 1)] * dt;
    let exy = 0.5 * (l[(0, 1)] + l[(1, 0)]) * dt;
    let w = 0.5 * (l[(1, 0)] - l[(0, 1)]) * dt;
    let tr = exx + eyy;
    Stress {
        xx: s.xx - 2.0 * w * s.xy + el.lambda * tr + 2.0 * el.g * exx,
        yy: s.yy + 2.0 * w * s.xy + el.lambda * tr + 2.0 * el.g * eyy,
        xy: s.xy + w * (s.xx - s.yy) + 2.0 * el.g * exy,
        zz: s.zz + el.lambda * tr,
    }
}

/// Mohr–Coulomb correction of a trial stress (in-plane eigen-decomposition, 3D principal
/// return including σ_zz, coaxial reconstruction).
#[inline]
pub fn mohr_coulomb(tr: Stress, el: &Elastic, mc: &McSurface) -> StressUpdate {
    let (elastic, r) = mc_elastic_test(&tr, mc);
    if elastic {
        return StressUpdate {
            stress: tr,
            region: Region::Elastic,
            plastic_work: 0.0,
            d_eps_p: 0.0,
        };
    }
    mohr_coulomb_plastic(tr, el, mc, r)
}

/// First half of [`mohr_coulomb`]: the cheap elastic test (before any division) and the
/// in-plane radius r = √(((σ_xx − σ_yy)/2)² + σ_xy²). Branch-free, so a solver can run it
/// over a block of points with full instruction overlap and correct only the plastic ones
/// with [`mohr_coulomb_plastic`] (same results bit for bit as [`mohr_coulomb`]).
#[inline(always)]
pub(crate) fn mc_elastic_test(tr: &Stress, mc: &McSurface) -> (bool, Real) {
    let c0 = 0.5 * (tr.xx + tr.yy);
    let hd = 0.5 * (tr.xx - tr.yy);
    let r = (hd * hd + tr.xy * tr.xy).sqrt();
    let (a, b, z) = (c0 + r, c0 - r, tr.zz);
    let (s1, s3) = (a.max(z), b.min(z));
    ((mc.yield_fn(s1, s3) <= 0.0) & (s1 <= mc.tension_cutoff), r)
}

/// Second half of [`mohr_coulomb`] for a trial stress that failed the elastic test; `r` from
/// [`mc_elastic_test`]. Branch-free (see [`return_sorted`]).
#[inline(always)]
pub(crate) fn mohr_coulomb_plastic(tr: Stress, el: &Elastic, mc: &McSurface, r: Real) -> StressUpdate {
    let c0 = 0.5 * (tr.xx + tr.yy);
    let hd = 0.5 * (tr.xx - tr.yy);
    let (a, b, z) = (c0 + r, c0 - r, tr.zz);
    // In-plane a ≥ b: only the place of σ_zz has to be found. Sorted trial: z ≥ a →
    // (z, a, b); z ≥ b → (a, z, b); else (a, b, z).
    let z_top = z >= a;
    let z_mid = !z_top & (z >= b);
    let z_up = z_top | z_mid;
    let st = [
        select(z_top, z, a),
        select(z_top, a, select(z_mid, z, b)),
        select(z_up, b, z),
    ];
    let Returned {
        out: so,
        region,
        gam,
        unchanged,
        face,
    } = return_sorted(st, el, mc);
    // Plastic strain increment: on the face it is γ n_g exactly (no compliance, no sqrt);
    // elsewhere from the stress correction.
    let sp = mc.sin_psi;
    let (pw_face, ep_face) = (gam * ((1.0 + sp) * so[0] - (1.0 - sp) * so[2]), gam * mc.face_eq);
    let de = el.strain_of([st[0] - so[0], st[1] - so[1], st[2] - so[2]]);
    let m = (de[0] + de[1] + de[2]) / 3.0;
    let dev2 = (de[0] - m) * (de[0] - m) + (de[1] - m) * (de[1] - m) + (de[2] - m) * (de[2] - m);
    let (pw_gen, ep_gen) = (dot3(so, de), (2.0 / 3.0 * dev2).sqrt());
    let plastic_work = select(unchanged, 0.0, select(face, pw_face, pw_gen));
    let d_eps_p = select(unchanged, 0.0, select(face, ep_face, ep_gen));
    // Back to the (a, b, z) order and the in-plane frame (coaxial with the trial).
    let s = [
        select(z_top, so[1], so[0]),
        select(z_up, so[2], so[1]),
        select(z_top, so[0], select(z_mid, so[1], so[2])),
    ];
    let ir = 1.0 / r;
    let pos = r > 0.0;
    let (c2, s2) = (select(pos, hd * ir, 1.0), select(pos, tr.xy * ir, 0.0));
    let cn = 0.5 * (s[0] + s[1]);
    let rn = 0.5 * (s[0] - s[1]);
    let stress = Stress {
        xx: select(unchanged, tr.xx, cn + rn * c2),
        yy: select(unchanged, tr.yy, cn - rn * c2),
        xy: select(unchanged, tr.xy, rn * s2),
        zz: select(unchanged, tr.zz, s[2]),
    };
    StressUpdate {
        stress,
        region,
        plastic_work,
        d_eps_p,
    }
}

/// Shear rate γ̇ = √(2 D':D') of a plane-strain velocity gradient [1/s].
#[inline(always)]
pub fn shear_rate(l: &Mat2) -> Real {
    let dxx = l[(0, 0)];
    let dyy = l[(1, 1)];
    let dxy = 0.5 * (l[(0, 1)] + l[(1, 0)]);
    let m = (dxx + dyy) / 3.0;
    let dd = (dxx - m).powi(2) + (dyy - m).powi(2) + m * m + 2.0 * dxy * dxy;
    (2.0 * dd).sqrt()
}

/// Inertial number I = γ̇ d̄/√(p/ρ_s), capped at `i_max` (also used where p ≤ 0).
#[inline(always)]
pub fn inertial_number(gamma_dot: Real, p: Real, d: Real, rho_s: Real, i_max: Real) -> Real {
    if p <= 0.0 {
        return if gamma_dot > 0.0 { i_max } else { 0.0 };
    }
    (gamma_dot * d / (p / rho_s).sqrt()).min(i_max)
}

/// Friction coefficient μ(I) of a μ(I) model (None for the other models).
#[inline(always)]
pub fn mu_of_i(model: &Model, i: Real) -> Option<Real> {
    match *model {
        Model::MuILinear { mu_min, b } => Some(mu_min + b * i),
        Model::MuIJop { mu_s, mu_2, i0 } => Some(if i > 0.0 {
            mu_s + (mu_2 - mu_s) / (i0 / i + 1.0)
        } else {
            mu_s
        }),
        _ => None,
    }
}

/// The surface of a material (φ from `friction_deg` for Mohr–Coulomb; for μ(I) models the
/// friction is replaced per point).
pub fn surface_of(m: &Material) -> McSurface {
    McSurface::from_degrees(m.friction_deg, m.dilation_deg, m.cohesion_pa, m.tension_cutoff_pa)
}

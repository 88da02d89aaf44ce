//! Constitutive law away from the solver: Mohr–Coulomb return mapping from trial stresses (one
//! case per region), a plane-strain biaxial element test reaching the predicted stress ratio,
//! μ(I) laws.

use granrepro::math::Mat2;
use granrepro::mpm::material::*;
use granrepro::mpm::{Model, Stress};

fn el() -> Elastic {
    Elastic::new(1.98e6, 0.22)
}
fn mc() -> McSurface {
    McSurface::from_degrees(22.2, 0.0, 0.0, 0.0)
}
fn sorted(s: [f64; 3]) -> [f64; 3] {
    let mut v = s;
    v.sort_by(|a, b| b.total_cmp(a));
    v
}
/// f of the returned state ≈ 0 and the correction Δσ is along D:∂g/∂σ (ψ = 0: deviatoric).
fn check_on_surface(trial: [f64; 3], out: [f64; 3], m: &McSurface) {
    let s = sorted(out);
    let f = m.yield_fn(s[0], s[2]);
    let scale = trial.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    assert!(f.abs() < 1e-10 * scale, "f = {f}");
    let dtr = (trial[0] + trial[1] + trial[2]) - (out[0] + out[1] + out[2]);
    assert!(
        dtr.abs() < 1e-9 * scale,
        "psi = 0 flow must keep the mean stress: {dtr}"
    );
}

#[test]
fn elastic_region() {
    let t = [-1000.0, -800.0, -900.0];
    let (o, r) = mohr_coulomb_return(t, &el(), &mc());
    assert_eq!(r, Region::Elastic);
    assert_eq!(o, t);
}

#[test]
fn face_region() {
    // σ1 = −500, σ2 = −900, σ3 = −1500 (tension positive): f > 0, distinct principal values.
    let t = [-1500.0, -500.0, -900.0];
    let m = mc();
    assert!(m.yield_fn(-500.0, -1500.0) > 0.0);
    let (o, r) = mohr_coulomb_return(t, &el(), &m);
    assert_eq!(r, Region::Face);
    check_on_surface(t, o, &m);
    // Input order preserved: index 0 stays the most compressive.
    assert!(o[0] < o[2] && o[2] < o[1]);
}

#[test]
fn edge_regions() {
    let m = mc();
    // Two nearly equal least-compressive values: the face return would swap σ1 and σ2.
    let t = [-300.0, -310.0, -1500.0];
    let (o, r) = mohr_coulomb_return(t, &el(), &m);
    assert_eq!(r, Region::EdgeCompression);
    check_on_surface(t, o, &m);
    assert!((o[0] - o[1]).abs() < 1e-9 * 1500.0);
    // Two nearly equal most-compressive values.
    let t = [-300.0, -1490.0, -1500.0];
    let (o, r) = mohr_coulomb_return(t, &el(), &m);
    assert_eq!(r, Region::EdgeExtension);
    check_on_surface(t, o, &m);
    assert!((o[1] - o[2]).abs() < 1e-9 * 1500.0);
}

#[test]
fn apex_and_tension_regions() {
    let m = mc();
    // Hydrostatic tension: no deviatoric return can reach the cone → apex (stress free, c = 0).
    let (o, r) = mohr_coulomb_return([100.0, 100.0, 100.0], &el(), &m);
    assert_eq!(r, Region::Apex);
    assert_eq!(o, [0.0, 0.0, 0.0]);
    // Mixed tension/compression far outside.
    let (o, r) = mohr_coulomb_return([200.0, -50.0, 10.0], &el(), &m);
    assert_eq!(r, Region::Apex);
    assert_eq!(o, [0.0, 0.0, 0.0]);
    // With cohesion 1 kPa and a 100 Pa cut-off: an admissible MC state above the cut-off.
    let mc_c = McSurface::from_degrees(22.2, 0.0, 1000.0, 100.0);
    let (o, r) = mohr_coulomb_return([150.0, 120.0, 130.0], &el(), &mc_c);
    assert_eq!(r, Region::Tension);
    assert!(o.iter().all(|&v| v <= 100.0));
}

#[test]
fn in_plane_reconstruction_is_coaxial() {
    let tr = Stress {
        xx: -400.0,
        yy: -1600.0,
        xy: 300.0,
        zz: -600.0,
    };
    let u = mohr_coulomb(tr, &el(), &mc());
    assert_ne!(u.region, Region::Elastic);
    // Principal directions unchanged: σ_xy/(σ_xx − σ_yy) is preserved.
    let a = tr.xy / (tr.xx - tr.yy);
    let b = u.stress.xy / (u.stress.xx - u.stress.yy);
    assert!((a - b).abs() < 1e-12);
    assert!(u.plastic_work > 0.0 && u.d_eps_p > 0.0);
}

/// Plane-strain biaxial test on one material point: isotropic p0, then axial (y) compression
/// with σ_xx held at −p0 (Newton on ε_xx). Mohr–Coulomb predicts the peak (= residual, perfect
/// plasticity) ratio σ_yy/σ_xx = (1 + sin φ)/(1 − sin φ) = 2.2 for φ = 22.2°.
#[test]
fn biaxial_element_test_reaches_predicted_ratio() {
    let e = el();
    let m = mc();
    let p0 = 1000.0;
    let mut s = Stress {
        xx: -p0,
        yy: -p0,
        xy: 0.0,
        zz: -p0,
    };
    let dt = 1.0;
    let deyy = -2e-6;
    let mut first_yield_ratio = None;
    let mut ratio = 1.0;
    for _ in 0..2000 {
        // Newton on ε̇_xx so that σ_xx stays at −p0 (elastic tangent as the Jacobian).
        let mut dexx = -e.lambda * deyy / (e.lambda + 2.0 * e.g);
        let mut u = mohr_coulomb(elastic_trial(&s, &Mat2::new(dexx, 0.0, 0.0, deyy), dt, &e), &e, &m);
        for _ in 0..50 {
            let r = u.stress.xx + p0;
            if r.abs() < 1e-9 {
                break;
            }
            let h = 1e-9;
            let u2 = mohr_coulomb(elastic_trial(&s, &Mat2::new(dexx + h, 0.0, 0.0, deyy), dt, &e), &e, &m);
            let k = (u2.stress.xx - u.stress.xx) / h;
            dexx -= r / k;
            u = mohr_coulomb(elastic_trial(&s, &Mat2::new(dexx, 0.0, 0.0, deyy), dt, &e), &e, &m);
        }
        s = u.stress;
        ratio = s.yy / s.xx;
        if u.region != Region::Elastic && first_yield_ratio.is_none() {
            first_yield_ratio = Some(ratio);
        }
    }
    let sf = (22.2f64).to_radians().sin();
    let kp = (1.0 + sf) / (1.0 - sf);
    let fy = first_yield_ratio.expect("never yielded");
    assert!((fy - kp).abs() < 0.01 * kp, "first yield at {fy}, predicted {kp}");
    assert!((ratio - kp).abs() < 1e-6 * kp, "residual ratio {ratio}, predicted {kp}");
    assert!((s.xx + p0).abs() < 1e-6);
}

#[test]
fn mu_of_i_laws() {
    let lin = Model::mu_i_default();
    let mu_min = (22.2f64).to_radians().tan();
    assert!((mu_of_i(&lin, 0.0).unwrap() - mu_min).abs() < 1e-15);
    assert!((mu_of_i(&lin, 0.01).unwrap() - (mu_min + 0.01)).abs() < 1e-15);
    let jop = Model::jop_default();
    assert!((mu_of_i(&jop, 0.0).unwrap() - mu_min).abs() < 1e-15);
    assert!((mu_of_i(&jop, 1e9).unwrap() - (mu_min + 0.2616)).abs() < 1e-6);
    assert!(mu_of_i(&Model::MohrCoulomb, 0.1).is_none());
    // I = γ̇ d/√(p/ρ_s): 10 /s, 1.15 mm, p = 1000 Pa, 2500 kg/m³ → 0.0115/√0.4 = 0.018183
    let i = inertial_number(10.0, 1000.0, 1.15e-3, 2500.0, 1.0);
    assert!((i - 0.0115 / 0.4f64.sqrt()).abs() < 1e-12);
    assert_eq!(inertial_number(10.0, -1.0, 1.15e-3, 2500.0, 1.0), 1.0);
    // Simple shear v_x = γ̇ y: γ̇ = √(2 D':D') = γ̇.
    assert!((shear_rate(&Mat2::new(0.0, 3.0, 0.0, 0.0)) - 3.0).abs() < 1e-12);
}

#[test]
fn face_plastic_strain_matches_compliance_of_the_correction() {
    // Face returns book Δε^p = γ n_g analytically; it must equal C⁻¹(σ_trial − σ).
    let e = el();
    for psi in [0.0, 10.0] {
        let m = McSurface::from_degrees(22.2, psi, 0.0, 0.0);
        let tr = Stress {
            xx: -400.0,
            yy: -1600.0,
            xy: 300.0,
            zz: -900.0,
        };
        let u = mohr_coulomb(tr, &e, &m);
        assert_eq!(u.region, Region::Face);
        // Principal frame of the (coaxial) trial and returned stresses.
        let pr = |s: &Stress| {
            let c = 0.5 * (s.xx + s.yy);
            let r = (0.25 * (s.xx - s.yy).powi(2) + s.xy * s.xy).sqrt();
            [c + r, c - r, s.zz]
        };
        let (t, o) = (pr(&tr), pr(&u.stress));
        let de = e.strain_of([t[0] - o[0], t[1] - o[1], t[2] - o[2]]);
        let w: f64 = (0..3).map(|k| o[k] * de[k]).sum();
        let mean = (de[0] + de[1] + de[2]) / 3.0;
        let eq = (2.0 / 3.0 * de.iter().map(|d| (d - mean).powi(2)).sum::<f64>()).sqrt();
        assert!(
            (w - u.plastic_work).abs() < 1e-9 * w.abs(),
            "psi {psi}: work {w} vs {}",
            u.plastic_work
        );
        assert!(
            (eq - u.d_eps_p).abs() < 1e-9 * eq,
            "psi {psi}: eps {eq} vs {}",
            u.d_eps_p
        );
    }
}

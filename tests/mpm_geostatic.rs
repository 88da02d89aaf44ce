//! Geostatic stress of an elastic column between frictionless walls (uniaxial strain):
//! σ_yy = −ρ g (H − y) and σ_xx = ν/(1−ν) σ_yy. Cell rows are compared (MPM stress is
//! piecewise constant per cell), and the a = 1 column of fig4-04 (Mohr–Coulomb, frictional
//! walls) is checked at the base against ρ g H_0 within 2 %.

use granrepro::mpm::{Model, MpmParams, column, geostatic};

#[test]
fn elastic_column_matches_rho_g_depth() {
    let mut p = MpmParams::quick();
    p.material.model = Model::Elastic;
    p.wall_friction = 0.0;
    let spec = column::ColumnSpec { l0: 0.032, h0: 0.064 };
    let mut col = column::build(&p, spec).unwrap();
    geostatic::run(&mut col.solver, &mut col.state, col.spec.h0).unwrap();
    let (h, rho_g, nu) = (p.cell_size, p.material.density * p.gravity, p.material.poisson);
    let rows = (col.spec.h0 / h).round() as usize;
    let mut worst: f64 = 0.0;
    for r in 0..rows {
        let (mut syy, mut sxx, mut y, mut n) = (0.0, 0.0, 0.0, 0.0);
        for q in &col.state.points {
            if q.x.y >= r as f64 * h && q.x.y < (r + 1) as f64 * h {
                syy += q.stress.yy;
                sxx += q.stress.xx;
                y += q.x.y;
                n += 1.0;
            }
        }
        let (syy, sxx, y) = (syy / n, sxx / n, y / n);
        let an = -rho_g * (col.spec.h0 - y);
        let err = (syy - an).abs() / (rho_g * col.spec.h0);
        worst = worst.max(err);
        assert!(
            (sxx - nu / (1.0 - nu) * syy).abs() < 0.02 * rho_g * col.spec.h0,
            "row {r}: K0 violated"
        );
    }
    eprintln!("elastic geostatic: max row error / (rho g H) = {worst:.3e}");
    assert!(worst < 0.02, "max row error {worst}");
}

#[test]
fn fig4_04_base_stress_within_2_percent() {
    let p = MpmParams::default();
    let g = column::fig4_04(&p).unwrap();
    eprintln!(
        "fig4-04: {} points, base sigma_yy {:.1} Pa vs {:.1} Pa, error {:.4}, {:?}",
        g.x.len(),
        g.base_sigma_yy,
        g.base_sigma_yy_analytic,
        g.base_error,
        g.report
    );
    assert!(g.base_error < 0.02);
    assert!((g.spec.l0 - 0.062).abs() < 1e-12 && (g.spec.h0 - 0.062).abs() < 1e-12);
    assert_eq!(g.x.len(), 124 * 124);
}

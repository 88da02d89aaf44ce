//! Column-collapse driver at test size: work-precision sweep (stiffness and step
//! variants against the finest run) and the pile preparation (pour, shift the wall).

use granrepro::dem::DemParams;
use granrepro::dem::column::{CollapseParams, Variant, work_precision};
use granrepro::dem::pile::{PileParams, prepare_pile};
use granrepro::dem::prep::{DepositionParams, diameters_uniform_by_area, hex_column};

#[test]
fn work_precision_sweep_reports_error_and_time() {
    let base = DemParams::default();
    let col = hex_column(0.012, 0.012, 1.15e-3, &base.softened(0.01), 0.05).unwrap();
    let cp = CollapseParams {
        t_max: 2.0,
        sample_every: 0.1,
        ..CollapseParams::default()
    };
    let v = |label: &str, k: f64, f: f64| Variant {
        label: label.into(),
        stiffness_factor: k,
        dt_fraction: f,
    };
    let rows = work_precision(
        &col,
        &base,
        &cp,
        &[
            v("ref", 0.01, 1.0 / 50.0),
            v("dt/10", 0.01, 1.0 / 10.0),
            v("k/10", 0.001, 1.0 / 20.0),
        ],
        3,
        1e-9,
        7,
    )
    .unwrap();
    for r in &rows {
        eprintln!(
            "{:>6}: dt {:.2e} ΔL {:.4} ± {:.4} H/L0 {:.3} err {:.3e} ± {:.1e} wall {:.2}s steps {}",
            r.variant.label, r.dt, r.mean, r.spread, r.h_final_over_l0, r.error, r.error_spread, r.wall_s, r.steps
        );
    }
    assert_eq!(rows[0].error, 0.0);
    assert!(rows.iter().all(|r| r.delta_l.len() == 3
        && r.mean > 0.0
        && r.wall_s > 0.0
        && r.spread.is_finite()
        && r.error_spread.is_finite()));
    // the members differ (the perturbation reaches the chaotic run-out) and the reference's
    // own spread enters the standard error of every other setting
    assert!(rows[1].error_spread > 0.0);
    assert!(rows[1].wall_s < rows[0].wall_s);
}

#[test]
fn pile_pour_and_spread() {
    let radii: Vec<f64> = diameters_uniform_by_area(150, 0.92e-3, 1.38e-3, 9)
        .iter()
        .map(|d| 0.5 * d)
        .collect();
    let p = DemParams {
        rolling: Default::default(),
        ..DemParams::default()
    }
    .softened(0.01);
    let pp = PileParams {
        deposition: DepositionParams {
            width: 0.012,
            softening: 1.0,
            max_settle_time: 0.1,
            ..DepositionParams::default()
        },
        shift_to: 5.0,
        max_time: 0.3,
        ..PileParams::default()
    };
    let pile = prepare_pile(&radii, &p, &pp).unwrap();
    // mean slope of the deposit: atan(H_0/L_0) (the surface fit is src/analysis/pile.rs)
    let slope = (pile.h0 / pile.l0).atan().to_degrees();
    eprintln!(
        "pile: L0 {:.4} m H0 {:.4} m slope {slope:.1}° settled {}",
        pile.l0, pile.h0, pile.settled
    );
    assert!(pile.l0 > 0.012 && slope > 0.0 && slope < 45.0);
}

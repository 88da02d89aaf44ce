//! Stability pre-flight and parameter validation.

use granrepro::mpm::preflight::{planned_dt, preflight};
use granrepro::mpm::{MpmError, MpmParams, StepRule};

#[test]
fn table_4_3_step_passes_with_courant_0_017() {
    let p = MpmParams::default();
    let r = preflight(&p, 1e-6, 0.0).unwrap();
    assert!((r.c_p - 34.27).abs() < 0.01);
    assert!((r.p_modulus - 2.2605e6).abs() < 1e3);
    assert!((r.courant - 0.0171).abs() < 1e-3);
    let table = r.to_string();
    assert!(table.contains("CFL") && table.contains("ok"));
    eprintln!("{table}");
}

#[test]
fn too_large_step_is_refused_with_the_limit() {
    let p = MpmParams::default();
    // docs/definitions.md c.3: h/(c_p + v) = 2e-3/(34.27 + 1.97) = 5.52e-5 s.
    match preflight(&p, 1e-4, 1.97) {
        Err(MpmError::StepTooLarge { dt, limit, .. }) => {
            assert_eq!(dt, 1e-4);
            assert!((limit - 5.52e-5).abs() < 0.01e-5, "limit {limit}");
        }
        other => panic!("expected StepTooLarge, got {other:?}"),
    }
    let q = MpmParams {
        step: StepRule::Cfl {
            courant: 0.5,
            dt_max: 1.0,
        },
        ..MpmParams::default()
    };
    let dt = planned_dt(&q, 1.97);
    assert!(preflight(&q, dt, 1.97).is_ok());
}

#[test]
fn validation_lists_every_bad_value() {
    let mut p = MpmParams::default();
    p.material.poisson = 0.5;
    p.material.young_pa = -1.0;
    p.material.friction_deg = 0.0;
    p.ppc = 15;
    p.flip = 2.0;
    let keys: Vec<String> = p.validate().into_iter().map(|i| i.key).collect();
    for k in [
        "material.poisson", "material.young_pa", "material.friction_deg", "ppc", "flip",
    ] {
        assert!(keys.iter().any(|x| x == k), "missing issue for {k}: {keys:?}");
    }
    assert!(MpmParams::default().validate().is_empty());
    assert!(MpmParams::quick().validate().is_empty());
}

#[test]
fn params_serde_defaults_and_unknown_keys() {
    let p: MpmParams = serde_yaml::from_str("material:\n  friction_deg: 23.0\nppc: 9\n").unwrap();
    assert_eq!(p.material.friction_deg, 23.0);
    assert_eq!(p.material.young_pa, 1.98e6);
    assert_eq!(p.ppc, 9);
    assert!(serde_yaml::from_str::<MpmParams>("material:\n  frictoin_deg: 23.0\n").is_err());
    let back: MpmParams = serde_json::from_str(&serde_json::to_string(&MpmParams::default()).unwrap()).unwrap();
    assert_eq!(back, MpmParams::default());
    let m: MpmParams = serde_yaml::from_str("material:\n  model: !mu_i_linear {mu_min: 0.22, b: 1.0}\n").unwrap();
    assert!(matches!(m.material.model, granrepro::mpm::Model::MuILinear { .. }));
}

#[test]
fn collapse_refuses_an_unstable_fixed_step_before_running() {
    let p = MpmParams {
        step: StepRule::Fixed { dt: 1e-3 },
        ..MpmParams::quick()
    };
    let r = granrepro::mpm::column::collapse(
        &p,
        granrepro::mpm::column::ColumnSpec::from_aspect(0.4),
        &Default::default(),
    );
    assert!(matches!(r, Err(MpmError::StepTooLarge { .. })));
}

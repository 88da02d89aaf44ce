//! Contract: the CD engine refuses what it cannot do, with the number and the fix:
//! a step that lets a grain move more than half the alert distance, non-finite state,
//! interpenetration beyond the limit, bad parameters; unconverged steps are counted.

use granrepro::cd::pile::{DropSpec, drop};
use granrepro::cd::{CdError, CdParams, World};
use granrepro::dem::{State, Wall};

#[test]
fn a_step_that_could_miss_a_contact_is_refused_with_the_limit_and_the_fix() {
    let mut s = State::new();
    s.insert(0.0, 0.01, 1e-3, 2600.0);
    s.vy[0] = -2.0; // 2 m/s × 1e-4 s = 0.2 mm > alert/2 = 0.1 mm
    let mut w = World::new(CdParams::default(), s, vec![Wall::floor(0.0)], None).unwrap();
    let e = w.step().unwrap_err();
    let msg = e.to_string();
    match e {
        CdError::StepTooLarge { dt_limit, alert, .. } => {
            assert!((dt_limit - 0.5 * alert / 2.0).abs() < 1e-12, "limit {dt_limit}");
            assert!(
                msg.contains("dt ≤ 5.000e-5") && msg.contains("alert_fraction ≥"),
                "{msg}"
            );
        }
        other => panic!("wrong error {other:?}"),
    }
}

#[test]
fn non_finite_velocity_is_caught_naming_the_grain() {
    let mut s = State::new();
    s.insert(0.0, 0.01, 1e-3, 2600.0);
    s.insert(0.01, 0.01, 1e-3, 2600.0);
    let mut w = World::new(CdParams::default(), s, vec![Wall::floor(0.0)], None).unwrap();
    w.bodies[1].v[2] = f64::NAN;
    match w.step() {
        Err(CdError::NonFinite { grain: 1, .. }) => {}
        other => panic!("expected NonFinite on grain 1, got {other:?}"),
    }
}

#[test]
fn interpenetration_beyond_the_limit_stops_the_run() {
    let mut s = State::new();
    s.insert(0.0, 0.01, 1e-3, 2600.0);
    s.insert(1.8e-3, 0.01, 1e-3, 2600.0); // 0.1 d overlap
    let mut w = World::new(
        CdParams {
            gravity: 0.0,
            ..CdParams::default()
        },
        s,
        vec![],
        None,
    )
    .unwrap();
    match w.step() {
        Err(CdError::Penetration { fraction, limit, .. }) => assert!(fraction > limit),
        other => panic!("expected Penetration, got {other:?}"),
    }
}

#[test]
fn bad_parameters_are_listed() {
    let p = CdParams {
        theta: 0.3,
        tolerance: -1.0,
        ..CdParams::default()
    };
    let mut s = State::new();
    s.insert(0.0, 0.01, 1e-3, 2600.0);
    let e = World::new(p, s, vec![], None).unwrap_err().to_string();
    assert!(e.contains("theta") && e.contains("tolerance"), "{e}");
}

#[test]
fn unconverged_steps_are_counted_not_hidden() {
    let spec = DropSpec {
        ncol: 8,
        nrow: 6,
        scale: 1e-3,
        seed: 2,
    };
    let p = CdParams {
        dt: 4e-5,
        max_iterations: 3,
        ..CdParams::default()
    };
    let r = drop(&spec, &p, 1500).unwrap();
    assert!(
        r.stats.unconverged > 100,
        "a 3-sweep cap cannot converge a settling pile: {} unconverged",
        r.stats.unconverged
    );
    assert!(r.stats.max_residual > p.residual_tolerance);
}

#[test]
fn every_step_can_be_logged_with_its_iterations_and_residual() {
    let spec = DropSpec {
        ncol: 4,
        nrow: 3,
        scale: 1e-3,
        seed: 2,
    };
    let (s, walls) = spec.build(2600.0);
    let mut w = World::new(
        CdParams {
            dt: 4e-5,
            ..CdParams::default()
        },
        s,
        walls,
        None,
    )
    .unwrap();
    w.log = Some(Vec::new());
    w.run(300).unwrap();
    let log = w.log.as_ref().unwrap();
    assert_eq!(log.len(), 300);
    assert_eq!(log.iter().map(|i| i.iterations as u64).sum::<u64>(), w.stats.iterations);
    assert_eq!(log.iter().filter(|i| !i.converged).count() as u64, w.stats.unconverged);
    assert!(log.iter().all(|i| i.residual.is_finite()));
}

#[test]
fn energy_rise_without_work_is_caught() {
    // a grain kicked from outside the solver gains energy no force did work for
    let spec = DropSpec {
        ncol: 4,
        nrow: 3,
        scale: 1e-3,
        seed: 2,
    };
    let (s, walls) = spec.build(2600.0);
    let mut w = World::new(
        CdParams {
            dt: 4e-5,
            ..CdParams::default()
        },
        s,
        walls,
        None,
    )
    .unwrap();
    w.run(200).unwrap();
    w.bodies[5].v[1] += 0.3;
    match w.step() {
        Err(CdError::EnergyRise { energy, allowed, .. }) => assert!(energy > allowed),
        other => panic!("expected EnergyRise, got {other:?}"),
    }
}

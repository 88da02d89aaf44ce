//! Contract: the pre-flight lists every time scale and refuses unstable steps with the
//! numbers and the fix; the explicit rolling dashpot of table 4.2 (I/c_r ≈ 1e-9 s) is
//! refused and really blows up, the implicit one is accepted and stays stable.

use granrepro::dem::{DemError, DemParams, RollingDamping, SizeClasses, State, Wall, World, preflight};
use granrepro::math::{PI, Real, Vec2};

fn column_sizes() -> SizeClasses {
    SizeClasses {
        r_min: 0.46e-3,
        r_mean: 0.575e-3,
        r_max: 0.69e-3,
    }
}

#[test]
fn chapter_step_is_audited_and_default_accepted() {
    let p = DemParams::default();
    let pf = preflight(&p, column_sizes(), true, p.dt).unwrap();
    let table = pf.to_string();
    eprintln!("{table}");
    // translational collision, wall, multi-contact, tangential and rolling rows present
    for key in [
        "collision grain-grain (d_min pair)", "collision grain-wall", "multi-contact normal", "tangential pair",
        "rolling dashpot relaxation",
    ] {
        assert!(table.contains(key), "row {key} missing");
    }
    // docs/definitions.md c.1: min–min t_c = 7.19e-6 s with eq 4.5's γ; ours (ζ exact) is
    // within 1 %
    let tc = pf.rows.iter().find(|r| r.name.contains("d_min pair")).unwrap().value;
    assert!((tc - 7.19e-6).abs() < 0.01 * 7.19e-6, "t_c = {tc}");
}

#[test]
fn too_large_step_is_refused_with_numbers() {
    let p = DemParams {
        dt: 5e-6,
        ..DemParams::default()
    };
    let err = preflight(&p, column_sizes(), true, p.dt).unwrap_err();
    let msg = err.to_string();
    eprintln!("{msg}");
    match err {
        DemError::StepTooLarge { dt, limit, .. } => {
            assert_eq!(dt, 5e-6);
            assert!(limit < 5e-6);
        }
        e => panic!("unexpected {e}"),
    }
    assert!(msg.contains("use dt <="));
}

#[test]
fn explicit_rolling_damping_is_refused() {
    let mut p = DemParams::default();
    p.rolling.damping = RollingDamping::Explicit;
    let err = preflight(&p, column_sizes(), true, p.dt).unwrap_err();
    let msg = err.to_string();
    eprintln!("{msg}");
    assert!(msg.contains("rolling"), "{msg}");
    assert!(msg.contains("implicit"), "{msg}");
    // the explicit limit is 2 I_eff / c_r ≈ 1.76e-9 s for a d_min pair (docs/definitions.md
    // c.2)
    if let DemError::StepTooLarge { limit, .. } = err {
        assert!(limit < 2e-9 && limit > 1.5e-9, "{limit}");
    }
}

/// Grain resting on the floor with a spin kick, run at the default step.
fn spinning_grain(damping: RollingDamping) -> Result<Real, DemError> {
    let mut p = DemParams::default();
    p.rolling.damping = damping;
    p.watchdog.every = 10;
    let r = 0.46e-3;
    let m = p.density * PI * r * r;
    let delta = m * p.gravity / p.wall.kn;
    let mut s = State::new();
    s.insert(0.0, r - delta, r, p.density);
    s.w[0] = 50.0;
    let mut w = World::new(p, s, vec![Wall::floor(0.0)], None)?;
    w.run(20_000)?;
    Ok(Vec2::new(w.state.vx[0], w.state.vy[0]).norm() + w.state.w[0].abs() * r)
}

#[test]
fn explicit_dashpot_blows_up_implicit_is_stable() {
    let bad = spinning_grain(RollingDamping::Explicit);
    eprintln!("explicit: {bad:?}");
    assert!(
        matches!(bad, Err(DemError::NonFinite { .. }) | Err(DemError::EnergyRise { .. })),
        "{bad:?}"
    );
    let good = spinning_grain(RollingDamping::Implicit).unwrap();
    eprintln!("implicit: final speed {good:e} m/s");
    assert!(good.is_finite() && good < 1.0);
}

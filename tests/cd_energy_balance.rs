//! Contract: the CD ledger closes, E_k + E_p + D_coll + D_fric + D_θ = E_0 + W, to
//! round-off, for elastic and inelastic impacts, θ = ½ and θ = 1, with driven walls.

use granrepro::cd::pile::DropSpec;
use granrepro::cd::{CdParams, World};
use granrepro::math::{Real, Vec2};

fn run(e: Real, theta: Real, mu: Real, drive: bool) -> (granrepro::cd::Balance, Real) {
    run_r(e, theta, mu, drive, 0.0)
}

fn run_r(e: Real, theta: Real, mu: Real, drive: bool, mu_r: Real) -> (granrepro::cd::Balance, Real) {
    let spec = DropSpec {
        ncol: 8,
        nrow: 6,
        scale: 1e-3,
        seed: 9,
    };
    let (s, mut walls) = spec.build(2600.0);
    if drive {
        walls[2].velocity = Vec2::new(-0.05, 0.0); // right wall pushes in
    }
    let p = CdParams {
        dt: 4e-5,
        theta,
        restitution_n: e,
        friction: mu,
        wall_friction: mu,
        rolling_friction: mu_r,
        ..CdParams::default()
    };
    let mut w = World::new(p, s, walls, None).unwrap();
    w.run(2500).unwrap();
    let m: Real = w.state.m.iter().sum();
    (w.balance(), m * 9.81 * 1e-3)
}

#[test]
fn ledger_closes_to_round_off() {
    for (e, theta, mu, drive) in [
        (0.0, 0.5, 0.4, false),
        (0.5, 0.5, 0.4, false),
        (1.0, 0.5, 0.0, false),
        (0.0, 1.0, 0.4, false),
        (0.0, 0.5, 0.4, true),
    ] {
        let (b, scale) = run(e, theta, mu, drive);
        eprintln!("e={e} θ={theta} μ={mu} drive={drive}: {b:?}");
        assert!(
            b.residual.abs() < 1e-9 * scale,
            "residual {} vs M g d = {scale}",
            b.residual
        );
        assert!(
            b.ledger.collisional >= -1e-9 * scale,
            "impacts dissipate: {}",
            b.ledger.collisional
        );
        if mu > 0.0 {
            assert!(b.ledger.frictional > 0.0, "friction dissipates");
        }
        if theta == 0.5 {
            assert_eq!(b.ledger.numerical, 0.0, "midpoint rule: no numerical damping");
        } else {
            assert!(b.ledger.numerical > 0.0, "θ = 1 damps");
        }
        if drive {
            assert!(b.ledger.external_work > 0.0, "the pushing wall does work");
        } else {
            assert_eq!(b.ledger.external_work, 0.0);
        }
    }
}

#[test]
fn ledger_closes_with_rolling_resistance() {
    let (b0, scale) = run_r(0.0, 0.5, 0.4, false, 0.0);
    let (b, _) = run_r(0.0, 0.5, 0.4, false, 0.2);
    assert!(b.residual.abs() < 1e-9 * scale, "residual {}", b.residual);
    assert!(
        b.now.erot < b0.now.erot,
        "rolling resistance brakes spins: {} vs {}",
        b.now.erot,
        b0.now.erot
    );
}

#[test]
fn elastic_frictionless_impacts_conserve_energy() {
    let (b, scale) = run(1.0, 0.5, 0.0, false);
    // e = 1, θ = ½: U_n = ū_n on impacts, so P_n ū_n = 0; only contacts activated while
    // separating (u⁻_n > 0) can exchange O(h²) energy.
    assert!(
        b.ledger.dissipated().abs() < 0.02 * (b.e0 - b.now.ep).abs().max(scale),
        "elastic: D = {:?}",
        b.ledger
    );
}

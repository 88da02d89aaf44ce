//! Analytic cases for the CD engine: incline (stick / slide / roll), bouncing disk (ε_n),
//! resting column (no drift, base impulse = weight·h), head-on collisions (momentum,
//! restitution), static pile (interpenetration bound).

use granrepro::cd::pile::{DropSpec, drop};
use granrepro::cd::{CdParams, World};
use granrepro::dem::{State, Wall};
use granrepro::math::{G, Real, Vec2};

const R: Real = 1e-3;

fn params() -> CdParams {
    CdParams {
        dt: 1e-4,
        tolerance: 1e-10,
        residual_tolerance: 1e-8,
        max_iterations: 5000,
        ..CdParams::default()
    }
}

/// One disk resting on an incline of angle `deg` (wall through the origin), released at
/// rest; returns (down-slope acceleration, slip velocity at the contact point at the end).
fn incline(deg: Real, mu: Real, spin: bool) -> (Real, Real) {
    incline_r(deg, mu, spin, 0.0)
}

fn incline_r(deg: Real, mu: Real, spin: bool, mu_r: Real) -> (Real, Real) {
    let th = deg.to_radians();
    let n = Vec2::new(-th.sin(), th.cos());
    let down = Vec2::new(-th.cos(), -th.sin());
    let mut s = State::new();
    let c = n * R;
    s.insert(c.x, c.y, R, 2600.0);
    if !spin {
        s.inv_i[0] = 0.0; // a sliding block: rotation locked
    }
    let p = CdParams {
        friction: mu,
        wall_friction: mu,
        rolling_friction: mu_r,
        ..params()
    };
    let mut w = World::new(p, s, vec![Wall::new("incline", Vec2::zeros(), n)], None).unwrap();
    let steps = 200;
    w.run(steps).unwrap();
    let v = Vec2::new(w.state.vx[0], w.state.vy[0]);
    let t = steps as Real * 1e-4;
    let a = v.dot(&down) / t;
    // contact-point velocity along the slope: v·down − ω r (ω > 0 counter-clockwise rolls
    // the disk down-slope... sign: rolling down a slope to the left means ω > 0)
    let slip = v.dot(&down) - w.state.w[0] * R;
    assert!(v.dot(&n).abs() < 1e-9, "no motion off the slope: {}", v.dot(&n));
    (a, slip)
}

#[test]
fn block_sticks_below_atan_mu_and_slides_above() {
    let mu: Real = 0.4;
    let crit = mu.atan().to_degrees(); // 21.8°
    for deg in [5.0, 15.0, crit - 0.5] {
        let (a, _) = incline(deg, mu, false);
        assert!(a.abs() < 1e-9, "{deg}°: block must stick, a = {a}");
    }
    for deg in [crit + 0.5, 30.0, 45.0] {
        let th = (deg as Real).to_radians();
        let exact = G * (th.sin() - mu * th.cos());
        let (a, _) = incline(deg, mu, false);
        assert!(
            (a - exact).abs() < 1e-6 * G,
            "{deg}°: a = {a}, expected g(sinθ − μcosθ) = {exact}"
        );
    }
}

#[test]
fn disk_rolls_below_atan_3mu_and_slides_above() {
    // a free disk (I = ½mr²) rolls without slip while tanθ ≤ 3μ: a = ⅔ g sinθ
    let mu = 0.2;
    for deg in [10.0, 25.0, 30.0] {
        let th = (deg as Real).to_radians();
        let (a, slip) = incline(deg, mu, true);
        assert!(
            (a - 2.0 / 3.0 * G * th.sin()).abs() < 1e-6 * G,
            "{deg}°: rolling a = {a}"
        );
        assert!(slip.abs() < 1e-9, "{deg}°: rolling without slip, slip = {slip}");
    }
    for deg in [35.0, 50.0] {
        let th = (deg as Real).to_radians();
        let (a, slip) = incline(deg, mu, true);
        assert!(
            (a - G * (th.sin() - mu * th.cos())).abs() < 1e-6 * G,
            "{deg}°: sliding a = {a}"
        );
        assert!(slip > 1e-3, "{deg}°: must slip, slip = {slip}");
    }
}

#[test]
fn rolling_resistance_holds_a_disk_below_atan_mu_r_and_brakes_its_rolling_above() {
    // moment balance F r ≤ μ_r r N: at rest while tanθ ≤ μ_r; above, rolling without slip
    // with a = ⅔ g (sinθ − μ_r cosθ) (μ = 0.8 keeps it from sliding)
    let (mu, mu_r) = (0.8, 0.1);
    for deg in [2.0, 5.0] {
        let (a, _) = incline_r(deg, mu, true, mu_r);
        assert!(a.abs() < 1e-9, "{deg}°: held by rolling resistance, a = {a}");
    }
    for deg in [10.0, 20.0] {
        let th = (deg as Real).to_radians();
        let (a, slip) = incline_r(deg, mu, true, mu_r);
        let exact = 2.0 / 3.0 * G * (th.sin() - mu_r * th.cos());
        assert!((a - exact).abs() < 1e-6 * G, "{deg}°: a = {a}, expected {exact}");
        assert!(slip.abs() < 1e-9, "rolls without slip: {slip}");
    }
}

/// Drop a disk from `h0` above the floor; return (impact speed, rebound speed) of the first
/// bounce (velocities at the start and end of the impact step).
fn bounce(e: Real, theta: Real) -> (Real, Real) {
    let mut s = State::new();
    s.insert(0.0, R + 0.01, R, 2600.0);
    let p = CdParams {
        restitution_n: e,
        theta,
        dt: 2e-5,
        ..params()
    };
    let mut w = World::new(p, s, vec![Wall::floor(0.0)], None).unwrap();
    for _ in 0..20000 {
        let before = w.state.vy[0];
        w.step().unwrap();
        let after = w.state.vy[0];
        if before < 0.0 && after > before + 0.5 * G * 2e-5 * 10.0 {
            return (-before, after);
        }
    }
    panic!("no bounce");
}

#[test]
fn bouncing_disk_returns_restitution() {
    for e in [0.0, 0.3, 0.75, 1.0] {
        for theta in [0.5, 1.0] {
            let (vin, vout) = bounce(e, theta);
            assert!(vin > 0.4, "impact speed {vin}");
            assert!(
                (vout / vin - e).abs() < 1e-9,
                "ε_n = {e}, θ = {theta}: returned {}",
                vout / vin
            );
        }
    }
}

#[test]
fn resting_column_holds_without_drift_and_base_impulse_is_the_weight() {
    let n = 12;
    let mut s = State::new();
    for k in 0..n {
        s.insert(0.0, R + 2.0 * R * k as Real, R, 2600.0);
    }
    let y0 = s.y.clone();
    let m: Real = s.m.iter().sum();
    let p = params();
    let h = p.dt;
    let mut w = World::new(p, s, vec![Wall::floor(0.0)], None).unwrap();
    w.run(2000).unwrap();
    let drift = w
        .state
        .y
        .iter()
        .zip(&y0)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, Real::max);
    assert!(drift < 1e-9 * 2.0 * R, "column drift {drift} m");
    assert!(w.state.vy.iter().all(|v| v.abs() < 1e-12), "column at rest");
    // impulse received by the floor body = M g h, downwards
    let floor_body = w.len();
    let base = -w.reaction[floor_body][1];
    assert!(
        (base - m * G * h).abs() < 1e-8 * m * G * h,
        "base impulse {base} vs weight·h {}",
        m * G * h
    );
    assert_eq!(w.stats.unconverged, 0);
}

#[test]
fn head_on_collisions_conserve_momentum_and_apply_restitution() {
    for e in [0.0, 0.5, 1.0] {
        for (r2, v1, v2) in [(R, 1.0, -1.0), (1.5 * R, 0.7, -0.2), (0.8 * R, 2.0, 0.5)] {
            let mut s = State::new();
            s.insert(-2.0 * R, 0.0, R, 2600.0);
            s.insert(r2 + 0.5e-4, 0.0, r2, 2600.0);
            s.vx[0] = v1;
            s.vx[1] = v2;
            let p = CdParams {
                gravity: 0.0,
                restitution_n: e,
                dt: 2e-5,
                alert_fraction: 0.2,
                ..params()
            };
            let (m1, m2) = (s.m[0], s.m[1]);
            let p0 = m1 * v1 + m2 * v2;
            let mut w = World::new(p, s, vec![], None).unwrap();
            w.run(400).unwrap();
            let (u1, u2) = (w.state.vx[0], w.state.vx[1]);
            let p1 = m1 * u1 + m2 * u2;
            assert!(
                (p1 - p0).abs() < 1e-12 * (m1 * v1.abs() + m2 * v2.abs()),
                "momentum {p0} → {p1}"
            );
            assert!(
                ((u2 - u1) - e * (v1 - v2)).abs() < 1e-9,
                "e = {e}: separation {} vs e·approach {}",
                u2 - u1,
                e * (v1 - v2)
            );
            assert!(
                w.state.vy.iter().chain(&w.state.w).all(|v| v.abs() < 1e-12),
                "head-on: no transverse motion"
            );
        }
    }
}

#[test]
fn static_pile_interpenetration_stays_below_one_percent_of_d() {
    // 12 × 8 grains of d ∈ [0.8, 1.2] mm dropped by ≤ 9 mm: v_max ≈ √(2 g H) ≈ 0.45 m/s,
    // c.5 step h = 0.02 d_min / v_max ≈ 3.5e-5 s → one-impact penetration ≤ h v/2 ≈ 1 % d_min
    let spec = DropSpec {
        ncol: 12,
        nrow: 8,
        scale: 1e-3,
        seed: 3,
    };
    let p = CdParams {
        dt: 3.5e-5,
        ..CdParams::default()
    };
    let r = drop(&spec, &p, 6000).unwrap();
    eprintln!(
        "pile: φ = {:.3}, max penetration {:.4} d, contacts {}, unconverged {} of {}, E_k/(Mgd) = {:.2e}",
        r.packing_fraction, r.stats.max_penetration, r.contacts_last, r.stats.unconverged, r.stats.steps, r.ke_over_mgd
    );
    assert!(r.ke_over_mgd < 1e-4, "pile at rest: E_k/(M g d̄) = {}", r.ke_over_mgd);
    assert!(
        r.stats.max_penetration < 0.01,
        "interpenetration {} d ≥ 1 % d",
        r.stats.max_penetration
    );
    assert!(
        r.contacts_last > 150,
        "a jammed pile has ≈ 2 contacts per grain: {}",
        r.contacts_last
    );
}

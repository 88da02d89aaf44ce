//! Analytic verification of the DEM solver (chapter 3 "Validation of DEM", table 4.2):
//! restitution against a wall and between two grains, the 45° incline of Ke & Bray (1995)
//! as tabulated in the thesis, rolling resistance holding a grain on a gentle slope,
//! floor reaction of a settled layer, and energy drift of an elastic frictionless gas.

use granrepro::dem::{DemParams, State, Wall, World};
use granrepro::math::{PI, Real, Vec2};

const R: Real = 0.575e-3; // mean grain of table 4.2

fn no_gravity() -> DemParams {
    DemParams {
        gravity: 0.0,
        ..DemParams::default()
    }
}

/// Rebound/impact speed ratio of one grain thrown at the floor.
fn wall_restitution(p: DemParams) -> Real {
    let mut s = State::new();
    s.insert(0.0, R * 1.001, R, p.density);
    let v_in = 0.5;
    s.vy[0] = -v_in;
    let mut w = World::new(p, s, vec![Wall::floor(0.0)], None).unwrap();
    w.preflight().unwrap();
    // run until the grain is clear of the floor again
    for _ in 0..100_000 {
        w.step().unwrap();
        if w.state.vy[0] > 0.0 && w.state.y[0] > R * 1.0005 {
            break;
        }
    }
    w.state.vy[0] / v_in
}

#[test]
fn restitution_grain_on_floor() {
    let mut p = no_gravity();
    p.rolling.enabled = false;
    let e = wall_restitution(p);
    eprintln!("wall restitution = {e:.5}");
    assert!((e - 0.75).abs() < 0.0075, "ε = {e}");
}

#[test]
fn restitution_grain_on_grain() {
    let mut p = no_gravity();
    p.rolling.enabled = false;
    let mut s = State::new();
    s.insert(-R * 1.001, 0.0, R, p.density);
    s.insert(R * 1.001, 0.0, R, p.density);
    let v = 0.5;
    s.vx[0] = v;
    s.vx[1] = -v;
    let mut w = World::new(p, s, vec![], None).unwrap();
    for _ in 0..100_000 {
        w.step().unwrap();
        if w.state.x[1] - w.state.x[0] > 2.0 * R * 1.0005 && w.state.vx[1] > 0.0 {
            break;
        }
    }
    let e = (w.state.vx[1] - w.state.vx[0]) / (2.0 * v);
    eprintln!("pair restitution = {e:.5}");
    assert!((e - 0.75).abs() < 0.0075, "ε = {e}");
}

/// Disk of radius 1 m, ρ = 2650 kg/m³ on a 45° plane (thesis table "Comparison of
/// theoretical and DEM results"), friction angle φ: returns (a/g, θ̈ r/g, N/(mg cosβ), S/(mg)).
fn incline(mu: Real) -> (Real, Real, Real, Real) {
    let beta = PI / 4.0;
    let r = 1.0;
    let mut p = DemParams::default();
    p.density = 2650.0;
    p.rolling.enabled = false;
    p.wall.friction = mu;
    p.dt = 2e-5;
    p.watchdog.every = 0;
    let n = Vec2::new(beta.sin(), beta.cos());
    let m = p.density * PI * r * r;
    let g = p.gravity;
    // start at the static overlap so the normal force is steady from t = 0
    let delta = m * g * beta.cos() / p.wall.kn;
    let c = n * (r - delta);
    let mut s = State::new();
    s.insert(c.x, c.y, r, p.density);
    let wall = Wall::new("incline", Vec2::zeros(), n);
    let mut w = World::new(p, s, vec![wall], None).unwrap();
    // least-squares quadratic fits of s(t) and θ(t) over t ∈ [0.05, 0.2] s average out
    // the ringing of the (undamped) tangential spring and the initial stick phase
    let down = Vec2::new(beta.cos(), -beta.sin());
    w.run_until(0.05).unwrap();
    let (mut ts, mut ss, mut th) = (vec![], vec![], vec![]);
    for _ in 0..150 {
        w.run_until(w.t + 1e-3).unwrap();
        ts.push(w.t);
        ss.push((Vec2::new(w.state.x[0], w.state.y[0]) - c).dot(&down));
        th.push(w.state.theta[0]);
    }
    let a = 2.0 * quad_coeff(&ts, &ss) / g;
    // clockwise rotation rolls the disk downhill (to the right)
    let alpha = -2.0 * quad_coeff(&ts, &th) * r / g;
    let f = w.info.wall_force[0];
    (
        a,
        alpha,
        f.dot(&n) / (-m * g * beta.cos()),
        f.dot(&down).abs() / (m * g),
    )
}

/// Coefficient c of the least-squares fit y ≈ a + b t + c t².
fn quad_coeff(t: &[Real], y: &[Real]) -> Real {
    let mut m = nalgebra::Matrix3::<Real>::zeros();
    let mut v = nalgebra::Vector3::<Real>::zeros();
    for (&ti, &yi) in t.iter().zip(y) {
        let b = nalgebra::Vector3::new(1.0, ti, ti * ti);
        m += b * b.transpose();
        v += b * yi;
    }
    m.lu().solve(&v).unwrap()[2]
}

#[test]
fn incline_45_sliding_frictionless() {
    let (a, alpha, nn, ss) = incline(0.0);
    eprintln!("phi=0: a/g={a:.4} alpha r/g={alpha:.4} N={nn:.4} S={ss:.4}");
    assert!((a - std::f64::consts::FRAC_1_SQRT_2).abs() < 0.002);
    assert!(alpha.abs() < 1e-6);
    assert!((nn - 1.0).abs() < 0.01);
    assert!(ss < 1e-9);
}

#[test]
fn incline_45_rolling_and_sliding() {
    let s2 = (0.5f64).sqrt();
    // μ = 0.2 < tanβ/3: slides while spinning: a = g(sinβ − μ cosβ), θ̈ r = 2μ g cosβ
    let (a, alpha, nn, ss) = incline(0.2);
    eprintln!("mu=0.2: a/g={a:.4} alpha r/g={alpha:.4} N={nn:.4} S={ss:.4}");
    assert!((a - s2 * 0.8).abs() < 0.01 * s2 * 0.8);
    assert!((alpha - 2.0 * 0.2 * s2).abs() < 0.01 * 0.4 * s2);
    assert!((nn - 1.0).abs() < 0.01);
    // μ = 0.5 > tanβ/3: rolls without slip: a = θ̈ r = (2/3) g sinβ
    let (a, alpha, _nn, _) = incline(0.5);
    eprintln!("mu=0.5: a/g={a:.4} alpha r/g={alpha:.4}");
    assert!((a - 2.0 / 3.0 * s2).abs() < 0.01 * s2);
    assert!((alpha - 2.0 / 3.0 * s2).abs() < 0.01 * s2);
}

/// Table 4.2 grain resting on a slope of angle β: rolling resistance (μ_r = 0.3, r_eff = r
/// at a wall) holds it for tanβ < μ_r, it rolls away above.
fn rolled_distance_on_slope(beta_deg: Real, rolling: bool) -> Real {
    let beta = beta_deg.to_radians();
    let mut p = DemParams::default();
    p.rolling.enabled = rolling;
    p.dt = 1e-7;
    let n = Vec2::new(beta.sin(), beta.cos());
    let m = p.density * PI * R * R;
    let delta = m * p.gravity * beta.cos() / p.wall.kn;
    let c = n * (R - delta);
    let mut s = State::new();
    s.insert(c.x, c.y, R, p.density);
    let mut w = World::new(p, s, vec![Wall::new("slope", Vec2::zeros(), n)], None).unwrap();
    w.preflight().unwrap();
    w.run_until(0.02).unwrap();
    (Vec2::new(w.state.x[0], w.state.y[0]) - c).norm()
}

#[test]
fn rolling_resistance_holds_grain_below_threshold() {
    // threshold atan(0.3) = 16.7° (below the wall's sliding angle atan(0.466) = 25°)
    let held = rolled_distance_on_slope(15.0, true);
    let rolls = rolled_distance_on_slope(19.0, true);
    let free = rolled_distance_on_slope(15.0, false);
    eprintln!("15°: {held:e} m, 19°: {rolls:e} m, 15° no rolling resistance: {free:e} m");
    assert!(held < 1e-6 * R, "grain crept {held} m below the threshold slope");
    assert!(rolls > 0.01 * R);
    assert!(free > 0.01 * R);
}

#[test]
fn settled_layer_floor_reaction_equals_weight() {
    // x-periodic strip (no side walls, so no Janssen arching), 3 hex rows of 20 grains
    let p = DemParams {
        dt: 2e-7,
        ..DemParams::default()
    };
    let lx = 40.0 * R * 1.02;
    let mut s = State::new();
    for row in 0..3 {
        for k in 0..20 {
            let rr = if (k + row) % 2 == 0 { R } else { 0.9 * R };
            s.insert(
                (k as Real + 0.5 * (row % 2) as Real) * 2.0 * R * 1.02,
                R * (1.05 + 2.0 * row as Real),
                rr,
                p.density,
            );
        }
    }
    let weight = s.total_mass() * p.gravity;
    let mut w = World::new(p, s, vec![Wall::floor(0.0)], Some(lx)).unwrap();
    let rep = granrepro::dem::prep::settle(&mut w, 1e-11, 0.03, 0.5).unwrap();
    assert!(rep.converged, "{rep:?}");
    let ek = w.energies().ek();
    let f = -w.info.wall_force[0].y;
    eprintln!("floor force {f:.6e} N/m, weight {weight:.6e}, Ek {ek:.3e}");
    assert!((f - weight).abs() < 1e-3 * weight);
}

#[test]
fn elastic_frictionless_gas_energy_drift_is_bounded() {
    // ε = 1 (γ = 0), μ = 0, no rolling: total energy is conserved up to O(dt²) and must
    // not drift. Bound: 1e-4 E_0 after 0.02 s with ~100 collisions per grain.
    let mut p = DemParams::default();
    p.grain.restitution = 1.0;
    p.wall.restitution = 1.0;
    p.grain.friction = 0.0;
    p.wall.friction = 0.0;
    p.rolling.enabled = false;
    p.dt = 1.5e-7;
    let mut s = State::new();
    let mut k = 0;
    for iy in 0..6 {
        for ix in 0..6 {
            let id = s.insert(
                R * (2.0 + 3.0 * ix as Real),
                R * (2.0 + 3.0 * iy as Real),
                R * (0.8 + 0.04 * k as Real % 0.4),
                p.density,
            );
            let a = 1.3 * k as Real;
            s.vx[id.0 as usize] = 0.3 * a.cos();
            s.vy[id.0 as usize] = 0.3 * a.sin();
            k += 1;
        }
    }
    let walls = vec![
        Wall::floor(0.0),
        Wall::left(0.0),
        Wall::right("right", 19.0 * R),
        Wall::ceiling("top", 19.0 * R),
    ];
    let mut w = World::new(p, s, walls, None).unwrap();
    let e0 = w.energies().total();
    let mut worst: Real = 0.0;
    for _ in 0..40 {
        w.run(3000).unwrap();
        let b = w.balance();
        worst = worst.max(b.residual.abs() / e0);
    }
    let e1 = w.energies().total();
    eprintln!("E0 {e0:.6e} E1 {e1:.6e} worst residual {worst:.3e}");
    assert!(worst < 1e-4, "energy drift {worst}");
    assert!(w.ledger.dissipated().abs() < 1e-12 * e0);
}

#[test]
fn contact_history_survives_neighbor_rebuilds() {
    // A collapsing hex column, run twice: once as is, once with forced extra rebuilds of
    // the Verlet list. History is carried by ContactKey, so the results are bit-identical.
    use granrepro::dem::prep::{box_walls, hex_lattice};
    let run = |extra: bool| {
        let p = DemParams::default().softened(0.01);
        let s = hex_lattice(0.01, 0.01, 1.15e-3, p.density);
        let mut w = World::new(p, s, box_walls(0.01), None).unwrap();
        w.walls[2].active = false;
        for _ in 0..20 {
            w.run(100).unwrap();
            if extra {
                w.rebuild();
            }
        }
        let mut hs: Vec<_> = w.contact_histories().filter(|(_, h)| h.tangential != 0.0).collect();
        hs.sort_by_key(|(k, _)| *k);
        let h = hs
            .iter()
            .map(|(k, h)| (k.i, k.j, h.tangential.to_bits(), h.rolling.to_bits()))
            .collect::<Vec<_>>();
        (
            w.state
                .x
                .iter()
                .chain(&w.state.w)
                .map(|v| v.to_bits())
                .collect::<Vec<_>>(),
            h,
            w.rebuilds(),
        )
    };
    let (a, ha, na) = run(false);
    let (b, hb, nb) = run(true);
    eprintln!("rebuilds {na} vs {nb}; {} contacts with tangential history", ha.len());
    assert!(nb > na + 10);
    assert!(ha.len() > 50, "contacts should carry tangential history");
    assert_eq!(ha, hb);
    assert!(a == b, "extra rebuilds changed the trajectory");
}

#[test]
fn moving_plate_meets_a_grain_on_time() {
    // A plate coming down at v onto a grain at rest, from 6 skins away: the grain–wall
    // pass visits only the grains listed near each wall, and the lists must follow the
    // plate (made again each time it has moved half a skin). The first contact force
    // comes at t = gap / v to within a step.
    let p = no_gravity();
    let dt = p.dt;
    let mut s = State::new();
    s.insert(0.0, 0.0, R, p.density);
    let skin = p.skin_fraction * 2.0 * R;
    let gap = 6.0 * skin;
    let v = gap / (400.0 * dt);
    let mut plate = Wall::ceiling("plate", R + gap);
    plate.velocity = Vec2::new(0.0, -v);
    let mut w = World::new(p, s, vec![plate], None).unwrap();
    // one step, then lists made afresh: a new world lists every grain (its slots may
    // hold histories) until its first evaluation
    w.step().unwrap();
    w.rebuild();
    let mut first = None;
    for k in 2..=800u32 {
        w.step().unwrap();
        if w.info.wall_force[0].y != 0.0 {
            first = Some(k);
            break;
        }
    }
    let k = first.expect("the plate passed through the grain");
    let expected = gap / (v * dt);
    eprintln!("first contact at step {k}, expected {expected:.1}");
    assert!(
        (k as Real - expected).abs() <= 1.5,
        "first contact at step {k}, expected {expected:.1}"
    );
    assert!(w.info.wall_force[0].y > 0.0, "the grain pushes the plate up");
}

#[test]
fn grains_moved_by_hand_are_seen_by_the_next_run() {
    // Grains placed by hand between runs (`invalidate_forces`) far from where the lists
    // were built: one onto another grain, one onto the floor. The next run must see both
    // contacts from its first force evaluation, as a world built at the new positions
    // does — bit for bit. (Before the run checked the lists, the first evaluation used
    // the stale pair list: no force between the two grains for the first half kick.)
    let p = DemParams {
        gravity: 0.0,
        ..DemParams::default()
    };
    let place = |s: &mut State| {
        // grain 1 onto grain 0; grain 2 onto the floor
        (s.x[1], s.y[1]) = (s.x[0] + 1.9 * R, s.y[0]);
        (s.x[2], s.y[2]) = (0.05, 0.99 * R);
    };
    let mut s = State::new();
    s.insert(0.0, 0.02, R, p.density);
    s.insert(0.03, 0.02, R, p.density);
    s.insert(0.05, 0.03, R, p.density);
    let mut edited = World::new(p.clone(), s.clone(), vec![Wall::floor(0.0)], None).unwrap();
    edited.run(10).unwrap();
    place(&mut edited.state);
    edited.invalidate_forces();
    edited.run(50).unwrap();
    let mut s2 = s.clone();
    place(&mut s2);
    // (nothing moved in the edited world's first 10 steps: at rest, no gravity, apart)
    let mut fresh = World::new(p, s2, vec![Wall::floor(0.0)], None).unwrap();
    fresh.run(50).unwrap();
    let bits = |w: &World| {
        w.state
            .x
            .iter()
            .chain(&w.state.y)
            .chain(&w.state.vx)
            .chain(&w.state.vy)
            .map(|v| v.to_bits())
            .collect::<Vec<_>>()
    };
    assert!(
        edited.state.vx[1] > 0.0 && edited.state.vy[2] > 0.0,
        "contacts not felt"
    );
    assert_eq!(bits(&edited), bits(&fresh));
}

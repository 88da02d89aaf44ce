//! Analytic cases of the per-run column analysis (src/analysis): each fails on wrong
//! geometry or physics in the shared DEM/MPM code.

use granrepro::analysis::cloud::Cloud;
use granrepro::analysis::failure::failure_line;
use granrepro::analysis::front::{Body, Link, front, lengths_for_gaps};
use granrepro::analysis::inertial::{Grain, coarse_grained};
use granrepro::analysis::runout::{line_fit, mu_e_geometric, staron_hinch_work};
use granrepro::analysis::voronoi::{cells, packing_fraction};

fn lattice(nx: usize, ny: usize, d: f64, hex: bool) -> (Vec<f64>, Vec<f64>) {
    let (mut x, mut y) = (Vec::new(), Vec::new());
    let dy = if hex { d * 3f64.sqrt() / 2.0 } else { d };
    for j in 0..ny {
        for i in 0..nx {
            let shift = if hex && j % 2 == 1 { 0.5 * d } else { 0.0 };
            x.push(0.5 * d + i as f64 * d + shift);
            y.push(0.5 * d + j as f64 * dy);
        }
    }
    (x, y)
}

#[test]
fn block_with_a_dilute_front_needs_the_linking_gap() {
    // A 10 × 5 block of touching grains (d = 1) and a dilute chain of 4 grains ahead of
    // it, each separated from the previous by a gap of 0.3 d.
    let d = 1.0;
    let (mut x, mut y) = lattice(10, 5, d, false);
    let mut xe = 10.0;
    for _ in 0..4 {
        xe += 0.3 + d;
        x.push(xe - 0.5);
        y.push(0.5);
    }
    let n = x.len();
    let r = vec![0.5; n];
    let m = vec![1.0; n];
    let b = Body {
        x: &x,
        y: &y,
        half: &r,
        mass: &m,
    };
    // Contact only: the front is the block's edge.
    let f = front(&b, Link::Contact { gap: 0.01 * d });
    assert!((f.length - 10.0).abs() < 1e-12, "L = {}", f.length);
    assert!((f.height - 5.0).abs() < 1e-12);
    assert_eq!(f.n_main, 50);
    // Linked within 0.5 d: the chain belongs to the mass, L = 10 + 4 × 1.3.
    let f = front(&b, Link::Contact { gap: 0.5 * d });
    assert!((f.length - 15.2).abs() < 1e-9, "L = {}", f.length);
    assert_eq!(f.n_main, 54);
    // The sensitivity helper gives the same numbers gap by gap.
    let l = lengths_for_gaps(&b, &[0.01, 0.29, 0.31, 1.0]);
    assert!((l[0] - 10.0).abs() < 1e-12 && (l[1] - 10.0).abs() < 1e-12);
    assert!((l[2] - 15.2).abs() < 1e-9 && (l[3] - 15.2).abs() < 1e-9);
}

fn sheared_cloud(theta_deg: f64, l0: f64, h0: f64, d: f64) -> Cloud {
    // Bodies on a square lattice filling [0, l0] × [0, h0]; |v| grows linearly with the
    // distance above the plane through the toe (l0, 0) at θ from the horizontal, zero
    // below it (a rigid wedge sliding on the failure plane would have a uniform speed; a
    // linear field tests that the threshold does not tilt the boundary).
    let (x, y) = lattice((l0 / d) as usize, (h0 / d) as usize, d, false);
    let t = theta_deg.to_radians();
    let mut vx = Vec::new();
    let mut vy = Vec::new();
    for i in 0..x.len() {
        // Signed distance from the plane, positive on the wedge side (unit normal
        // (sin θ, cos θ) is orthogonal to the plane's direction (−cos θ, sin θ)).
        let dist = (x[i] - l0) * t.sin() + y[i] * t.cos();
        let v = if dist > 0.0 { dist } else { 0.0 };
        vx.push(v * t.cos());
        vy.push(-v * t.sin());
    }
    let n = x.len();
    Cloud {
        t: 1.0,
        x,
        y,
        half: vec![0.5 * d; n],
        mass: vec![1.0; n],
        vx,
        vy,
    }
}

#[test]
fn linear_velocity_field_gives_the_failure_angle() {
    for theta in [50.0, 55.0, 60.0] {
        let c = sheared_cloud(theta, 0.05, 0.04, 2.5e-4);
        let f = failure_line(&c, 0.05, 5e-4, 0.1).expect("a failure line");
        assert!(
            (f.angle_deg - theta).abs() < 1.0,
            "θ = {theta}: measured {}",
            f.angle_deg
        );
        assert!(f.r2 > 0.99);
    }
    // A vertical surface (the whole right half moving) reads 90°.
    let mut c = sheared_cloud(55.0, 0.05, 0.04, 2.5e-4);
    for i in 0..c.len() {
        c.vx[i] = if c.x[i] > 0.025 { 1.0 } else { 0.0 };
        c.vy[i] = 0.0;
    }
    let f = failure_line(&c, 0.05, 5e-4, 0.1).unwrap();
    assert!((f.angle_deg - 90.0).abs() < 0.5, "{}", f.angle_deg);
}

#[test]
fn hexagonal_lattice_has_the_densest_packing_fraction() {
    let d = 1.0e-3;
    let (x, y) = lattice(20, 20, d, true);
    let r = vec![0.5 * d; x.len()];
    let c = cells(&x, &y, &r, 0.4 * d);
    // Away from the wall and the base (their cells run to x = 0, y = 0: a wall effect).
    let away = |i: usize| x[i] > d && y[i] > d;
    let (phi, n) = packing_fraction(&c, &r, away);
    let exact = std::f64::consts::PI / (2.0 * 3f64.sqrt());
    assert!(n > 200, "interior cells: {n}");
    assert!((phi - exact).abs() < 1e-9, "φ = {phi}, π/(2√3) = {exact}");
    // Every interior cell is the hexagon of area (√3/2) d².
    for i in 0..x.len() {
        if c.interior[i] && away(i) {
            assert!(
                (c.area[i] - 3f64.sqrt() / 2.0 * d * d).abs() < 1e-15,
                "cell {i}: {}",
                c.area[i]
            );
        }
    }
    // A square lattice: π/4.
    let (x, y) = lattice(15, 15, d, false);
    let c = cells(&x, &y, &r[..x.len()], 0.4 * d);
    let (phi, _) = packing_fraction(&c, &r[..x.len()], |i| x[i] > d && y[i] > d);
    assert!((phi - std::f64::consts::FRAC_PI_4).abs() < 1e-9, "φ = {phi}");
}

#[test]
fn simple_shear_gives_the_analytic_inertial_number() {
    // A layer of bodies on a lattice of spacing s, v_x = γ̇ y. Lithostatic p at the centre
    // of a cell row = g × (mass per width above). I = γ̇ d / √(p/ρ_s).
    let s = 1.0e-3;
    let (nx, ny) = (60, 30);
    let (x, y) = lattice(nx, ny, s, false);
    let n = x.len();
    let rho = 2000.0;
    let m = rho * s * s;
    let gdot = 20.0;
    let c = Cloud {
        t: 0.0,
        vx: y.iter().map(|y| gdot * y).collect(),
        vy: vec![0.0; n],
        x,
        y,
        half: vec![0.5 * s; n],
        mass: vec![m; n],
    };
    let g = 9.81;
    let cell = 3.0 * s;
    let st = coarse_grained(
        &c,
        Grain {
            cell,
            d: s,
            rho_s: rho,
            g,
        },
    );
    // Rows of cells from the top: the k-th cell row from the top has p = ρ g cell (k + ½).
    // Mass-weighted over the interior rows k = 1 .. nrow−2 (equal masses).
    let nrow = ny / 3;
    let mut expect = 0.0;
    let mut cnt = 0.0;
    for k in 1..nrow - 1 {
        let p = rho * g * cell * (k as f64 + 0.5);
        expect += gdot * s / (p / rho).sqrt();
        cnt += 1.0;
    }
    expect /= cnt;
    assert!(
        (st.mean - expect).abs() < 1e-9 * expect,
        "mean I {} vs {}",
        st.mean,
        expect
    );
    assert!(st.flowing_fraction > 0.5);
    // A rigid translation does not flow.
    let mut c2 = c.clone();
    c2.vx = vec![0.3; n];
    let st = coarse_grained(
        &c2,
        Grain {
            cell,
            d: s,
            rho_s: rho,
            g,
        },
    );
    assert_eq!(st.flowing_fraction, 0.0);
}

#[test]
fn runout_helpers() {
    // μ_e = H_0/(L_f − L_0).
    assert!((mu_e_geometric(0.02, 0.05, 0.1) - 0.4).abs() < 1e-12);
    // W = g Σ m |Δx|.
    assert!((staron_hinch_work(&[0.0, 1.0], &[0.5, 0.0], &[2.0, 1.0], 10.0) - 20.0).abs() < 1e-12);
    // A straight line has R² = 1 and its slope.
    let t: Vec<f64> = (0..50).map(|k| k as f64 * 0.1).collect();
    let l: Vec<f64> = t.iter().map(|t| 2.0 * t + 1.0).collect();
    let (v, r2, n) = line_fit(&t, &l, 0.8, 2.8);
    assert!((v - 2.0).abs() < 1e-12 && (r2 - 1.0).abs() < 1e-12 && (19..=21).contains(&n));
}

#[test]
fn deposit_front_shape_tells_a_triangle_from_a_parabola() {
    // fig 4.20's measure: a straight (triangular) front is fitted exactly by a line, a
    // parabolic one is not; the R² gain of the quadratic separates the two.
    use granrepro::analysis::runout::{poly_r2, surface_profile};
    let x: Vec<f64> = (0..30).map(|k| 0.5 + k as f64).collect();
    let tri: Vec<f64> = x.iter().map(|v| 10.0 - v / 3.0).collect();
    let par: Vec<f64> = x.iter().map(|v| 10.0 * (1.0 - (v / 30.0).powi(2))).collect();
    let gain = |h: &[f64]| poly_r2(&x, h, 2) - poly_r2(&x, h, 1);
    assert!(gain(&tri).abs() < 1e-9, "a line gains nothing: {}", gain(&tri));
    assert!(gain(&par) > 0.02, "a parabola gains: {}", gain(&par));
    // the surface of grains stacked to those heights is read back bin by bin
    let half = vec![0.5; x.len()];
    let y: Vec<f64> = tri.iter().map(|h| h - 0.5).collect();
    let prof = surface_profile(&x, &y, &half, 1.0);
    for ((_, h), want) in prof.iter().zip(&tri) {
        assert!((h - want).abs() < 1e-12);
    }
}

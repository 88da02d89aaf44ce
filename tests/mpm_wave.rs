//! 1D elastic wave speed. An elastic column between frictionless bilateral walls (uniaxial
//! strain) on a fixed base, loaded by gravity suddenly at t = 0. Every mode of the fixed–free
//! bar starts from rest and peaks together at t = T/2 = 2H/c_p, c_p = √(M/ρ) with the
//! plane-strain P-wave modulus M = E(1−ν)/((1+ν)(1−2ν)) (docs/definitions.md c.3:
//! 34.27 m/s): the mean settlement reaches its first maximum there.

use granrepro::mpm::{Axis, Grid, Model, MpmParams, Solver, State, Wall, particles};

#[test]
fn p_wave_speed_from_first_settlement_peak() {
    let c = measure(1.0);
    let cp = MpmParams::default().material.p_wave_speed();
    let err = (c - cp).abs() / cp;
    eprintln!("wave: measured c_p = {c:.3} m/s, theory {cp:.3} m/s, error {err:.3e}");
    assert!(err < 0.02, "wave speed error {err}");
}

/// Regression (front points ejected from the a = 0.4 toe at 2 mm / 4 PPC): points dilated
/// several-fold at a thinning front had a wave speed √J c_p with constant moduli and broke
/// the CFL limit. Moduli now scale with density (E V_0/V), so a bar whose points are all
/// dilated by J = 4 carries waves at c_p (constant moduli would give 2 c_p).
#[test]
fn dilated_points_keep_the_p_wave_speed() {
    let c = measure(4.0);
    let cp = MpmParams::default().material.p_wave_speed();
    let err = (c - cp).abs() / cp;
    eprintln!("dilated (J = 4) wave: measured {c:.3} m/s, theory {cp:.3} m/s, error {err:.3e}");
    assert!(err < 0.02, "wave speed error {err}");
}

/// Wave speed measured in the column of points pre-dilated by `j` (volume j·V_0, same mass).
fn measure(j: f64) -> f64 {
    let mut p = MpmParams::quick();
    p.material.model = Model::Elastic;
    p.cell_size = 2e-3;
    p.ppc = 4;
    let (w, hgt) = (4e-3, 0.1);
    let s = p.spacing();
    let pts = particles::rectangle(
        0.0,
        0.0,
        (w / s).round() as usize,
        (hgt / s).round() as usize,
        s,
        p.material.density,
        0,
    );
    let walls = vec![
        Wall {
            axis: Axis::X,
            at: 0.0,
            material_on_plus_side: true,
            friction: 0.0,
            bilateral: true,
        },
        Wall {
            axis: Axis::X,
            at: w,
            material_on_plus_side: false,
            friction: 0.0,
            bilateral: true,
        },
        Wall {
            axis: Axis::Y,
            at: 0.0,
            material_on_plus_side: true,
            friction: 0.0,
            bilateral: true,
        },
    ];
    let grid = Grid::covering(0.0, 0.0, w, hgt * 1.1, p.cell_size);
    let mut solver = Solver::new(&p, grid, walls).unwrap();
    let mut pts = pts;
    for q in &mut pts {
        q.j = j;
        q.vol = j * q.vol0;
    }
    let mut state = State::new(pts);
    let cp = p.material.p_wave_speed();
    assert!((cp - 34.27).abs() < 0.01, "c_p = {cp}");
    let dt = 0.05 * p.cell_size / cp;
    let mean_y = |st: &State| st.points.iter().map(|q| q.x.y).sum::<f64>() / st.points.len() as f64;
    let y0 = mean_y(&state);
    // First maximum of the settlement u(t), refined by a parabola through the three samples
    // around it (sub-step resolution).
    let (mut um2, mut um1) = (0.0, 0.0);
    let mut t_peak = None;
    for _ in 0..4000 {
        solver.step(&mut state, dt).unwrap();
        let u = y0 - mean_y(&state);
        if u < um1 && um1 > 0.0 {
            let denom = um2 - 2.0 * um1 + u;
            let off = if denom != 0.0 { 0.5 * (um2 - u) / denom } else { 0.0 };
            t_peak = Some(state.t - dt + off * dt);
            break;
        }
        um2 = um1;
        um1 = u;
    }
    let t_peak = t_peak.expect("no peak");
    2.0 * hgt / t_peak
}

//! Conservation in the grid transfers: without gravity and walls one step conserves total
//! mass on the grid and total linear momentum (internal forces sum to zero because the GIMP
//! gradients do), for FLIP and PIC, USL and MUSL.

use granrepro::math::Vec2;
use granrepro::mpm::{Grid, Model, MpmParams, Scheme, Solver, State, StepRule, Stress, particles};

fn lcg(seed: &mut u64) -> f64 {
    *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    (*seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
}

fn run(flip: f64, scheme: Scheme) {
    let mut p = MpmParams::quick();
    p.gravity = 0.0;
    p.flip = flip;
    p.scheme = scheme;
    p.material.model = Model::MohrCoulomb;
    p.step = StepRule::Fixed { dt: 1e-5 };
    let s = p.spacing();
    let mut pts = particles::rectangle(0.02, 0.02, 20, 12, s, p.material.density, 0);
    let mut seed = 3u64;
    for q in &mut pts {
        q.v = Vec2::new(lcg(&mut seed), lcg(&mut seed));
        q.stress = Stress {
            xx: -500.0 + 200.0 * lcg(&mut seed),
            yy: -800.0 + 200.0 * lcg(&mut seed),
            xy: 100.0 * lcg(&mut seed),
            zz: -600.0,
        };
        q.x += Vec2::new(0.3 * s * lcg(&mut seed), 0.3 * s * lcg(&mut seed));
    }
    let grid = Grid::covering(0.0, 0.0, 0.1, 0.08, p.cell_size);
    let mut solver = Solver::new(&p, grid, vec![]).unwrap();
    let mut state = State::new(pts);
    let mom = |st: &State| st.points.iter().fold(Vec2::zeros(), |a, q| a + q.v * q.mass);
    let mass: f64 = state.points.iter().map(|q| q.mass).sum();
    let m0 = mom(&state);
    let scale = state.points.iter().map(|q| q.mass * q.v.norm()).sum::<f64>();
    for _ in 0..5 {
        solver.step(&mut state, 1e-5).unwrap();
        let grid_mass = solver.grid_mass(&mut state).unwrap();
        assert!(
            (grid_mass - mass).abs() < 1e-12 * mass,
            "grid mass {grid_mass} vs {mass}"
        );
    }
    let m1 = mom(&state);
    assert!(
        (m1 - m0).norm() < 1e-12 * scale,
        "momentum drift {:?} (scale {scale})",
        m1 - m0
    );
}

#[test]
fn usl_flip_conserves_mass_and_momentum() {
    run(1.0, Scheme::Usl);
}
#[test]
fn usl_pic_conserves_mass_and_momentum() {
    run(0.0, Scheme::Usl);
}
#[test]
fn musl_conserves_mass_and_momentum() {
    run(1.0, Scheme::Musl);
}

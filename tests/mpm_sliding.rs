//! Block sliding on a frictional base: an elastic block launched at v0 along the base (Coulomb
//! μ, nodal constraint) decelerates at μ g and stops after v0/(μ g).

use granrepro::math::Vec2;
use granrepro::mpm::{Grid, Model, MpmParams, Solver, State, StepRule, boundary, geostatic, particles};

fn slide(mu: f64) -> (f64, f64) {
    let mut p = MpmParams::quick();
    p.material.model = Model::Elastic;
    p.cell_size = 2e-3;
    p.ppc = 4;
    p.wall_friction = mu;
    p.step = StepRule::Cfl {
        courant: 0.5,
        dt_max: 1e-3,
    };
    let s = p.spacing();
    let (bw, bh) = (0.02, 0.01);
    let mut pts = particles::rectangle(
        0.01,
        0.0,
        (bw / s) as usize,
        (bh / s) as usize,
        s,
        p.material.density,
        0,
    );
    let nu = p.material.poisson;
    geostatic::k0_stress(&mut pts, bh, p.material.density, p.gravity, nu / (1.0 - nu));
    let v0 = 0.5;
    for q in &mut pts {
        q.v = Vec2::new(v0, 0.0);
    }
    let mut walls = boundary::column_walls(mu);
    walls.remove(0); // base only
    let grid = Grid::covering(0.0, 0.0, 0.12, 0.02, p.cell_size);
    let mut solver = Solver::new(&p, grid, walls).unwrap();
    let mut state = State::new(pts);
    let vx = |st: &State| {
        let m: f64 = st.points.iter().map(|q| q.mass).sum();
        st.points.iter().map(|q| q.mass * q.v.x).sum::<f64>() / m
    };
    let a_th = mu * p.gravity;
    let t_stop = v0 / a_th;
    // Least-squares slope of v_x(t) over the middle of the sliding phase.
    let (t0, t1) = (0.2 * t_stop, 0.8 * t_stop);
    let (mut n, mut st, mut sv, mut stt, mut stv) = (0.0, 0.0, 0.0, 0.0, 0.0);
    while state.t < t1 {
        let dt = solver.dt(&state);
        solver.step(&mut state, dt).unwrap();
        if state.t >= t0 {
            let v = vx(&state);
            n += 1.0;
            st += state.t;
            sv += v;
            stt += state.t * state.t;
            stv += state.t * v;
        }
    }
    let slope = (n * stv - st * sv) / (n * stt - st * st);
    (-slope, a_th)
}

#[test]
fn block_decelerates_at_mu_g() {
    for mu in [0.2, 0.466] {
        let (a, a_th) = slide(mu);
        let err = (a - a_th).abs() / a_th;
        eprintln!("sliding block mu = {mu}: deceleration {a:.4} m/s², theory {a_th:.4}, error {err:.3e}");
        assert!(err < 0.03, "deceleration error {err} for mu = {mu}");
    }
}

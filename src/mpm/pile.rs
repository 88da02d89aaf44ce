//! The MPM pile (docs/definitions.md SC-PILE, PILE-MPM, stages P8 and R10/R11): material
//! points on a regular lattice (√PPC per cell and direction) filling the outline of the DEM
//! deposit, loaded geostatically, then given the horizontal excitation and run until rest.
//!
//! Geostatic stage (docs/definitions.md I7): a cohesionless Mohr–Coulomb slope steeper than
//! φ is not statically admissible, so the pile is loaded with a higher friction angle
//! (`geostatic_friction_deg`) and the run's φ is restored at t = 0 (option ii of I7); the
//! stress field is kept, velocities and plastic history reset.

use crate::analysis::front::{Link, front};
use crate::analysis::pile::PileRun;
use crate::analysis::pile::{
    Frame, FrameTimes, Profile, Sample, Sampled, StopRule, excitation, kinetic, sample_run, surface_at,
};
use crate::math::{Real, Vec2};
use crate::mpm::boundary::column_walls;
use crate::mpm::energy::energies;
use crate::mpm::error::MpmError;
use crate::mpm::grid::Grid;
use crate::mpm::params::MpmParams;
use crate::mpm::particles::Point;
use crate::mpm::solver::Solver;
use crate::mpm::state::State;

/// Points of spacing s = h/√PPC on the lattice under the surface `profile` (bin centre,
/// top) for x ∈ [0, `l0`]: a point is kept when its centre lies below the surface.
pub fn seed_points(params: &MpmParams, profile: &[(Real, Real)], l0: Real) -> Vec<Point> {
    let s = params.spacing();
    let nx = (l0 / s).ceil() as usize;
    let h_max = profile
        .iter()
        .filter(|p| p.1.is_finite())
        .map(|p| p.1)
        .fold(0.0, Real::max);
    let ny = (h_max / s).ceil() as usize;
    let mut pts = Vec::new();
    for i in 0..nx {
        let x = (i as Real + 0.5) * s;
        let top = surface_at(profile, x, l0);
        for j in 0..ny {
            let y = (j as Real + 0.5) * s;
            if y < top {
                pts.push(Point::new(
                    pts.len() as u32,
                    Vec2::new(x, y),
                    s * s,
                    params.material.density,
                ));
            }
        }
    }
    pts
}

/// Front and height of the points (D01 MPM variant: linked within 1.5 s, L = max(x + l_p)).
pub fn front_of_points(points: &[Point], lp: Real, s: Real) -> crate::analysis::front::Front {
    front(
        &super::column_front::PointBodies::new(points, lp).body(),
        Link::Distance(1.5 * s),
    )
}

/// Geometry and loading of an MPM pile.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MpmPileSpec {
    /// Friction angle of the geostatic stage [deg] (I7 option ii).
    pub geostatic_friction_deg: Real,
    /// Grid length as a multiple of L_0 (must hold the longest run-out).
    pub domain_length_l0: Real,
    /// Grid height as a multiple of H_0.
    pub domain_height_h0: Real,
}

impl Default for MpmPileSpec {
    fn default() -> Self {
        MpmPileSpec {
            geostatic_friction_deg: 30.0,
            domain_length_l0: 8.0,
            domain_height_h0: 2.0,
        }
    }
}

/// A loaded MPM pile at rest.
#[derive(Debug, Clone)]
pub struct MpmPile {
    /// Points with the geostatic stress.
    pub state: State,
    /// Grid (reused by the runs).
    pub grid: Grid,
    /// Geostatic report: simulated time [s].
    pub geostatic_time: Real,
}

/// Seed the points under `profile` and load them geostatically.
pub fn load_pile(
    params: &MpmParams,
    spec: &MpmPileSpec,
    profile: &[(Real, Real)],
    l0: Real,
) -> Result<MpmPile, MpmError> {
    let pts = seed_points(params, profile, l0);
    if pts.is_empty() {
        return Err(MpmError::InvalidParams(vec![crate::validate::Issue {
            key: "mpm.cell_size".into(),
            value: format!("{}", params.cell_size),
            allowed: "a point spacing h/√PPC small enough for the pile to hold points".into(),
        }]));
    }
    let h0 = pts.iter().map(|p| p.x.y).fold(0.0, Real::max) + params.spacing();
    let grid = Grid::covering(
        0.0,
        0.0,
        spec.domain_length_l0 * l0,
        spec.domain_height_h0 * h0 + 4.0 * params.cell_size,
        params.cell_size,
    );
    let mut geo = params.clone();
    geo.material.friction_deg = spec.geostatic_friction_deg;
    let mut solver = Solver::new(&geo, grid.clone(), column_walls(params.wall_friction))?;
    let mut state = State::new(pts);
    let rep = crate::mpm::geostatic::run(&mut solver, &mut state, h0)?;
    Ok(MpmPile {
        state,
        grid,
        geostatic_time: rep.time,
    })
}

/// Excite a loaded pile and run it until `stop`.
/// `link`: largest centre distance [m] at which two points belong to the same mass (D01's
/// MPM rule is 1.5 × the initial spacing; the stage passes 2 cells, the GIMP stencil).
pub fn run_pile(
    pile: &MpmPile,
    params: &MpmParams,
    profile: Profile,
    e0: Real,
    stop: &StopRule,
    link: Real,
) -> Result<PileRun, MpmError> {
    run_pile_frames(pile, params, profile, e0, stop, link, &FrameTimes::default())
}

/// A frame of material points (σ_yy included: fig4-24b).
pub fn point_frame(st: &State, lp: Real) -> Frame {
    let p = &st.points;
    Frame {
        t: st.t,
        x: p.iter().map(|q| q.x.x).collect(),
        y: p.iter().map(|q| q.x.y).collect(),
        half: vec![lp; p.len()],
        vx: p.iter().map(|q| q.v.x).collect(),
        vy: p.iter().map(|q| q.v.y).collect(),
        sigma_yy: p.iter().map(|q| q.stress.yy).collect(),
    }
}

/// [`run_pile`] taking frames at `frames` (times [s], at sample instants); the run does not
/// stop before the last frame.
pub fn run_pile_frames(
    pile: &MpmPile,
    params: &MpmParams,
    profile: Profile,
    e0: Real,
    stop: &StopRule,
    link: Real,
    frames: &FrameTimes,
) -> Result<PileRun, MpmError> {
    let mut state = pile.state.clone();
    let lp = params.half_width();
    let y: Vec<Real> = state.points.iter().map(|p| p.x.y).collect();
    let m: Vec<Real> = state.points.iter().map(|p| p.mass).collect();
    let top = y.iter().fold(0.0, |a: Real, b| a.max(*b)) + lp;
    let vx = excitation(profile, &y, &m, top, e0);
    let e0_check = kinetic(&m, &vx) / e0;
    for (p, v) in state.points.iter_mut().zip(&vx) {
        p.v = Vec2::new(*v, 0.0);
    }
    let solver = Solver::new(params, pile.grid.clone(), column_walls(params.wall_friction))?;
    let el = *solver.elastic();
    let g = params.gravity;
    let rec = |st: &State| -> Sample {
        let e = energies(st, &el, g);
        let f = front_of_points(&st.points, lp, link / 1.5);
        Sample {
            t: st.t,
            l: f.length,
            h: f.height,
            ek: e.kinetic_grid,
            ekx: e.kinetic_x,
            eky: e.kinetic_y,
            erot: 0.0,
        }
    };
    let dts = stop.dt_sample(g);
    let mut next = dts;
    let advance = |(solver, state): &mut (Solver, State)| -> Result<(), MpmError> {
        while state.t < next - 1e-12 {
            let dt = solver.dt(state).min(next - state.t).max(1e-9);
            solver.step(state, dt)?;
        }
        next += dts;
        Ok(())
    };
    let mut sv = (solver, state);
    let run = sample_run(
        &mut sv,
        stop,
        frames,
        e0,
        g,
        |s| s.1.t,
        |s| rec(&s.1),
        |s| point_frame(&s.1, lp),
        advance,
    )?;
    let state = sv.1;
    let l0 = run.samples[0].l;
    let Sampled {
        samples,
        frames: shots,
        stopped,
    } = run;
    let xs = state.points.iter().map(|p| p.x.x).collect();
    let ys = state.points.iter().map(|p| p.x.y).collect();
    Ok(PileRun {
        samples,
        l0,
        e0,
        e0_check,
        stopped,
        steps: state.step,
        final_bodies: (xs, ys, vec![lp; state.points.len()]),
        frames: shots,
    })
}

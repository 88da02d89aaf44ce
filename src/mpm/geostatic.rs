//! Geostatic initial stress (chapter 4 §4.2.1: "initial vertical effective stress … before
//! the collapse stage"; method UNSPEC, docs/definitions.md SC-COL).
//!
//! Method chosen: gravity loading of the stress-free points with the walls in place (the
//! column additionally behind a frictionless roller gate), Cundall local non-viscous damping
//! α = `geostatic.damping` on the nodal forces, PIC velocity transfer and a CFL step, until the kinetic energy falls
//! below `ke_tol · M g H` (after at least `min_time`). The constitutive model is the run's
//! own (Mohr–Coulomb yields locally where K0 = ν/(1−ν) = 0.28 is below the active limit;
//! the gate contains it). Afterwards velocities, plastic strain/work, the deformation
//! gradient (V_0 ← V), time, step count and the ledger are reset: the collapse starts from the
//! loaded stress state at rest.
//!
//! [`k0_stress`] is the analytic alternative (σ_yy = −ρg(H − y), σ_xx = σ_zz = K0 σ_yy), used to
//! start verification blocks near equilibrium.

use super::energy::{energies, total_mass};
use super::error::MpmError;
use super::particles::{Point, Stress};
use super::solver::Solver;
use super::state::{Ledger, State};
use crate::math::{Real, Vec2};

/// Outcome of the geostatic stage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeostaticReport {
    /// Simulated loading time [s].
    pub time: Real,
    /// Steps taken.
    pub steps: u64,
    /// Final E_k/(M g H) [-].
    pub ke_ratio: Real,
    /// Wall-clock time [s].
    pub wall_s: Real,
}

/// Load `state` under gravity with damping until stationary; then reset it to rest at t = 0.
/// `height` is the column height H used in the stationarity ratio [m]. The solver's walls are
/// used as they are (add the gate before, remove it after).
pub fn run(solver: &mut Solver, state: &mut State, height: Real) -> Result<GeostaticReport, MpmError> {
    let gp = solver.params().geostatic.clone();
    let g = solver.params().gravity;
    let el = *solver.elastic();
    let scale = (total_mass(&state.points) * g * height).max(1e-300);
    let (old_damping, old_flip) = (solver.damping, solver.flip);
    solver.damping = gp.damping;
    solver.flip = 0.0;
    let clock = std::time::Instant::now();
    let (t_start, s_start) = (state.t, state.step);
    let mut ratio;
    let mut k = 0u64;
    loop {
        let dt = solver.cfl_dt(state, gp.courant);
        solver.step(state, dt)?;
        k += 1;
        let t = state.t - t_start;
        if k.is_multiple_of(20) || t >= gp.max_time {
            ratio = energies(state, &el, g).kinetic / scale;
            if t >= gp.min_time && ratio < gp.ke_tol {
                break;
            }
            if t >= gp.max_time {
                solver.damping = old_damping;
                solver.flip = old_flip;
                return Err(MpmError::GeostaticNotStationary {
                    t,
                    ratio,
                    tol: gp.ke_tol,
                });
            }
        }
    }
    solver.damping = old_damping;
    solver.flip = old_flip;
    let report = GeostaticReport {
        time: state.t - t_start,
        steps: state.step - s_start,
        ke_ratio: ratio,
        wall_s: clock.elapsed().as_secs_f64(),
    };
    reset_to_rest(state);
    Ok(report)
}

/// Zero velocities, plastic history and the clock; make the current configuration the
/// reference one (J = 1, V_0 = V).
pub fn reset_to_rest(state: &mut State) {
    for p in &mut state.points {
        p.v = Vec2::zeros();
        p.eps_p = 0.0;
        p.work_p = 0.0;
        p.vol0 = p.vol;
        p.j = 1.0;
    }
    state.t = 0.0;
    state.step = 0;
    state.ledger = Ledger::default();
    state.last_dt = 0.0;
}

/// Analytic K0 stress: σ_yy = −ρ g (H − y), σ_xx = σ_zz = K0 σ_yy, σ_xy = 0, for points under
/// a free surface at height `surface` [m].
pub fn k0_stress(points: &mut [Point], surface: Real, density: Real, g: Real, k0: Real) {
    for p in points {
        let syy = -density * g * (surface - p.x.y).max(0.0);
        p.stress = Stress {
            xx: k0 * syy,
            yy: syy,
            xy: 0.0,
            zz: k0 * syy,
        };
    }
}

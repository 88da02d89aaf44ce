//! Benchmark: the deposit of the Siconos reference script (`bench/siconos/deposit.py
//! NCOL NROW NSTEPS`): NCOL × NROW disks, r ∈ [0.4, 0.6] m in 8 classes,
//! ρ = 2600, μ = 0.4, ε = 0, θ = ½, h = 2e-3 s, tolerance 1e-4, dropped from a lattice of
//! pitch 1.22 m into a box of width 1.22·NCOL m. Everything in the steps is timed
//! (detection, solve, update, ledger, watchdog), as Siconos' wall time includes its own.
//!
//! Tolerance: Siconos stops on its relative natural-map residual; we require both our
//! impulse-change norm and our natural-map residual ≤ 1e-4, i.e. at least as strict.
//! Alert distance 0.15 d_min: grains of the 20-row drop reach ≈ 10 m/s, 0.02 m per step,
//! and the pre-flight needs h·v ≤ alert/2.

use crate::analysis::pile::{Profile, excitation};
use crate::cd::error::CdError;
use crate::cd::params::CdParams;
use crate::cd::pile::{DropSpec, core_packing_fraction, drop, settled_deposit};
use crate::cd::world::{Timers, World};
use crate::dem::state::State;
use crate::dem::walls::Wall;
use crate::math::Real;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// One measurement.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BenchResult {
    /// Case name, e.g. `siconos-25x20`.
    pub case: String,
    /// Rayon threads of the pool it ran in (the engine is sequential).
    pub threads: usize,
    /// Grains.
    pub particles: usize,
    /// Mean active contacts per step.
    pub contacts: f64,
    /// Active contacts at the last step.
    pub contacts_last: usize,
    /// Steps.
    pub steps: u64,
    /// NLGS sweeps, summed over steps.
    pub iterations: u64,
    /// Wall time of the steps [s].
    pub wall_s: f64,
    /// Σ contacts × sweeps / wall_s.
    pub contact_iterations_per_s: f64,
    /// Steps that hit the iteration cap.
    pub unconverged: u64,
    /// Largest exit residual.
    pub max_residual: f64,
    /// Core packing fraction at the end ([`crate::cd::pile::core_packing_fraction`]).
    pub packing_fraction: f64,
    /// Kinetic energy / (M g d̄) at the end (settled when ≪ 1).
    pub ke_over_mgd: f64,
    /// Seconds per phase.
    pub timers: Timers,
}

/// Parameters of the Siconos-equivalent case.
pub fn siconos_params() -> CdParams {
    CdParams {
        dt: 2e-3,
        theta: 0.5,
        friction: 0.4,
        wall_friction: 0.4,
        restitution_n: 0.0,
        restitution_t: 0.0,
        tolerance: 1e-4,
        residual_tolerance: 1e-4,
        max_iterations: 2000,
        alert_fraction: 0.15,
        ..CdParams::default()
    }
}

/// Run the `ncol × nrow` Siconos deposit for `steps` steps in a pool of `threads`.
pub fn run(ncol: usize, nrow: usize, threads: usize, steps: u64) -> Result<BenchResult, CdError> {
    in_pool(threads, || {
        let spec = DropSpec {
            ncol,
            nrow,
            scale: 1.0,
            seed: 1,
        };
        let r = drop(&spec, &siconos_params(), steps)?;
        Ok(BenchResult {
            case: format!("siconos-{ncol}x{nrow}"),
            threads,
            particles: r.state.len(),
            contacts: r.contacts_mean,
            contacts_last: r.contacts_last,
            steps: r.stats.steps,
            iterations: r.stats.iterations,
            wall_s: r.wall_s,
            contact_iterations_per_s: r.stats.contact_iterations as f64 / r.wall_s,
            unconverged: r.stats.unconverged,
            max_residual: r.stats.max_residual,
            packing_fraction: r.packing_fraction,
            ke_over_mgd: r.ke_over_mgd,
            timers: r.timers,
        })
    })
}

/// The dense scenes of `bench cd-dense`: the pile and the shear cell are dense packings, where
/// every grain carries contacts and Gauss–Seidel needs many sweeps, unlike the loose drop of
/// [`run`]. The `ncol × nrow` deposit of [`run`] (same disks, walls and contact law) is settled
/// for `settle_s` seconds (untimed, [`settled_deposit`]) and stopped. With `kick_mgd > 0` every
/// grain then gets the pile's gradient excitation (D19, [`excitation`]: v_x ∝ y_max − y) of
/// E_0 = kick_mgd · M g d̄, M the total mass: the chapter's pile scene in miniature.
pub fn dense_scene(ncol: usize, nrow: usize, settle_s: Real, kick_mgd: Real) -> Result<(State, Vec<Wall>), CdError> {
    let spec = DropSpec {
        ncol,
        nrow,
        scale: 1.0,
        seed: 1,
    };
    let params = siconos_params();
    let (mut st, walls) = settled_deposit(&spec, &params, settle_s)?;
    if kick_mgd > 0.0 {
        let m: Real = st.m.iter().sum();
        let dbar = 2.0 * st.r.iter().sum::<Real>() / st.len() as Real;
        let top = st.y.iter().zip(&st.r).map(|(y, r)| y + r).fold(Real::MIN, Real::max);
        st.vx = excitation(
            Profile::Gradient,
            &st.y,
            &st.m,
            top,
            kick_mgd * m * params.gravity * dbar,
        );
    }
    Ok((st, walls))
}

/// Time `steps` steps of a scene from [`dense_scene`] in a pool of `threads` (box width
/// `width`, for the packing fraction), the sweeps in key order or `coloured`
/// (`CdParams::coloured_sweeps`).
pub fn run_scene(
    case: &str,
    scene: &(State, Vec<Wall>),
    width: Real,
    threads: usize,
    steps: u64,
    coloured: bool,
) -> Result<BenchResult, CdError> {
    in_pool(threads, || {
        let params = CdParams {
            coloured_sweeps: coloured,
            ..siconos_params()
        };
        let mut w = World::new(params.clone(), scene.0.clone(), scene.1.clone(), None)?;
        let t0 = Instant::now();
        let mut csum = 0.0;
        for _ in 0..steps {
            csum += w.step()?.contacts as Real;
        }
        let wall_s = t0.elapsed().as_secs_f64();
        let s = &w.state;
        let e = w.energies();
        let m: Real = s.m.iter().sum();
        let dbar = 2.0 * s.r.iter().sum::<Real>() / s.len() as Real;
        Ok(BenchResult {
            case: case.to_string(),
            threads,
            particles: s.len(),
            contacts: csum / steps.max(1) as Real,
            contacts_last: w.last.contacts,
            steps: w.stats.steps,
            iterations: w.stats.iterations,
            wall_s,
            contact_iterations_per_s: w.stats.contact_iterations as f64 / wall_s,
            unconverged: w.stats.unconverged,
            max_residual: w.stats.max_residual,
            packing_fraction: core_packing_fraction(&s.x, &s.y, &s.r, width),
            ke_over_mgd: (e.ek + e.erot) / (m * params.gravity * dbar),
            timers: w.timers,
        })
    })
}

/// `f` run in a rayon pool of `threads` (the engine's parallel loops use the caller's pool).
fn in_pool<T>(threads: usize, f: impl FnOnce() -> Result<T, CdError> + Send) -> Result<T, CdError>
where
    T: Send,
{
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| CdError::Setup(e.to_string()))?
        .install(f)
}

/// Box width of the `ncol`-column deposit [m].
pub fn deposit_width(ncol: usize) -> Real {
    DropSpec {
        ncol,
        nrow: 1,
        scale: 1.0,
        seed: 1,
    }
    .width()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The dense scene is dense (the settled deposit: stopped, at least 1.5 contacts per disk,
    /// still at rest after 5 steps) and its kick carries exactly E_0, so the benchmark times
    /// what it says.
    #[test]
    fn the_dense_scene_is_settled_and_kicked_with_its_energy() {
        let scene = dense_scene(10, 8, 2.0, 0.0).unwrap();
        assert!(scene.0.vx.iter().chain(&scene.0.vy).all(|v| *v == 0.0), "stopped");
        let r = run_scene("t", &scene, deposit_width(10), 1, 5, false).unwrap();
        assert!(
            r.contacts >= 1.5 * r.particles as f64,
            "contacts {} for {} disks",
            r.contacts,
            r.particles
        );
        assert!(r.ke_over_mgd < 1e-3, "at rest: {}", r.ke_over_mgd);
        let (k, _) = dense_scene(10, 8, 2.0, 13.0).unwrap();
        let m: Real = k.m.iter().sum();
        let dbar = 2.0 * k.r.iter().sum::<Real>() / k.len() as Real;
        let ek: Real = k.m.iter().zip(&k.vx).map(|(m, v)| 0.5 * m * v * v).sum();
        let want = 13.0 * m * siconos_params().gravity * dbar;
        assert!((ek - want).abs() <= 1e-9 * want, "E_0 {ek} against {want}");
    }
}

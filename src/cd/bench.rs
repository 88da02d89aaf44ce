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

use crate::cd::error::CdError;
use crate::cd::params::CdParams;
use crate::cd::pile::{DropSpec, drop};
use crate::cd::world::Timers;
use serde::{Deserialize, Serialize};

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
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| CdError::Setup(e.to_string()))?;
    pool.install(|| {
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

//! Explicit GIMP material point method, 2D plane strain (issue 4; thesis chapter 3 §MPM and
//! §GIMP, chapter 4 §4.2.1, table 4.3).
//!
//! A step is `reset_grid → p2g → grid_update → g2p → update_stress → relocate` (`solver`);
//! the constitutive law is in `material`, the wall constraints in `boundary`, the geostatic
//! stage in `geostatic`, the column scenes in `column`.
//!
//! Choices for what the chapter leaves unspecified (each documented where it is made):
//! - uGIMP (fixed particle half-width l_p = h/(2√PPC)); USL by default (the thesis' scheme),
//!   MUSL available; pure FLIP velocity update by default (`flip` = 1).
//! - Mohr–Coulomb with c = 0, ψ = 0, Rankine tension cut-off at 0 Pa; no regularisation.
//! - Elastic moduli scale with the current density (E V_0/V): constant wave speed, so dilated
//!   points at a thinning front cannot break the CFL limit.
//! - μ(I): μ_min = tan 22.2° (docs/definitions.md I6), b = 1, d̄ = 1.15 mm, ρ_s = 2500 kg/m³,
//!   p = −tr σ/3, I capped at 1; Jop et al. (2006) form available.
//! - Walls: unilateral Coulomb constraint on nodal velocities (friction 0.466) on the nodes on
//!   and beyond x = 0 and y = 0.
//! - Geostatic stage: gravity loading behind a frictionless roller gate with Cundall local
//!   damping and PIC transfer until E_k < 1e-9 M g H; then reset to rest; gate removed at t = 0.
//! - Column sizes: the DEM columns (A = 3.9e-3 m²), L_0 snapped to whole cells.
//! - Time step: fixed (table 4.3: 1e-6 s) or CFL h/(c_p + max|v|) × Courant.

pub mod bench;
pub mod boundary;
pub mod column;
pub mod column_front;
pub mod column_spec;
pub mod energy;
pub mod error;
pub mod geostatic;
pub mod grid;
pub mod material;
pub mod params;
pub mod particles;
pub mod pile;
pub mod preflight;
pub mod shape;
pub mod solver;
pub mod state;
mod stress_block;
mod transfer;
pub mod watchdog;

pub use energy::{Energies, energies};
pub use error::MpmError;
pub use grid::Grid;
pub use params::{Axis, Geostatic, Material, Model, MpmParams, Scheme, StepRule, Wall};
pub use particles::{Point, PointId, Stress};
pub use solver::{PhaseTimes, Solver};
pub use state::{Ledger, State};

//! Contact Dynamics (CD) for rigid 2D disks (chapter 4 §4.4.1; Moreau 1993, Jean 1999,
//! Radjai & Dubois 2011): no overlap spring, no small time scale; velocities and contact
//! impulses are the unknowns of each step, solved by nonlinear Gauss–Seidel.
//!
//! Step phases ([`World::step`]): `preflight` → **`detect`** → **`gauss_seidel`** →
//! **`update_positions`** → `ledger` → `watchdog`.
//!
//! Equations (per unit thickness, m = ρπr², I = ½mr²):
//! - Moreau–Jean θ-scheme: M(v⁺ − v⁻) = h F + Σ_c H_cᵀ P_c, x⁺ = x⁻ + h((1−θ)v⁻ + θv⁺).
//! - Contact c (gap g, normal n from a to b, t = perp n): u = H_c v = ((v_b − v_a)·n,
//!   (v_b − v_a)·t − ω_a r_a − ω_b r_b). Index set: g + ½ h u_free,n ≤ 0 (Siconos' γ = ½).
//! - Signorini at velocity level with Newton restitution in Moreau's form:
//!   0 ≤ U_n ⊥ P_n ≥ 0, U = (u⁺ + ε u⁻)/(1 + ε) (ε applied on impacts, u⁻_n < 0).
//! - Coulomb: |P_t| ≤ μ P_n, sticking U_t = 0, sliding P_t = −μ P_n sign U_t; solved
//!   exactly per contact with its Delassus block W = H M⁻¹ Hᵀ ([`solver::local_solve`]).
//! - NLGS in fixed key order (or colour class by colour class on the thread pool,
//!   [`colour`]), warm-started by contact key, under-relaxation ω; converged on
//!   ‖ΔP‖/‖P‖ ≤ tol and the natural-map residual ([`solver`]).
//! - Ledger ([`energy`]): E_k + E_p + D_coll + D_fric + D_θ = E_0 + W, exact to round-off.
//!
//! Files: `params`, `error`, `body` (hot AoS body records, clumps), `contacts` (index set,
//! Delassus, warm start), `solver` (NLGS), `colour` (its parallel sweep), `preflight`, `energy`, `world` (the step);
//! drivers: `shear` (periodic shear → μ(I)), `pile` (deposit, impact, work-precision),
//! `bench`. Grain state and the Verlet cell list are the DEM's ([`crate::dem::State`],
//! [`crate::dem::neighbors`]). Rolling resistance (|M_r| ≤ μ_r r_eff P_n) is optional and off
//! by default.

pub mod bench;
pub mod body;
pub mod colour;
pub mod contacts;
pub mod energy;
pub mod error;
pub mod params;
pub mod pile;
pub mod preflight;
pub mod shear;
pub mod solver;
pub mod world;

pub use energy::{Balance, Energies, Ledger};
pub use error::CdError;
pub use params::CdParams;
pub use world::{Stats, StepInfo, Timers, World};

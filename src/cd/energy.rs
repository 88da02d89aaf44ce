//! Energy ledger of the Moreau–Jean step. With ū = ½(u⁻ + u⁺) and v_θ = (1−θ)v⁻ + θv⁺,
//! the discrete momentum balance M(v⁺ − v⁻) = hF + Σ Hᵀ P gives, exactly,
//!
//!   ΔE_k + ΔE_p = W_applied + W_imposed + Σ_c P_c·ū_c − h(½ − θ) F·(v⁺ − v⁻)
//!
//! (ΔE_p = −h F_g·v_θ because positions advance with v_θ). So the ledger books per step:
//! collisional dissipation −Σ P_n ū_n, frictional −Σ P_t ū_t, the θ-scheme's numerical
//! damping h(½ − θ)F·(v⁺ − v⁻) (zero at θ = ½), the work of applied forces on bodies
//! other than grains h F·v_θ (the shear plate's pressure), and the work of imposed
//! velocity components −R·v̄ (driven walls and plates, R their contact impulse). The
//! balance residual E_k + E_p + D − E_0 − W is round-off: the tests bound it.

use crate::math::Real;
use serde::{Deserialize, Serialize};

/// Cumulative dissipation and external work [J per metre of thickness].
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Ledger {
    /// Normal impulses: −Σ P_n ū_n (impacts; Moreau's restitution sets how much).
    pub collisional: Real,
    /// Tangential impulses −Σ P_t ū_t (Coulomb sliding) and rolling moments −Σ M_r ω̄_rel.
    pub frictional: Real,
    /// θ-scheme numerical damping h(θ − ½)F·(v⁺ − v⁻).
    pub numerical: Real,
    /// Work of applied forces on walls/clumps and of imposed velocities.
    pub external_work: Real,
}

impl Ledger {
    /// Total dissipated.
    pub fn dissipated(&self) -> Real {
        self.collisional + self.frictional + self.numerical
    }
}

/// Energies of a configuration [J/m].
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Energies {
    /// Translational kinetic energy of free components.
    pub ek: Real,
    /// Rotational kinetic energy.
    pub erot: Real,
    /// Gravity potential Σ m g y of grains.
    pub ep: Real,
}

impl Energies {
    /// E_k + E_rot + E_p.
    pub fn total(&self) -> Real {
        self.ek + self.erot + self.ep
    }
}

/// Balance check E + D = E_0 + W.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Balance {
    /// Initial E_k + E_rot + E_p.
    pub e0: Real,
    /// Current energies.
    pub now: Energies,
    /// Ledger.
    pub ledger: Ledger,
    /// E + D − E_0 − W.
    pub residual: Real,
}

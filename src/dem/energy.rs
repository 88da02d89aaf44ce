//! Energy ledger (docs/definitions.md D06, D07): state energies on demand and cumulative
//! work of every dissipative term, so that E_0 + W_ext = E_p + E_k + E_rot + elastic +
//! dissipated can be checked.
//!
//! Dissipation is booked per contact as "energy taken from the grains by the force minus
//! the change of what its spring stores" (exact bookkeeping of the discrete springs), and
//! the stored tangential/rolling energy of a contact that opens is booked as dissipated.
//! Split (D07, our choice): collisional = grain–grain normal dashpot; frictional =
//! grain–grain tangential (Coulomb sliding + dashpot) + rolling (plastic rolling slip and
//! the rolling dashpot, grain–grain and grain–wall: the chapter models shape with it, so
//! it is friction-like); wall = grain–wall normal dashpot + grain–wall tangential.

use crate::math::Real;
use serde::{Deserialize, Serialize};
use std::ops::AddAssign;

/// Cumulative dissipation and external work [J per metre of thickness].
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Ledger {
    /// Grain–grain normal dashpot (collisional).
    pub normal_damping: Real,
    /// Grain–grain tangential sliding + dashpot (+ springs released at separation).
    pub tangential: Real,
    /// Rolling resistance: plastic rolling slip, dashpot, released rolling springs.
    pub rolling: Real,
    /// Grain–wall normal dashpot.
    pub wall_normal: Real,
    /// Grain–wall tangential sliding + dashpot (+ released springs).
    pub wall_tangential: Real,
    /// Work done on the grains by prescribed motion (driven grains, moving walls).
    pub external_work: Real,
}

impl Ledger {
    /// Total dissipated energy.
    pub fn dissipated(&self) -> Real {
        self.normal_damping + self.tangential + self.rolling + self.wall_normal + self.wall_tangential
    }
    /// D07 collisional work W_c (grain–grain normal dashpot + wall normal dashpot).
    pub fn collisional(&self) -> Real {
        self.normal_damping + self.wall_normal
    }
    /// D07 frictional work W_f (tangential + rolling + wall tangential).
    pub fn frictional(&self) -> Real {
        self.tangential + self.rolling + self.wall_tangential
    }
}

impl AddAssign for Ledger {
    fn add_assign(&mut self, o: Self) {
        self.normal_damping += o.normal_damping;
        self.tangential += o.tangential;
        self.rolling += o.rolling;
        self.wall_normal += o.wall_normal;
        self.wall_tangential += o.wall_tangential;
        self.external_work += o.external_work;
    }
}

/// Energies of a configuration [J/m] (D06).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Energies {
    /// Potential energy Σ m g y (centre height above y = 0).
    pub ep: Real,
    /// ½ Σ m v_x².
    pub ekx: Real,
    /// ½ Σ m v_y².
    pub eky: Real,
    /// ½ Σ I ω².
    pub erot: Real,
    /// Normal springs ½ k_n δ² (grain–grain and grain–wall).
    pub elastic_normal: Real,
    /// Tangential springs ½ k_t ξ².
    pub elastic_tangential: Real,
    /// Rolling springs ½ k_r θ_r².
    pub elastic_rolling: Real,
}

impl Energies {
    /// Translational kinetic energy E_k = E_kx + E_ky (eq 4.11).
    pub fn ek(&self) -> Real {
        self.ekx + self.eky
    }
    /// Stored elastic energy.
    pub fn elastic(&self) -> Real {
        self.elastic_normal + self.elastic_tangential + self.elastic_rolling
    }
    /// Mechanical + stored energy.
    pub fn total(&self) -> Real {
        self.ep + self.ek() + self.erot + self.elastic()
    }
}

/// Balance at one instant: residual = E_0 + W_ext − (E_p + E_k + E_rot + elastic + dissipated).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Balance {
    /// Initial total energy E_0 (state energies at the ledger start).
    pub e0: Real,
    /// Current energies.
    pub energies: Energies,
    /// Current cumulative ledger.
    pub ledger: Ledger,
    /// E_0 + W_ext − (total + dissipated) [J/m].
    pub residual: Real,
}

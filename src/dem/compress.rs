//! Laterally confined uniaxial compression (docs/definitions.md SC-COMP-DEM, stage C2): a
//! settled column between rigid frictional side walls is loaded by a top plate moving down
//! at a constant strain rate; the slope of plate stress against strain is the modulus the
//! chapter calls E = 1.98e6 Pa. Under lateral confinement that slope is the constrained
//! modulus M (I12), so E = M(1+ν)(1−2ν)/(1−ν) is reported too.
//!
//! Protocol (UNSPEC, our choice): seat the plate until σ ≥ `seating_stress`, then strain
//! from there; fit σ − σ_seat = M ε by least squares over ε ∈ [0, `fit_strain`].
//! For linear contacts in the quasi-static regime M ∝ k_n, so a run with softened
//! stiffness can be scaled back by 1/factor (`modulus / softening`); the result reports
//! the raw slope.

use crate::dem::error::DemError;
use crate::dem::params::DemParams;
use crate::dem::prep::{Column, box_walls};
use crate::dem::walls::Wall;
use crate::dem::world::World;
use crate::math::{Real, Vec2};
use serde::{Deserialize, Serialize};

/// Compression settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CompressionParams {
    /// Axial strain rate [1/s]. UNSPEC; 0.1 /s keeps the plate speed ≪ the wave speed
    /// (the fit range spans ≳ 100 wave transits of the column).
    pub strain_rate: Real,
    /// Strain applied after seating.
    pub max_strain: Real,
    /// Upper end of the linear fit ("initial slope") [strain]. Proposal: 0.1 %.
    pub fit_strain: Real,
    /// Plate stress that counts as seated [Pa]. UNSPEC: 100 Pa.
    pub seating_stress: Real,
    /// Poisson ratio used to convert M to E (table 4.3: 0.22).
    pub poisson: Real,
    /// Curve sampling interval [strain].
    pub sample_strain: Real,
}

impl Default for CompressionParams {
    fn default() -> Self {
        Self {
            strain_rate: 0.1,
            max_strain: 2e-3,
            fit_strain: 1e-3,
            seating_stress: 100.0,
            poisson: 0.22,
            sample_strain: 2e-5,
        }
    }
}

/// One point of the stress–strain curve.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StressStrain {
    /// Axial strain since seating.
    pub strain: Real,
    /// Plate stress σ_yy [Pa].
    pub stress: Real,
    /// Mean horizontal stress on the side walls [Pa].
    pub lateral: Real,
}

/// Result of the compression test.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CompressionResult {
    /// Curve.
    pub curve: Vec<StressStrain>,
    /// Fitted slope M = dσ/dε over [0, fit_strain] [Pa].
    pub modulus: Real,
    /// E = M(1+ν)(1−2ν)/(1−ν) [Pa].
    pub young: Real,
    /// K_0 = Δσ_h/Δσ_v over the fit range.
    pub k0: Real,
    /// Sample height at seating [m].
    pub height: Real,
}

/// Compress `column` (gate closed, rigid frictional side walls) with `params`.
pub fn compression_test(
    column: &Column,
    params: &DemParams,
    cp: &CompressionParams,
) -> Result<CompressionResult, DemError> {
    let mut walls = box_walls(column.l0);
    let top = (0..column.state.len())
        .map(|i| column.state.y[i] + column.state.r[i])
        .fold(0.0, Real::max);
    let plate = Wall::ceiling("plate", top + 0.01 * column.l0.min(top));
    let h_ref = top;
    let v = cp.strain_rate * h_ref;
    walls.push(plate);
    let mut p = params.clone();
    p.ledger = false;
    let mut w = column.world(&p, walls)?;
    w.energy_check = false;
    w.preflight()?;
    // The sample may have been prepared at another contact stiffness: drain the overlap
    // energy that the change releases (kinetic damping) before the plate moves, so the
    // modulus is measured on a packing in equilibrium at *this* stiffness.
    crate::dem::prep::quench(&mut w, 1e-8, 40_000)?;
    w.walls[3].velocity = Vec2::new(0.0, -v);
    let l0 = column.l0;
    let stress = |w: &World| w.info.wall_force[3].y / l0;
    let lateral = |w: &World| (w.info.wall_force[2].x - w.info.wall_force[1].x) / (2.0 * h_ref);
    // seating
    let chunk = ((cp.sample_strain / cp.strain_rate / w.params.dt).ceil() as u64).max(1);
    let mut guard = 0;
    while stress(&w) < cp.seating_stress {
        w.run(chunk)?;
        guard += 1;
        if guard > 100_000 {
            return Err(DemError::Setup("plate never reached the seating stress".into()));
        }
    }
    let y_seat = w.walls[3].origin.y;
    let height = y_seat;
    let (s0, l0s) = (stress(&w), lateral(&w));
    let mut curve = vec![StressStrain {
        strain: 0.0,
        stress: s0,
        lateral: l0s,
    }];
    loop {
        w.run(chunk)?;
        let eps = (y_seat - w.walls[3].origin.y) / height;
        curve.push(StressStrain {
            strain: eps,
            stress: stress(&w),
            lateral: lateral(&w),
        });
        if eps >= cp.max_strain {
            break;
        }
    }
    let fit: Vec<&StressStrain> = curve.iter().filter(|c| c.strain <= cp.fit_strain).collect();
    let (mut sxx, mut sxy, mut sxl) = (0.0, 0.0, 0.0);
    for c in &fit {
        sxx += c.strain * c.strain;
        sxy += c.strain * (c.stress - s0);
        sxl += (c.stress - s0) * (c.lateral - l0s);
    }
    let modulus = sxy / sxx.max(1e-300);
    let syy: Real = fit.iter().map(|c| (c.stress - s0).powi(2)).sum();
    let k0 = sxl / syy.max(1e-300);
    let nu = cp.poisson;
    let young = modulus * (1.0 + nu) * (1.0 - 2.0 * nu) / (1.0 - nu);
    Ok(CompressionResult {
        curve,
        modulus,
        young,
        k0,
        height,
    })
}

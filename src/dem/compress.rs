//! Laterally confined uniaxial compression (docs/definitions.md SC-COMP-DEM, stage C2): a
//! settled column between rigid frictional side walls is loaded by a top plate moving down
//! at a constant strain rate; the slope of plate stress against strain is the modulus the
//! chapter calls E = 1.98e6 Pa. Under lateral confinement that slope is the constrained
//! modulus M (I12), so E = M(1+ν)(1−2ν)/(1−ν) is reported too.
//!
//! Protocol (UNSPEC, our choice): drain the sample to rest at the test's stiffness (kinetic
//! damping, repeated until E_k/E_p < `rest_ratio`; the report says whether it got there),
//! seat the plate until σ ≥ `seating_stress`, then strain from there. Each curve point is
//! the plate stress *averaged over its strain interval* (every step), not one instant:
//! the plate touches a few surface grains, whose contacts open and close within an
//! interval. M is the least-squares slope of σ against ε over ε ∈ [0, `fit_strain`], with
//! an intercept, so a noisy seating point does not tilt it. (Until 2026-12-03 the
//! sample was drained for at most 40,000 steps whether or not it came to rest, each point
//! was one instant and the line went through the seating point: at quick size and epsd
//! μ_r = 0.1 the plate stress dropped to zero and back every 5e-4 strain, and M came out
//! −6.7e4 Pa.)
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
    /// Curve sampling interval [strain]; the stress of a point is its interval's mean.
    pub sample_strain: Real,
    /// The sample is at rest when E_k/E_p falls below this before the plate moves.
    pub rest_ratio: Real,
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
            rest_ratio: 1e-8,
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
    /// Stress of the fitted line at ε = 0 [Pa] (σ ≈ `fit_intercept` + M ε over the fit).
    pub fit_intercept: Real,
    /// E = M(1+ν)(1−2ν)/(1−ν) [Pa].
    pub young: Real,
    /// K_0 = Δσ_h/Δσ_v over the fit range.
    pub k0: Real,
    /// Sample height at seating [m].
    pub height: Real,
    /// E_k/E_p of the sample when the plate started (below `rest_ratio`: at rest).
    pub rest_ke_over_ep: Real,
    /// Whether the sample came to rest (`rest_ke_over_ep < rest_ratio`) within the cap.
    pub at_rest: bool,
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
    // Up to 25 rounds of 40,000 steps (1e6 steps: ≈ 0.15 s at the table's k_n, several
    // free-fall times of the column).
    let mut rest = crate::dem::prep::quench(&mut w, cp.rest_ratio, 40_000)?;
    for _ in 1..25 {
        if rest.converged {
            break;
        }
        rest = crate::dem::prep::quench(&mut w, cp.rest_ratio, 40_000)?;
    }
    w.walls[3].velocity = Vec2::new(0.0, -v);
    let l0 = column.l0;
    let chunk = ((cp.sample_strain / cp.strain_rate / w.params.dt).ceil() as u64).max(1);
    // Plate (axial) and side-wall (lateral) stress, averaged over the `chunk` steps.
    let interval = |w: &mut World| -> Result<(Real, Real), DemError> {
        let (mut a, mut b) = (0.0, 0.0);
        for _ in 0..chunk {
            w.step()?;
            a += w.info.wall_force[3].y / l0;
            b += (w.info.wall_force[2].x - w.info.wall_force[1].x) / (2.0 * h_ref);
        }
        Ok((a / chunk as Real, b / chunk as Real))
    };
    // seating
    let mut guard = 0;
    let (mut s0, mut l0s) = interval(&mut w)?;
    while s0 < cp.seating_stress {
        (s0, l0s) = interval(&mut w)?;
        guard += 1;
        if guard > 100_000 {
            return Err(DemError::Setup("plate never reached the seating stress".into()));
        }
    }
    let y_seat = w.walls[3].origin.y;
    let height = y_seat;
    let mut curve = vec![StressStrain {
        strain: 0.0,
        stress: s0,
        lateral: l0s,
    }];
    loop {
        let (s, l) = interval(&mut w)?;
        let eps = (y_seat - w.walls[3].origin.y) / height;
        curve.push(StressStrain {
            strain: eps,
            stress: s,
            lateral: l,
        });
        if eps >= cp.max_strain {
            break;
        }
    }
    let fit: Vec<&StressStrain> = curve.iter().filter(|c| c.strain <= cp.fit_strain).collect();
    let n = fit.len().max(1) as Real;
    let mean = |f: &dyn Fn(&StressStrain) -> Real| fit.iter().map(|c| f(c)).sum::<Real>() / n;
    let (me, ms, ml) = (mean(&|c| c.strain), mean(&|c| c.stress), mean(&|c| c.lateral));
    let (mut sxx, mut sxy, mut syy, mut syl) = (0.0, 0.0, 0.0, 0.0);
    for c in &fit {
        let (de, ds, dl) = (c.strain - me, c.stress - ms, c.lateral - ml);
        sxx += de * de;
        sxy += de * ds;
        syy += ds * ds;
        syl += ds * dl;
    }
    let modulus = sxy / sxx.max(1e-300);
    let k0 = syl / syy.max(1e-300);
    let nu = cp.poisson;
    let young = modulus * (1.0 + nu) * (1.0 - 2.0 * nu) / (1.0 - nu);
    Ok(CompressionResult {
        curve,
        modulus,
        fit_intercept: ms - modulus * me,
        young,
        k0,
        height,
        rest_ke_over_ep: rest.ke_over_ep,
        at_rest: rest.converged,
    })
}

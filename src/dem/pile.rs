//! Pile preparation (figures.md SC-PILE, stage P5): pour grains into a box of given
//! width, then shift the right-hand wall far to the right so the grains spread, and let
//! them come to rest. Reports L_0 (main mass, D01), H_0 and the surface slope.

use crate::analysis::front::{Body, Link, front};
use crate::dem::error::DemError;
use crate::dem::params::DemParams;
use crate::dem::prep::{DepositionParams, ballistic_deposition, box_walls, settle};
use crate::dem::state::State;
use crate::dem::world::World;
use crate::math::Real;
use serde::{Deserialize, Serialize};

/// Pile settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PileParams {
    /// Deposition into the initial box (its `width` is the box width).
    pub deposition: DepositionParams,
    /// New right-wall position as a multiple of the box width.
    pub shift_to: Real,
    /// Settling criterion after the shift, (E_k+E_rot)/E_p.
    pub settle_ratio: Real,
    /// Cap on the spreading time [s].
    pub max_time: Real,
}

impl Default for PileParams {
    fn default() -> Self { Self { deposition: DepositionParams::default(), shift_to: 20.0, settle_ratio: 1e-6, max_time: 5.0 } }
}

/// A prepared pile.
#[derive(Debug, Clone)]
pub struct Pile {
    /// Grains at rest.
    pub state: State,
    /// L_0: right edge of the main mass [m].
    pub l0: Real,
    /// H_0: top of the main mass [m].
    pub h0: Real,
    /// Surface slope [deg] from a line fit of the surface between 0.2 and 0.8 L_0.
    pub slope_deg: Real,
    /// Whether the spreading pile reached the settling criterion.
    pub settled: bool,
}

/// Surface angle: highest grain top per bin of width d̄, fitted over x ∈ [0.2, 0.8] L.
pub fn surface_slope_deg(s: &State, l: Real) -> Real {
    let d = 2.0 * s.radius_stats().1;
    let nb = ((l / d).ceil() as usize).max(1);
    let mut top = vec![Real::NEG_INFINITY; nb];
    for i in 0..s.len() {
        let b = ((s.x[i] / d).max(0.0) as usize).min(nb - 1);
        top[b] = top[b].max(s.y[i] + s.r[i]);
    }
    let pts: Vec<(Real, Real)> = (0..nb)
        .map(|b| ((b as Real + 0.5) * d, top[b]))
        .filter(|&(x, y)| y.is_finite() && x >= 0.2 * l && x <= 0.8 * l)
        .collect();
    if pts.len() < 2 { return 0.0; }
    let n = pts.len() as Real;
    let mx = pts.iter().map(|p| p.0).sum::<Real>() / n;
    let my = pts.iter().map(|p| p.1).sum::<Real>() / n;
    let cov: Real = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let var: Real = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    (-cov / var).atan().to_degrees()
}

/// Pour `radii` into the box, shift the right wall, settle.
pub fn prepare_pile(radii: &[Real], params: &DemParams, pp: &PileParams) -> Result<Pile, DemError> {
    let (s, _) = ballistic_deposition(radii, params, &pp.deposition)?;
    let width = pp.deposition.width;
    let mut walls = box_walls(width);
    walls[2].origin.x = pp.shift_to * width;
    let mut w = World::new(params.clone(), s, walls, None)?;
    let rep = settle(&mut w, pp.settle_ratio, 0.05, pp.max_time)?;
    let s = w.state;
    let d = 2.0 * s.radius_stats().1;
    let f = front(&Body { x: &s.x, y: &s.y, half: &s.r, mass: &s.m }, Link::Contact { gap: 0.01 * d });
    let slope_deg = surface_slope_deg(&s, f.length);
    Ok(Pile { l0: f.length, h0: f.height, slope_deg, settled: rep.converged, state: s })
}

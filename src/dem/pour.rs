//! The pour of a pile (chapter §4.4.1: "the grains are first poured uniformly into a
//! rectangular box"): all the grains in one lattice layer, of the rows they fill.
//!
//! `prep::ballistic_deposition` rains layers of `rows_per_layer` lattice rows and waits
//! 1.3 × the fall time of a layer's top row, computed from `rows_per_layer`. A pile asks for
//! one layer with a cap far above its grains (`rows_per_layer: 100000`); passed through, the
//! wait was the fall from 100,000 rows up — 10.3 s of simulated time at rest, 3.4 M steps
//! of the 13,000-grain paper pile, before the wall moved (issue 28: its preparation took
//! 4,599 s, now 329 s). [`pour`] caps the layer at the rows the grains fill.
//!
//! Kept apart from `dem::pile` (whose `prepare_pile` the stage calls with the capped
//! parameters) so that the fix does not change the source closure of the committed results
//! built on `dem::pile`; fold it into `prepare_pile` with the next change of that file.

use crate::dem::prep::DepositionParams;
use crate::math::Real;

/// `dep` with `rows_per_layer` capped at the lattice rows `radii` fill, by the row rule of
/// `ballistic_deposition` (rows of `floor((width − 2 r_max − offset)/pitch) + 1` slots,
/// every other row offset by half a pitch; a negative quotient saturates to 0). A cap below
/// the rows filled is kept (several layers).
pub fn pour(radii: &[Real], dep: &DepositionParams) -> DepositionParams {
    let r_max = radii.iter().cloned().fold(0.0, Real::max);
    let pitch = 2.0 * r_max * dep.spacing;
    let (mut rows, mut placed) = (0usize, 0usize);
    while placed < radii.len() && rows < dep.rows_per_layer {
        let offset = if rows % 2 == 1 { 0.5 * pitch } else { 0.0 };
        placed += ((dep.width - 2.0 * r_max - offset) / pitch).floor() as usize + 1;
        rows += 1;
    }
    DepositionParams {
        rows_per_layer: rows.max(1),
        ..dep.clone()
    }
}

//! Work-precision of the three methods (`stages/wp-*.yaml`): error against wall time of
//! the DEM column, the CD pile and the MPM column over their resolution knobs, and the
//! atlas that gathers them (`wp-summary`). One kind, `work-precision` ([`study`]), with a
//! `method:`; each method's study in its own file.

pub mod cd_wp;
pub mod dem_wp;
pub mod mpm_tall;
pub mod mpm_wp;
pub mod study;
pub mod wp_summary;

/// The kinds of this study, registered in [`crate::stages::registry`]. Adding a kind: its
/// file, its `pub mod` line above and its line here.
pub const KINDS: &[crate::stages::Kind] = &[study::KIND, wp_summary::KIND];

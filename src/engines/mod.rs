//! The interface between the study kinds and the three methods (DEM, CD, MPM).
//!
//! Contract: a study kind (`column-collapse`, `pile-run`) is written once, against the
//! types here, and names its method with a `method:` field ([`Method`]). Each method's
//! adapter turns its solver's result into the method-agnostic record the study analyses
//! (for the column, [`column::ColumnTrace`]); the analysis, the published scalars that
//! mean the same for every method and the charts are then computed once, from that record.
//! The solvers themselves (`src/dem`, `src/cd`, `src/mpm`) stay free of I/O and of this
//! module; the adapters live beside their study's kind (`src/stages/column/dem_collapse.rs`,
//! `src/stages/column/mpm_collapse.rs`).

pub mod column;
pub mod method;

pub use method::Method;

//! The interface between the study kinds and the three methods (DEM, CD, MPM).
//!
//! Contract: a study kind (`column-collapse`, `pile-run`) is written once, against the
//! traits here, and names its method with a `method:` field ([`Method`]). Each method's
//! adapter turns its solver's result into the method-agnostic record the study analyses
//! ([`column::ColumnTrace`], [`pile::Excited`]); the analysis, the published scalars that
//! mean the same for every method and the charts are then computed once, from that record.
//! Every adapter also gives its pre-flight ([`preflight::Preflight`]), so `run --explain`
//! asks the stage's engine, not a table of methods. The solvers themselves (`src/dem`,
//! `src/cd`, `src/mpm`) stay free of I/O and of this module; the adapters live beside their
//! study's kind (`src/stages/column/{dem,mpm}_collapse.rs`,
//! `src/stages/pile/{grain,mpm}_pile.rs`).

pub mod column;
pub mod method;
pub mod pile;
pub mod preflight;

pub use method::Method;
pub use preflight::Preflight;

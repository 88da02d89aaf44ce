//! The pile study (chapter 4 §4.4, docs/definitions.md SC-PILE; `stages/pile/`): the DEM
//! pile's preparation, pile runs by DEM, CD or MPM and their run-out, the method-agnostic
//! time-series analysis, the packing of a DEM pile, the pile comparisons, and the run-out
//! against kinetic energy of columns and piles (fig 4.45).

pub mod common;
pub mod compare;
pub mod energy_runout;
pub mod grain_pile;
pub mod members;
pub mod mpm_pile;
pub mod packing;
pub mod prep;
pub mod run;
pub mod run_params;
pub mod runout;
pub mod series;
pub mod series_derived;

/// The kinds of this study, registered in [`crate::stages::registry`]. Adding a kind: its
/// file, its `pub mod` line above and its line here.
pub const KINDS: &[crate::stages::Kind] = &[
    prep::PREP_KIND,
    run::RUN_KIND,
    runout::RUNOUT_KIND,
    series::KIND,
    energy_runout::KIND,
    packing::KIND,
    compare::KIND,
];

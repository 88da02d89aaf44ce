//! The column-collapse study (chapter 4 §4.2–4.3; `stages/col-*.yaml`, `stages/column/`):
//! DEM column preparation, snapshots and collapse; the MPM geostatic stage and collapse;
//! the per-run analysis both collapses share, the thick-front rule, and the study's
//! analysis kinds (scheme, inertial number, packing, density pair).

pub mod analysis;
pub mod collapse;
pub mod common;
pub mod dem_collapse;
pub mod dem_common;
pub mod dem_prep;
pub mod dem_snapshot;
pub mod density_pair;
pub mod front_rules;
pub mod inertial;
pub mod mpm_collapse;
pub mod mpm_common;
pub mod mpm_geostatic;
pub mod packing;
pub mod scheme;

/// The kinds of this study, registered in [`crate::stages::registry`]. Adding a kind: its
/// file, its `pub mod` line above and its line here.
pub const KINDS: &[crate::stages::Kind] = &[
    dem_prep::PREP_KIND,
    dem_snapshot::SNAPSHOT_KIND,
    collapse::KIND,
    mpm_geostatic::GEOSTATIC_KIND,
    scheme::SCHEME_KIND,
    inertial::INERTIAL_KIND,
    packing::PACKING_KIND,
    density_pair::PAIR_KIND,
];

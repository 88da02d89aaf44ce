//! Stage kinds: each is one pure function of its typed parameters and its input
//! artifacts, returning an [`Output`]. A kind's `version` is bumped whenever its numerics
//! change; it is part of the cache key, so bumping it re-runs exactly its dependants.

pub mod calib;
pub mod cd_stages;
pub mod column_analysis;
pub mod compare;
pub mod dem_common;
pub mod dem_stages;
pub mod energy_runout;
pub mod fit_stage;
pub mod front_rules;
pub mod kind;
pub mod laws;
pub mod mpm_stages;
pub mod pile_compare;
pub mod pile_packing;
pub mod pile_series;
pub mod pile_stages;
pub mod plot;
pub mod psd;
pub mod registry;
pub mod snapshot;
pub mod tables;
pub mod wp_summary;

pub use kind::{Kind, ParamProblem, ParamsFn, RunFn, Validate, decode, typed};
pub use registry::registry;

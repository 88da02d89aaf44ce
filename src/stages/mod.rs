//! Stage kinds: each is one pure function of its typed parameters and its input
//! artifacts, returning an [`Output`]. A kind's `version` is bumped whenever its numerics
//! change; it is part of the cache key, so bumping it re-runs exactly its dependants.

pub mod calib;
pub mod cd_stages;
pub mod column;
pub mod dem_stages;
pub mod generic;
pub mod kind;
pub mod mpm_stages;
pub mod pile;
pub mod registry;
pub mod wp_summary;

pub use kind::{Kind, ParamProblem, ParamsFn, RunFn, Validate, decode, typed};
pub use registry::registry;

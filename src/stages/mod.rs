//! Stage kinds: each is one pure function of its typed parameters and its input
//! artifacts, returning an [`Output`]. A kind's `version` is bumped whenever its numerics
//! change; it is part of the cache key, so bumping it re-runs exactly its dependants.
//!
//! The kinds are grouped by study, as the stage files under `stages/` are: [`generic`]
//! (figures, tables, fits, the PSD), [`column`], [`pile`], [`calib`] and
//! [`work_precision`]. Each kind lives in its own file with its params struct and its
//! `KIND`; what the kinds of a study share is in that study's `common.rs` (or
//! `dem_common.rs` / `mpm_common.rs`).

pub mod calib;
pub mod catalogue;
pub mod column;
pub mod generic;
pub mod kind;
pub mod pile;
pub mod reads;
pub mod registry;
pub mod work_precision;

pub use kind::{Kind, ParamProblem, ParamsFn, RunFn, Validate, decode, typed};
pub use registry::registry;

//! The declarative pipeline: load and validate `pipeline.yaml`, plan the stages a target
//! needs, run them through the content-addressed cache, publish reports.
pub mod cache;
pub mod check;
pub mod clean;
pub mod context;
pub mod dag;
pub mod diag;
pub mod estimate;
pub mod export;
pub mod fsio;
pub mod keys;
pub mod load;
mod load_hints;
pub mod order;
pub mod plan;
mod profile_matrix;
pub mod profiles;
pub mod project;
pub mod publish;
pub mod reads;
pub mod run;
pub mod spec;
pub mod status;
pub mod store;
pub mod timings;
pub mod yaml;

pub use context::{Claim, InputRef, Output, StageCtx};
pub use diag::{Diagnostic, Diagnostics};
pub use profiles::{load, load_text};
pub use run::{Outcome, Project, RunOptions, RunSummary};
pub use spec::{Override, Pipeline, Stage};

//! granrepro — regenerate every figure and table of the thesis chapter "Multi-scale
//! modelling of dry granular flows" (K. Kumar, PhD thesis, University of Cambridge, 2015,
//! chapter 4; DOI 10.5281/zenodo.160339, CC BY 4.0) from one declarative pipeline file.
//!
//! Layout: [`pipeline`] plans and runs stages with a content-addressed cache; [`stages`]
//! holds the stage kinds (one pure function of params and input artifacts each);
//! [`sample`], [`fit`], [`analysis`] are the numerics they use; [`report`] writes tables,
//! figures and the HTML index. Solvers never touch files.
#![warn(missing_docs)]
// `!(x > 0.0)` is how this crate says "not a positive number, NaN included": a NaN must
// fail a guard (a validation, a contact test), and `x <= 0.0` would let it through. The
// lint's rewrite with `partial_cmp` says the same thing less plainly.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod analysis;
pub mod bench_leave_out;
pub mod cd;
pub mod claims;
pub mod cli;
pub mod dem;
pub mod engines;
pub mod fit;
pub mod math;
pub mod mpm;
pub mod pipeline;
pub mod provenance;
pub mod report;
pub mod sample;
pub mod scene;
pub mod scene_cd;
pub mod scene_mpm;
pub(crate) mod shared;
pub mod stages;
pub mod validate;
pub mod vtk;

//! Kinds that serve every study: the PSD generator and its figure, tables 4.1–4.3, power-law
//! fits and the chapter's stated laws, and the YAML-declared figures (`plot`, `snapshot`)
//! and comparisons (`sweep-compare`).

pub mod compare;
pub mod fit_stage;
pub mod laws;
pub mod plot;
pub mod psd;
pub mod snapshot;
pub mod tables;

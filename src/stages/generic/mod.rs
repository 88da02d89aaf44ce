//! Kinds that serve every study: the PSD generator and its figure, tables 4.1–4.3, power-law
//! fits and the chapter's stated laws, and the YAML-declared figures (`plot`, `snapshot`)
//! and comparisons (`sweep-compare`).

pub mod compare;
pub mod fit_stage;
pub mod laws;
pub mod plot;
pub mod plot_lines;
pub mod plot_points;
pub mod psd;
pub mod snapshot;
pub mod tables;

/// The kinds of this study, registered in [`crate::stages::registry`]. Adding a kind: its
/// file, its `pub mod` line above and its line here.
pub const KINDS: &[crate::stages::Kind] = &[
    psd::KIND,
    psd::FIGURE_KIND,
    tables::KIND,
    fit_stage::KIND,
    laws::KIND,
    plot::KIND,
    compare::KIND,
    snapshot::KIND,
];

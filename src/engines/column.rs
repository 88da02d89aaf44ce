//! The column collapse, as every method reports it to the `column-collapse` kind.
//!
//! Contract: [`ColumnEngine::collapse`] runs the method's solver on the stage's scene,
//! publishes what only that method has (its tables, its own scalars, notes and checks,
//! VTK files), and returns a [`ColumnTrace`]: the method-agnostic record (time series,
//! bodies at release, at τ_c and at rest, run-out by the method's linking rule) from which
//! the kind computes, once for every method, the shared scalars, the per-run analysis of
//! §4.2 and the two charts. What the method reports after the analysis (measurements that
//! depend on it, closing notes) goes in [`Collapsed::finish`], so the published order of a
//! run's measurements is the method's own.

use crate::analysis::cloud::Cloud;
use crate::analysis::inertial::Stats;
use crate::pipeline::context::{Output, StageCtx};

use super::Method;
use super::preflight::Preflight;

/// One energy curve of the run's energy chart: label, palette index, E/E_0 per sample.
pub struct EnergyCurve {
    /// Legend label.
    pub label: String,
    /// Palette index.
    pub color: usize,
    /// E/E_0 at each sample of [`ColumnTrace::t`].
    pub over_e0: Vec<f64>,
}

/// What one collapse provides, whatever the method. Lengths in m, times in s, energies
/// per unit thickness in J/m.
pub struct ColumnTrace {
    /// The method that ran.
    pub method: Method,
    /// L_0, H_0 [m].
    pub l0: f64,
    /// See `l0`.
    pub h0: f64,
    /// τ_c = √(H_0/g) [s].
    pub tau: f64,
    /// d̄ [m] (the volume-mean diameter; the MPM's grain diameter).
    pub d: f64,
    /// Gravity [m/s²].
    pub g: f64,
    /// Sample times [s].
    pub t: Vec<f64>,
    /// L(t), H(t) [m] by the method's linking rule.
    pub l: Vec<f64>,
    /// See `l`.
    pub h: Vec<f64>,
    /// The gathered length over every body (D01, the rule both methods share) [m].
    pub l_gathered: Vec<f64>,
    /// Translational kinetic energy (eq 4.11) [J/m].
    pub ek: Vec<f64>,
    /// E_p [J/m].
    pub ep: Vec<f64>,
    /// Coarse-grained I statistics per sample (D08).
    pub inertial: Vec<Stats>,
    /// Linking gaps of the sensitivity table [d̄], and L(t) for each (rows = samples).
    pub gaps: Vec<f64>,
    /// See `gaps`.
    pub gap_lengths: Vec<Vec<f64>>,
    /// Linking gap of `l` [d̄] (NaN: another rule, said in a note).
    pub link_gap: f64,
    /// The bodies at the sample closest to τ_c (within 5 %), for D18.
    pub at_tau: Option<Cloud>,
    /// Horizontal positions at release and at the end, and masses (same order), for D17.
    pub x_start: Vec<f64>,
    /// See `x_start`.
    pub x_end: Vec<f64>,
    /// See `x_start`.
    pub mass: Vec<f64>,
    /// Friction angle φ of the material [°] (NaN: none known to the stage).
    pub phi_deg: f64,
    /// Grain friction coefficient for the Staron–Hinch law (NaN: not a grain method).
    pub mu_grain: f64,
    /// Whether the stop rule was met (false: the upper bound ended the run).
    pub at_rest: bool,
    /// (L_f − L_0)/L_0 at rest by the method's D01 rule.
    pub runout_norm: f64,
    /// L_f [m].
    pub lf_m: f64,
    /// H_f [m].
    pub hf_m: f64,
    /// The energy chart's curves, in legend order.
    pub energies: Vec<EnergyCurve>,
    /// What the flow chart's footer says of the run (resolution, ΔL).
    pub footer: String,
}

/// What the shared part found that a method's later measurements use.
pub struct Shared {
    /// t_f [s]: when the front settles to within 0.5 d̄ of its final position (D10).
    pub t_f: f64,
}

/// What runs after the shared analysis: the method's own later measurements and notes.
pub type Finish<'a> = Box<dyn FnOnce(&mut Output, &Shared) -> anyhow::Result<()> + 'a>;

/// A finished collapse: its trace and what the method adds after the shared analysis.
pub struct Collapsed<'a> {
    /// The method-agnostic record.
    pub trace: ColumnTrace,
    /// Runs after the shared analysis.
    pub finish: Finish<'a>,
}

/// A method that runs the column collapse.
pub trait ColumnEngine: Preflight {
    /// Run the collapse of the stage's scene; publish the method's own outputs in `out`.
    fn collapse<'a>(&'a self, ctx: &'a StageCtx, out: &mut Output) -> anyhow::Result<Collapsed<'a>>;
}

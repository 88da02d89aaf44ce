//! Kind `work-precision`: error against wall time of one method over its resolution knobs
//! (`method: dem | cd | mpm`), the measurement behind every "error vs run time" the report
//! shows. DEM: the column run-out over contact stiffness and time-step fraction
//! ([`super::dem_wp`]); CD: the pile impact over time step and NLGS tolerance
//! ([`super::cd_wp`]); MPM: the column run-out over PPC, cell size and Courant number
//! ([`super::mpm_wp`]). `wp-summary` gathers them.

use serde_json::Value;

use super::cd_wp::WpParams as CdWp;
use super::dem_wp::WpParams as DemWp;
use super::mpm_wp::WorkPrecisionParams as MpmWp;
use crate::engines::Method;
use crate::pipeline::context::{Arity, Output, StageCtx};
use crate::stages::Kind;
use crate::stages::column::dem_common::explain_dem;
use crate::stages::column::mpm_common::explain_mpm;
use crate::stages::kind::{CostCtx, Outputs, ParamProblem, Roles, TableDecl, Work, split_method, typed, with_method};

/// The methods with a work-precision study.
const METHODS: &[Method] = &[Method::Dem, Method::Cd, Method::Mpm];

/// A `work-precision` stage's params: its method and that method's own params.
pub enum WpParams {
    /// `method: dem`.
    Dem(DemWp),
    /// `method: cd`.
    Cd(CdWp),
    /// `method: mpm`.
    Mpm(MpmWp),
}

impl WpParams {
    /// Decode canonical params.
    pub fn decode(v: &Value) -> anyhow::Result<WpParams> {
        let (m, rest) = split_method(v, METHODS).map_err(|e| anyhow::anyhow!("{}: {}", e.key, e.message))?;
        Ok(match m {
            Method::Dem => WpParams::Dem(serde_json::from_value(rest)?),
            Method::Cd => WpParams::Cd(serde_json::from_value(rest)?),
            Method::Mpm => WpParams::Mpm(serde_json::from_value(rest)?),
        })
    }
}

/// Schema: the method, then that method's own schema.
fn params(v: &Value) -> Result<Value, Vec<ParamProblem>> {
    let (m, rest) = split_method(v, METHODS).map_err(|e| vec![e])?;
    let canonical = match m {
        Method::Dem => typed::<DemWp>(&rest)?,
        Method::Cd => typed::<CdWp>(&rest)?,
        Method::Mpm => typed::<MpmWp>(&rest)?,
    };
    Ok(with_method(m, canonical))
}

fn run(ctx: &StageCtx) -> anyhow::Result<Output> {
    match WpParams::decode(&ctx.params)? {
        WpParams::Dem(p) => super::dem_wp::run(ctx, p),
        WpParams::Cd(p) => super::cd_wp::run(ctx, p),
        WpParams::Mpm(p) => super::mpm_wp::run(ctx, p),
    }
}

fn cost(c: &CostCtx) -> Option<Work> {
    match WpParams::decode(c.params).ok()? {
        WpParams::Dem(p) => super::dem_wp::cost(&p, c),
        WpParams::Cd(p) => super::cd_wp::cost(&p, c),
        WpParams::Mpm(p) => super::mpm_wp::cost(&p, c),
    }
}

/// The pre-flight table of the method's base parameters.
fn explain(v: &Value) -> String {
    match split_method(v, METHODS).map(|(m, _)| m) {
        Ok(Method::Mpm) => explain_mpm(v),
        Ok(Method::Cd) => "CD: no stability limit on Δt (contact dynamics is implicit in the contact forces); \
                           each variant's Δt and NLGS tolerance are in its params"
            .into(),
        _ => explain_dem(v),
    }
}

/// Kind `work-precision`.
pub const KIND: Kind = Kind {
    name: "work-precision",
    source: file!(),
    method: None,
    version: 3,
    about: "error vs wall time of one method (`method:`) over its resolution knobs: DEM stiffness × time step (column run-out), CD time step × NLGS tolerance (pile impact), MPM PPC × cell size × Courant (column run-out)",
    params,
    run,
    explain: Some(explain),
    roles: Roles::ByMethod(&[
        (
            Method::Dem,
            &[
                ("column", Arity::One),
                ("calibration", Arity::OptionalOne),
                ("coarser", Arity::OptionalOne),
            ],
        ),
        (Method::Cd, &[]),
        (
            Method::Mpm,
            &[("shear", Arity::OptionalOne), ("compression", Arity::OptionalOne)],
        ),
    ]),
    outputs: Outputs {
        scalars: &[
            "base_config_duration_rel_error", "base_config_duration_rel_error_se", "base_config_ep_final_rel_error",
            "base_config_ep_final_rel_error_se", "base_config_runout_q99_rel_error", "base_config_runout_rel_error",
            "base_config_runout_rel_error_se", "duration_error_*", "duration_error_se_*", "ep_final_error_*",
            "ep_final_error_se_*", "error_*", "error_se_*", "grains", "members", "reference_com_shift_norm",
            "reference_dissipated_j_m", "reference_points", "reference_runout_mean", "reference_runout_norm",
            "reference_runout_q99_norm", "reference_runout_std", "reference_steps", "runout_mean_*", "runout_std_*",
            "shift_vs_base_*", "tall_*",
        ],
        tables: &[
            TableDecl {
                name: "table",
                columns: &[
                    "capped", "cell_size_m", "com_shift_norm", "com_shift_norm_std", "com_shift_rel_error",
                    "com_shift_rel_error_se", "courant", "dissipated_j_m", "dissipated_j_m_std",
                    "dissipated_rel_error", "dissipated_rel_error_se", "dt_fraction", "dt_s", "duration_rel_error",
                    "duration_rel_error_se", "duration_tau_mean", "ek_final_over_ek0", "ep_final_mean",
                    "ep_final_rel_error", "ep_final_rel_error_se", "full_size", "grains", "hf_over_l0", "max_iterations",
                    "max_penetration_d", "mean_iterations", "members", "point_steps", "points", "ppc", "reference", "runout_norm",
                    "runout_norm_mean", "runout_norm_std", "runout_q99_norm", "runout_q99_rel_error",
                    "runout_rel_error", "runout_rel_error_se", "scheme_musl", "shape_linear", "steps",
                    "stiffness_factor", "tolerance", "unconverged_steps", "variant",
                ],
            },
            TableDecl {
                name: "timing",
                columns: &["cell_size_m", "courant", "ppc", "settle_wall_s", "variant", "wall_s"],
            },
            TableDecl {
                name: "tall_resolution",
                columns: &[
                    "a", "cell_size_m", "cells_across", "ep_over_e0_0_5tau", "ep_over_e0_1tau", "ep_over_e0_2tau",
                    "points", "ppc", "runout_norm_end", "steps", "t_kemax_over_tau_c",
                ],
            },
            TableDecl {
                name: "tall_timing",
                columns: &["cells_across", "ppc", "wall_s"],
            },
        ],
        measurements: &[],
        texts: &[],
    },
    reads: None,
    cost: Some(cost),
    atlas: None,
};

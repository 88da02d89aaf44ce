//! Kind `column-collapse`: the granular column collapse of §4.2–4.3 by any method that
//! runs it (`method: dem | mpm`). The method runs its solver and publishes what only it has
//! ([`super::dem_collapse`], [`super::mpm_collapse`]); this file publishes, once for every
//! method, the scalars that mean the same for grains and material points, the per-run
//! analysis ([`super::analysis`]) and the two charts (flow and energies).

use serde_json::Value;

use super::dem_collapse::CollapseStageParams as DemColumn;
use super::mpm_collapse::CollapseParams as MpmColumn;
use crate::engines::Method;
use crate::engines::column::{Collapsed, ColumnEngine, ColumnTrace, Shared};
use crate::pipeline::context::{Arity, Output, StageCtx};
use crate::report::plot::{Chart, Series, Style, footer};
use crate::stages::Kind;
use crate::stages::kind::{CostCtx, Outputs, ParamProblem, Roles, TableDecl, Work, split_method, typed, with_method};

/// The methods that run the column.
const METHODS: &[Method] = &[Method::Dem, Method::Mpm];

/// A `column-collapse` stage's params: its method and that method's own params.
pub enum ColumnParams {
    /// `method: dem`.
    Dem(DemColumn),
    /// `method: mpm`.
    Mpm(MpmColumn),
}

impl ColumnParams {
    /// Decode canonical params.
    pub fn decode(v: &Value) -> anyhow::Result<ColumnParams> {
        let (m, rest) = split_method(v, METHODS).map_err(|e| anyhow::anyhow!("{}: {}", e.key, e.message))?;
        Ok(match m {
            Method::Mpm => ColumnParams::Mpm(serde_json::from_value(rest)?),
            _ => ColumnParams::Dem(serde_json::from_value(rest)?),
        })
    }
    fn engine(&self) -> &dyn ColumnEngine {
        match self {
            ColumnParams::Dem(p) => p,
            ColumnParams::Mpm(p) => p,
        }
    }
}

/// Schema: the method, then that method's own schema.
fn params(v: &Value) -> Result<Value, Vec<ParamProblem>> {
    let (m, rest) = split_method(v, METHODS).map_err(|e| vec![e])?;
    let canonical = match m {
        Method::Mpm => typed::<MpmColumn>(&rest)?,
        _ => typed::<DemColumn>(&rest)?,
    };
    Ok(with_method(m, canonical))
}

/// `--explain`: the stage's engine's pre-flight.
fn explain(v: &Value) -> String {
    match ColumnParams::decode(v) {
        Ok(p) => p.engine().preflight(),
        Err(e) => format!("refused: {e}"),
    }
}

/// Cost: the method's (DEM: grains ∝ the input column's area; MPM: its points), steps per
/// simulated second.
fn cost(c: &CostCtx) -> Option<Work> {
    match ColumnParams::decode(c.params).ok()? {
        ColumnParams::Dem(p) => super::dem_collapse::cost(&p, c),
        ColumnParams::Mpm(p) => super::mpm_collapse::cost(&p),
    }
}

fn run(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p = ColumnParams::decode(&ctx.params)?;
    let mut out = Output::default();
    let Collapsed { trace, finish } = p.engine().collapse(ctx, &mut out)?;
    let shared = publish(&trace, &mut out)?;
    finish(&mut out, &shared)?;
    charts(ctx, &trace, &mut out)?;
    Ok(out)
}

/// The scalars every method publishes alike, and the per-run analysis.
fn publish(tr: &ColumnTrace, out: &mut Output) -> anyhow::Result<Shared> {
    let e0 = tr.ep.first().copied().unwrap_or(1.0);
    let n = tr.t.len();
    // D10: t_f = when the front settles to within 0.5 d̄ of its final position (d̄ the
    // volume-mean diameter, as docs/definitions.md SC-PSD defines it).
    let t_f = crate::analysis::front::stop_time(&tr.t, &tr.l, 0.5 * tr.d);
    // The first sample of largest E_k.
    let kmax = (0..n).reduce(|a, i| if tr.ek[a] >= tr.ek[i] { a } else { i });
    let last = n.checked_sub(1);
    let at_last = |f: &dyn Fn(usize) -> f64| last.map(f).unwrap_or(f64::NAN);
    out.scalar("a", tr.h0 / tr.l0)
        .scalar("l0_m", tr.l0)
        .scalar("h0_m", tr.h0)
        .scalar("tau_c_s", tr.tau)
        .scalar("runout_norm", tr.runout_norm)
        .scalar("runout_gathered_norm", at_last(&|i| (tr.l_gathered[i] - tr.l0) / tr.l0))
        .scalar(
            "front_gathered_max_backward_jump_over_l0",
            crate::analysis::runout::max_backward_jump(&tr.l_gathered, tr.l0),
        )
        .scalar("lf_m", tr.lf_m)
        .scalar("hf_over_l0", tr.hf_m / tr.l0)
        .scalar("t_end_over_tau_c", at_last(&|i| tr.t[i] / tr.tau))
        .scalar("t_f_over_tau_c", t_f / tr.tau)
        .scalar("t_kemax_over_tau_c", kmax.map(|i| tr.t[i] / tr.tau).unwrap_or(f64::NAN))
        .scalar("ed_over_e0_end", at_last(&|i| 1.0 - (tr.ek[i] + tr.ep[i]) / e0));
    super::analysis::analyse(
        out,
        &super::analysis::Run {
            method: tr.method.label(),
            l0: tr.l0,
            h0: tr.h0,
            tau: tr.tau,
            d: tr.d,
            t: &tr.t,
            l: &tr.l,
            h: &tr.h,
            ek: &tr.ek,
            ep: &tr.ep,
            inertial: &tr.inertial,
            gaps: &tr.gaps,
            gap_lengths: &tr.gap_lengths,
            link_gap: tr.link_gap,
            at_tau: tr.at_tau.as_ref(),
            x_start: &tr.x_start,
            x_end: &tr.x_end,
            mass: &tr.mass,
            phi_deg: tr.phi_deg,
            mu_grain: tr.mu_grain,
            at_rest: tr.at_rest,
            g: tr.g,
        },
    )?;
    Ok(Shared { t_f })
}

/// The run's two charts: (L − L_0)/L_0 and H/L_0 against t/τ_c, and the energies.
fn charts(ctx: &StageCtx, tr: &ColumnTrace, out: &mut Output) -> anyhow::Result<()> {
    let label = tr.method.label();
    let a = tr.h0 / tr.l0;
    let t: Vec<f64> = tr.t.iter().map(|v| v / tr.tau).collect();
    let curve = |y: &mut dyn Iterator<Item = f64>| t.iter().copied().zip(y).collect::<Vec<_>>();
    let chart = Chart {
        title: ctx
            .caption
            .clone()
            .unwrap_or_else(|| format!("{label} column collapse, a = {a:.2}")),
        footer: footer(&ctx.profile, &tr.footer),
        x_label: "t/τ_c".into(),
        y_label: "(L − L_0)/L_0,  H/L_0".into(),
        series: vec![
            Series::new(
                format!("{label} (L − L_0)/L_0"),
                Style::Line,
                curve(&mut tr.l.iter().map(|v| (v - tr.l0) / tr.l0)),
                0,
            ),
            Series::new(
                format!("{label} H/L_0"),
                Style::Line,
                curve(&mut tr.h.iter().map(|v| v / tr.l0)),
                1,
            ),
        ],
        ..Default::default()
    };
    out.figure("figure", chart.to_svg()?);
    let en = Chart {
        title: format!("{label} energy evolution, a = {a:.2}"),
        footer: footer(&ctx.profile, ""),
        x_label: "t/τ_c".into(),
        y_label: "E/E_0".into(),
        series: tr
            .energies
            .iter()
            .map(|e| {
                Series::new(
                    e.label.clone(),
                    Style::Line,
                    curve(&mut e.over_e0.iter().copied()),
                    e.color,
                )
            })
            .collect(),
        ..Default::default()
    };
    out.figure("energy", en.to_svg()?);
    Ok(())
}

/// Kind `column-collapse`.
pub const KIND: Kind = Kind {
    name: "column-collapse",
    source: file!(),
    method: None,
    version: 1,
    about: "Granular column collapse by DEM or MPM (`method:`): L(t), H(t), energies, until at rest",
    params,
    run,
    explain: Some(explain),
    roles: Roles::ByMethod(&[
        (
            Method::Dem,
            &[("column", Arity::One), ("calibration", Arity::OptionalOne)],
        ),
        (
            Method::Mpm,
            &[("shear", Arity::OptionalOne), ("compression", Arity::OptionalOne)],
        ),
    ]),
    outputs: Outputs {
        scalars: &[
            "a",
            "at_rest",
            "delta_e_j",
            "dt_s",
            "ed_over_e0_3tau",
            "ed_over_e0_end",
            "elastic_over_e0_end",
            "ep_over_e0_3tau",
            "erot_over_e0_end",
            "failure_angle_deg",
            "failure_angle_mohr_coulomb_deg",
            "failure_fit_r2",
            "failure_fit_slices",
            "failure_time_over_tau_c",
            "friction_angle_deg",
            "friction_angle_shear_deg",
            "front_linearity_r2_08_28",
            "front_gathered_max_backward_jump_over_l0",
            "front_max_backward_jump_over_l0",
            "front_speed_08_28_m_s",
            "h0_m",
            "hf_over_l0",
            "i_cg_max",
            "i_cg_mean_all_mass_max",
            "i_cg_mean_max",
            "i_cg_p95_max",
            "i_max_cap",
            "i_point_mean_all_mass_max",
            "i_point_mean_deep_max",
            "i_point_mean_max",
            "i_point_median_max",
            "i_point_p95_max",
            "l0_m",
            "lf_m",
            "link_gap_over_d",
            "max_balance_residual_over_e0",
            "max_overlap_fraction",
            "mu_e_energy",
            "mu_e_energy_deg",
            "mu_e_law",
            "mu_e_law_deg",
            "mu_e_runout",
            "mu_e_runout_deg",
            "mu_r",
            "n",
            "phi_voronoi_final",
            "phi_voronoi_initial",
            "plastic_work_over_e0_end",
            "points",
            "runout_eq46",
            "runout_gathered_norm",
            "runout_norm",
            "runout_norm_1tau",
            "runout_norm_3tau",
            "runout_q99_norm",
            "runout_thick_norm",
            "staron_hinch_w_j",
            "steps",
            "stop_rule_met",
            "stopped",
            "stress_free_fraction_max",
            "t_end_over_tau_c",
            "t_f_over_tau_c",
            "t_kemax_over_tau_c",
            "t_kemax_s",
            "t_stop_over_tau_c",
            "tau_c_s",
            "w_collisional_over_e0_end",
            "w_frictional_over_e0_end",
        ],
        tables: &[
            TableDecl {
                name: "link_gap_sensitivity",
                columns: &[
                    "gap_over_d", "largest_backward_jump_over_l0", "runout_norm_1tau", "runout_norm_2tau",
                    "runout_norm_3tau", "runout_norm_final",
                ],
            },
            // DEM only.
            TableDecl {
                name: "packing",
                columns: &[
                    "grains", "interior_cells", "phi_voronoi", "phi_voronoi_beyond_l0", "phi_voronoi_footprint",
                    "t_over_tau_c",
                ],
            },
            TableDecl {
                name: "runout_by_gap",
                columns: &["runout_norm_gap*", "t_over_tau_c"],
            },
            TableDecl {
                name: "runout_by_threshold",
                columns: &["runout_thick_norm_*d", "t_over_tau_c"],
            },
            TableDecl {
                name: "snapshots",
                columns: &[
                    "half_m", "k", "speed_m_s", "t_over_tau_c", "vx_m_s", "vy_m_s", "x_m", "y_m",
                ],
            },
            TableDecl {
                name: "table",
                columns: &[
                    "balance_residual_j", "ed_over_e0", "ek_grid_j", "ek_j", "ek_over_e0", "ekx_j", "eky_j",
                    "elastic_j", "ep_j", "ep_over_e0", "erot_j", "h_m", "h_over_l0", "i_cg_flowing_fraction",
                    "i_cg_max", "i_cg_mean", "i_cg_median", "i_cg_p95", "i_point_flowing_fraction", "i_point_mean",
                    "i_point_mean_deep", "i_point_median", "i_point_p95", "l_m", "plastic_work_j",
                    "runout_gathered_norm", "runout_norm", "stress_free_fraction", "t_over_tau_c", "t_s",
                    "w_collisional_j", "w_frictional_j", "wall_friction_work_j",
                ],
            },
        ],
        measurements: &[
            "acceleration-phase", "comes-to-rest", "constant-spreading-velocity", "failure-angle",
            "height-undisturbed", "inertial-number-dense", "motion-persists-6tau", "mu-e-energy", "mu-e-runout",
            "runout-eq4.6", "spreading-ceases-3tau",
        ],
        texts: &[],
    },
    reads: None,
    cost: Some(cost),
    atlas: None,
};

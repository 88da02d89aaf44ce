//! Kind `wp-summary`: the work-precision atlas (issue 12). Reads every work-precision
//! stage through the DAG (role `sources`: `work-precision` stages of any method,
//! recognised by their table columns) and writes
//! - `table`: one row per (method, setting, quantity): the knobs, the quantity, its
//!   relative error against the method's finest setting (the stage's own reference), the
//!   error's standard error where the stage ran an ensemble (DEM: members from perturbed
//!   starts), the wall time of one run at that setting, and whether the row is the
//!   reference or the setting the profile's figures use (`profile`, from the params);
//! - `orders`: Richardson observed orders p = ln(ΔQ_coarse/ΔQ_fine)/ln r for every knob
//!   sequence of three settings with a constant ratio r and all other knobs equal, and a
//!   verdict: "sound" only when both differences have one sign, grow with the knob,
//!   exceed twice their standard error and give p ≥ 0.5 (else the reason);
//! - scalars `<method>_profile_error`, `_profile_error_se`; the tables `timing` (wall time
//!   of every row) and `profile` (the profile's setting per method: error, standard error,
//!   wall time), read by the report page's "error vs run time" table — wall times are
//!   measurements, kept out of `table` and the scalars so those stay bit-identical;
//! - no figure: the plot `wp-atlas` (stages/wp-atlas.yaml) draws `table`'s errors against
//!   `timing`'s wall times, log–log, one series per method and quantity.
//! Nothing is run here: the stage only reads tables, so its quick cost is ≈ 0.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::pipeline::context::{InputRef, Output, StageCtx, col_f64, frame};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// Parameters of a `wp-summary` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
#[derive(Default)]
pub struct SummaryParams {
    /// Setting label whose error and wall time stand for the profile's figures, per method
    /// (`dem`, `mpm`, `cd`); labels as in the atlas table's `setting` column.
    pub profile: BTreeMap<String, String>,
}

impl Validate for SummaryParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        for k in self.profile.keys() {
            c.check(
                ["dem", "mpm", "cd"].contains(&k.as_str()),
                &format!("profile.{k}"),
                k,
                "a method: dem, mpm or cd",
            );
        }
        c.issues
    }
}

/// One atlas row.
#[derive(Debug, Clone)]
struct Row {
    method: &'static str,
    stage: String,
    setting: String,
    knobs: Vec<(&'static str, f64)>,
    quantity: &'static str,
    value: f64,
    value_se: f64,
    error: f64,
    error_se: f64,
    wall_s: f64,
    reference: bool,
    members: f64,
}

fn g(v: f64) -> String {
    crate::report::plot::tick(v)
}

fn has(df: &polars::prelude::DataFrame, c: &str) -> bool {
    df.get_column_names().iter().any(|n| n.as_str() == c)
}

/// Rows of one work-precision input.
fn rows_of(inp: &InputRef) -> anyhow::Result<Vec<Row>> {
    let t = inp.table("table")?;
    let timing = inp.table("timing")?;
    let wall = col_f64(&timing, "wall_s")?;
    let mut out = Vec::new();
    if has(&t, "stiffness_factor") {
        // DEM: ensembles; wall = one member's collapse + its share of the settling
        let (k, f, q, sd, m) = (
            col_f64(&t, "stiffness_factor")?,
            col_f64(&t, "dt_fraction")?,
            col_f64(&t, "runout_norm_mean")?,
            col_f64(&t, "runout_norm_std")?,
            col_f64(&t, "members")?,
        );
        let (e, se) = (col_f64(&t, "runout_rel_error")?, col_f64(&t, "runout_rel_error_se")?);
        let settle = col_f64(&timing, "settle_wall_s").unwrap_or_else(|_| vec![0.0; wall.len()]);
        let grains = col_f64(&t, "grains").ok();
        for i in 0..k.len() {
            let mut setting = format!("k{}-dt{}", g(k[i]), g(f[i]));
            let mut knobs = vec![("stiffness_factor", k[i]), ("dt_fraction", f[i])];
            if let Some(n) = &grains {
                if n[i] != n[0] {
                    setting.push_str(&format!("-n{}", g(n[i])));
                }
                knobs.push(("grains", n[i]));
            }
            out.push(Row {
                method: "dem",
                stage: inp.id.clone(),
                setting,
                knobs,
                quantity: "runout",
                value: q[i],
                value_se: sd[i] / m[i].max(1.0).sqrt(),
                error: e[i],
                error_se: se[i],
                wall_s: wall[i] + settle[i],
                reference: i == 0,
                members: m[i],
            });
        }
    } else if has(&t, "ppc") {
        // MPM: deterministic runs, ensembles of perturbed starts where the stage ran them;
        // the reference run is not in the table
        let (n, h, c, q, e) = (
            col_f64(&t, "ppc")?,
            col_f64(&t, "cell_size_m")?,
            col_f64(&t, "courant")?,
            col_f64(&t, "runout_norm")?,
            col_f64(&t, "runout_rel_error")?,
        );
        let opt = |c: &str, v: f64| col_f64(&t, c).unwrap_or_else(|_| vec![v; n.len()]);
        let (lin, musl, m, sd, se) = (
            opt("shape_linear", 0.0),
            opt("scheme_musl", 0.0),
            opt("members", 1.0),
            opt("runout_norm_std", f64::NAN),
            opt("runout_rel_error_se", f64::NAN),
        );
        for i in 0..n.len() {
            let mut setting = format!("ppc{}-h{}mm-C{}", g(n[i]), g(1e3 * h[i]), g(c[i]));
            let mut knobs = vec![("ppc", n[i]), ("cell_size_m", h[i]), ("courant", c[i])];
            if lin[i] != 0.0 {
                setting.push_str("-linear");
            }
            if musl[i] != 0.0 {
                setting.push_str("-musl");
            }
            knobs.push(("shape_linear", lin[i]));
            knobs.push(("scheme_musl", musl[i]));
            out.push(Row {
                method: "mpm",
                stage: inp.id.clone(),
                setting,
                knobs,
                quantity: "runout",
                value: q[i],
                value_se: sd[i] / m[i].max(1.0).sqrt(),
                error: e[i],
                error_se: se[i],
                wall_s: wall[i],
                reference: false,
                members: m[i],
            });
        }
    } else if has(&t, "tolerance") {
        // CD: the first variant is the reference; ensembles of perturbed starts where the
        // stage ran them
        let (dt, tol) = (col_f64(&t, "dt_s")?, col_f64(&t, "tolerance")?);
        let opt = |c: &str, v: f64| col_f64(&t, c).unwrap_or_else(|_| vec![v; dt.len()]);
        let (cap, m) = (opt("max_iterations", f64::NAN), opt("members", 1.0));
        for (quantity, qc, ec) in [
            ("runout", "runout_norm", "runout_rel_error"),
            ("centre-of-mass travel", "com_shift_norm", "com_shift_rel_error"),
            ("dissipated energy", "dissipated_j_m", "dissipated_rel_error"),
        ] {
            let (q, e) = (col_f64(&t, qc)?, col_f64(&t, ec)?);
            let (sd, se) = (opt(&format!("{qc}_std"), f64::NAN), opt(&format!("{ec}_se"), f64::NAN));
            for i in 0..dt.len() {
                let mut setting = format!("dt{}-tol{}", g(dt[i]), g(tol[i]));
                let mut knobs = vec![("dt_s", dt[i]), ("tolerance", tol[i])];
                if cap[i].is_finite() {
                    if cap[i] != cap[0] {
                        setting.push_str(&format!("-it{}", g(cap[i])));
                    }
                    knobs.push(("max_iterations", cap[i]));
                }
                out.push(Row {
                    method: "cd",
                    stage: inp.id.clone(),
                    setting,
                    knobs,
                    quantity,
                    value: q[i],
                    value_se: sd[i] / m[i].max(1.0).sqrt(),
                    error: e[i],
                    error_se: se[i],
                    wall_s: wall[i],
                    reference: i == 0,
                    members: m[i],
                });
            }
        }
    } else {
        anyhow::bail!(
            "input `{}` is not a work-precision stage (no stiffness_factor, ppc or tolerance column)",
            inp.id
        );
    }
    Ok(out)
}

/// One observed-order estimate.
#[derive(Debug, Clone)]
struct Order {
    method: &'static str,
    quantity: &'static str,
    knob: &'static str,
    at: String,
    levels: String,
    ratio: f64,
    order: f64,
    sound: bool,
    why: String,
}

/// Richardson observed orders along every knob (module doc).
fn orders(rows: &[Row]) -> Vec<Order> {
    let mut out = Vec::new();
    let mut groups: BTreeMap<(String, &'static str, &'static str, String), Vec<&Row>> = BTreeMap::new();
    for r in rows {
        for (ki, (knob, _)) in r.knobs.iter().enumerate() {
            let others: Vec<String> = r
                .knobs
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != ki)
                .map(|(_, (n, v))| format!("{n}={}", g(*v)))
                .collect();
            groups
                .entry((r.stage.clone(), r.quantity, knob, others.join(",")))
                .or_default()
                .push(r);
        }
    }
    for ((_, quantity, knob, at), mut g_rows) in groups {
        let ki = g_rows[0].knobs.iter().position(|(n, _)| *n == knob).unwrap_or(0);
        // finest first: the knob value that refines (smaller step/cell/tolerance; more PPC;
        // stiffer contacts)
        let finer_is_larger = matches!(knob, "ppc" | "stiffness_factor" | "max_iterations" | "grains");
        g_rows.sort_by(|a, b| {
            let (x, y) = (a.knobs[ki].1, b.knobs[ki].1);
            if finer_is_larger {
                y.total_cmp(&x)
            } else {
                x.total_cmp(&y)
            }
        });
        for w in g_rows.windows(3) {
            let x: Vec<f64> = w.iter().map(|r| r.knobs[ki].1).collect();
            let (r1, r2) = (x[1] / x[0], x[2] / x[1]);
            let levels = x.iter().map(|v| g(*v)).collect::<Vec<_>>().join(", ");
            let ratio = if finer_is_larger { 1.0 / r1 } else { r1 };
            if !((r1 / r2 - 1.0).abs() < 0.02) || (r1 - 1.0).abs() < 1e-9 {
                out.push(Order {
                    method: w[0].method,
                    quantity,
                    knob,
                    at: at.clone(),
                    levels,
                    ratio: f64::NAN,
                    order: f64::NAN,
                    sound: false,
                    why: "levels not in a constant ratio".into(),
                });
                continue;
            }
            let (d1, d2) = (w[1].value - w[0].value, w[2].value - w[1].value);
            let se = |a: &Row, b: &Row| (a.value_se.powi(2) + b.value_se.powi(2)).sqrt();
            let (s1, s2) = (se(w[0], w[1]), se(w[1], w[2]));
            let p = (d2 / d1).abs().ln() / ratio.ln().abs();
            let why = if d1 == 0.0 || d2 == 0.0 {
                "a difference is zero".to_string()
            } else if d1.signum() != d2.signum() {
                "differences change sign (not in the asymptotic range)".to_string()
            } else if s1.is_finite() && (d1.abs() < 2.0 * s1 || d2.abs() < 2.0 * s2) {
                format!(
                    "differences {:.3}, {:.3} within 2 standard errors ({:.3}, {:.3}) of the ensemble",
                    d1.abs(),
                    d2.abs(),
                    s1,
                    s2
                )
            } else if d2.abs() <= d1.abs() {
                "difference does not grow with the knob".to_string()
            } else if p < 0.5 {
                format!("observed order {p:.2} < 0.5: no convergence visible")
            } else {
                String::new()
            };
            out.push(Order {
                method: w[0].method,
                quantity,
                knob,
                at: at.clone(),
                levels,
                ratio,
                order: p,
                sound: why.is_empty(),
                why: if why.is_empty() { "sound".into() } else { why },
            });
        }
    }
    out
}

fn run(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: SummaryParams = decode(ctx)?;
    let mut rows = Vec::new();
    for inp in ctx.inputs_of("sources") {
        rows.extend(rows_of(inp)?);
    }
    let is_profile = |r: &Row| p.profile.get(r.method).is_some_and(|s| *s == r.setting);
    let mut out = Output::default();
    let fcol = |f: &dyn Fn(&Row) -> f64| rows.iter().map(f).collect::<Vec<f64>>();
    let mut df = frame(vec![
        ("value", fcol(&|r| r.value)),
        ("value_se", fcol(&|r| r.value_se)),
        ("rel_error", fcol(&|r| r.error)),
        ("rel_error_se", fcol(&|r| r.error_se)),
        ("reference", fcol(&|r| r.reference as u8 as f64)),
        ("profile", fcol(&|r| is_profile(r) as u8 as f64)),
    ])?;
    use polars::prelude::{Column, NamedFrom, Series as PlSeries};
    let text = |name: &str, f: &dyn Fn(&Row) -> String| {
        Column::from(PlSeries::new(name.into(), rows.iter().map(f).collect::<Vec<String>>()))
    };
    let mut cols = vec![
        text("method", &|r| r.method.to_string()),
        text("stage", &|r| r.stage.clone()),
        text("setting", &|r| r.setting.clone()),
        text("quantity", &|r| r.quantity.to_string()),
    ];
    cols.extend(df.columns().iter().cloned());
    df = polars::prelude::DataFrame::new_infer_height(cols)?;
    out.table("table", df);
    let ord = orders(&rows);
    let ocols = vec![
        Column::from(PlSeries::new(
            "method".into(),
            ord.iter().map(|o| o.method.to_string()).collect::<Vec<_>>(),
        )),
        Column::from(PlSeries::new(
            "quantity".into(),
            ord.iter().map(|o| o.quantity.to_string()).collect::<Vec<_>>(),
        )),
        Column::from(PlSeries::new(
            "knob".into(),
            ord.iter().map(|o| o.knob.to_string()).collect::<Vec<_>>(),
        )),
        Column::from(PlSeries::new(
            "other_knobs".into(),
            ord.iter().map(|o| o.at.clone()).collect::<Vec<_>>(),
        )),
        Column::from(PlSeries::new(
            "levels".into(),
            ord.iter().map(|o| o.levels.clone()).collect::<Vec<_>>(),
        )),
        Column::from(PlSeries::new(
            "ratio".into(),
            ord.iter().map(|o| o.ratio).collect::<Vec<_>>(),
        )),
        Column::from(PlSeries::new(
            "observed_order".into(),
            ord.iter().map(|o| o.order).collect::<Vec<_>>(),
        )),
        Column::from(PlSeries::new(
            "verdict".into(),
            ord.iter().map(|o| o.why.clone()).collect::<Vec<_>>(),
        )),
    ];
    out.table("orders", polars::prelude::DataFrame::new_infer_height(ocols)?);
    let n_sound = ord.iter().filter(|o| o.sound).count();
    for o in ord.iter().filter(|o| o.sound) {
        out.scalar(&format!("{}_order_{}", o.method, o.knob), o.order);
    }
    out.scalar("orders_sound", n_sound as f64)
        .scalar("orders_tested", ord.len() as f64);
    let mut prof: Vec<(&str, Row)> = Vec::new();
    for (method, setting) in &p.profile {
        let hit: Vec<&Row> = rows
            .iter()
            .filter(|r| r.method == method && r.setting == *setting)
            .collect();
        let Some(r) = hit.first() else {
            let have: Vec<&str> = rows
                .iter()
                .filter(|r| r.method == method)
                .map(|r| r.setting.as_str())
                .collect();
            anyhow::bail!(
                "profile.{method} = `{setting}` is not a setting of the {method} work-precision stage (have: {})",
                have.join(", ")
            );
        };
        out.scalar(&format!("{method}_profile_error"), r.error);
        if r.error_se.is_finite() {
            out.scalar(&format!("{method}_profile_error_se"), r.error_se);
        }
        prof.push((r.method, (*r).clone()));
    }
    // Wall times are measurements, not results: tables of their own, so `table` and the
    // scalars stay bit-identical across runs (as the work-precision stages do).
    out.table(
        "timing",
        polars::prelude::DataFrame::new_infer_height(vec![
            text("method", &|r| r.method.to_string()),
            text("setting", &|r| r.setting.clone()),
            text("quantity", &|r| r.quantity.to_string()),
            Column::new("wall_s".into(), fcol(&|r| r.wall_s)),
        ])?,
    );
    out.table(
        "profile",
        polars::prelude::DataFrame::new_infer_height(vec![
            Column::from(PlSeries::new(
                "method".into(),
                prof.iter().map(|(m, _)| m.to_string()).collect::<Vec<_>>(),
            )),
            Column::from(PlSeries::new(
                "setting".into(),
                prof.iter().map(|(_, r)| r.setting.clone()).collect::<Vec<_>>(),
            )),
            Column::from(PlSeries::new(
                "quantity".into(),
                prof.iter().map(|(_, r)| r.quantity.to_string()).collect::<Vec<_>>(),
            )),
            Column::new(
                "rel_error".into(),
                prof.iter().map(|(_, r)| r.error).collect::<Vec<f64>>(),
            ),
            Column::new(
                "rel_error_se".into(),
                prof.iter().map(|(_, r)| r.error_se).collect::<Vec<f64>>(),
            ),
            Column::new(
                "wall_s".into(),
                prof.iter().map(|(_, r)| r.wall_s).collect::<Vec<f64>>(),
            ),
        ])?,
    );
    let members = |m: &str| {
        rows.iter()
            .filter(|r| r.method == m)
            .map(|r| r.members)
            .fold(0.0, f64::max)
    };
    out.note(format!(
        "Error = |Q − Q_ref|/Q_ref against each stage's finest setting, Q an ensemble mean: ± standard error of the difference of means (members from perturbed starts: DEM {}, MPM {}, CD {}; 1 = a single deterministic run, no spread measured). Wall time: one run at the setting (DEM: one member's collapse plus its settling). Observed orders: {n_sound} of {} knob triples sound (table `orders`, with the reason for each rejection).",
        members("dem"), members("mpm"), members("cd"),
        ord.len()
    ));
    Ok(out)
}

/// Kind `wp-summary`.
pub const KIND: Kind = Kind {
    name: "wp-summary",
    source: file!(),
    method: None,
    version: 6,
    about: "work-precision atlas: every work-precision stage's error vs wall time in one table (drawn by a plot), observed orders, the profile's error and cost",
    params: typed::<SummaryParams>,
    run,
    explain: None,
    roles: crate::stages::kind::Roles::Fixed(&[("sources", crate::pipeline::context::Arity::Many)]),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "cd_order_*", "cd_profile_error", "cd_profile_error_se", "dem_order_*", "dem_profile_error",
            "dem_profile_error_se", "mpm_order_*", "mpm_profile_error", "mpm_profile_error_se", "orders_sound",
            "orders_tested",
        ],
        tables: &[
            crate::stages::kind::TableDecl {
                name: "orders",
                columns: &[
                    "knob", "levels", "method", "observed_order", "other_knobs", "quantity", "ratio", "verdict",
                ],
            },
            crate::stages::kind::TableDecl {
                name: "profile",
                columns: &["method", "quantity", "rel_error", "rel_error_se", "setting", "wall_s"],
            },
            crate::stages::kind::TableDecl {
                name: "table",
                columns: &[
                    "method", "profile", "quantity", "reference", "rel_error", "rel_error_se", "setting", "stage",
                    "value", "value_se",
                ],
            },
            crate::stages::kind::TableDecl {
                name: "timing",
                columns: &["method", "quantity", "setting", "wall_s"],
            },
        ],
        measurements: &[],
        texts: &[],
    },
    reads: None,
    cost: None,
    atlas: Some("profile"),
};

/// Relative error of an ensemble mean against the reference ensemble's mean, and its
/// standard error √(s²/n + s_ref²/n_ref)/|mean_ref| (NaN for single runs): the
/// work-precision stages' measure for every quantity (run-out, duration, final energy).
pub fn ensemble_error(v: &[f64], reference: &[f64]) -> (f64, f64, f64) {
    let stats = |x: &[f64]| {
        let n = x.len() as f64;
        let m = x.iter().sum::<f64>() / n;
        let s2 = if x.len() > 1 {
            x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (n - 1.0)
        } else {
            f64::NAN
        };
        (m, s2, n)
    };
    let ((m, s2, n), (mr, sr2, nr)) = (stats(v), stats(reference));
    let d = mr.abs().max(1e-300);
    (m, (m - mr).abs() / d, (s2 / n + sr2 / nr).sqrt() / d)
}

#[cfg(test)]
mod ensemble_error_tests {
    use super::ensemble_error;

    #[test]
    fn error_and_standard_error_of_two_ensembles() {
        // means 2 and 1.5 (s² = 1 and 0.25, n = 3): error 0.25/… = |2 − 1.5|/1.5
        let (m, e, se) = ensemble_error(&[1.0, 2.0, 3.0], &[1.0, 1.5, 2.0]);
        assert_eq!(m, 2.0);
        assert!((e - 0.5 / 1.5).abs() < 1e-15);
        assert!((se - ((1.0 / 3.0 + 0.25 / 3.0) as f64).sqrt() / 1.5).abs() < 1e-15);
        // the reference against itself: no error
        assert_eq!(ensemble_error(&[1.0, 2.0], &[1.0, 2.0]).1, 0.0);
        // single runs have no standard error
        assert!(ensemble_error(&[1.0], &[2.0]).2.is_nan());
    }
}

#[cfg(test)]
mod declared_tests {
    /// A sound observed order is published as `{method}_order_{knob}`; until 2026-12-07 the
    /// declaration listed none, so the first sound order (the quick MPM's PPC order, once
    /// its run-out was the gathered length) failed the stage at run time.
    #[test]
    fn every_order_scalar_the_stage_can_publish_is_declared() {
        let knobs: [(&str, &[&str]); 3] = [
            ("dem", &["stiffness_factor", "dt_fraction", "grains"]),
            ("mpm", &["ppc", "cell_size_m", "courant", "shape_linear", "scheme_musl"]),
            ("cd", &["dt_s", "tolerance", "max_iterations"]),
        ];
        for (method, ks) in knobs {
            for k in ks {
                let name = format!("{method}_order_{k}");
                assert!(super::KIND.outputs.has_scalar(&name), "{name} is not declared");
            }
        }
    }
}

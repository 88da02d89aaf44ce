//! Kind `pile-run` (chapter 4 §4.4, docs/definitions.md SC-PILE): one method (DEM, CD or
//! MPM), one excitation profile, a list of input energies; the same grains (DEM deposit)
//! seed every method. Per-run summary (D01, D10–D16) and the time series (`series`: E_k/E_0,
//! L, H against t per energy), which declared `plot` stages draw (figs 4.34b/4.35,
//! `pile-cd-ek`); the run draws no figure of its own.

use serde_json::Value;

use super::prep::grains as prep_grains;
use super::run_params::params;
use super::run_params::{RunParams, SnapSpec};
use crate::analysis::pile::{D_NORM, FrameTimes, Profile, Summary, cavity_area, wall_gap};
use crate::dem::State;
use crate::engines::Method;
use crate::engines::pile::{Excited, PileEngine, PileScene};
use crate::pipeline::context::{Claim, InputRef, Output, StageCtx, col_f64, frame};
use crate::stages::kind::{CostCtx, Work};
use crate::stages::{Kind, decode};

fn pile_from(input: &InputRef, density: f64) -> anyhow::Result<PileScene> {
    let sc = input.scalars()?;
    let settled = sc.get("settled").copied().unwrap_or(0.0);
    anyhow::ensure!(
        settled == 1.0,
        "input pile `{}` did not come to rest before the excitation (settled = {settled}): raise its pile.max_time or soften its rest criterion within the allowed range",
        input.id
    );
    let df = input.table("table")?;
    let (x, y, r) = (col_f64(&df, "x_m")?, col_f64(&df, "y_m")?, col_f64(&df, "r_m")?);
    let mut s = State::new();
    for i in 0..x.len() {
        s.insert(x[i], y[i], r[i], density);
    }
    let sf = input.table("surface")?;
    let profile: Vec<(f64, f64)> = col_f64(&sf, "x_m")?.into_iter().zip(col_f64(&sf, "top_m")?).collect();
    let get = |k: &str| {
        sc.get(k)
            .copied()
            .ok_or_else(|| anyhow::anyhow!("input `{}` has no scalar `{k}`", input.id))
    };
    Ok(PileScene {
        state: s,
        profile,
        l0: get("l0_m")?,
        packing: get("packing_fraction")?,
    })
}

fn run_run(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: RunParams = decode(ctx)?;
    let engine = p.engine();
    let pin = ctx.input("pile")?;
    let pile = pile_from(pin, engine.density())?;
    engine.accept(pin)?;
    let g = engine.gravity();
    let mut out = Output::default();
    let n = p.energies_mgd.len();
    let runs = engine.excite(ctx, &pile, &mut out)?;
    let col = |f: &dyn Fn(&Summary) -> f64| -> Vec<f64> { runs.iter().map(|r| f(&r.summary)).collect() };
    out.table(
        "table",
        frame(vec![
            ("e0_mgd", col(&|s| s.e0_mgd)),
            ("e0_j", col(&|s| s.e0_j)),
            ("e0_check", col(&|s| s.e0_check)),
            ("l0_d", col(&|s| s.l0)),
            ("lf_d", col(&|s| s.lf)),
            ("dl", col(&|s| s.dl)),
            ("tf", col(&|s| s.tf)),
            ("vs", col(&|s| s.vs)),
            ("ekx0_mgd", col(&|s| s.ekx0)),
            ("tau", col(&|s| s.tau)),
            ("tfp", col(&|s| s.tfp)),
            ("eky_peak", col(&|s| s.eky_peak)),
            ("stopped", col(&|s| s.stopped)),
            ("t_end", col(&|s| s.t_end)),
            ("steps", runs.iter().map(|r| r.run.steps as f64).collect()),
        ])?,
    );
    let tu = (D_NORM / g).sqrt();
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); 8];
    for Excited { summary: s, run: r, .. } in &runs {
        for q in &r.samples {
            let v = [
                s.e0_mgd,
                q.t / tu,
                q.l / D_NORM,
                q.h / D_NORM,
                q.ek / r.e0,
                q.ekx / r.e0,
                q.eky / r.e0,
                q.erot / r.e0,
            ];
            for (c, x) in cols.iter_mut().zip(v) {
                c.push(x);
            }
        }
    }
    let names = [
        "e0_mgd", "t", "l_d", "h_d", "ek_over_e0", "ekx_over_e0", "eky_over_e0", "erot_over_e0",
    ];
    out.table("series", frame(names.iter().cloned().zip(cols).collect())?);
    if let Some(sn) = &p.snapshots {
        snapshot_outputs(&mut out, &p, engine.as_ref(), sn, &runs, g)?;
    }
    let worst = runs
        .iter()
        .map(|r| (r.summary.e0_check - 1.0).abs())
        .fold(0.0, f64::max);
    out.checks.push(Claim::at_most(
        "e0-exact",
        "fig4-24: Σ ½ m v_x² at t = 0 equals E_0 (largest |ratio − 1| over the energies)",
        1e-9,
        worst,
    ));
    let frames_only = |s: &Summary| {
        p.snapshots
            .as_ref()
            .is_some_and(|sn| sn.end_after_last && (sn.e0_mgd - s.e0_mgd).abs() <= 1e-9 * s.e0_mgd.abs())
    };
    if runs.iter().any(|r| frames_only(&r.summary)) {
        out.note("The snapshot run ended at its last frame (snapshots.end_after_last): its row of the table is of a truncated run (stopped = 0), not a run-out.".to_string());
    }
    let unstopped = runs
        .iter()
        .filter(|r| r.summary.stopped == 0.0 && !frames_only(&r.summary))
        .count();
    out.checks.push(Claim::at_most(
        "stopped",
        "every run met the stopping rule before stop.t_max (number that did not)",
        0.0,
        unstopped as f64,
    ));
    out.scalar("runs", runs.len() as f64)
        .scalar("method_code", p.method as u8 as f64);
    out.note(format!(
        "Wall time per energy [s]: {}.",
        runs.iter()
            .map(|r| format!("{:.1}", r.wall_s))
            .collect::<Vec<_>>()
            .join(", ")
    ));
    out.note(format!(
        "{} pile, {} profile, {} energies; stopping rule: E_k + E_rot < {:.0e} E_0 and L within {} d over {} √(d/g), after {} √(d/g), at most {} √(d/g).",
        p.method.label(), p.profile.name(), n, p.stop.ek_ratio, p.stop.still_tol, p.stop.still_time, p.stop.t_min, p.stop.t_max
    ));
    Ok(out)
}

/// Frame instants [s] of the run at `e` [mgd] (none unless it is the snapshot run).
pub(super) fn frame_times(p: &RunParams, e: f64, g: f64) -> FrameTimes {
    match &p.snapshots {
        Some(sn) if (sn.e0_mgd - e).abs() <= 1e-9 * e.abs() => FrameTimes {
            times: sn.times.iter().map(|t| t * (D_NORM / g).sqrt()).collect(),
            end_after_last: sn.end_after_last,
        },
        _ => FrameTimes::default(),
    }
}

/// The snapshot run's frames (`snapshots` table, the `snapshot` kind's schema with time in
/// √(d/g)), per-frame front, cavity and wall gap (`snapshot_metrics`), and the chapter's
/// statements on the cavity and the left wall (figs 4.31, 4.32, 4.42, 4.43).
fn snapshot_outputs(
    out: &mut Output,
    p: &RunParams,
    engine: &dyn PileEngine,
    sn: &SnapSpec,
    runs: &[Excited],
    g: f64,
) -> anyhow::Result<()> {
    let tu = (D_NORM / g).sqrt();
    let Some(Excited { run: r, .. }) = runs
        .iter()
        .find(|r| (r.summary.e0_mgd - sn.e0_mgd).abs() <= 1e-9 * sn.e0_mgd.abs())
    else {
        anyhow::bail!("snapshots.e0_mgd = {} matches no run", sn.e0_mgd)
    };
    anyhow::ensure!(
        r.frames.len() == sn.times.len(),
        "the {} mgd run took {} of {} frames (it ended at {:.1} √(d/g))",
        sn.e0_mgd,
        r.frames.len(),
        sn.times.len(),
        r.samples.last().map(|q| q.t / tu).unwrap_or(0.0)
    );
    out.table(
        "snapshots",
        crate::stages::generic::snapshot::frame_rows(&r.frames, "t_over_sqrt_d_g", tu)?,
    );
    let d = D_NORM;
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); 5];
    for (k, f) in r.frames.iter().enumerate() {
        let l = r
            .samples
            .iter()
            .min_by(|a, b| (a.t - f.t).abs().total_cmp(&(b.t - f.t).abs()))
            .map(|q| q.l)
            .unwrap_or(f64::NAN);
        // over every body (the linked front of a thinning grain layer jumps; the cavity is
        // left of the highest point, which a far grain does not move)
        let reach = f.x.iter().zip(&f.half).map(|(x, h)| x + h).fold(0.0, f64::max);
        // the method's: MPM points are one continuum while they share grid nodes
        let extra = engine.cavity_link(f.half.first().copied().unwrap_or(0.0));
        let cav = cavity_area(&f.x, &f.y, &f.half, reach, 2.0 * d, extra) / (d * d);
        let gap = wall_gap(&f.x, &f.half) / d;
        for (c, v) in cols.iter_mut().zip([k as f64, f.t / tu, l / d, cav, gap]) {
            c.push(v);
        }
    }
    let names = ["k", "t_over_sqrt_d_g", "front_d", "cavity_d2", "wall_gap_d"];
    let (cav, gap) = (cols[3].clone(), cols[4].clone());
    out.table("snapshot_metrics", frame(names.iter().cloned().zip(cols).collect())?);
    let peak = cav.iter().cloned().fold(0.0, f64::max);
    let last = *cav.last().unwrap_or(&f64::NAN);
    let worst_gap = gap.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let fill = if peak > 0.0 { last / peak } else { f64::NAN };
    out.scalar("snap_e0_mgd", sn.e0_mgd)
        .scalar("snap_cavity_peak_d2", peak)
        .scalar("snap_cavity_last_d2", last)
        .scalar("snap_cavity_last_over_peak", fill)
        .scalar("snap_wall_gap_max_d", worst_gap);
    let span = format!(
        "frames at {} √(d/g), E_0 = {} mgd",
        sn.times.iter().map(|t| format!("{t}")).collect::<Vec<_>>().join(", "),
        sn.e0_mgd
    );
    // The chapter's statements are about the sequence: a single frame (fig4-24's t = 0) decides none.
    if r.frames.len() < 3 {
        return Ok(());
    }
    match p.profile {
        Profile::Gradient => {
            // In contact: within the method's gap of the wall (a grain: half a diameter; MPM:
            // material in the wall's grid cell, the wall being a node line).
            let (eps, says) = engine.wall_contact();
            out.claims.push(Claim::at_most("wall-contact", &format!("\"the granular heap remains in contact with the left wall irrespective of the input energy\": largest over the frames of the smallest body–wall gap min(x − half), in d ({span}; bound {eps:.2} d: {says})"), eps, worst_gap));
            out.claims.push(Claim::at_most("cavity-partly-filled", &format!("\"This cavity gets partially filled as the granular mass at the top collapse behind the flowing mass\": cavity area at the last frame over its peak (cavity: the dent left of the highest point under the surface seen from the right, 2 d bins; {span}; bound 0.9)"), 0.9, fill));
        }
        Profile::Uniform => {
            out.claims.push(Claim::at_least("cavity-not-filled", &format!("\"unlike the gradient input velocity, the cavity left behind the granular mass is not filled\": cavity area at the last frame over its peak ({span}; bound 0.9)"), 0.9, fill));
        }
    }
    Ok(())
}

/// `--explain`: the stage's engine's pre-flight.
fn explain(v: &Value) -> String {
    match serde_json::from_value::<RunParams>(v.clone()) {
        Ok(p) => p.engine().preflight(),
        Err(e) => format!("refused: {e}"),
    }
}

/// Kind `pile-run`.
pub const RUN_KIND: Kind = Kind {
    name: "pile-run",
    source: file!(),
    method: None,
    // 5: no figure of its own; its E_k/E_0 against t is drawn by declared plots of its
    // `series` (fig4-34, fig4-35 through pile-series, pile-cd-ek) (issue 23)
    version: 5,
    about: "pile under horizontal excitation (DEM, CD or MPM) over a list of input energies: run-out, duration, energies, decay (D01, D10–D16)",
    params,
    run: run_run,
    explain: Some(explain),
    // The MPM takes its friction from the CD shear test unless `mpm_friction` is set.
    roles: crate::stages::kind::Roles::ByMethod(&[
        (Method::Dem, &[("pile", crate::pipeline::context::Arity::One)]),
        (Method::Cd, &[("pile", crate::pipeline::context::Arity::One)]),
        (
            Method::Mpm,
            &[
                ("pile", crate::pipeline::context::Arity::One),
                ("shear", crate::pipeline::context::Arity::OptionalOne),
            ],
        ),
    ]),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "cd_dt_max_s", "dt_s", "method_code", "mpm_base_friction", "mpm_density", "mpm_friction",
            "mpm_friction_deg", "mpm_geostatic_time_s", "mpm_points", "runs", "snap_cavity_last_d2",
            "snap_cavity_last_over_peak", "snap_cavity_peak_d2", "snap_e0_mgd", "snap_sigma_yy_points",
            "snap_sigma_yy_rel_err", "snap_vx_max_m_s", "snap_vx_triangle_m_s", "snap_wall_gap_max_d",
            "stiffness_factor",
        ],
        tables: &[
            crate::stages::kind::TableDecl {
                name: "series",
                columns: &[
                    "e0_mgd", "ek_over_e0", "ekx_over_e0", "eky_over_e0", "erot_over_e0", "h_d", "l_d", "t",
                ],
            },
            crate::stages::kind::TableDecl {
                name: "snapshot_metrics",
                columns: &["cavity_d2", "front_d", "k", "t_over_sqrt_d_g", "wall_gap_d"],
            },
            crate::stages::kind::TableDecl {
                name: "snapshots",
                columns: &[
                    "half_m", "k", "sigma_yy_pa", "speed_m_s", "t_over_sqrt_d_g", "vx_m_s", "vy_m_s", "x_m", "y_m",
                ],
            },
            crate::stages::kind::TableDecl {
                name: "table",
                columns: &[
                    "dl", "e0_check", "e0_j", "e0_mgd", "ekx0_mgd", "eky_peak", "l0_d", "lf_d", "steps", "stopped",
                    "t_end", "tau", "tf", "tfp", "vs",
                ],
            },
        ],
        measurements: &["cavity-not-filled", "cavity-partly-filled", "wall-contact"],
        texts: &[],
    },
    reads: None,
    cost: Some(cost),
    atlas: None,
};

/// Cost: every energy runs to `stop.t_max` at most (in √(d/g); the same d̄ at both
/// profiles): an upper bound, as the runs stop earlier by the stopping rule.
fn cost(c: &CostCtx) -> Option<Work> {
    let p: RunParams = c.typed()?;
    let grains = prep_grains((c.inputs)("pile").first()?)?;
    let time = p.energies_mgd.len() as f64 * p.stop.t_max;
    Some((p.engine().work(grains, time), false))
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    /// `run --explain` of a CD or MPM pile printed the DEM's pre-flight table.
    #[test]
    fn explain_follows_the_method() {
        let dem = super::explain(&json!({ "method": "dem" }));
        let cd = super::explain(&json!({ "method": "cd" }));
        let mpm = super::explain(&json!({ "method": "mpm" }));
        assert!(cd.starts_with("CD:"), "{cd}");
        assert_ne!(mpm, dem);
        assert_ne!(cd, dem);
    }
}

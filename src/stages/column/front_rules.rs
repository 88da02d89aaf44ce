//! The run-out by the thick-deposit front rule (`crate::analysis::thick_front`, issue 25)
//! at several thresholds, over a run's snapshots: one table shared by the DEM and MPM
//! column stages, so the rule's sensitivity to its threshold is seen beside each run.

use crate::analysis::cloud::Cloud;
use crate::analysis::thick_front::ThickRule;
use crate::pipeline::context::{Output, frame};

/// Check `run.front` of a column stage's parameters into `c`.
pub fn check(rule: &ThickRule, c: &mut crate::validate::Checker) {
    if let Some((k, v, a)) = rule.issue() {
        c.fail(&format!("run.{k}"), v, a);
    }
}

/// Thresholds of the sensitivity table [d̄].
pub const THRESHOLDS_D: [f64; 3] = [0.5, 1.0, 2.0];

/// (L − L_0)/L_0 by the thick-deposit rule with threshold `threshold_d` d̄ (d̄ = `d`).
pub fn runout_thick(c: &Cloud, d: f64, threshold_d: f64, l0: f64) -> f64 {
    (ThickRule { threshold_d }.front(&c.body(), d).length - l0) / l0
}

/// Table `runout_by_threshold`: t/τ_c and (L − L_0)/L_0 at each of [`THRESHOLDS_D`] for
/// every cloud (snapshots, then the final state).
pub fn table(clouds: &[Cloud], d: f64, l0: f64, tau: f64) -> anyhow::Result<polars::prelude::DataFrame> {
    let names: Vec<String> = THRESHOLDS_D.iter().map(|k| format!("runout_thick_norm_{k}d")).collect();
    let mut cols = vec![("t_over_tau_c", clouds.iter().map(|c| c.t / tau).collect())];
    for (k, n) in THRESHOLDS_D.iter().zip(&names) {
        cols.push((n.as_str(), clouds.iter().map(|c| runout_thick(c, d, *k, l0)).collect()));
    }
    frame(cols)
}

/// Add the table `runout_by_threshold` ([`table`]) and the scalar `runout_thick_norm` (the
/// threshold of `rule`, on the last cloud: the final state) to `out`; returns that run-out.
/// `l0_tau` = (L_0 [m], τ_c [s]).
pub fn report(out: &mut Output, clouds: &[Cloud], d: f64, l0_tau: (f64, f64), rule: ThickRule) -> anyhow::Result<f64> {
    let (l0, tau) = l0_tau;
    out.table("runout_by_threshold", table(clouds, d, l0, tau)?);
    let v = clouds
        .last()
        .map(|c| runout_thick(c, d, rule.threshold_d, l0))
        .unwrap_or(f64::NAN);
    out.scalar("runout_thick_norm", v);
    Ok(v)
}

/// [`report`] for an MPM run: its snapshots, then its final state, points as squares of
/// half-width `lp` [m]; `d` = d̄ [m], `tau` = τ_c [s]. An additional measurement: the
/// MPM's run-out, L(t), H(t) and stop rule keep their links (docs/definitions.md D01).
pub fn report_mpm(
    out: &mut Output,
    r: &crate::mpm::column::CollapseResult,
    lp: f64,
    d: f64,
    tau: f64,
    rule: ThickRule,
) -> anyhow::Result<f64> {
    let clouds: Vec<Cloud> = r
        .snapshots
        .iter()
        .chain([&r.final_state])
        .map(|s| s.cloud(lp))
        .collect();
    let v = report(out, &clouds, d, (r.spec.l0, tau), rule)?;
    out.note(format!("Run-out by the thick-deposit front (an additional measurement; src/analysis/thick_front.rs, the rule the DEM column also reports): runout_thick_norm = {v:.3}, the farthest x up to which the deposit, connected to the main mass, is at least {} d̄ thick (points as squares of half-width l_p; table runout_by_threshold at 0.5, 1, 2 d̄). runout_norm, L(t), H(t) and the stop rule keep the grid/edge-gap links: at quick resolution the spreading sheet is about one point (≈ d̄) thick and flickers across the threshold, so an L(t) by this rule can jump backward by more than the 0.5 L_0 bound at quick resolution (docs/definitions.md D01).", rule.threshold_d));
    Ok(v)
}

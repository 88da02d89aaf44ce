//! The DEM calibration's choice (issue 24, item 3): the `dem-calibration` stage gathers the
//! `dem-calibration-point` grid ([`super::dem_calibration`]) and chooses the μ_r and rolling
//! model every DEM scene receives, by a stated rule:
//!
//! - `joint`: some grid point meets both targets — φ_cs = 22.2 ± 1° from the shear test
//!   and the ensemble run-outs at a = 0.4 and a ≈ 6 within ±15 % of eq 4.6 — and the one
//!   with the smallest worst miss (normalised by its tolerance) is taken;
//! - otherwise the two μ_r windows do not overlap on the grid, and the stage's
//!   `calib_target` decides: `flows` takes the point whose run-outs are closest to eq 4.6
//!   (the column and pile studies are the chapter's subject, and its DEM points are the
//!   DEM's own output), `friction-angle` the point whose φ_cs is closest to 22.2°.
//!
//! The rule and its reason are text fields of the stage's JSON (`rule`, `rule_reason`).
//! The point the other target would choose is marked beside the chosen one in the figures
//! and the table (`pick_flows`, `pick_friction_angle`), so a declared variant with the
//! other `calib_target` over the same points shows what that choice does to the flows
//! without running anything.

use serde::{Deserialize, Serialize};

use super::dem_calibration::{eq46, model_name};
use crate::pipeline::context::{Claim, Output, StageCtx, frame};
use crate::report::legend::Marker;
use crate::report::plot::{Chart, Legend, Series, Style, footer};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// Which target decides when no grid point meets both.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CalibTarget {
    /// The ensemble run-outs at a = 0.4 and a ≈ 6 against eq 4.6.
    #[default]
    Flows,
    /// The shear test's critical-state friction angle against 22.2°.
    FrictionAngle,
}

/// The rule that chose the point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rule {
    /// A grid point meets both targets.
    Joint,
    /// No point meets both: the run-outs decided.
    Flows,
    /// No point meets both: the friction angle decided.
    FrictionAngle,
}

impl Rule {
    /// The `rule` field of the JSON.
    pub fn name(self) -> &'static str {
        match self {
            Rule::Joint => "joint",
            Rule::Flows => "flows",
            Rule::FrictionAngle => "friction-angle",
        }
    }
}

/// Parameters of the `dem-calibration` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CalibParams {
    /// Target friction angle [°] ("A critical state friction angle of 22.2° was obtained").
    pub friction_angle_deg: f64,
    /// Allowed |φ − target| [°] (the issue's ±1°; the chapter's ±0.2° is its fit error).
    pub friction_tolerance_deg: f64,
    /// Allowed relative deviation of the ensemble-mean run-out from eq 4.6.
    pub runout_tolerance: f64,
    /// The target that decides when no grid point meets both (`flows` | `friction-angle`).
    pub calib_target: CalibTarget,
}

impl Default for CalibParams {
    fn default() -> Self {
        CalibParams {
            friction_angle_deg: 22.2,
            friction_tolerance_deg: 1.0,
            runout_tolerance: 0.15,
            calib_target: CalibTarget::Flows,
        }
    }
}

impl Validate for CalibParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        c.check(
            self.friction_angle_deg.is_finite() && self.friction_angle_deg > 0.0 && self.friction_angle_deg < 60.0,
            "friction_angle_deg",
            self.friction_angle_deg,
            "in (0, 60)°",
        );
        c.positive("friction_tolerance_deg", self.friction_tolerance_deg);
        c.in_open("runout_tolerance", self.runout_tolerance, 0.0, 1.0);
        c.issues
    }
}

/// One gathered grid point.
pub struct Point {
    /// Stage id of the point.
    pub id: String,
    /// Rolling-friction coefficient.
    pub mu_r: f64,
    /// 1 for the capped rolling model, 0 for EPSD.
    pub capped: f64,
    /// Shear-test φ_cs [°].
    pub phi: f64,
    /// (a, mean, std, eq 4.6)
    pub runouts: Vec<(f64, f64, f64, f64)>,
}

impl Point {
    /// |φ − φ*|/tol_φ (≤ 1 inside the friction-angle window).
    pub fn friction_miss(&self, p: &CalibParams) -> f64 {
        (self.phi - p.friction_angle_deg).abs() / p.friction_tolerance_deg
    }
    /// Largest |ΔL/eq 4.6 − 1|/tol_L over the columns (≤ 1 inside the run-out window).
    pub fn runout_miss(&self, p: &CalibParams) -> f64 {
        self.runouts
            .iter()
            .map(|&(_, m, _, law)| (m / law - 1.0).abs() / p.runout_tolerance)
            .fold(0.0, f64::max)
    }
    /// Largest normalised miss of both targets; ≤ 1 meets all.
    pub fn cost(&self, p: &CalibParams) -> f64 {
        self.friction_miss(p).max(self.runout_miss(p))
    }
}

/// The point one target picks: smallest miss of it, ties by the other.
fn pick(pts: &[Point], p: &CalibParams, target: CalibTarget) -> usize {
    let key = |q: &Point| match target {
        CalibTarget::Flows => (q.runout_miss(p), q.friction_miss(p)),
        CalibTarget::FrictionAngle => (q.friction_miss(p), q.runout_miss(p)),
    };
    (0..pts.len())
        .min_by(|&a, &b| {
            let (ka, kb) = (key(&pts[a]), key(&pts[b]));
            ka.0.total_cmp(&kb.0).then(ka.1.total_cmp(&kb.1))
        })
        .expect("at least one grid point")
}

/// The stated choice: the chosen point, its rule and the reason in words (no numbers, so
/// the golden snapshot pins it exactly).
pub fn choose(pts: &[Point], p: &CalibParams) -> (usize, Rule, String) {
    let costs: Vec<f64> = pts.iter().map(|q| q.cost(p)).collect();
    let best = (0..pts.len())
        .min_by(|&a, &b| costs[a].total_cmp(&costs[b]))
        .expect("at least one grid point");
    if costs[best] <= 1.0 {
        return (
            best,
            Rule::Joint,
            "both targets met: the grid point with the smallest worst miss".into(),
        );
    }
    let window = |inside: &dyn Fn(&Point) -> bool| {
        let ids: Vec<&str> = pts.iter().filter(|q| inside(q)).map(|q| q.id.as_str()).collect();
        if ids.is_empty() {
            "no grid point".to_string()
        } else {
            ids.join(", ")
        }
    };
    let windows = format!(
        "windows do not overlap (friction-angle window: {}; run-out window: {})",
        window(&|q| q.friction_miss(p) <= 1.0),
        window(&|q| q.runout_miss(p) <= 1.0)
    );
    match p.calib_target {
        CalibTarget::Flows => (
            pick(pts, p, CalibTarget::Flows),
            Rule::Flows,
            format!("{windows}; calib_target flows: the run-outs closest to eq 4.6 at a = 0.4 and a ≈ 6"),
        ),
        CalibTarget::FrictionAngle => (
            pick(pts, p, CalibTarget::FrictionAngle),
            Rule::FrictionAngle,
            format!("{windows}; calib_target friction-angle: the shear-test φ_cs closest to the chapter's"),
        ),
    }
}

fn gather(ctx: &StageCtx) -> anyhow::Result<Vec<Point>> {
    let mut pts = Vec::new();
    for input in ctx.inputs_of("points") {
        let sc = input.scalars()?;
        let get = |k: &str| {
            sc.get(k)
                .copied()
                .ok_or_else(|| anyhow::anyhow!("input `{}` has no scalar `{k}`", input.id))
        };
        let mut runouts = Vec::new();
        for (k, &m) in sc.iter().filter(|(k, _)| k.starts_with("runout_mean_a")) {
            let key = &k["runout_mean_a".len()..];
            let a: f64 = key.parse()?;
            runouts.push((a, m, get(&format!("runout_std_a{key}"))?, eq46(a)));
        }
        runouts.sort_by(|x, y| x.0.total_cmp(&y.0));
        pts.push(Point {
            id: input.id.clone(),
            mu_r: get("mu_r")?,
            capped: get("model_capped")?,
            phi: get("friction_angle_deg")?,
            runouts,
        });
    }
    anyhow::ensure!(
        !pts.is_empty(),
        "stage `{}` needs `points` inputs (dem-calibration-point stages)",
        ctx.id
    );
    Ok(pts)
}

fn describe(q: &Point) -> String {
    format!(
        "`{}` (μ_r = {}, {} rolling model: φ_cs = {:.2}°, run-out/eq 4.6 = {})",
        q.id,
        q.mu_r,
        model_name(q.capped),
        q.phi,
        q.runouts
            .iter()
            .map(|r| format!("{:.2} at a = {}", r.1 / r.3, r.0))
            .collect::<Vec<_>>()
            .join(", ")
    )
}

fn run_calib(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: CalibParams = decode(ctx)?;
    let pts = gather(ctx)?;
    let (best, rule, reason) = choose(&pts, &p);
    let chosen = &pts[best];
    // The point the other target picks (the variant's choice), when the windows do not overlap.
    let other = match rule {
        Rule::Joint => None,
        Rule::Flows => Some((pick(&pts, &p, CalibTarget::FrictionAngle), "friction-angle")),
        Rule::FrictionAngle => Some((pick(&pts, &p, CalibTarget::Flows), "flows")),
    }
    .filter(|(i, _)| *i != best);
    let mut out = Output::default();
    let a_list: Vec<f64> = chosen.runouts.iter().map(|r| r.0).collect();
    let flag = |i: usize| {
        (0..pts.len())
            .map(|j| if j == i { 1.0 } else { 0.0 })
            .collect::<Vec<f64>>()
    };
    let mut cols: Vec<(String, Vec<f64>)> = vec![
        ("mu_r".into(), pts.iter().map(|q| q.mu_r).collect()),
        ("model_capped".into(), pts.iter().map(|q| q.capped).collect()),
        ("friction_angle_deg".into(), pts.iter().map(|q| q.phi).collect()),
    ];
    for &a in &a_list {
        let col = |f: &dyn Fn(&(f64, f64, f64, f64)) -> f64| {
            pts.iter()
                .map(|q| q.runouts.iter().find(|r| r.0 == a).map(f).unwrap_or(f64::NAN))
                .collect::<Vec<f64>>()
        };
        cols.push((format!("runout_mean_a{a}"), col(&|r| r.1)));
        cols.push((format!("runout_std_a{a}"), col(&|r| r.2)));
        cols.push((format!("runout_over_eq46_a{a}"), col(&|r| r.1 / r.3)));
    }
    cols.push(("cost".into(), pts.iter().map(|q| q.cost(&p)).collect()));
    cols.push((
        "friction_miss".into(),
        pts.iter().map(|q| q.friction_miss(&p)).collect(),
    ));
    cols.push(("runout_miss".into(), pts.iter().map(|q| q.runout_miss(&p)).collect()));
    cols.push(("chosen".into(), flag(best)));
    cols.push(("pick_flows".into(), flag(pick(&pts, &p, CalibTarget::Flows))));
    cols.push((
        "pick_friction_angle".into(),
        flag(pick(&pts, &p, CalibTarget::FrictionAngle)),
    ));
    out.table(
        "table",
        frame(cols.iter().map(|(n, v)| (n.as_str(), v.clone())).collect())?,
    );
    let count = |f: &dyn Fn(&Point) -> bool| pts.iter().filter(|q| f(q)).count() as f64;
    out.scalar("mu_r", chosen.mu_r)
        .scalar("rolling_model_capped", chosen.capped)
        .scalar("friction_angle_deg", chosen.phi)
        .scalar("cost", chosen.cost(&p))
        .scalar("both_targets_met", if rule == Rule::Joint { 1.0 } else { 0.0 })
        .scalar("grid_points", pts.len() as f64)
        .scalar("friction_window_points", count(&|q| q.friction_miss(&p) <= 1.0))
        .scalar("runout_window_points", count(&|q| q.runout_miss(&p) <= 1.0));
    out.text("rule", rule.name()).text("rule_reason", reason.clone());
    let by = match rule {
        Rule::Joint => "the grid point meeting both targets",
        Rule::Flows => "the point calibrated on the flows (calibration target, not a reproduction)",
        Rule::FrictionAngle => "the point calibrated on the friction angle",
    };
    for &(a, m, s, law) in &chosen.runouts {
        // Named by regime, not by a: the prepared column's a (5.8 at quick size, 5.9 at
        // paper size for a target of 6) must not change the name the ledger reads.
        let regime = if a <= 2.7 { "short" } else { "tall" };
        out.scalar(&format!("runout_mean_a{a}"), m)
            .scalar(&format!("runout_std_a{a}"), s)
            .scalar(&format!("runout_over_eq46_{regime}"), m / law);
        out.claims.push(
            Claim::rel(
                &format!("runout-eq4.6-{regime}"),
                &format!(
                    "eq 4.6 run-out at a = {a}: (L_f − L_0)/L_0 ≈ {} — ensemble mean ± {s:.3} (s.d.) at {by}",
                    if a <= 2.7 { "1.67a" } else { "2.7a^(2/3)" }
                ),
                law,
                m,
                p.runout_tolerance,
            )
            .calibrated(),
        );
    }
    out.claims.push(
        Claim::abs(
            "friction-angle",
            &format!("\"A critical state friction angle of 22.2° was obtained\" — shear test at {by}"),
            p.friction_angle_deg,
            chosen.phi,
            p.friction_tolerance_deg,
        )
        .calibrated(),
    );
    out.note(format!(
        "Rule `{}`: {reason}. Chosen: {}; it is used downstream and every number resting on it is labelled calibrated.",
        rule.name(),
        describe(chosen)
    ));
    if let Some((i, target)) = other {
        out.note(format!(
            "calib_target {target} would choose {} instead (the declared variant of this stage with calib_target: {target}; its run-outs are the grid point's ensembles, no new runs).",
            describe(&pts[i])
        ));
    }
    let marks = Marks {
        chosen: best,
        rule,
        other,
    };
    out.figure("figure", phi_chart(ctx, &p, &pts, &marks).to_svg()?);
    out.figure("runout", runout_chart(ctx, &p, &pts, &a_list, &marks).to_svg()?);
    Ok(out)
}

/// The chosen point and the other target's pick, as the figures mark them.
struct Marks {
    chosen: usize,
    rule: Rule,
    other: Option<(usize, &'static str)>,
}

impl Marks {
    fn footer(&self, ctx: &StageCtx, what: &str) -> String {
        footer(&ctx.profile, &format!("{what} · rule: {}", self.rule.name()))
    }
    /// Marker series for the chosen point and the other pick, y from `y`.
    fn series(&self, pts: &[Point], y: &dyn Fn(&Point) -> Vec<f64>) -> Vec<Series> {
        let q = &pts[self.chosen];
        let mut chosen = Series::new(
            format!(
                "chosen (rule {}): μ_r = {}, {}",
                self.rule.name(),
                q.mu_r,
                model_name(q.capped)
            ),
            Style::Points,
            y(q).into_iter().map(|v| (q.mu_r, v)).collect(),
            7,
        );
        chosen.marker = Marker::Diamond;
        let mut v = vec![chosen];
        if let Some((i, target)) = self.other {
            let o = &pts[i];
            let mut s = Series::new(
                format!(
                    "variant calib_target {target}: μ_r = {}, {}",
                    o.mu_r,
                    model_name(o.capped)
                ),
                Style::Points,
                y(o).into_iter().map(|w| (o.mu_r, w)).collect(),
                5,
            );
            s.marker = Marker::SquareOpen;
            v.push(s);
        }
        v
    }
}

fn models(pts: &[Point]) -> Vec<f64> {
    let mut m: Vec<f64> = pts.iter().map(|q| q.capped).collect();
    m.sort_by(f64::total_cmp);
    m.dedup();
    m
}

fn x_span(pts: &[Point]) -> (f64, f64) {
    let xs = pts.iter().map(|q| q.mu_r);
    (
        xs.clone().fold(f64::INFINITY, f64::min),
        xs.fold(f64::NEG_INFINITY, f64::max),
    )
}

/// Two dashed lines bounding a band, labelled once.
fn band(label: String, (x0, x1): (f64, f64), lo: f64, hi: f64) -> [Series; 2] {
    [
        Series::new(label, Style::Dashed, vec![(x0, lo), (x1, lo)], 7),
        Series::new("", Style::Dashed, vec![(x0, hi), (x1, hi)], 7),
    ]
}

fn phi_chart(ctx: &StageCtx, p: &CalibParams, pts: &[Point], marks: &Marks) -> Chart {
    let mut series = Vec::new();
    for (k, &m) in models(pts).iter().enumerate() {
        let mut v: Vec<(f64, f64)> = pts.iter().filter(|q| q.capped == m).map(|q| (q.mu_r, q.phi)).collect();
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        series.push(Series::new(
            format!("shear test, {} rolling model", model_name(m)),
            Style::LinePoints,
            v,
            k,
        ));
    }
    series.extend(band(
        format!("target {} ± {}° (band)", p.friction_angle_deg, p.friction_tolerance_deg),
        x_span(pts),
        p.friction_angle_deg - p.friction_tolerance_deg,
        p.friction_angle_deg + p.friction_tolerance_deg,
    ));
    series.extend(marks.series(pts, &|q| vec![q.phi]));
    Chart {
        title: format!("{} — friction angle", ctx.id),
        footer: marks.footer(ctx, "shear test φ_cs at each grid point"),
        x_label: "rolling friction μ_r [-]".into(),
        y_label: "critical-state friction angle φ_cs [°]".into(),
        series,
        legend: Legend::LowerRight,
        ..Default::default()
    }
}

fn runout_chart(ctx: &StageCtx, p: &CalibParams, pts: &[Point], a_list: &[f64], marks: &Marks) -> Chart {
    let mut series = Vec::new();
    let mut colour = 0;
    for &m in &models(pts) {
        for &a in a_list {
            let mut v: Vec<(f64, f64, f64)> = pts
                .iter()
                .filter(|q| q.capped == m)
                .filter_map(|q| {
                    q.runouts
                        .iter()
                        .find(|r| r.0 == a)
                        .map(|r| (q.mu_r, r.1 / r.3, r.2 / r.3))
                })
                .collect();
            v.sort_by(|a, b| a.0.total_cmp(&b.0));
            let err: Vec<f64> = v.iter().map(|t| t.2).collect();
            series.push(
                Series::new(
                    format!("a = {a}, {} model (mean ± s.d.)", model_name(m)),
                    Style::LinePoints,
                    v.iter().map(|t| (t.0, t.1)).collect(),
                    colour,
                )
                .with_errors(err),
            );
            colour += 1;
        }
    }
    series.extend(band(
        format!("eq 4.6 ± {:.0} % (band)", 100.0 * p.runout_tolerance),
        x_span(pts),
        1.0 - p.runout_tolerance,
        1.0 + p.runout_tolerance,
    ));
    series.extend(marks.series(pts, &|q| q.runouts.iter().map(|r| r.1 / r.3).collect()));
    Chart {
        title: format!("{} — run-out against eq 4.6", ctx.id),
        footer: marks.footer(ctx, "ensemble mean ± s.d. over perturbed starts"),
        x_label: "rolling friction μ_r [-]".into(),
        y_label: "(L_f − L_0)/L_0 ÷ eq 4.6".into(),
        series,
        legend: Legend::UpperRight,
        ..Default::default()
    }
}

/// Kind `dem-calibration`.
pub const CALIB_KIND: Kind = Kind {
    name: "dem-calibration",
    source: file!(),
    method: Some(crate::engines::Method::Dem),
    version: 3, // 3: eq 4.6 run-outs named by regime (runout-eq4.6-short / -tall)
    about: "DEM calibration: gathers dem-calibration-point stages and chooses μ_r and the rolling model by a stated rule (joint if a point meets φ_cs and eq 4.6, else the stage's calib_target: flows or friction-angle)",
    params: typed::<CalibParams>,
    run: run_calib,
    explain: None,
    roles: crate::stages::kind::Roles::Fixed(&[("points", crate::pipeline::context::Arity::Many)]),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "both_targets_met", "cost", "friction_angle_deg", "friction_window_points", "grid_points", "mu_r",
            "rolling_model_capped", "runout_mean_a*", "runout_over_eq46_short", "runout_over_eq46_tall",
            "runout_std_a*", "runout_window_points",
        ],
        tables: &[crate::stages::kind::TableDecl {
            name: "table",
            columns: &[
                "chosen", "cost", "friction_angle_deg", "friction_miss", "model_capped", "mu_r", "pick_flows",
                "pick_friction_angle", "runout_mean_a*", "runout_miss", "runout_over_eq46_a*", "runout_std_a*",
            ],
        }],
        measurements: &["friction-angle", "runout-eq4.6-short", "runout-eq4.6-tall"],
        texts: &["rule", "rule_reason"],
    },
    reads: None,
    cost: None,
    atlas: None,
};

#[cfg(test)]
mod tests {
    use super::*;

    fn pt(id: &str, mu_r: f64, capped: f64, phi: f64, r04: f64, r58: f64) -> Point {
        Point {
            id: id.into(),
            mu_r,
            capped,
            phi,
            runouts: vec![(0.4, r04, 0.04, eq46(0.4)), (5.8, r58, 0.2, eq46(5.8))],
        }
    }

    /// The quick grid of docs/calibration.md (γ = 0.6 φ): no point meets both.
    fn quick_grid() -> Vec<Point> {
        vec![
            pt("calib-point-mu_r0.1", 0.1, 0.0, 17.5, 0.577, 8.41),
            pt("calib-point-mu_r0.3", 0.3, 0.0, 20.5, 0.387, 6.17),
            pt("calib-point-capped-mu_r0.1", 0.1, 1.0, 18.3, 0.670, 8.41),
            pt("calib-point-capped-mu_r0.3", 0.3, 1.0, 18.3, 0.417, 6.92),
        ]
    }

    #[test]
    fn windows_apart_flows_choose_the_run_outs_and_say_why() {
        let p = CalibParams::default();
        let (i, rule, why) = choose(&quick_grid(), &p);
        assert_eq!(
            (quick_grid()[i].id.as_str(), rule),
            ("calib-point-capped-mu_r0.1", Rule::Flows)
        );
        assert!(why.contains("windows do not overlap"), "{why}");
        assert!(why.contains("friction-angle window: no grid point"), "{why}");
        // epsd 0.1 is inside the run-out window too (13.7 % short at a = 0.4), capped 0.1 closer
        assert!(
            why.contains("run-out window: calib-point-mu_r0.1, calib-point-capped-mu_r0.1"),
            "{why}"
        );
    }

    #[test]
    fn windows_apart_friction_angle_target_chooses_phi() {
        let p = CalibParams {
            calib_target: CalibTarget::FrictionAngle,
            ..Default::default()
        };
        let (i, rule, _) = choose(&quick_grid(), &p);
        assert_eq!(
            (quick_grid()[i].id.as_str(), rule),
            ("calib-point-mu_r0.3", Rule::FrictionAngle)
        );
    }

    #[test]
    fn a_point_meeting_both_is_joint_whatever_the_target() {
        let mut g = quick_grid();
        g.push(pt("calib-point-mu_r0.2", 0.2, 0.0, 22.0, 0.64, 8.2));
        for t in [CalibTarget::Flows, CalibTarget::FrictionAngle] {
            let p = CalibParams {
                calib_target: t,
                ..Default::default()
            };
            let (i, rule, _) = choose(&g, &p);
            assert_eq!((g[i].id.as_str(), rule), ("calib-point-mu_r0.2", Rule::Joint));
        }
    }

    #[test]
    fn calib_target_reads_its_yaml_names_and_refuses_others() {
        let v: CalibParams = serde_yaml::from_str("calib_target: friction-angle").unwrap();
        assert_eq!(v.calib_target, CalibTarget::FrictionAngle);
        let v: CalibParams = serde_yaml::from_str("calib_target: flows").unwrap();
        assert_eq!(v.calib_target, CalibTarget::Flows);
        assert!(serde_yaml::from_str::<CalibParams>("calib_target: phi").is_err());
    }
}

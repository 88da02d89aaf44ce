//! Stage kinds `psd` (sample grain diameters from a cumulative-β grading) and
//! `psd-figure` (fig4-01b: cumulative % finer by area, target curve vs sampled grains).

use serde::{Deserialize, Serialize};

use crate::pipeline::context::{Claim, Output, StageCtx, col_f64, frame};
use crate::report::plot::{Chart, Series, Style, footer, tick};
use crate::sample::psd::{BetaGrading, ks_distance, stats, volume_cdf_of_sample};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// Parameters of a `psd` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PsdParams {
    /// Smallest diameter [mm].
    pub d_min_mm: f64,
    /// Largest diameter [mm].
    pub d_max_mm: f64,
    /// Cumulative-β shape parameter a (1 with b = 1: uniform by volume fraction).
    pub beta_a: f64,
    /// Cumulative-β shape parameter b.
    pub beta_b: f64,
    /// Number of grains.
    pub n: usize,
    /// RNG seed (ChaCha8), recorded in the outputs.
    pub seed: u64,
}

impl Default for PsdParams {
    fn default() -> Self {
        // Chapter 4 §4.2.1: "[d_min, d_max] = 0.92 - 1.38 mm", "~3000 disks".
        PsdParams {
            d_min_mm: 0.92,
            d_max_mm: 1.38,
            beta_a: 1.0,
            beta_b: 1.0,
            n: 3000,
            seed: 1,
        }
    }
}

impl Validate for PsdParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        c.positive("d_min_mm", self.d_min_mm);
        c.positive("d_max_mm", self.d_max_mm);
        // A constraint between two keys names both, whichever of them was mistyped.
        c.check(
            self.d_max_mm > self.d_min_mm,
            "d_max_mm",
            format!("{} (with d_min_mm = {})", self.d_max_mm, self.d_min_mm),
            &format!("> d_min_mm ({})", self.d_min_mm),
        );
        c.in_closed("beta_a", self.beta_a, 0.05, 100.0);
        c.in_closed("beta_b", self.beta_b, 0.05, 100.0);
        c.check(
            self.n >= 10 && self.n <= 10_000_000,
            "n",
            self.n,
            "an integer in [10, 10000000]",
        );
        c.issues
    }
}

impl PsdParams {
    /// The grading curve in SI units.
    pub fn grading(&self) -> BetaGrading {
        BetaGrading {
            d_min: self.d_min_mm * 1e-3,
            d_max: self.d_max_mm * 1e-3,
            a: self.beta_a,
            b: self.beta_b,
        }
    }
}

fn run_psd(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: PsdParams = decode(ctx)?;
    let g = p.grading();
    let d = g.sample(p.n, p.seed);
    let s = stats(&d);
    let mut out = Output::default();
    let idx: Vec<f64> = (0..d.len()).map(|i| i as f64).collect();
    out.table("table", frame(vec![("grain", idx), ("d_m", d.clone())])?);
    out.scalar("n", s.n as f64)
        .scalar("seed", p.seed as f64)
        .scalar("d10_m", s.d10)
        .scalar("d50_m", s.d50)
        .scalar("d60_m", s.d60)
        .scalar("coefficient_of_uniformity", s.cu)
        .scalar("d_mean_volume_m", s.d_mean_volume)
        .scalar("d_mean_number_m", s.d_mean_number)
        .scalar("polydispersity_r", p.d_max_mm / p.d_min_mm)
        .scalar("ks_distance", ks_distance(&d, &g));
    out.note(format!(
        "Cumulative β({}, {}) grading on [{}, {}] mm, {} grains, ChaCha8 seed {} (stratified quantiles, shuffled).",
        p.beta_a, p.beta_b, p.d_min_mm, p.d_max_mm, p.n, p.seed
    ));
    Ok(out)
}

/// Kind `psd`.
pub const KIND: Kind = Kind {
    name: "psd",
    source: file!(),
    method: None,
    version: 1,
    about: "sample disk diameters from a cumulative-beta grading curve (thesis ch. 3)",
    params: typed::<PsdParams>,
    run: run_psd,
    explain: None,
    roles: crate::stages::kind::NO_INPUTS,
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "coefficient_of_uniformity", "d10_m", "d50_m", "d60_m", "d_mean_number_m", "d_mean_volume_m",
            "ks_distance", "n", "polydispersity_r", "seed",
        ],
        tables: &[crate::stages::kind::TableDecl {
            name: "table",
            columns: &["d_m", "grain"],
        }],
        measurements: &[],
        texts: &[],
    },
    reads: None,
    cost: None,
    atlas: None,
};

/// Parameters of a `psd-figure` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PsdFigureParams {
    /// Points on the target curve.
    pub curve_points: usize,
    /// Mean diameter the chapter states [mm] (claim).
    pub paper_mean_mm: f64,
    /// Largest Kolmogorov distance accepted (claim; docs/definitions.md fig4-01: < 0.05).
    pub ks_max: f64,
}

impl Default for PsdFigureParams {
    fn default() -> Self {
        PsdFigureParams {
            curve_points: 200,
            paper_mean_mm: 1.15,
            ks_max: 0.05,
        }
    }
}

impl Validate for PsdFigureParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        c.check(
            self.curve_points >= 2 && self.curve_points <= 100_000,
            "curve_points",
            self.curve_points,
            "an integer in [2, 100000]",
        );
        c.positive("paper_mean_mm", self.paper_mean_mm);
        c.in_open_closed("ks_max", self.ks_max, 0.0, 1.0);
        c.issues
    }
}

fn run_psd_figure(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: PsdFigureParams = decode(ctx)?;
    let input = ctx.input("psd")?;
    let psd: PsdParams = serde_json::from_value(input.params.clone())?;
    let g = psd.grading();
    let d = col_f64(&input.table("table")?, "d_m")?;
    let s = stats(&d);
    let (sorted, cdf) = volume_cdf_of_sample(&d);
    let ks = ks_distance(&d, &g);
    let n = p.curve_points;
    let dd: Vec<f64> = (0..n)
        .map(|i| g.d_min + (g.d_max - g.d_min) * i as f64 / (n - 1) as f64)
        .collect();
    let target: Vec<f64> = dd.iter().map(|&x| 100.0 * g.volume_cdf(x)).collect();
    // Sample CDF evaluated on the same grid (fraction of area finer than or equal to d).
    let sample_on_grid: Vec<f64> = dd
        .iter()
        .map(|&x| {
            let k = sorted.partition_point(|&v| v <= x);
            if k == 0 { 0.0 } else { 100.0 * cdf[k - 1] }
        })
        .collect();
    let mut out = Output::default();
    out.table(
        "table",
        frame(vec![
            ("d_mm", dd.iter().map(|x| x * 1e3).collect()),
            ("target_pct_finer", target.clone()),
            ("sample_pct_finer", sample_on_grid),
        ])?,
    );
    out.table(
        "grains",
        frame(vec![
            ("d_mm", sorted.iter().map(|x| x * 1e3).collect()),
            ("pct_finer", cdf.iter().map(|c| 100.0 * c).collect()),
        ])?,
    );
    out.scalar("d10_mm", s.d10 * 1e3)
        .scalar("d50_mm", s.d50 * 1e3)
        .scalar("d60_mm", s.d60 * 1e3)
        .scalar("coefficient_of_uniformity", s.cu)
        .scalar("d_mean_volume_mm", s.d_mean_volume * 1e3)
        .scalar("d_mean_number_mm", s.d_mean_number * 1e3)
        .scalar("ks_distance", ks)
        .scalar("n", s.n as f64)
        .scalar("seed", psd.seed as f64);
    out.checks.push(Claim::rel(
        "mean-diameter",
        "\"mean grain diameter of 1.15mm\" (volume mean of the sampled grains)",
        p.paper_mean_mm,
        s.d_mean_volume * 1e3,
        0.01,
    ));
    out.checks.push(Claim::abs(
        "polydispersity",
        "\"poly-dispersity r = d_max/d_min = 1.5\"",
        1.5,
        psd.d_max_mm / psd.d_min_mm,
        1e-9,
    ));
    out.checks.push(Claim::at_most(
        "ks-distance",
        "sampled grains follow the target distribution (Kolmogorov distance < 0.05, docs/definitions.md fig4-01)",
        p.ks_max,
        ks,
    ));
    // Thin the grain markers for a readable figure (every k-th grain, deterministic).
    let step = (sorted.len() / 150).max(1);
    let grains: Vec<(f64, f64)> = sorted
        .iter()
        .zip(&cdf)
        .step_by(step)
        .map(|(x, c)| (x * 1e3, 100.0 * c))
        .collect();
    let chart = Chart {
        title: ctx.caption.clone().unwrap_or_else(|| "Grain size distribution".into()),
        footer: footer(
            &ctx.profile,
            &format!("{} grains, seed {}, KS distance {:.4}", s.n, psd.seed, ks),
        ),
        x_label: "grain diameter d [mm]".into(),
        y_label: "cumulative % finer (by area)".into(),
        x_range: Some((psd.d_min_mm - 0.02, psd.d_max_mm + 0.02)),
        y_range: Some((0.0, 100.0)),
        series: vec![
            Series::new(
                format!(
                    "target: Graded a={}, b={}, r={} (cumulative β by volume)",
                    tick(psd.beta_a),
                    tick(psd.beta_b),
                    tick(psd.d_max_mm / psd.d_min_mm)
                ),
                Style::Line,
                dd.iter().zip(&target).map(|(x, y)| (x * 1e3, *y)).collect(),
                7,
            ),
            Series::new(
                format!("sampled grains (every {step}th shown)"),
                Style::Points,
                grains,
                0,
            ),
        ],
        ..Default::default()
    };
    out.figure("figure", chart.to_svg()?);
    Ok(out)
}

/// Kind `psd-figure`.
pub const FIGURE_KIND: Kind = Kind {
    name: "psd-figure",
    source: file!(),
    method: None,
    version: 3,
    about: "fig4-01b: cumulative % finer of sampled grains vs the target grading",
    params: typed::<PsdFigureParams>,
    run: run_psd_figure,
    explain: None,
    roles: crate::stages::kind::Roles::Fixed(&[("psd", crate::pipeline::context::Arity::One)]),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "coefficient_of_uniformity", "d10_mm", "d50_mm", "d60_mm", "d_mean_number_mm", "d_mean_volume_mm",
            "ks_distance", "n", "seed",
        ],
        tables: &[
            crate::stages::kind::TableDecl {
                name: "grains",
                columns: &["d_mm", "pct_finer"],
            },
            crate::stages::kind::TableDecl {
                name: "table",
                columns: &["d_mm", "sample_pct_finer", "target_pct_finer"],
            },
        ],
        measurements: &[],
        texts: &[],
    },
    reads: None,
    cost: None,
    atlas: None,
};

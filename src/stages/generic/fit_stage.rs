//! Kind `power-law-fit`: fit y = c·x^n (one regime, or two with a given or estimated
//! break) to columns of any upstream table, or to scalars gathered across the members of
//! a sweep; compare the exponents with the chapter's; overlay stated laws (dashed).

use serde::{Deserialize, Serialize};

use crate::fit::{PowerFit, fixed_exponent, power_law, two_regimes};
use crate::pipeline::context::{Claim, Output, StageCtx, col_f64, frame};
use crate::report::plot::{Chart, Series, Style, footer};
use crate::stages::kind::{Item, Read};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// Where the (x, y) points come from.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Default)]
#[serde(rename_all = "snake_case")]
pub enum Source {
    /// Columns `x`, `y` of each `data` input's table (rows concatenated).
    #[default]
    Table,
    /// Scalars `x`, `y` of each `data` input (one point per input: a sweep).
    Scalars,
}

/// A quoted exponent to check.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PaperExponent {
    /// 0 = single/low regime, 1 = high regime.
    #[serde(default)]
    pub regime: usize,
    /// The chapter's exponent.
    pub exponent: f64,
    /// Allowed |ours − paper|; default: 2 × our standard error + the paper's ±.
    #[serde(default)]
    pub tolerance: Option<f64>,
    /// The chapter's ± on it.
    #[serde(default)]
    pub paper_error: f64,
    /// Quote.
    #[serde(default)]
    pub statement: String,
}

/// Parameters of a `power-law-fit` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FitParams {
    /// Data source.
    pub source: Source,
    /// Table name in each input (Source::Table).
    pub table: String,
    /// x column / scalar.
    pub x: String,
    /// y column / scalar.
    pub y: String,
    /// 1 or 2 regimes.
    pub regimes: usize,
    /// Break point (2 regimes); estimated when absent.
    pub break_x: Option<f64>,
    /// Fix the exponents (one per regime) and fit only prefactors.
    pub fixed_exponents: Option<Vec<f64>>,
    /// Keep x ≥ x_min.
    pub x_min: Option<f64>,
    /// Keep x ≤ x_max.
    pub x_max: Option<f64>,
    /// Axis labels.
    pub x_label: String,
    /// Axis labels.
    pub y_label: String,
    /// Exponents quoted by the chapter.
    pub paper: Vec<PaperExponent>,
    /// Laws (names from `reference-laws`) to overlay from the `laws` input.
    pub overlay_laws: Vec<String>,
}

impl Default for FitParams {
    fn default() -> Self {
        FitParams {
            source: Source::Table,
            table: "table".into(),
            x: "x".into(),
            y: "y".into(),
            regimes: 1,
            break_x: None,
            fixed_exponents: None,
            x_min: None,
            x_max: None,
            x_label: "x".into(),
            y_label: "y".into(),
            paper: vec![],
            overlay_laws: vec![],
        }
    }
}

impl Validate for FitParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        c.check(
            self.regimes == 1 || self.regimes == 2,
            "regimes",
            self.regimes,
            "1 or 2",
        );
        if let Some(b) = self.break_x {
            c.positive("break_x", b);
        }
        if let Some(f) = &self.fixed_exponents {
            c.check(
                f.len() == self.regimes,
                "fixed_exponents",
                format!("{f:?}"),
                "one exponent per regime",
            );
        }
        for (i, p) in self.paper.iter().enumerate() {
            c.check(
                p.regime < self.regimes,
                &format!("paper[{i}].regime"),
                p.regime,
                "0 (low/single) or 1 (high, with regimes: 2)",
            );
        }
        for l in &self.overlay_laws {
            c.check(
                super::laws::eval(l, 1.0).is_some(),
                "overlay_laws",
                l,
                &format!(
                    "one of {}",
                    super::laws::LAWS.iter().map(|l| l.0).collect::<Vec<_>>().join(", ")
                ),
            );
        }
        c.issues
    }
}

fn gather(ctx: &StageCtx, p: &FitParams) -> anyhow::Result<(Vec<f64>, Vec<f64>)> {
    let (mut xs, mut ys) = (Vec::new(), Vec::new());
    let data = ctx.inputs_of("data");
    anyhow::ensure!(
        !data.is_empty(),
        "stage `{}` needs inputs under the role `data`",
        ctx.id
    );
    for inp in data {
        match p.source {
            Source::Table => {
                let df = inp.table(&p.table)?;
                xs.extend(col_f64(&df, &p.x)?);
                ys.extend(col_f64(&df, &p.y)?);
            }
            Source::Scalars => {
                xs.push(inp.scalar(&p.x)?);
                ys.push(inp.scalar(&p.y)?);
            }
        }
    }
    let keep: Vec<bool> = xs
        .iter()
        .map(|&x| p.x_min.is_none_or(|m| x >= m) && p.x_max.is_none_or(|m| x <= m))
        .collect();
    let xs2 = xs.iter().zip(&keep).filter(|(_, k)| **k).map(|(x, _)| *x).collect();
    let ys2 = ys.iter().zip(&keep).filter(|(_, k)| **k).map(|(y, _)| *y).collect();
    Ok((xs2, ys2))
}

fn run(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: FitParams = decode(ctx)?;
    let (x, y) = gather(ctx, &p)?;
    let mut fits: Vec<PowerFit> = Vec::new();
    let mut break_x = f64::NAN;
    if p.regimes == 1 {
        fits.push(match &p.fixed_exponents {
            Some(e) => fixed_exponent(&x, &y, e[0])?,
            None => power_law(&x, &y)?,
        });
    } else {
        let t = two_regimes(&x, &y, p.break_x)?;
        break_x = t.break_x;
        match &p.fixed_exponents {
            Some(e) => {
                let (lx, ly): (Vec<f64>, Vec<f64>) = x
                    .iter()
                    .zip(&y)
                    .filter(|(a, _)| **a <= break_x)
                    .map(|(a, b)| (*a, *b))
                    .unzip();
                let (hx, hy): (Vec<f64>, Vec<f64>) = x
                    .iter()
                    .zip(&y)
                    .filter(|(a, _)| **a > break_x)
                    .map(|(a, b)| (*a, *b))
                    .unzip();
                fits.push(fixed_exponent(&lx, &ly, e[0])?);
                fits.push(fixed_exponent(&hx, &hy, e[1])?);
            }
            None => {
                fits.push(t.low);
                fits.push(t.high);
            }
        }
    }
    let mut out = Output::default();
    let reg: Vec<f64> = (0..fits.len()).map(|i| i as f64).collect();
    out.table(
        "table",
        frame(vec![
            ("regime", reg),
            ("x_min", fits.iter().map(|f| f.x_min).collect()),
            ("x_max", fits.iter().map(|f| f.x_max).collect()),
            ("exponent", fits.iter().map(|f| f.exponent).collect()),
            ("exponent_se", fits.iter().map(|f| f.exponent_se).collect()),
            ("prefactor", fits.iter().map(|f| f.prefactor).collect()),
            (
                "log10_prefactor_se",
                fits.iter().map(|f| f.log10_prefactor_se).collect(),
            ),
            ("r2", fits.iter().map(|f| f.r2).collect()),
            ("n_points", fits.iter().map(|f| f.n as f64).collect()),
        ])?,
    );
    out.table("points", frame(vec![("x", x.clone()), ("y", y.clone())])?);
    let names = if fits.len() == 1 {
        vec![""]
    } else {
        vec!["_low", "_high"]
    };
    for (f, n) in fits.iter().zip(&names) {
        out.scalar(&format!("exponent{n}"), f.exponent)
            .scalar(&format!("exponent_se{n}"), f.exponent_se)
            .scalar(&format!("prefactor{n}"), f.prefactor)
            // s.e. of the prefactor from that of its log: c·ln 10·s.e.(log10 c)
            .scalar(
                &format!("prefactor_se{n}"),
                f.prefactor * std::f64::consts::LN_10 * f.log10_prefactor_se,
            )
            .scalar(&format!("r2{n}"), f.r2);
    }
    if p.regimes == 2 {
        out.scalar("break_x", break_x);
    }
    for (i, q) in p.paper.iter().enumerate() {
        let f = &fits[q.regime];
        let tol = q.tolerance.unwrap_or(2.0 * f.exponent_se + q.paper_error);
        let id = format!(
            "exponent-{}",
            if fits.len() == 1 {
                "single".to_string()
            } else if q.regime == 0 {
                "low".into()
            } else {
                "high".into()
            }
        );
        let id = if p.paper.len() > 1 && p.paper.iter().filter(|o| o.regime == q.regime).count() > 1 {
            format!("{id}-{i}")
        } else {
            id
        };
        out.claims
            .push(Claim::abs(&id, &q.statement, q.exponent, f.exponent, tol));
    }
    // Figure: data, fits (dashed, "fit"), stated laws (dashed, "stated law").
    let mut series = vec![Series::new(
        "data",
        Style::Points,
        x.iter().copied().zip(y.iter().copied()).collect(),
        0,
    )];
    for (k, f) in fits.iter().enumerate() {
        let pts: Vec<(f64, f64)> = (0..50)
            .map(|i| {
                let xv = f.x_min * (f.x_max / f.x_min).powf(i as f64 / 49.0);
                (xv, f.eval(xv))
            })
            .collect();
        series.push(Series::new(
            format!(
                "fit: {:.3}·x^({:.3} ± {:.3}), R² = {:.3}",
                f.prefactor, f.exponent, f.exponent_se, f.r2
            ),
            Style::Dashed,
            pts,
            1 + k,
        ));
    }
    if !p.overlay_laws.is_empty() {
        let laws = ctx.input("laws")?.table("table")?;
        let a = col_f64(&laws, "a")?;
        for (k, l) in p.overlay_laws.iter().enumerate() {
            let v = col_f64(&laws, l)?;
            let label = super::laws::LAWS.iter().find(|x| x.0 == l).map(|x| x.1).unwrap_or(l);
            series.push(Series::new(
                label,
                Style::Dashed,
                a.iter().copied().zip(v).collect(),
                4 + k,
            ));
        }
    }
    let chart = Chart::log_log(
        ctx.caption.clone().unwrap_or_else(|| format!("{} vs {}", p.y, p.x)),
        footer(&ctx.profile, ""),
        &p.x_label,
        &p.y_label,
        series,
    );
    out.figure("figure", chart.to_svg()?);
    Ok(out)
}

/// Kind `power-law-fit`.
pub const KIND: Kind = Kind {
    name: "power-law-fit",
    source: file!(),
    method: None,
    version: 1,
    about: "log-log least-squares power law (1 or 2 regimes) with standard errors, vs quoted exponents",
    params: typed::<FitParams>,
    run,
    explain: None,
    roles: crate::stages::kind::Roles::ByParams(roles),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "break_x", "exponent", "exponent_high", "exponent_low", "exponent_se", "exponent_se_high",
            "exponent_se_low", "prefactor", "prefactor_high", "prefactor_low", "prefactor_se", "prefactor_se_high",
            "prefactor_se_low", "r2", "r2_high", "r2_low",
        ],
        tables: &[
            crate::stages::kind::TableDecl {
                name: "points",
                columns: &["x", "y"],
            },
            crate::stages::kind::TableDecl {
                name: "table",
                columns: &[
                    "exponent", "exponent_se", "log10_prefactor_se", "n_points", "prefactor", "r2", "regime", "x_max",
                    "x_min",
                ],
            },
        ],
        measurements: &["exponent-high", "exponent-low", "exponent-single"],
        texts: &[],
    },
    reads: Some(reads),
    cost: None,
    atlas: None,
};

/// What the fit names of its `data` inputs (checked at load).
pub fn reads(v: &serde_json::Value) -> Vec<Read> {
    let Ok(p) = serde_json::from_value::<FitParams>(v.clone()) else {
        return vec![];
    };
    let read = |key: &str, item: Item| Read {
        role: "data".into(),
        key: key.into(),
        item,
    };
    match p.source {
        Source::Table => vec![
            read("table", Item::Table(p.table.clone())),
            read("x", Item::Column(p.table.clone(), p.x.clone())),
            read("y", Item::Column(p.table.clone(), p.y.clone())),
        ],
        Source::Scalars => vec![
            read("x", Item::Scalar(p.x.clone())),
            read("y", Item::Scalar(p.y.clone())),
        ],
    }
}

/// Roles: the data (one or more); the laws input is required when laws are overlaid.
fn roles(v: &serde_json::Value) -> Vec<(&'static str, crate::pipeline::context::Arity)> {
    use crate::pipeline::context::Arity::*;
    let overlays = v
        .get("overlay_laws")
        .and_then(|o| o.as_array())
        .is_some_and(|a| !a.is_empty());
    vec![("data", Many), ("laws", if overlays { One } else { OptionalOne })]
}

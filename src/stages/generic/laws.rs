//! Kind `reference-laws`: the scaling laws the chapter *states* (eq 4.6, eq 4.7) and the
//! experimental ones it compares with (Lajeunesse et al. 2005, Lube et al. 2005, as
//! written in thesis chapter 2), tabulated on a grid of aspect ratios. Figures overlay
//! these as dashed lines labelled "stated law" — they are never drawn as data.

use serde::{Deserialize, Serialize};

use crate::pipeline::context::{Output, StageCtx, frame};
use crate::report::plot::{Chart, Series, Style, footer};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// A law by name: value at aspect ratio `a`.
pub fn eval(name: &str, a: f64) -> Option<f64> {
    Some(match name {
        // eq 4.6 (DEM): 1.67a for a ≲ 2.7, 2.7a^(2/3) for a ≳ 2.7 (discontinuous, I4).
        "eq4_6_runout" => {
            if a <= 2.7 {
                1.67 * a
            } else {
                2.7 * a.powf(2.0 / 3.0)
            }
        }
        // eq 4.7: H_f/L_0 ∝ a (a ≲ 0.7), ∝ a^(2/3) (a ≳ 0.7). The chapter gives no
        // prefactors: we take H_f/L_0 = a below (undisturbed top) and make the upper
        // branch continuous at 0.7: 0.7^(1/3)·a^(2/3). Documented choice.
        "eq4_7_height" => {
            if a <= 0.7 {
                a
            } else {
                0.7f64.powf(1.0 / 3.0) * a.powf(2.0 / 3.0)
            }
        }
        // Thesis ch. 2, Lajeunesse et al. (2005): 1.35a (a ≲ 0.74), 2.0a^1.2 (a ≳ 0.74).
        "lajeunesse2005_runout" => {
            if a <= 0.74 {
                1.35 * a
            } else {
                2.0 * a.powf(1.2)
            }
        }
        // Thesis ch. 2, 2D collapse: H_f/L_0 = a (a ≲ 0.7), a^(1/3) (a ≳ 0.7).
        "lajeunesse2005_height_2d" => {
            if a <= 0.7 {
                a
            } else {
                a.powf(1.0 / 3.0)
            }
        }
        // Thesis ch. 2, Lube et al. (2005): 1.24a (a ≲ 1.7), 1.6a^1.2 (a ≳ 1.7).
        "lube2005_runout" => {
            if a <= 1.7 {
                1.24 * a
            } else {
                1.6 * a.powf(1.2)
            }
        }
        _ => return None,
    })
}

/// Every law name with its legend label.
pub const LAWS: [(&str, &str); 5] = [
    ("eq4_6_runout", "stated law eq 4.6: (L_f−L_0)/L_0 = 1.67a | 2.7a^(2/3)"),
    (
        "eq4_7_height",
        "stated law eq 4.7: H_f/L_0 ∝ a | a^(2/3) (prefactor: continuity)",
    ),
    (
        "lajeunesse2005_runout",
        "stated law, Lajeunesse et al. 2005: 1.35a | 2.0a^1.2",
    ),
    (
        "lajeunesse2005_height_2d",
        "stated law, Lajeunesse et al. 2005 (2D): a | a^(1/3)",
    ),
    ("lube2005_runout", "stated law, Lube et al. 2005: 1.24a | 1.6a^1.2"),
];

/// Parameters of a `reference-laws` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LawParams {
    /// Smallest aspect ratio.
    pub a_min: f64,
    /// Largest aspect ratio.
    pub a_max: f64,
    /// Grid points (log-spaced).
    pub n_points: usize,
}

impl Default for LawParams {
    fn default() -> Self {
        LawParams {
            a_min: 0.1,
            a_max: 12.0,
            n_points: 241,
        }
    }
}

impl Validate for LawParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        c.positive("a_min", self.a_min);
        c.check(self.a_max > self.a_min, "a_max", self.a_max, "> a_min");
        c.check(
            self.n_points >= 2 && self.n_points <= 100_000,
            "n_points",
            self.n_points,
            "an integer in [2, 100000]",
        );
        c.issues
    }
}

fn run(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: LawParams = decode(ctx)?;
    let a: Vec<f64> = (0..p.n_points)
        .map(|i| p.a_min * (p.a_max / p.a_min).powf(i as f64 / (p.n_points - 1) as f64))
        .collect();
    let mut cols = vec![("a", a.clone())];
    let mut series = Vec::new();
    for (i, (name, label)) in LAWS.iter().enumerate() {
        let v: Vec<f64> = a.iter().map(|&x| eval(name, x).unwrap()).collect();
        series.push(Series::new(
            *label,
            Style::Dashed,
            a.iter().copied().zip(v.iter().copied()).collect(),
            i,
        ));
        cols.push((name, v));
    }
    let mut out = Output::default();
    out.table("table", frame(cols)?);
    // I4: eq 4.6's branches do not meet at 2.7; they cross at (2.7/1.67)^3.
    let lo = 1.67 * 2.7;
    let hi = 2.7 * 2.7f64.powf(2.0 / 3.0);
    out.scalar("eq4_6_low_branch_at_2_7", lo)
        .scalar("eq4_6_high_branch_at_2_7", hi)
        .scalar("eq4_6_jump_fraction", hi / lo - 1.0)
        .scalar("eq4_6_branches_cross_at_a", (2.7f64 / 1.67).powi(3));
    out.note("docs/definitions.md I4: eq 4.6's branches jump by 16 % at a = 2.7 and cross at a = 4.23; each branch is fitted separately, continuity is not forced.");
    let chart = Chart::log_log(
        ctx.caption.clone().unwrap_or_else(|| "Stated scaling laws".into()),
        footer(&ctx.profile, "laws as stated, not simulations"),
        "aspect ratio a = H_0/L_0",
        "(L_f − L_0)/L_0  or  H_f/L_0",
        series,
    );
    out.figure("figure", chart.to_svg()?);
    Ok(out)
}

/// Kind `reference-laws`.
pub const KIND: Kind = Kind {
    name: "reference-laws",
    source: file!(),
    method: None,
    version: 1,
    about: "the chapter's stated scaling laws (eq 4.6, 4.7) and experimental ones, for overlays",
    params: typed::<LawParams>,
    run,
    explain: None,
    roles: crate::stages::kind::NO_INPUTS,
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "eq4_6_branches_cross_at_a", "eq4_6_high_branch_at_2_7", "eq4_6_jump_fraction", "eq4_6_low_branch_at_2_7",
        ],
        tables: &[crate::stages::kind::TableDecl {
            name: "table",
            columns: &[
                "a", "eq4_6_runout", "eq4_7_height", "lajeunesse2005_height_2d", "lajeunesse2005_runout",
                "lube2005_runout",
            ],
        }],
        measurements: &[],
        texts: &[],
    },
    reads: None,
    cost: None,
    atlas: None,
};

//! Kind `sweep-compare`: the chapter's comparative claims between two families of runs —
//! "hexagonal packing runs out less than random", "MPM runs further than DEM for a > 2.7",
//! "dense columns run ~30 % further" — measured on our sweeps. Members of two input roles
//! are paired on a scalar (the aspect ratio `a`), the ratio of a scalar is taken per pair,
//! and its mean over a range of the pairing scalar is the claim's value.
//!
//! Roles are free names declared by the params (`a`, `b` of each comparison), checked in
//! `src/pipeline/check.rs` like a `plot`'s.

use serde::{Deserialize, Serialize};

use crate::pipeline::context::{Claim, Output, StageCtx, frame};
use crate::stages::kind::{Item, Read};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// What the chapter says about the ratio ours(a)/ours(b).
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
#[serde(rename_all = "snake_case")]
pub enum Relation {
    /// Mean ratio ≤ 1 ("shorter", "less").
    Less,
    /// Mean ratio ≥ 1 ("longer", "further").
    Greater,
    /// Mean ratio = 1 within `tolerance` ("identical", "the same").
    Equal,
    /// Mean ratio = `paper` within `tolerance` ("~30 % further": 1.3).
    Ratio,
}

/// One comparison.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Comparison {
    /// Claim id.
    pub id: String,
    /// The chapter's words.
    pub statement: String,
    /// Numerator role.
    pub a: String,
    /// Denominator role.
    pub b: String,
    /// Scalar compared.
    pub y: String,
    /// Pairing scalar.
    #[serde(default = "aspect")]
    pub pair_on: String,
    /// Pair a member with the nearest member of `b` whose `pair_on` is within this
    /// fraction of it: the realised aspect ratio of a trimmed deposit or a hexagonal lattice
    /// differs from the nominal one by a few per cent (0.38 for a nominal 0.4), while the
    /// sweep's neighbours are ≥ 25 % apart.
    #[serde(default = "pair_tol")]
    pub pair_tolerance: f64,
    /// Keep pairs with pair_on in [lo, hi].
    #[serde(default)]
    pub range: Option<[f64; 2]>,
    /// The relation stated.
    pub relation: Relation,
    /// Paper ratio (relation: ratio).
    #[serde(default)]
    pub paper: Option<f64>,
    /// Allowed |mean ratio − paper| (relations equal, ratio).
    #[serde(default)]
    pub tolerance: Option<f64>,
}

fn aspect() -> String {
    "a".into()
}
fn pair_tol() -> f64 {
    0.1
}

/// Parameters of a `sweep-compare` stage.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CompareParams {
    /// The comparisons.
    pub claims: Vec<Comparison>,
}

impl CompareParams {
    /// Every input role the comparisons read.
    pub fn roles(&self) -> Vec<String> {
        let mut r: Vec<String> = Vec::new();
        for c in &self.claims {
            for s in [&c.a, &c.b] {
                if !r.contains(s) {
                    r.push(s.clone());
                }
            }
        }
        r
    }
}

impl Validate for CompareParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        c.check(!self.claims.is_empty(), "claims", "[]", "at least one comparison");
        for (i, q) in self.claims.iter().enumerate() {
            let k = |f: &str| format!("claims[{i}].{f}");
            c.check(q.a != q.b, &k("b"), &q.b, "a role other than `a`");
            c.check(
                q.pair_tolerance.is_finite() && (0.0..0.5).contains(&q.pair_tolerance),
                &k("pair_tolerance"),
                q.pair_tolerance,
                "a fraction in [0, 0.5)",
            );
            if let Some([lo, hi]) = q.range {
                c.check(
                    lo.is_finite() && hi.is_finite() && lo <= hi,
                    &k("range"),
                    format!("[{lo}, {hi}]"),
                    "[lo, hi] with lo ≤ hi",
                );
            }
            match q.relation {
                Relation::Ratio => {
                    c.check(
                        q.paper.is_some_and(|p| p.is_finite() && p > 0.0),
                        &k("paper"),
                        format!("{:?}", q.paper),
                        "the stated ratio (> 0)",
                    );
                    c.check(
                        q.tolerance.is_some_and(|t| t.is_finite() && t > 0.0),
                        &k("tolerance"),
                        format!("{:?}", q.tolerance),
                        "a stated tolerance on the ratio (> 0)",
                    );
                }
                Relation::Equal => c.check(
                    q.tolerance.is_some_and(|t| t.is_finite() && t > 0.0),
                    &k("tolerance"),
                    format!("{:?}", q.tolerance),
                    "a stated tolerance on the ratio (> 0)",
                ),
                Relation::Less | Relation::Greater => c.check(
                    q.paper.is_none() && q.tolerance.is_none(),
                    &k("relation"),
                    "less/greater with paper or tolerance",
                    "`less`/`greater` compare with 1: drop paper and tolerance, or use `ratio`",
                ),
            }
        }
        c.issues
    }
}

fn run(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: CompareParams = decode(ctx)?;
    let mut out = Output::default();
    let (mut cid, mut xs, mut ya, mut yb) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (ci, q) in p.claims.iter().enumerate() {
        let side = |role: &str| -> anyhow::Result<Vec<(f64, f64)>> {
            ctx.inputs_of(role)
                .iter()
                .map(|i| Ok((i.scalar(&q.pair_on)?, i.scalar(&q.y)?)))
                .collect()
        };
        let (sa, sb) = (side(&q.a)?, side(&q.b)?);
        let mut ratios = Vec::new();
        for &(x, va) in &sa {
            if q.range.is_some_and(|[lo, hi]| x < lo || x > hi) {
                continue;
            }
            let nearest = sb.iter().min_by(|p, q| (p.0 - x).abs().total_cmp(&(q.0 - x).abs()));
            if let Some(&(_, vb)) =
                nearest.filter(|(xb, _)| (xb - x).abs() <= q.pair_tolerance * xb.abs().max(x.abs()) + 1e-12)
            {
                ratios.push(va / vb);
                cid.push(ci as f64);
                xs.push(x);
                ya.push(va);
                yb.push(vb);
            }
        }
        anyhow::ensure!(
            !ratios.is_empty(),
            "comparison `{}`: no member of `{}` pairs with one of `{}` on `{}` in the range",
            q.id,
            q.a,
            q.b,
            q.pair_on
        );
        let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
        out.scalar(&format!("{}_ratio", q.id), mean)
            .scalar(&format!("{}_pairs", q.id), ratios.len() as f64);
        let st = format!(
            "{} [mean {}/{} of `{}` over {} pair(s)]",
            q.statement,
            q.a,
            q.b,
            q.y,
            ratios.len()
        );
        out.claims.push(match q.relation {
            Relation::Less => Claim::at_most(&q.id, &st, 1.0, mean),
            Relation::Greater => Claim::at_least(&q.id, &st, 1.0, mean),
            Relation::Equal => Claim::abs(&q.id, &st, 1.0, mean, q.tolerance.unwrap_or(0.0)),
            Relation::Ratio => Claim::abs(
                &q.id,
                &st,
                q.paper.unwrap_or(f64::NAN),
                mean,
                q.tolerance.unwrap_or(0.0),
            ),
        });
    }
    out.table(
        "table",
        frame(vec![
            ("comparison", cid),
            ("x", xs),
            ("y_a", ya.clone()),
            ("y_b", yb.clone()),
            ("ratio", ya.iter().zip(&yb).map(|(a, b)| a / b).collect()),
        ])?,
    );
    Ok(out)
}

/// Kind `sweep-compare`.
pub const KIND: Kind = Kind {
    name: "sweep-compare",
    source: file!(),
    method: None,
    version: 1,
    about: "comparative claims between two families of runs (ratio of a scalar, paired on a)",
    params: typed::<CompareParams>,
    run,
    explain: None,
    roles: crate::stages::kind::Roles::Named(named_roles),
    outputs: crate::stages::kind::Outputs {
        scalars: &["*_pairs", "*_ratio"],
        tables: &[crate::stages::kind::TableDecl {
            name: "table",
            columns: &["comparison", "ratio", "x", "y_a", "y_b"],
        }],
        measurements: &["*"],
        texts: &[],
    },
    reads: Some(reads),
    cost: None,
    atlas: None,
};

/// What the comparisons name of their inputs (checked at load).
pub fn reads(v: &serde_json::Value) -> Vec<Read> {
    let Ok(p) = serde_json::from_value::<CompareParams>(v.clone()) else {
        return vec![];
    };
    let mut out = Vec::new();
    for (i, c) in p.claims.iter().enumerate() {
        for role in [&c.a, &c.b] {
            for (f, s) in [("y", &c.y), ("pair_on", &c.pair_on)] {
                out.push(Read {
                    role: role.clone(),
                    key: format!("claims[{i}].{f}"),
                    item: Item::Scalar(s.clone()),
                });
            }
        }
    }
    out
}

/// Roles: those the comparisons read.
fn named_roles(v: &serde_json::Value) -> Option<Vec<String>> {
    serde_json::from_value::<CompareParams>(v.clone())
        .ok()
        .map(|p| p.roles())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ratio_needs_paper_and_tolerance() {
        let p: CompareParams = serde_json::from_value(serde_json::json!({ "claims": [
            { "id": "x", "statement": "s", "a": "dense", "b": "loose", "y": "runout_norm", "relation": "ratio" }
        ]}))
        .unwrap();
        let keys: Vec<String> = p.validate().into_iter().map(|i| i.key).collect();
        assert_eq!(keys, vec!["claims[0].paper", "claims[0].tolerance"]);
        assert_eq!(p.roles(), vec!["dense", "loose"]);
    }
}

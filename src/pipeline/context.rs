//! What a stage sees ([`StageCtx`]: its canonical params and its input artifacts) and what
//! it returns ([`Output`]: tables, scalars, claim checks, figures and extra files).

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::{Context, anyhow};
use indicatif::ProgressBar;
use polars::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::Value;

/// How many stages a role takes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Arity {
    /// Exactly one stage, always.
    One,
    /// Exactly one stage, when given.
    OptionalOne,
    /// One or more stages (fan-in).
    Many,
}

/// One of the chapter's quantitative claims against our number — or, in
/// [`Output::checks`], a consistency check (an input, an identity, a numerical condition)
/// that uses the same shape but is never counted as a reproduced claim.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Claim {
    /// Stable id, e.g. `geostatic-stress`.
    pub id: String,
    /// The claim, quoting the chapter where possible.
    pub statement: String,
    /// The chapter's value.
    pub paper: f64,
    /// Ours.
    pub ours: f64,
    /// Allowed |ours − paper| (absolute, in the claim's unit).
    pub tolerance: f64,
    /// |ours − paper| ≤ tolerance.
    pub pass: bool,
    /// Ours depends on a parameter we tuned to hit this or another claim: shown
    /// "calibrated" wherever it appears, never as independent agreement.
    #[serde(default)]
    pub calibrated: bool,
}

impl Claim {
    /// Build a claim with an absolute tolerance.
    pub fn abs(id: &str, statement: &str, paper: f64, ours: f64, tolerance: f64) -> Claim {
        let pass = ours.is_finite() && (ours - paper).abs() <= tolerance;
        Claim {
            id: id.into(),
            statement: statement.into(),
            paper,
            ours,
            tolerance,
            pass,
            calibrated: false,
        }
    }
    /// Build a claim with a relative tolerance (fraction of |paper|).
    pub fn rel(id: &str, statement: &str, paper: f64, ours: f64, rel: f64) -> Claim {
        Claim::abs(id, statement, paper, ours, rel * paper.abs())
    }
    /// A one-sided claim "ours ≤ bound" (paper = bound, tolerance = 0 means ours must not exceed it).
    pub fn at_most(id: &str, statement: &str, bound: f64, ours: f64) -> Claim {
        Claim {
            id: id.into(),
            statement: statement.into(),
            paper: bound,
            ours,
            tolerance: 0.0,
            pass: ours.is_finite() && ours <= bound,
            calibrated: false,
        }
    }
    /// A one-sided claim "ours ≥ bound".
    pub fn at_least(id: &str, statement: &str, bound: f64, ours: f64) -> Claim {
        Claim {
            id: id.into(),
            statement: statement.into(),
            paper: bound,
            ours,
            tolerance: 0.0,
            pass: ours.is_finite() && ours >= bound,
            calibrated: false,
        }
    }
    /// Mark as resting on a calibrated parameter.
    pub fn calibrated(mut self) -> Claim {
        self.calibrated = true;
        self
    }
}

/// The fixed keys of a stage's JSON; a text result ([`Output::text`]) may not take one.
pub const RESULT_KEYS: &[&str] = &["stage", "profile", "scalars", "measurements", "checks"];

/// Everything a stage produces. The first table is the stage's main table.
#[derive(Default)]
pub struct Output {
    /// Named tables (`table` is the main one).
    pub tables: Vec<(String, DataFrame)>,
    /// Named scalars (SI units, or nondimensional as the chapter defines them).
    pub scalars: BTreeMap<String, f64>,
    /// The chapter's results that our simulations reproduce or not.
    pub claims: Vec<Claim>,
    /// Consistency checks: inputs, identities, numerical conditions (never counted as
    /// reproduced claims).
    pub checks: Vec<Claim>,
    /// Named SVG figures (`figure` is the main one).
    pub figures: Vec<(String, String)>,
    /// Extra files (Markdown tables, VTK snapshots): name with extension → bytes.
    pub files: Vec<(String, Vec<u8>)>,
    /// Notes for the report (choices made, profile error).
    pub notes: Vec<String>,
    /// Named text results (a choice's rule and reason): top-level keys of the stage's JSON.
    pub texts: BTreeMap<String, String>,
}

impl Output {
    /// Add a table.
    pub fn table(&mut self, name: &str, df: DataFrame) -> &mut Self {
        self.tables.push((name.into(), df));
        self
    }
    /// Add a scalar.
    pub fn scalar(&mut self, name: &str, v: f64) -> &mut Self {
        self.scalars.insert(name.into(), v);
        self
    }
    /// Add a figure.
    pub fn figure(&mut self, name: &str, svg: String) -> &mut Self {
        self.figures.push((name.into(), svg));
        self
    }
    /// Add a text result (a top-level key of the stage's JSON; not one of its fixed keys).
    pub fn text(&mut self, name: &str, v: impl Into<String>) -> &mut Self {
        debug_assert!(!RESULT_KEYS.contains(&name), "text `{name}` shadows a result key");
        self.texts.insert(name.into(), v.into());
        self
    }
    /// Add a note.
    pub fn note(&mut self, s: impl Into<String>) -> &mut Self {
        self.notes.push(s.into());
        self
    }
}

/// One upstream stage as seen by a consumer.
#[derive(Debug, Clone)]
pub struct InputRef {
    /// Upstream stage id.
    pub id: String,
    /// Its cache entry directory.
    pub dir: PathBuf,
    /// Its canonical params.
    pub params: Value,
}

impl InputRef {
    /// Read one of its tables (`table` for the main one).
    pub fn table(&self, name: &str) -> anyhow::Result<DataFrame> {
        let p = self.dir.join(format!("{name}.parquet"));
        let f = std::fs::File::open(&p)
            .with_context(|| format!("input `{}` has no table `{name}` ({})", self.id, p.display()))?;
        Ok(ParquetReader::new(f).finish()?)
    }
    /// Its scalars.
    pub fn scalars(&self) -> anyhow::Result<BTreeMap<String, f64>> {
        let p = self.dir.join("result.json");
        let v: Value = serde_json::from_slice(&std::fs::read(&p)?)?;
        let m = v
            .get("scalars")
            .and_then(|s| s.as_object())
            .ok_or_else(|| anyhow!("{}: no scalars", p.display()))?;
        Ok(m.iter()
            .filter_map(|(k, v)| v.as_f64().map(|x| (k.clone(), x)))
            .collect())
    }
    /// One scalar, or an error naming it.
    pub fn scalar(&self, name: &str) -> anyhow::Result<f64> {
        self.scalars()?
            .get(name)
            .copied()
            .ok_or_else(|| anyhow!("input `{}` has no scalar `{name}`", self.id))
    }
    /// An extra file's bytes.
    pub fn file(&self, name: &str) -> anyhow::Result<Vec<u8>> {
        std::fs::read(self.dir.join(name)).with_context(|| format!("input `{}` has no file `{name}`", self.id))
    }
}

/// The stage's view of the world.
pub struct StageCtx {
    /// Stage id.
    pub id: String,
    /// Profile name.
    pub profile: String,
    /// Caption from pipeline.yaml.
    pub caption: Option<String>,
    /// Canonical params.
    pub params: Value,
    /// Inputs by role.
    pub inputs: BTreeMap<String, Vec<InputRef>>,
    /// Progress bar of this stage (hidden when not on a terminal).
    pub progress: ProgressBar,
    /// Threads available to the stage's solver (rayon pool size).
    pub threads: usize,
}

impl StageCtx {
    /// The single input of a role.
    pub fn input(&self, role: &str) -> anyhow::Result<&InputRef> {
        match self.inputs.get(role).map(|v| v.as_slice()) {
            Some([one]) => Ok(one),
            Some([]) | None => Err(anyhow!(
                "stage `{}` needs an input named `{role}` (declare it under `inputs:` in pipeline.yaml)",
                self.id
            )),
            Some(_) => Err(anyhow!(
                "stage `{}`: input `{role}` must name exactly one stage",
                self.id
            )),
        }
    }
    /// The single input of a role, if declared.
    pub fn input_opt(&self, role: &str) -> Option<&InputRef> {
        self.inputs.get(role).and_then(|v| v.first())
    }
    /// All inputs of a role (fan-in of a matrix), in declared order.
    pub fn inputs_of(&self, role: &str) -> &[InputRef] {
        self.inputs.get(role).map(|v| v.as_slice()).unwrap_or(&[])
    }
    /// Report progress as a fraction in [0, 1].
    pub fn set_progress(&self, frac: f64) {
        self.progress.set_position((frac.clamp(0.0, 1.0) * 1000.0) as u64);
    }
}

/// Build a DataFrame from named f64 columns (all the same length).
pub fn frame(cols: Vec<(&str, Vec<f64>)>) -> anyhow::Result<DataFrame> {
    let columns: Vec<Column> = cols.into_iter().map(|(n, v)| Column::new(n.into(), v)).collect();
    Ok(DataFrame::new_infer_height(columns)?)
}

/// A column of a DataFrame as f64 values (nulls become NaN).
pub fn col_f64(df: &DataFrame, name: &str) -> anyhow::Result<Vec<f64>> {
    let c = df.column(name).map_err(|_| anyhow!("table has no column `{name}`"))?;
    let c = c.cast(&DataType::Float64)?;
    Ok(c.f64()?.iter().map(|v| v.unwrap_or(f64::NAN)).collect())
}

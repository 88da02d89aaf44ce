//! The ledger's rows as written in `stages/ledger.yaml`: their types, the reader and the
//! loader's validation (exit 2 naming the file, the row and the key).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::pipeline::diag::{Diagnostic, locate};
use crate::stages::kind::{Item, Kind as StageKind};

/// The ledger's file, relative to the directory holding pipeline.yaml.
pub const LEDGER_FILE: &str = "stages/ledger.yaml";

/// What a row is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// A number the chapter reports that our simulation could miss.
    Quantitative,
    /// A direction only ("decreases", "longer"): counted apart.
    Qualitative,
    /// A number our inputs decide (a preparation target, a value tuned to it).
    Check,
}

impl Kind {
    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Quantitative => "quantitative",
            Kind::Qualitative => "qualitative",
            Kind::Check => "check",
        }
    }
}

/// How the measurement is compared with the chapter's value. Written as a one-key
/// mapping: `{abs: x}`, `{rel: r}`, `{at_least: b}`, `{at_most: b}`, `{range: [lo, hi]}`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(try_from = "ToleranceSpec")]
pub enum Tolerance {
    /// |ours − paper| ≤ this, in the claim's unit (the chapter's stated ±, or a bound
    /// given in the row's reading).
    Abs(f64),
    /// |ours − paper| ≤ this × |paper| (15 % where the chapter states no ±).
    Rel(f64),
    /// ours ≥ this bound (a direction: a ratio above 1, a difference above 0).
    AtLeast(f64),
    /// ours ≤ this bound.
    AtMost(f64),
    /// lo ≤ ours ≤ hi (a range the chapter states, e.g. 50–55°).
    Range(f64, f64),
}

/// The YAML shape of a [`Tolerance`] (a mapping with exactly one of these keys).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ToleranceSpec {
    abs: Option<f64>,
    rel: Option<f64>,
    at_least: Option<f64>,
    at_most: Option<f64>,
    range: Option<[f64; 2]>,
}

impl TryFrom<ToleranceSpec> for Tolerance {
    type Error = String;
    fn try_from(t: ToleranceSpec) -> Result<Self, String> {
        let all = [
            t.abs.map(Tolerance::Abs),
            t.rel.map(Tolerance::Rel),
            t.at_least.map(Tolerance::AtLeast),
            t.at_most.map(Tolerance::AtMost),
            t.range.map(|[lo, hi]| Tolerance::Range(lo, hi)),
        ];
        let mut given = all.into_iter().flatten();
        match (given.next(), given.next()) {
            (Some(x), None) => Ok(x),
            _ => Err("a tolerance has exactly one of abs, rel, at_least, at_most, range".into()),
        }
    }
}

/// Where the row's number comes from.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Measure {
    /// The stage (the first member of the ensemble when `members` is given).
    pub stage: String,
    /// One of the stage's published measurements (by id)…
    #[serde(default)]
    pub measurement: Option<String>,
    /// …or one of its scalars.
    #[serde(default)]
    pub scalar: Option<String>,
    /// The scalar of the same stage holding the measurement's standard error (a fit's
    /// s.e.), when it has one.
    #[serde(default)]
    pub se: Option<String>,
    /// Every member of the ensemble (the same measurement in each); default: `stage`
    /// alone. Members absent from the profile being judged are skipped.
    #[serde(default)]
    pub members: Vec<String>,
    /// A comparison of two methods or conditions: this measurement minus another (a
    /// difference of energies, "3 % more")…
    #[serde(default)]
    pub minus: Option<Box<Measure>>,
    /// …or over another (a ratio, "25 % less", "longer").
    #[serde(default)]
    pub over: Option<Box<Measure>>,
}

impl Measure {
    /// The stages read, in order.
    pub fn stages(&self) -> Vec<&str> {
        if self.members.is_empty() {
            vec![self.stage.as_str()]
        } else {
            self.members.iter().map(String::as_str).collect()
        }
    }
    /// Every stage read, both sides of a comparison included.
    pub fn all_stages(&self) -> Vec<&str> {
        let mut v = self.stages();
        for o in self.minus.iter().chain(self.over.iter()) {
            v.extend(o.all_stages());
        }
        v
    }
    /// `stage/measurement` or `stage:scalar` (`a − b`, `a / b`), as shown.
    pub fn label(&self) -> String {
        let one = match (&self.measurement, &self.scalar) {
            (Some(m), _) => format!("{}/{m}", self.stage),
            (None, Some(s)) => format!("{}:{s}", self.stage),
            _ => self.stage.clone(),
        };
        let n = if self.members.len() > 1 {
            format!(" ({} members)", self.members.len())
        } else {
            String::new()
        };
        match (&self.minus, &self.over) {
            (Some(b), _) => format!("{one}{n} − {}", b.label()),
            (None, Some(b)) => format!("{one}{n} / {}", b.label()),
            _ => format!("{one}{n}"),
        }
    }
}

/// One result of the chapter.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Row {
    /// Unique id.
    pub id: String,
    /// Chapter section (`4.2.2`).
    pub section: String,
    /// The figure or equation it belongs to (`fig4-05`), when there is one.
    #[serde(default)]
    pub figure: Option<String>,
    /// The chapter's words, quoted.
    pub chapter: String,
    /// What is judged, in our words (the quantity, the condition).
    pub measured: String,
    /// Method the chapter states it for (DEM, MPM, CD, or "MPM vs DEM").
    pub method: String,
    /// The chapter's value (for a direction, the bound it implies).
    pub paper: f64,
    /// The chapter's stated ±, when it gives one.
    #[serde(default)]
    pub stated: Option<f64>,
    /// Tolerance rule.
    pub tolerance: Tolerance,
    /// Kind.
    pub kind: Kind,
    /// The measurement.
    pub measure: Measure,
    /// A chaotic output (a run-out, a duration, a time of a DEM or CD flow): judged on the
    /// ensemble mean, and *not resolved* while its spread is unknown (one member).
    #[serde(default)]
    pub chaotic: bool,
    /// The headline result this row is (part of); rows sharing it are one headline row.
    #[serde(default)]
    pub headline: Option<String>,
    /// Why a miss is a miss: `scale`, `model`, `calibration` or `chapter` (the chapter at
    /// odds with itself), then the reasoning.
    #[serde(default)]
    pub diagnosis: Option<String>,
    /// The diagnosis as examined on another profile's results (`{paper: "..."}`): shown
    /// there instead of `diagnosis`, which was written on the quick profile's.
    #[serde(default)]
    pub diagnosis_at: std::collections::BTreeMap<String, String>,
    /// Our reading of an ambiguous statement (which definition, which time).
    #[serde(default)]
    pub reading: Option<String>,
    /// Rests on a value chosen with this claim in mind (besides the tuned stages upstream,
    /// which are found from the stage graph): say which.
    #[serde(default)]
    pub tuned: Option<String>,
}

/// A stage whose output is a tuned value: every measurement downstream of it is
/// *calibrated*.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tuned {
    /// Stage id (or, ending in `*`, an id prefix).
    pub stage: String,
    /// What was tuned, to what.
    pub what: String,
}

/// Does `pattern` (a stage id, or an id prefix ending in `*`) name stage `id`?
fn names(pattern: &str, id: &str) -> bool {
    match pattern.strip_suffix('*') {
        Some(prefix) => id.starts_with(prefix),
        None => pattern == id,
    }
}

impl Tuned {
    /// Does this entry name stage `id`?
    pub fn matches(&self, id: &str) -> bool {
        names(&self.stage, id)
    }
}

/// A scene a profile runs reduced so far that its results test the pipeline, not the
/// chapter (the quick pile: 250 grains against ≈ 13,000). Every row reading it, or a
/// stage downstream of it, is shown at that profile as not comparable, with `why`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Reduced {
    /// The profile (quick).
    pub profile: String,
    /// The scene, as the report names it ("the pile").
    pub scene: String,
    /// Stage ids (or, ending in `*`, id prefixes).
    pub stages: Vec<String>,
    /// Why its results cannot be set against the chapter's, with numbers.
    pub why: String,
}

impl Reduced {
    /// Does this entry name stage `id`?
    pub fn matches(&self, id: &str) -> bool {
        self.stages.iter().any(|s| names(s, id))
    }
}

/// The whole ledger.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ledger {
    /// Tuned stages.
    #[serde(default)]
    pub tuned: Vec<Tuned>,
    /// Scenes a profile runs too small to compare with the chapter.
    #[serde(default)]
    pub reduced: Vec<Reduced>,
    /// The rows, in chapter order.
    pub claims: Vec<Row>,
}

/// Why the ledger could not be read, located.
fn diag(file: &Path, text: &str, path: &[&str], key: String, message: String, help: &str) -> Diagnostic {
    Diagnostic {
        file: file.to_path_buf(),
        line: locate(text, path, 1),
        key,
        message,
        help: help.to_string(),
    }
}

/// Read and parse the ledger beside `root`'s pipeline.yaml. `Ok(None)` when there is none.
pub fn read(root: &Path) -> Result<Option<(Ledger, PathBuf, String)>, Vec<Diagnostic>> {
    let file = root.join(LEDGER_FILE);
    let Ok(text) = std::fs::read_to_string(&file) else {
        return Ok(None);
    };
    let yaml: serde_yaml::Value = serde_yaml::from_str(&text).map_err(|e| {
        vec![Diagnostic {
            file: file.clone(),
            line: e.location().map(|l| l.line()),
            key: String::new(),
            message: format!("YAML syntax error: {e}"),
            help: "fix the YAML syntax (indentation, ':' after keys, matching quotes)".into(),
        }]
    })?;
    match serde_path_to_error::deserialize::<_, Ledger>(yaml) {
        Ok(l) => Ok(Some((l, file, text))),
        Err(e) => {
            let key = e.path().to_string();
            let inner = e.inner().to_string();
            let field = inner.split('`').nth(1).unwrap_or("").to_string();
            let segs: Vec<&str> = if inner.starts_with("unknown field") {
                vec![field.as_str()]
            } else {
                key.split('.').filter(|s| !s.contains('[')).collect()
            };
            Err(vec![diag(
                &file,
                &text,
                &segs,
                key.clone(),
                inner,
                "a row has id, section, chapter, measured, method, paper, tolerance ({abs|rel|at_least|at_most: x} or {range: [lo, hi]}), kind (quantitative | qualitative | check) and measure {stage, measurement | scalar}; optional: figure, stated, chaotic, headline, diagnosis, diagnosis_at, reading, tuned",
            )])
        }
    }
}

/// Check the ledger: ids unique, no sentence judged twice on the same measurement, exactly
/// one of measurement/scalar, tolerances that can fail and equal the stated ±; with
/// `stage_ids` (the stage ids of every profile), also that every stage it names is declared.
/// The loader passes no ids: a project may declare a subset of the chapter's stages, and a
/// row whose stage it lacks is *not run*; `tests/ledger.rs` checks the shipped ledger
/// against the shipped pipeline.
pub fn validate(l: &Ledger, file: &Path, text: &str, stage_ids: Option<&BTreeSet<String>>) -> Vec<Diagnostic> {
    let mut out = Vec::new();
    let mut ids = BTreeSet::new();
    let mut judged: BTreeMap<(String, String), String> = BTreeMap::new();
    for (i, r) in l.claims.iter().enumerate() {
        let key = |k: &str| format!("claims[{i}] ({}).{k}", r.id);
        let mut bad = |k: &str, message: String, help: &str| {
            out.push(diag(file, text, &[r.id.as_str(), k], key(k), message, help));
        };
        if !ids.insert(r.id.clone()) {
            bad(
                "id",
                format!("claim id `{}` is used twice", r.id),
                "give each row its own id",
            );
        }
        let mut sides = vec![&r.measure];
        sides.extend(r.measure.minus.as_deref().into_iter().chain(r.measure.over.as_deref()));
        if sides.iter().any(|m| m.measurement.is_some() == m.scalar.is_some()) {
            bad(
                "measure",
                "the measure names both or neither of `measurement` and `scalar`".into(),
                "name exactly one: a measurement id the stage publishes, or one of its scalars",
            );
        }
        if r.measure.minus.is_some() && r.measure.over.is_some() {
            bad(
                "measure",
                "the measure has both `minus` and `over`".into(),
                "compare with one: a difference or a ratio",
            );
        }
        let mut named: Vec<&str> = r.measure.all_stages();
        named.extend(sides.iter().map(|m| m.stage.as_str()));
        for s in named {
            if stage_ids.is_some_and(|ids| !ids.contains(s)) {
                bad(
                    "measure",
                    format!("stage `{s}` is not declared in pipeline.yaml (in any profile)"),
                    "name a stage id of pipeline.yaml (`granrepro list`)",
                );
            }
        }
        let can_fail = match r.tolerance {
            Tolerance::Abs(t) => t.is_finite() && t >= 0.0,
            Tolerance::Rel(t) => t.is_finite() && t >= 0.0 && r.paper != 0.0,
            Tolerance::AtLeast(b) | Tolerance::AtMost(b) => b.is_finite(),
            Tolerance::Range(lo, hi) => lo.is_finite() && hi.is_finite() && lo <= hi,
        };
        if !can_fail || !r.paper.is_finite() {
            bad(
                "tolerance",
                format!(
                    "the tolerance {:?} around {} cannot fail (or is not a number)",
                    r.tolerance, r.paper
                ),
                "abs/rel ≥ 0 and finite (rel needs a non-zero paper value); bounds finite; range lo ≤ hi",
            );
        }
        if let Some(pm) = r.stated
            && r.tolerance != Tolerance::Abs(pm)
        {
            bad(
                "tolerance",
                format!("the chapter states ± {pm}, but the tolerance is {:?}", r.tolerance),
                "where the chapter states a ±, the tolerance is that ±: `tolerance: {abs: <the stated ±>}` (never widened)",
            );
        }
        // One chapter sentence, one measurement: judged once.
        let sentence: String = r.chapter.split_whitespace().collect::<Vec<_>>().join(" ");
        let m = format!("{}|{}", r.measure.label(), r.measure.all_stages().join(","));
        if let Some(first) = judged.insert((sentence, m), r.id.clone()) {
            bad(
                "chapter",
                format!("judges the same chapter sentence on the same measurement as `{first}`"),
                "keep one row: a sentence is judged once per measurement",
            );
        }
    }
    for r in &l.claims {
        for p in r.diagnosis_at.keys() {
            if !crate::pipeline::spec::PROFILES.contains(&p.as_str()) {
                out.push(diag(
                    file,
                    text,
                    &["claims", r.id.as_str()],
                    format!("claims[{}].diagnosis_at.{p}", r.id),
                    format!("unknown profile `{p}`"),
                    &format!("allowed: {}", crate::pipeline::spec::PROFILES.join(", ")),
                ));
            }
        }
    }
    for (i, r) in l.reduced.iter().enumerate() {
        if !crate::pipeline::spec::PROFILES.contains(&r.profile.as_str()) {
            out.push(diag(
                file,
                text,
                &["reduced"],
                format!("reduced[{i}].profile"),
                format!("unknown profile `{}`", r.profile),
                &format!("allowed: {}", crate::pipeline::spec::PROFILES.join(", ")),
            ));
        }
        for st in &r.stages {
            if !st.ends_with('*') && stage_ids.is_some_and(|ids| !ids.contains(st)) {
                out.push(diag(
                    file,
                    text,
                    &["reduced"],
                    format!("reduced[{i}].stages"),
                    format!("stage `{st}` is not declared in pipeline.yaml"),
                    "name a stage id, or an id prefix ending in `*`",
                ));
            }
        }
    }
    for (i, t) in l.tuned.iter().enumerate() {
        if !t.stage.ends_with('*') && stage_ids.is_some_and(|ids| !ids.contains(&t.stage)) {
            out.push(diag(
                file,
                text,
                &["tuned", t.stage.as_str()],
                format!("tuned[{i}].stage"),
                format!("stage `{}` is not declared in pipeline.yaml", t.stage),
                "name a stage id, or an id prefix ending in `*`",
            ));
        }
    }
    out
}

/// Read and validate the ledger beside `root`'s pipeline.yaml (the loader's call: problems
/// are reported before anything runs; stage names are not checked, see [`validate`]).
pub fn check(root: &Path) -> Vec<Diagnostic> {
    match read(root) {
        Ok(Some((l, file, text))) => validate(&l, &file, &text, None),
        Ok(None) => vec![],
        Err(d) => d,
    }
}

/// Check what each row reads against what its stage's kind declares it publishes
/// (`stages/kind.rs`): a `measure.measurement` the kind never measures, or a
/// `measure.scalar` / `measure.se` it never publishes, is refused at load. `kind_of` gives
/// a stage id's kind in the profile being loaded; a stage it does not know is *not run*,
/// not refused (see [`validate`]).
pub fn check_outputs(root: &Path, kind_of: &dyn Fn(&str) -> Option<StageKind>) -> Vec<Diagnostic> {
    let Ok(Some((l, file, text))) = read(root) else {
        return vec![];
    };
    let mut out = Vec::new();
    for (i, r) in l.claims.iter().enumerate() {
        let mut stack: Vec<(String, &Measure)> = vec![("measure".into(), &r.measure)];
        while let Some((at, m)) = stack.pop() {
            // (key, name, a measurement id rather than a scalar)
            let mut wants: Vec<(&str, &String, bool)> = Vec::new();
            if let Some(id) = &m.measurement {
                wants.push(("measurement", id, true));
            }
            if let Some(s) = &m.scalar {
                wants.push(("scalar", s, false));
            }
            if let Some(s) = &m.se {
                wants.push(("se", s, false));
            }
            let stages = std::iter::once(&m.stage).chain(m.members.iter());
            let mut seen: Vec<&str> = Vec::new();
            for st in stages {
                let Some(kind) = kind_of(st) else { continue };
                if seen.contains(&kind.name) {
                    continue;
                }
                seen.push(kind.name);
                for &(k, name, is_measurement) in &wants {
                    let refused = if !is_measurement {
                        crate::pipeline::reads::refuse(&Item::Scalar(name.clone()), &kind.outputs)
                    } else if kind.outputs.has_measurement(name) {
                        None
                    } else {
                        Some((
                            format!("measurement `{name}`"),
                            format!(
                                "measurements of `{}`: {}",
                                kind.name,
                                kind.outputs.measurements.join(", ")
                            ),
                        ))
                    };
                    if let Some((what, help)) = refused {
                        out.push(diag(
                            &file,
                            &text,
                            &[r.id.as_str(), k],
                            format!("claims[{i}] ({}).{at}.{k}", r.id),
                            format!("{what}, which kind `{}` (stage `{st}`) does not publish", kind.name),
                            &help,
                        ));
                    }
                }
            }
            if let Some(x) = &m.minus {
                stack.push((format!("{at}.minus"), x));
            }
            if let Some(x) = &m.over {
                stack.push((format!("{at}.over"), x));
            }
        }
    }
    out
}

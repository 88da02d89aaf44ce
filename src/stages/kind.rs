//! What a stage kind is, declared in one place ([`Kind`]): its name, version, parameter
//! schema, input roles, the outputs it publishes, what it reads of its inputs by name, its
//! cost model, its body and its pre-flight table; and the schema helpers every kind uses
//! ([`typed`], [`decode`], [`Validate`]).
//!
//! The loader checks a pipeline against these declarations before anything runs: each
//! stage's inputs against its kind's [`Roles`], and each scalar, table or measurement a
//! stage (or the claims ledger) names of an input against that input kind's [`Outputs`].
//! The runner checks every run against its kind's [`Outputs`], so a declaration cannot
//! drift from what the kind publishes. Adding a kind is one file and one registry line.

use serde::Serialize;
use serde::de::DeserializeOwned;
use serde_json::Value;

use crate::engines::Method;
use crate::pipeline::context::{Arity, Output, StageCtx};
use crate::validate::Issue;

/// A parameter problem found by a kind's schema.
#[derive(Debug, Clone)]
pub struct ParamProblem {
    /// Dotted key path inside the params (empty for the whole mapping).
    pub key: String,
    /// What is wrong.
    pub message: String,
    /// What is allowed.
    pub allowed: String,
}

/// Parameter schema: checks a params mapping and returns it canonical (defaults filled).
pub type ParamsFn = fn(&Value) -> Result<Value, Vec<ParamProblem>>;
/// The stage body.
pub type RunFn = fn(&StageCtx) -> anyhow::Result<Output>;

/// The input roles a kind reads.
#[derive(Clone, Copy)]
pub enum Roles {
    /// These roles, whatever the params.
    Fixed(&'static [(&'static str, Arity)]),
    /// Roles that depend on the params (an optional input made required by a setting).
    ByParams(fn(&Value) -> Vec<(&'static str, Arity)>),
    /// A study kind's roles, by the method its params name (`method:`).
    ByMethod(&'static [(Method, &'static [(&'static str, Arity)])]),
    /// The params name their roles (`plot`, `sweep-compare`, `snapshot`): each role they
    /// read must be an input and each input must be read. None: the params do not decode
    /// (reported by the schema).
    Named(fn(&Value) -> Option<Vec<String>>),
}

impl Roles {
    /// The roles with their arity, for the `Fixed` and `ByParams` forms (None for `Named`).
    pub fn fixed(&self, params: &Value) -> Option<Vec<(&'static str, Arity)>> {
        match self {
            Roles::Fixed(r) => Some(r.to_vec()),
            Roles::ByParams(f) => Some(f(params)),
            Roles::ByMethod(by) => {
                let m = params.get("method").and_then(Value::as_str).and_then(Method::parse);
                Some(
                    by.iter()
                        .find(|(k, _)| Some(*k) == m)
                        .map(|(_, r)| r.to_vec())
                        .unwrap_or_default(),
                )
            }
            Roles::Named(_) => None,
        }
    }
}

/// No inputs.
pub const NO_INPUTS: Roles = Roles::Fixed(&[]);

/// A table a kind publishes, with its columns.
#[derive(Debug, Clone, Copy)]
pub struct TableDecl {
    /// Table name (`table` is the main one).
    pub name: &'static str,
    /// Its columns.
    pub columns: &'static [&'static str],
}

/// What a kind publishes. A name with a `*` declares a family (see [`covers`]); every
/// other name is exact. A kind may leave out an output in some runs (one that depends on
/// its params); it may never publish one it does not declare.
#[derive(Debug, Clone, Copy)]
pub struct Outputs {
    /// Scalars (SI, or nondimensional as the chapter defines them).
    pub scalars: &'static [&'static str],
    /// Tables and their columns.
    pub tables: &'static [TableDecl],
    /// Measurement ids (what the claims ledger reads; the chapter's results measured).
    pub measurements: &'static [&'static str],
    /// Text fields (a choice's rule and its reason), published as top-level keys of the
    /// stage's JSON.
    pub texts: &'static [&'static str],
}

/// A kind that publishes nothing by name (a figure only).
pub const NO_OUTPUTS: Outputs = Outputs {
    scalars: &[],
    tables: &[],
    measurements: &[],
    texts: &[],
};

/// Does a declared name cover `name`? Each `*` in it stands for any run of characters
/// (`runout_mean_a*`, `panel*_max_*`); a name without one is exact.
pub fn covers(declared: &str, name: &str) -> bool {
    let mut parts = declared.split('*');
    let first = parts.next().unwrap_or("");
    let Some(mut rest) = name.strip_prefix(first) else {
        return false;
    };
    let parts: Vec<&str> = parts.collect();
    let Some((last, middle)) = parts.split_last() else {
        return rest.is_empty();
    };
    for p in middle {
        match rest.find(p) {
            Some(i) => rest = &rest[i + p.len()..],
            None => return false,
        }
    }
    rest.len() >= last.len() && rest.ends_with(last)
}

impl Outputs {
    /// Is the scalar `name` declared?
    pub fn has_scalar(&self, name: &str) -> bool {
        self.scalars.iter().any(|d| covers(d, name))
    }
    /// The declared table `name`.
    pub fn table(&self, name: &str) -> Option<&TableDecl> {
        self.tables.iter().find(|t| covers(t.name, name))
    }
    /// Is the measurement id declared?
    pub fn has_measurement(&self, id: &str) -> bool {
        self.measurements.iter().any(|d| covers(d, id))
    }
    /// Is the text field `name` declared?
    pub fn has_text(&self, name: &str) -> bool {
        self.texts.contains(&name)
    }
    /// Is `col` a column of the declared table `table`?
    pub fn has_column(&self, table: &str, col: &str) -> bool {
        self.table(table)
            .is_some_and(|t| t.columns.iter().any(|c| covers(c, col)))
    }
}

/// One output of an input that a stage names in its params, checked at load.
#[derive(Debug, Clone, PartialEq)]
pub enum Item {
    /// A scalar.
    Scalar(String),
    /// A table.
    Table(String),
    /// A column of a table.
    Column(String, String),
    /// A scalar, or a column of the table (a normalisation that reads either).
    ColumnOrScalar(String, String),
}

/// A name a stage's params read of the inputs of one role.
#[derive(Debug, Clone, PartialEq)]
pub struct Read {
    /// The role.
    pub role: String,
    /// The params key that names it (for the error message).
    pub key: String,
    /// What it names.
    pub item: Item,
}

/// What a kind's run costs, for `plan --estimate`: factors in relative units (grains,
/// steps, points; only the ratio between profiles means anything), and whether the work
/// is the larger of the factors (a stage of two parts) rather than their product.
pub type Work = (Vec<(&'static str, f64)>, bool);

/// What a cost model sees: the stage's canonical params and, by role, its inputs' (each
/// with its own inputs in turn).
pub struct CostCtx<'a> {
    /// The stage's canonical params.
    pub params: &'a Value,
    /// The stages feeding a role, in input order.
    pub inputs: InputsOf<'a>,
}

/// The stages feeding a role, in input order, as [`CostCtx`]s.
pub type InputsOf<'a> = Box<dyn Fn(&str) -> Vec<CostCtx<'a>> + 'a>;

impl CostCtx<'_> {
    /// The stage's params as its typed struct (None when they do not decode).
    pub fn typed<P: DeserializeOwned>(&self) -> Option<P> {
        serde_json::from_value(self.params.clone()).ok()
    }
    /// The first input of `role`, its params typed.
    pub fn input<P: DeserializeOwned>(&self, role: &str) -> Option<P> {
        (self.inputs)(role).first().and_then(|c| c.typed())
    }
    /// Every input of `role`, its params typed (those that decode).
    pub fn all<P: DeserializeOwned>(&self, role: &str) -> Vec<P> {
        (self.inputs)(role).iter().filter_map(|c| c.typed()).collect()
    }
}

/// A kind's cost model: None when the kind is bookkeeping (its measured time is used).
pub type CostFn = fn(&CostCtx) -> Option<Work>;

/// A registered stage kind.
#[derive(Clone, Copy)]
pub struct Kind {
    /// Name used in `kind:`.
    pub name: &'static str,
    /// The file that declares it (`file!()`): where its source closure starts, for the
    /// results lock (`crate::provenance::sources::closure`).
    pub source: &'static str,
    /// The one method whose solver this kind runs (its numbers carry that method's measured
    /// error). None: a study kind that names its method in `method:`, or a kind that only
    /// reads results (its method is that of the solver stages upstream, see
    /// `crate::pipeline::publish::stage_methods`).
    pub method: Option<Method>,
    /// Version of the kind's numerics (part of the cache key).
    pub version: u32,
    /// One-line description (shown by `granrepro list --kinds`).
    pub about: &'static str,
    /// Parameter schema.
    pub params: ParamsFn,
    /// Stage body.
    pub run: RunFn,
    /// Pre-flight stability table for `run --explain` (solver stages only).
    pub explain: Option<fn(&Value) -> String>,
    /// The input roles it reads.
    pub roles: Roles,
    /// What it publishes.
    pub outputs: Outputs,
    /// What its params name of its inputs' outputs (checked at load); None: nothing.
    pub reads: Option<fn(&Value) -> Vec<Read>>,
    /// Its cost model for `plan --estimate`; None: bookkeeping (as measured).
    pub cost: Option<CostFn>,
    /// The table of the profile's measured error per method that this kind publishes (the
    /// work-precision atlas): the runner stamps every other stage's figures with it and
    /// the report's "error vs run time" table reads it. None: an ordinary kind.
    pub atlas: Option<&'static str>,
}

/// Parameters that validate their own values (ranges, physical sense).
pub trait Validate {
    /// All problems at once; empty when valid.
    fn validate(&self) -> Vec<Issue>;
}

/// Schema helper: deserialize `v` into `P` (unknown keys and wrong types are errors),
/// validate it, and return the canonical JSON with every default filled.
pub fn typed<P: DeserializeOwned + Serialize + Validate>(v: &Value) -> Result<Value, Vec<ParamProblem>> {
    let p: P = serde_path_to_error::deserialize(v.clone()).map_err(|e| {
        let path = e.path().to_string();
        let inner = e.inner().to_string();
        // serde reports an unknown field at its parent's path: name the field itself.
        let key = match inner.split('`').nth(1) {
            Some(field) if inner.starts_with("unknown field") => {
                if path == "." || path.is_empty() {
                    field.to_string()
                } else if path == field || path.ends_with(&format!(".{field}")) {
                    path.clone()
                } else {
                    format!("{path}.{field}")
                }
            }
            _ => {
                if path == "." {
                    String::new()
                } else {
                    path
                }
            }
        };
        let (message, allowed) = match inner.split_once(", expected") {
            Some((m, a)) => (m.to_string(), format!("expected{a}")),
            None => (inner.clone(), String::new()),
        };
        vec![ParamProblem { key, message, allowed }]
    })?;
    let issues = p.validate();
    if !issues.is_empty() {
        return Err(issues
            .into_iter()
            .map(|i| ParamProblem {
                key: i.key,
                message: format!("value {} is not allowed", i.value),
                allowed: i.allowed,
            })
            .collect());
    }
    Ok(serde_json::to_value(&p).expect("params serialize"))
}

/// Decode the canonical params of a stage into its typed struct.
pub fn decode<P: DeserializeOwned>(ctx: &StageCtx) -> anyhow::Result<P> {
    Ok(serde_json::from_value(ctx.params.clone())?)
}

/// A study kind's params name their method (`method: dem`): the method and the rest of
/// the mapping (that method's own params). A problem names the `method` key and lists
/// `allowed`.
pub fn split_method(v: &Value, allowed: &[Method]) -> Result<(Method, Value), ParamProblem> {
    let list = allowed.iter().map(|m| m.key()).collect::<Vec<_>>().join(" | ");
    let problem = |message: String| ParamProblem {
        key: "method".into(),
        message,
        allowed: list.clone(),
    };
    let map = v
        .as_object()
        .ok_or_else(|| problem("the params are not a mapping".into()))?;
    let m = match map.get("method") {
        None => return Err(problem("missing: the study needs its method".into())),
        Some(Value::String(s)) => Method::parse(s)
            .filter(|m| allowed.contains(m))
            .ok_or_else(|| problem(format!("`{s}` is not a method of this study")))?,
        Some(other) => return Err(problem(format!("`{other}` is not a method name"))),
    };
    let mut rest = map.clone();
    rest.remove("method");
    Ok((m, Value::Object(rest)))
}

/// The canonical params of a study kind: `canonical` (the method's own, defaults filled)
/// with its `method` put back.
pub fn with_method(m: Method, canonical: Value) -> Value {
    let mut v = canonical;
    if let Some(map) = v.as_object_mut() {
        map.insert("method".into(), Value::String(m.key().into()));
    }
    v
}

impl std::fmt::Debug for Kind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Kind({} v{})", self.name, self.version)
    }
}

#[cfg(test)]
mod tests {
    use super::covers;

    #[test]
    fn families_cover_their_members_only() {
        assert!(covers("runout_norm", "runout_norm"));
        assert!(!covers("runout_norm", "runout_norm_1tau"));
        assert!(covers("runout_mean_a*", "runout_mean_a0.4"));
        assert!(!covers("runout_mean_a*", "runout_std_a0.4"));
        assert!(covers("panel*_max_*", "panel2_max_vx_m_s"));
        assert!(!covers("panel*_max_*", "panel2_bodies"));
        assert!(covers("*_ratio", "hex-shorter-runout_ratio"));
        assert!(!covers("*_ratio", "hex-shorter-runout_pairs"));
        assert!(covers("*", "anything"));
        // The suffix may not overlap the prefix.
        assert!(!covers("ab*ba", "aba"));
    }
}

//! What a stage kind is: its name, version, parameter schema and body ([`Kind`]), and the
//! schema helpers every kind uses ([`typed`], [`decode`], [`Validate`]). A leaf of the
//! stage layer: kinds and the pipeline import it, it imports neither.

use serde::Serialize;
use serde::de::DeserializeOwned;
use serde_json::Value;

use crate::pipeline::context::{Output, StageCtx};
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

/// A registered stage kind.
#[derive(Clone, Copy)]
pub struct Kind {
    /// Name used in `kind:`.
    pub name: &'static str,
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

impl std::fmt::Debug for Kind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Kind({} v{})", self.name, self.version)
    }
}

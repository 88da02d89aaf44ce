//! Loading and validating `pipeline.yaml` (schema in `docs/pipeline.md`).
//!
//! Parameters of a stage are merged, later layers winning, from: its `params_file`(s),
//! the file's `profiles.<P>` section, the inline `params`, the entry's `profiles.<P>`,
//! its matrix value, and `--set` overrides. The merged mapping is then checked by the
//! kind's schema. Every problem is collected with file, line and key; nothing runs until
//! the whole pipeline is valid.

pub use super::yaml::{canonical, to_json};
use super::yaml::{has_path, yaml_scalar_string};
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use serde::Deserialize;
use serde_json::Value as Json;
use serde_yaml::{Mapping, Value as Yaml};

use super::diag::locate;
use crate::stages::Kind;

/// Allowed profile names.
pub const PROFILES: [&str; 2] = ["quick", "paper"];

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct PipelineFile {
    pub(super) version: u32,
    #[serde(default)]
    #[allow(dead_code)]
    pub(super) description: Option<String>,
    pub(super) stages: Vec<Yaml>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct StageEntry {
    pub(super) id: String,
    pub(super) kind: String,
    #[serde(default)]
    pub(super) caption: Option<String>,
    #[serde(default)]
    pub(super) params_file: Option<OneOrMany>,
    #[serde(default)]
    pub(super) params: Option<Mapping>,
    #[serde(default)]
    pub(super) profiles: BTreeMap<String, Mapping>,
    #[serde(default)]
    pub(super) inputs: Option<InputsSpec>,
    #[serde(default)]
    pub(super) matrix: Option<BTreeMap<String, Vec<Yaml>>>,
    #[serde(default)]
    pub(super) on_demand: bool,
}

#[derive(Deserialize)]
#[serde(untagged)]
pub(super) enum OneOrMany {
    One(String),
    Many(Vec<String>),
}

#[derive(Deserialize)]
#[serde(untagged)]
pub(super) enum InputsSpec {
    /// `[a, b]`: role = stage id.
    List(Vec<String>),
    /// `{role: id}` or `{role: [id, id]}`.
    Map(BTreeMap<String, OneOrMany>),
}

/// One `--set STAGE.KEY=VALUE` override.
#[derive(Debug, Clone)]
pub struct Override {
    /// Stage id (a matrix base id applies to every member). Ids may contain dots
    /// (`col-dem-prep-a0.4`): [`load`] re-splits `STAGE.KEY` at the longest known id.
    pub stage: String,
    /// Dotted key inside params.
    pub key: String,
    /// Value, parsed as YAML.
    pub value: Yaml,
}

impl Override {
    /// Parse `STAGE.KEY=VALUE` (split at the first '.' until the pipeline's ids are known).
    pub fn parse(s: &str) -> Result<Override, String> {
        let (lhs, rhs) = s
            .split_once('=')
            .ok_or_else(|| format!("--set {s}: expected STAGE.KEY=VALUE"))?;
        let (stage, key) = lhs
            .split_once('.')
            .ok_or_else(|| format!("--set {s}: expected STAGE.KEY=VALUE (no '.' between stage and key)"))?;
        let value: Yaml = serde_yaml::from_str(rhs).map_err(|e| format!("--set {s}: value is not valid YAML: {e}"))?;
        Ok(Override {
            stage: stage.to_string(),
            key: key.to_string(),
            value,
        })
    }
    /// Re-split `STAGE.KEY` so STAGE is the longest of `ids` that fits.
    pub(super) fn resolve(&self, ids: &std::collections::HashSet<String>) -> Override {
        let lhs = format!("{}.{}", self.stage, self.key);
        let best = ids
            .iter()
            .filter(|id| lhs.len() > id.len() + 1 && lhs.starts_with(id.as_str()) && lhs.as_bytes()[id.len()] == b'.')
            .max_by_key(|id| id.len());
        match best {
            Some(id) => Override {
                stage: id.clone(),
                key: lhs[id.len() + 1..].to_string(),
                value: self.value.clone(),
            },
            None => self.clone(),
        }
    }
    /// `key=value`, as marked on published outputs.
    pub fn show(&self) -> String {
        format!("{}.{}={}", self.stage, self.key, yaml_scalar_string(&self.value))
    }
}

/// A resolved stage, ready to plan.
#[derive(Debug, Clone)]
pub struct Stage {
    /// Unique id (matrix members: `<base>-<key><value>`).
    pub id: String,
    /// Id as written in pipeline.yaml.
    pub base_id: String,
    /// Kind name.
    pub kind: String,
    /// Kind's solver version.
    pub version: u32,
    /// Caption for the report.
    pub caption: Option<String>,
    /// Canonical params (defaults filled, keys sorted).
    pub params: Json,
    /// Inputs: role → upstream stage ids (in declared order).
    pub inputs: Vec<(String, Vec<String>)>,
    /// Line of the entry in pipeline.yaml.
    pub line: Option<usize>,
    /// `--set` overrides applied to this stage or to any stage upstream of it
    /// (`STAGE.KEY=VALUE`).
    pub overrides: Vec<String>,
    /// Run only when named (`--stage`) or needed by a named stage: a study that is part of
    /// neither profile's whole run (`on_demand: true` in pipeline.yaml).
    pub on_demand: bool,
}

/// A validated pipeline for one profile.
#[derive(Debug, Clone)]
pub struct Pipeline {
    /// Path of pipeline.yaml.
    pub path: PathBuf,
    /// Directory holding pipeline.yaml (stage files are relative to it).
    pub root: PathBuf,
    /// Profile the params were resolved for.
    pub profile: String,
    /// Stages in topological order (inputs first; ties in file order).
    pub stages: Vec<Stage>,
    pub(super) index: HashMap<String, usize>,
    /// The kinds registry used.
    pub kinds: BTreeMap<&'static str, Kind>,
}

impl Pipeline {
    /// The work-precision atlas: the first stage whose kind declares `atlas`, with the
    /// table it publishes the profile's measured errors in.
    pub fn atlas(&self) -> Option<(&str, &'static str)> {
        self.stages.iter().find_map(|s| {
            self.kinds
                .get(s.kind.as_str())
                .and_then(|k| k.atlas)
                .map(|t| (s.id.as_str(), t))
        })
    }

    /// Stage by id.
    pub fn get(&self, id: &str) -> Option<&Stage> {
        self.index.get(id).map(|&i| &self.stages[i])
    }
    /// Ids of every member of a base id (a plain stage is its own single member).
    pub fn members(&self, base: &str) -> Vec<&str> {
        if let Some(&i) = self.index.get(base) {
            return vec![self.stages[i].id.as_str()];
        }
        self.stages
            .iter()
            .filter(|s| s.base_id == base)
            .map(|s| s.id.as_str())
            .collect()
    }
}

/// Where a layer of params came from, for messages.
pub(super) struct Layer {
    pub(super) file: PathBuf,
    pub(super) text: Option<String>,
    /// Path prefix of the layer's mapping inside its file.
    pub(super) prefix: Vec<String>,
    pub(super) anchor: usize,
    pub(super) value: Yaml,
    /// `profiles.P` when the layer is a profile's section (named in a problem it sets).
    pub(super) section: Option<String>,
}

/// One layer of a stage's params, for attributing a problem: (file, its text, key
/// prefix inside the file, line anchor, the layer's mapping).
pub(super) type LayerRef = (PathBuf, Option<String>, Vec<String>, usize, Yaml);

/// The file and line of the last layer that sets the dotted `key` (the stage entry
/// when no layer does).
pub(super) fn attribute(layers: &[LayerRef], key: &str, path: &Path, line: Option<usize>) -> (PathBuf, Option<usize>) {
    // Indices stay in the path (a problem inside a list belongs to the layer holding the
    // list); the line is located by the key names alone.
    let parts: Vec<&str> = key.split(['.', '[']).filter(|s| !s.is_empty()).collect();
    let names: Vec<&str> = parts.iter().copied().filter(|s| !s.ends_with(']')).collect();
    for (f, t, prefix, anchor, v) in layers.iter().rev() {
        if parts.is_empty() || has_path(v, &parts) {
            let l = t.as_deref().and_then(|t| {
                let rel: Vec<&str> = names.iter().skip(prefix.len()).cloned().collect();
                if rel.is_empty() {
                    Some(*anchor)
                } else {
                    locate(t, &rel, *anchor)
                }
            });
            return (f.clone(), l);
        }
    }
    (path.to_path_buf(), line)
}

/// A stage computed from an overridden input is overridden too: give each stage (in
/// topological order) the `--set` overrides of everything upstream.
pub(super) fn inherit_overrides(stages: &mut [Stage], index: &HashMap<String, usize>) {
    for i in 0..stages.len() {
        let mut all = stages[i].overrides.clone();
        for id in stages[i].inputs.iter().flat_map(|(_, ids)| ids.iter()) {
            for o in index.get(id).map(|&j| stages[j].overrides.clone()).unwrap_or_default() {
                if !all.contains(&o) {
                    all.push(o);
                }
            }
        }
        stages[i].overrides = all;
    }
}

/// Every id the raw stage entries define (base ids and matrix member ids), for
/// resolving `--set STAGE.KEY` when ids contain dots.
pub(super) fn known_ids(raw: &[Yaml]) -> std::collections::HashSet<String> {
    let mut out = std::collections::HashSet::new();
    for e in raw {
        let Some(id) = e.get("id").and_then(|v| v.as_str()) else {
            continue;
        };
        out.insert(id.to_string());
        // The stage's matrix and every profile's (a `--set` may name a member of either).
        let profile_matrices = e
            .get("profiles")
            .and_then(|p| p.as_mapping())
            .into_iter()
            .flat_map(|p| p.values())
            .filter_map(|p| p.get("matrix"));
        for mat in e.get("matrix").into_iter().chain(profile_matrices) {
            let Yaml::Mapping(m) = mat else { continue };
            for (k, vals) in m {
                for v in vals.as_sequence().into_iter().flatten() {
                    out.insert(format!("{id}-{}{}", yaml_scalar_string(k), yaml_scalar_string(v)));
                }
            }
        }
    }
    out
}

/// Every stage id an inputs spec names.
pub(super) fn input_refs(spec: &InputsSpec) -> Vec<&str> {
    match spec {
        InputsSpec::List(v) => v.iter().map(String::as_str).collect(),
        InputsSpec::Map(m) => m
            .values()
            .flat_map(|v| match v {
                OneOrMany::One(s) => std::slice::from_ref(s).iter(),
                OneOrMany::Many(v) => v.iter(),
            })
            .map(String::as_str)
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::super::yaml::merge;
    use super::*;

    fn y(s: &str) -> Yaml {
        serde_yaml::from_str(s).unwrap()
    }

    #[test]
    fn merge_is_deep_and_switches_enum_variants() {
        let mut base = y("mpm: {cell_size: 2, step: {fixed: {dt: 1}}, material: {e: 1, nu: 2}}");
        merge(&mut base, &y("mpm: {step: {cfl: {courant: 0.5}}, material: {nu: 3}}"));
        assert_eq!(
            base,
            y("mpm: {cell_size: 2, step: {cfl: {courant: 0.5}}, material: {e: 1, nu: 3}}")
        );
        // Top-level sections of different files never replace each other.
        let mut top = y("mpm: {a: {b: 1}}");
        merge(&mut top, &y("run: {c: {d: 2}}"));
        assert_eq!(top, y("mpm: {a: {b: 1}}\nrun: {c: {d: 2}}"));
    }
}

//! Cache keys of a pipeline's stages (nested through their inputs) and, for `status`, why a
//! stage's key moved.

use std::collections::{BTreeMap, HashMap};

use serde_json::Value;

use super::cache::KeyRecord;
use super::spec::Pipeline;

/// Compute the key record of every stage in topological order.
pub fn key_records(p: &Pipeline) -> HashMap<String, (KeyRecord, String)> {
    let mut out: HashMap<String, (KeyRecord, String)> = HashMap::new();
    for s in &p.stages {
        let inputs = s
            .inputs
            .iter()
            .map(|(role, ids)| {
                (
                    role.clone(),
                    ids.iter().map(|id| (id.clone(), out[id].1.clone())).collect(),
                )
            })
            .collect();
        let rec = KeyRecord {
            kind: s.kind.clone(),
            version: s.version,
            params: s.params.clone(),
            profile: p.profile.clone(),
            inputs,
        };
        let key = rec.key();
        out.insert(s.id.clone(), (rec, key));
    }
    out
}

/// Why a stage is stale, one line per reason.
pub fn stale_reasons(old: &KeyRecord, new: &KeyRecord) -> Vec<String> {
    let mut r = Vec::new();
    if old.kind != new.kind {
        r.push(format!("kind changed ({} → {})", old.kind, new.kind));
    }
    if old.version != new.version {
        r.push(format!("solver version changed ({} → {})", old.version, new.version));
    }
    let (a, b) = (flatten(&old.params), flatten(&new.params));
    for (k, v) in &b {
        match a.get(k) {
            Some(o) if o == v => {}
            Some(o) => r.push(format!("params.{k} changed ({o} → {v})")),
            None => r.push(format!("params.{k} added ({v})")),
        }
    }
    for k in a.keys() {
        if !b.contains_key(k) {
            r.push(format!("params.{k} removed"));
        }
    }
    let oi: HashMap<&str, &str> = old
        .inputs
        .iter()
        .flat_map(|(_, v)| v.iter().map(|(i, k)| (i.as_str(), k.as_str())))
        .collect();
    for (_, v) in &new.inputs {
        for (id, k) in v {
            match oi.get(id.as_str()) {
                Some(ok) if ok == k => {}
                Some(_) => r.push(format!("input `{id}` changed")),
                None => r.push(format!("input `{id}` added")),
            }
        }
    }
    if r.is_empty() {
        r.push("entry missing from the cache".into());
    }
    r
}

fn flatten(v: &Value) -> BTreeMap<String, String> {
    fn go(prefix: &str, v: &Value, out: &mut BTreeMap<String, String>) {
        match v {
            Value::Object(m) => {
                for (k, x) in m {
                    go(
                        &if prefix.is_empty() {
                            k.clone()
                        } else {
                            format!("{prefix}.{k}")
                        },
                        x,
                        out,
                    );
                }
            }
            other => {
                out.insert(prefix.to_string(), other.to_string());
            }
        }
    }
    let mut out = BTreeMap::new();
    go("", v, &mut out);
    out
}

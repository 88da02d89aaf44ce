//! YAML values as the loader handles them: deep merge of parameter layers, dotted-path set
//! and lookup (`--set`, matrix values), scalar rendering for stage ids, and the canonical
//! JSON (keys sorted) that schemas read and cache keys hash. A leaf: no pipeline types.

use std::collections::BTreeMap;

use serde_json::Value as Json;
use serde_yaml::{Mapping, Value as Yaml};

/// A scalar as it appears in a stage id (`0.4`, `true`, `epsd`).
pub(crate) fn yaml_scalar_string(v: &Yaml) -> String {
    match v {
        Yaml::String(s) => s.clone(),
        Yaml::Number(n) => n.to_string(),
        Yaml::Bool(b) => b.to_string(),
        other => serde_yaml::to_string(other).unwrap_or_default().trim().to_string(),
    }
}

/// Deep-merge `over` into `base` (mappings merge key by key; anything else replaces).
pub(crate) fn merge(base: &mut Yaml, over: &Yaml) {
    merge_at(base, over, 0)
}

pub(crate) fn merge_at(base: &mut Yaml, over: &Yaml, depth: usize) {
    match (base, over) {
        // Below the top level, two single-key mappings with different keys whose values
        // are mappings are variants of an enum (`step: {fixed: {dt}}` overridden by
        // `step: {cfl: {..}}`): the override replaces instead of merging into an
        // ambiguous two-variant mapping.
        (Yaml::Mapping(b), Yaml::Mapping(o))
            if depth > 0
                && b.len() == 1
                && o.len() == 1
                && b.keys().next() != o.keys().next()
                && b.values().next().is_some_and(|v| v.is_mapping())
                && o.values().next().is_some_and(|v| v.is_mapping()) =>
        {
            *b = o.clone();
        }
        (Yaml::Mapping(b), Yaml::Mapping(o)) => {
            for (k, v) in o {
                match b.get_mut(k) {
                    Some(slot) => merge_at(slot, v, depth + 1),
                    None => {
                        b.insert(k.clone(), v.clone());
                    }
                }
            }
        }
        (b, o) => *b = o.clone(),
    }
}

/// Set the dotted `key` of `root` to `value`, creating mappings on the way (how `--set`
/// and matrix values enter a stage's params). A value on the way that is neither a
/// mapping nor empty is left as it is (the kind's schema then names it), never replaced.
pub(crate) fn set_path(root: &mut Yaml, key: &str, value: Yaml) {
    let mut cur = root;
    let parts: Vec<&str> = key.split('.').collect();
    for (i, p) in parts.iter().enumerate() {
        match cur {
            Yaml::Mapping(_) => {}
            Yaml::Null => *cur = Yaml::Mapping(Mapping::new()),
            _ => return,
        }
        let Yaml::Mapping(m) = cur else { unreachable!() };
        let k = Yaml::String(p.to_string());
        if i + 1 == parts.len() {
            m.insert(k, value);
            return;
        }
        if !m.contains_key(&k) {
            m.insert(k.clone(), Yaml::Mapping(Mapping::new()));
        }
        cur = m.get_mut(&k).unwrap();
    }
}

/// The value a matrix member sets at the dotted `key` of the merged params `base`: the
/// matrix value itself, or, where `base` holds a list there, a one-element list of it. A
/// matrix over a list parameter runs each element as its own member (`matrix:
/// { energies_mgd: [2.597, 5.194] }` on a `pile-run`: one energy per member, each cached
/// as it completes, so a long sweep runs in pieces); readers fan in the members.
pub(crate) fn matrix_value(base: &Yaml, key: &str, value: &Yaml) -> Yaml {
    let mut cur = base;
    for p in key.split('.') {
        match cur {
            Yaml::Mapping(m) => match m.get(Yaml::String(p.to_string())) {
                Some(v) => cur = v,
                None => return value.clone(),
            },
            _ => return value.clone(),
        }
    }
    match cur {
        Yaml::Sequence(_) => Yaml::Sequence(vec![value.clone()]),
        _ => value.clone(),
    }
}

/// Does `root` hold the key path (`["panels", "0]", "series"]`: a segment `N]` is a
/// sequence index, as in `panels[0].series`)?
pub(crate) fn has_path(root: &Yaml, key: &[&str]) -> bool {
    let mut cur = root;
    for p in key {
        let next = match (p.strip_suffix(']').and_then(|i| i.parse::<usize>().ok()), cur) {
            (Some(i), Yaml::Sequence(s)) => s.get(i),
            (None, Yaml::Mapping(m)) => m.get(Yaml::String(p.to_string())),
            _ => None,
        };
        match next {
            Some(v) => cur = v,
            None => return false,
        }
    }
    true
}

/// Serialize a YAML value to canonical JSON (map keys sorted).
pub fn to_json(v: &Yaml) -> Result<Json, String> {
    let j = serde_json::to_value(v).map_err(|e| e.to_string())?;
    Ok(canonical(j))
}

/// Sort object keys recursively.
pub fn canonical(v: Json) -> Json {
    match v {
        Json::Object(m) => {
            let sorted: BTreeMap<String, Json> = m.into_iter().map(|(k, v)| (k, canonical(v))).collect();
            Json::Object(sorted.into_iter().collect())
        }
        Json::Array(a) => Json::Array(a.into_iter().map(canonical).collect()),
        other => other,
    }
}

#[cfg(test)]
mod matrix_value_tests {
    use super::matrix_value;
    use serde_yaml::Value as Yaml;

    /// A matrix over a list parameter sets a one-element list; over a scalar, the value.
    #[test]
    fn a_list_parameter_takes_one_element_per_member() {
        let base: Yaml = serde_yaml::from_str("energies_mgd: [1.0, 2.0]\nmpm: { ppc: 4 }").unwrap();
        let v = Yaml::from(2.0);
        assert_eq!(matrix_value(&base, "energies_mgd", &v), Yaml::Sequence(vec![v.clone()]));
        assert_eq!(matrix_value(&base, "mpm.ppc", &v), v);
        assert_eq!(matrix_value(&base, "mpm.cell_size", &v), v);
        assert_eq!(matrix_value(&base, "a", &v), v);
    }
}

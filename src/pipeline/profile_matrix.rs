//! A stage's matrix in one profile: `profiles.P.matrix` sweeps other values of the
//! stage's matrix key, or, with an empty list, leaves the stage out of that profile.

use std::collections::BTreeMap;
use std::path::Path;

use serde_yaml::Value as Yaml;

use super::diag::{Diagnostics, locate};
use super::spec::StageEntry;

/// What a stage's `profiles.P.matrix` makes of it in `profile`.
pub(super) enum ProfileMatrix {
    /// Its matrix for this profile is set (or it has none).
    Resolved,
    /// A profile's matrix is wrong (reported).
    Bad,
    /// An empty list leaves it out of this profile: where that is written (line, key).
    Absent(Option<usize>, String),
}

/// A profile may sweep other values of the stage's matrix key (`profiles: { quick:
/// { matrix: { a: [0.4, 6] } } }`): fewer aspect ratios in the quick profile, the
/// chapter's list in the paper one. It replaces the values, never the key. An empty list
/// leaves the stage out of that profile (extra ensemble members the quick budget has no
/// room for); its dependants there must not name it. Every profile's matrix is checked;
/// `entry.matrix` becomes `profile`'s.
pub(super) fn profile_matrix(
    entry: &mut StageEntry,
    profile: &str,
    text: &str,
    line: Option<usize>,
    path: &Path,
    diags: &mut Diagnostics,
) -> ProfileMatrix {
    let mut bad = false;
    let mut absent = None;
    for (pname, pm) in entry.profiles.iter_mut() {
        let Some(mv) = pm.remove(Yaml::String("matrix".into())) else {
            continue;
        };
        let l = line.and_then(|ln| locate(text, &["profiles", pname, "matrix"], ln));
        let base = entry.matrix.as_ref().and_then(|m| m.keys().next().cloned());
        let parsed: Option<BTreeMap<String, Yaml>> = serde_yaml::from_value(mv).ok();
        let same_key = match (&parsed, &base) {
            (Some(pm), Some(k)) => pm.len() == 1 && pm.keys().next() == Some(k),
            _ => false,
        };
        if !same_key {
            diags.push(
                path,
                l,
                format!("stages[{}].profiles.{pname}.matrix", entry.id),
                "a profile's matrix must sweep the stage's own matrix key",
                match base {
                    Some(k) => format!("write `matrix: {{ {k}: [..] }}` (the key of the stage's `matrix:`)"),
                    None => "declare `matrix:` on the stage first; a profile only changes its values".to_string(),
                },
            );
            bad = true;
            continue;
        }
        // The right key: its values must be a list, as the stage's own.
        let (k, v) = parsed.into_iter().flatten().next().expect("one key, checked above");
        let lk = line
            .and_then(|ln| locate(text, &["profiles", pname, "matrix", &k], ln))
            .or(l);
        match serde_yaml::from_value::<Vec<Yaml>>(v) {
            Ok(values) => {
                if pname == profile {
                    if values.is_empty() {
                        absent = Some((lk, format!("stages[{}].profiles.{pname}.matrix.{k}", entry.id)));
                    }
                    entry.matrix = Some(BTreeMap::from([(k, values)]));
                }
            }
            Err(_) => {
                diags.push(
                    path,
                    lk,
                    format!("stages[{}].profiles.{pname}.matrix.{k}", entry.id),
                    format!("the values of `{k}` must be a list"),
                    format!("write `{k}: [v1, v2, ..]` (one stage per value)"),
                );
                bad = true;
            }
        }
    }
    match (bad, absent) {
        (true, _) => ProfileMatrix::Bad,
        (false, Some((at, key))) => ProfileMatrix::Absent(at, key),
        (false, None) => ProfileMatrix::Resolved,
    }
}

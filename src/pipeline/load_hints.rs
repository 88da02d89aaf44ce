//! The loader's problem messages, made to name what the user wrote: the keys a choice
//! holds, the other side of a bound between two parameters, and the profile section that
//! set a key wrong (`src/pipeline/load.rs` attributes each problem to its file and line).

use super::spec::{Layer, LayerRef};
/// A choice written as a one-key mapping (`step: { cfl: … }`) that ended up with several
/// keys — typically a profile layer naming another choice with a scalar, which merges
/// instead of replacing — is named with the keys it holds, so the message says which
/// layer's key to fix.
pub(super) fn with_variants(params: &serde_json::Value, key: &str, message: &str, allowed: &str) -> String {
    if !allowed.contains("single key") {
        return with_bounds(params, key, message, allowed);
    }
    let at = key
        .split('.')
        .filter(|k| !k.is_empty())
        .try_fold(params, |v, k| v.get(k));
    match at.and_then(|v| v.as_object()) {
        Some(m) if m.len() > 1 => format!(
            "{message}: it holds {} keys ({}), a choice takes exactly one",
            m.len(),
            m.keys().map(|k| format!("`{k}`")).collect::<Vec<_>>().join(", ")
        ),
        _ => message.to_string(),
    }
}

/// A bound that names another parameter ("< pile.max_time") is a relation between two
/// keys, and either may be the one set wrong: the message gives the other's value too.
fn with_bounds(params: &serde_json::Value, key: &str, message: &str, allowed: &str) -> String {
    let others: Vec<String> = allowed
        .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == '.'))
        .filter(|w| w.contains('.') && *w != key && w.chars().next().is_some_and(|c| c.is_ascii_alphabetic()))
        .filter_map(|w| {
            let v = w.split('.').try_fold(params, |v, k| v.get(k))?;
            (v.is_number() || v.is_string()).then(|| format!("{w} = {v}"))
        })
        .collect();
    if others.is_empty() {
        message.to_string()
    } else {
        format!("{message} ({})", others.join(", "))
    }
}

/// The profile section (`profiles.P`) of the last layer that sets the dotted `key`, when
/// that layer is a profile's and no matrix or `--set` layer after them (`later`) sets it.
/// A key a profile's section sets wrong is named there.
pub(super) fn section_of(
    layers: &[Layer],
    later: &[LayerRef],
    key: &str,
) -> Option<String> {
    let parts: Vec<&str> = key
        .split(['.', '['])
        .filter(|s| !s.is_empty() && !s.ends_with(']'))
        .collect();
    if parts.is_empty() || later.iter().any(|l| super::yaml::has_path(&l.4, &parts)) {
        return None;
    }
    layers
        .iter()
        .rev()
        .find(|l| super::yaml::has_path(&l.value, &parts))?
        .section
        .clone()
}

//! Checks of a pipeline that do not belong to one kind's schema: safe stage ids, numbers
//! that are finite and not absurdly large, matrix keys and values (read by the kind's
//! schema before any member id is formed), the input roles each kind reads, and one
//! message per root cause.

use std::collections::{BTreeMap, HashMap};

use serde_json::Value as Json;
use serde_yaml::Value as Yaml;

use super::diag::{Diagnostic, Diagnostics};
use crate::stages::Kind;
use crate::stages::kind::Roles;

/// Longest stage id allowed.
pub const MAX_ID_LEN: usize = 100;

/// Check a stage id: `[A-Za-z0-9][A-Za-z0-9._-]*`, no `..`, at most [`MAX_ID_LEN`]
/// characters. Ids become file names under `reports/`, so nothing else is allowed.
pub fn check_id(id: &str) -> Result<(), String> {
    let shown = format!("{id:?}");
    if id.is_empty() {
        return Err("the stage id is empty".into());
    }
    if id.len() > MAX_ID_LEN {
        return Err(format!(
            "stage id {shown} is {} characters long (at most {MAX_ID_LEN})",
            id.len()
        ));
    }
    if !id.chars().next().is_some_and(|c| c.is_ascii_alphanumeric()) {
        return Err(format!("stage id {shown} must start with a letter or digit"));
    }
    if let Some(c) = id
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-')))
    {
        return Err(format!("stage id {shown} contains {c:?}"));
    }
    if id.contains("..") {
        return Err(format!("stage id {shown} contains `..`"));
    }
    Ok(())
}

/// What stage ids may contain, for help lines.
pub const ID_HELP: &str =
    "ids match [A-Za-z0-9][A-Za-z0-9._-]* (no `..`, at most 100 characters); they name files under reports/";

/// Largest magnitude accepted for a floating-point parameter. No physical parameter of
/// the chapter comes near it (E ~ 1e8 Pa, k_n ~ 1e5 N/m, ρ ~ 2.5e3 kg/m³); values beyond
/// it (1e308) overflow the solvers' arithmetic instead of meaning anything.
pub const MAX_MAGNITUDE: f64 = 1e15;

/// A number that cannot be a parameter: (dotted key, rendered value, what is allowed).
pub type BadNumber = (String, String, String);

/// Every float in `v` that is NaN, infinite or larger in magnitude than
/// [`MAX_MAGNITUDE`], with its dotted key.
pub fn bad_numbers(v: &Yaml) -> Vec<BadNumber> {
    let mut out = Vec::new();
    walk(v, String::new(), &mut out);
    out
}

fn walk(v: &Yaml, key: String, out: &mut Vec<BadNumber>) {
    match v {
        Yaml::Mapping(m) => {
            for (k, x) in m {
                let ks = match k {
                    Yaml::String(s) => s.clone(),
                    other => serde_yaml::to_string(other).unwrap_or_default().trim().to_string(),
                };
                walk(x, if key.is_empty() { ks } else { format!("{key}.{ks}") }, out);
            }
        }
        Yaml::Sequence(s) => {
            for (i, x) in s.iter().enumerate() {
                walk(x, format!("{key}[{i}]"), out);
            }
        }
        Yaml::Tagged(t) => walk(&t.value, key, out),
        Yaml::Number(n) if n.is_f64() => {
            let x = n.as_f64().unwrap_or(f64::NAN);
            if !x.is_finite() {
                out.push((key, n.to_string(), "must be a finite number (not .nan / .inf)".into()));
            } else if x.abs() > MAX_MAGNITUDE {
                out.push((
                    key,
                    n.to_string(),
                    format!("must be a physically plausible number, |value| <= {MAX_MAGNITUDE:e}"),
                ));
            }
        }
        _ => {}
    }
}

/// What a stage's matrix key is to its kind.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MatrixKey {
    /// A parameter of the kind: each member sets it to its value.
    Param,
    /// Not a parameter, but an input is swept on the same key: the values only name the
    /// members and pair them with that input's (`col-dem` over `a` reads `col-dem-prep-a<a>`).
    Pairing,
}

/// Check a matrix key and its values the way a `--set` key is checked: each value is set
/// on the stage's merged params `base` and the kind's schema reads the result. A key the
/// schema does not know is accepted only when `pairs` (an input is swept on the same key);
/// a value the parameter's type or range refuses is an error naming the value. Err:
/// (message, help). Values with NaN/inf are left to [`bad_numbers`]. `inputs` (the stage
/// ids the stage reads) are named when the key pairs with none of them.
pub fn matrix_key(
    kind: &Kind,
    base: &Yaml,
    key: &str,
    vals: &[Yaml],
    pairs: bool,
    inputs: &[&str],
) -> Result<MatrixKey, (String, String)> {
    let under = |k: &str, p: &str| p == k || p.starts_with(&format!("{k}.")) || p.starts_with(&format!("{k}["));
    for v in vals {
        let mut m = base.clone();
        super::yaml::set_path(&mut m, key, super::yaml::matrix_value(base, key, v));
        if !bad_numbers(&m).is_empty() {
            continue;
        }
        let Ok(json) = super::yaml::to_json(&m) else { continue };
        let Err(problems) = (kind.params)(&json) else { continue };
        for pr in problems {
            if pr.message.starts_with("unknown field") && under(&pr.key, key) {
                if pairs {
                    return Ok(MatrixKey::Pairing);
                }
                let list = pr
                    .allowed
                    .trim_start_matches("expected one of ")
                    .trim_start_matches("expected ")
                    .to_string();
                let whose = match pr.key.rsplit_once('.') {
                    Some((parent, _)) => format!("the keys under `{parent}` are"),
                    None => "its parameters are".to_string(),
                };
                let nor = if inputs.is_empty() {
                    " (and it has no inputs to be swept on)".to_string()
                } else {
                    format!(" (nor is any of its inputs swept on `{key}`: {})", inputs.join(", "))
                };
                return Err((
                    format!("`{}` is not a parameter of {}; {whose} {list}{nor}", pr.key, kind.name),
                    "sweep one of the kind's parameters, or the key an input is swept on (the members then pair with that input's)".into(),
                ));
            }
            if under(key, &pr.key) {
                let shown = serde_yaml::to_string(v).unwrap_or_default().trim().to_string();
                return Err((
                    format!("matrix value `{shown}` of `{key}`: {}", pr.message),
                    if pr.allowed.is_empty() {
                        format!("see the `{}` kind's parameters in docs/pipeline.md", kind.name)
                    } else {
                        pr.allowed
                    },
                ));
            }
        }
    }
    Ok(MatrixKey::Param)
}

/// The matrix key of every raw stage entry that sweeps one (for telling a pairing key
/// from a misspelt parameter).
pub(super) fn matrix_keys(raw: &[Yaml]) -> HashMap<String, String> {
    let mut out = HashMap::new();
    for e in raw {
        let (Some(id), Some(Yaml::Mapping(m))) = (e.get("id").and_then(|v| v.as_str()), e.get("matrix")) else {
            continue;
        };
        if let (1, Some(k)) = (m.len(), m.keys().next().and_then(|k| k.as_str())) {
            out.insert(id.to_string(), k.to_string());
        }
    }
    out
}

/// The line of a YAML error: where the parser stopped, or for errors without a place
/// (a second document) the second document's `---`, else line 1.
pub(super) fn error_line(e: &serde_yaml::Error, text: &str) -> Option<usize> {
    e.location().map(|l| l.line()).or_else(|| {
        let docs: Vec<usize> = text
            .lines()
            .enumerate()
            .filter(|(_, l)| l.starts_with("---") || l.starts_with("..."))
            .map(|(i, _)| i + 1)
            .collect();
        docs.iter().find(|&&l| l > 1).or(docs.first()).copied().or(Some(1))
    })
}

/// serde's "data did not match any variant of untagged enum" for `inputs` or
/// `params_file` names neither the role nor what is allowed: find the offending entry in
/// the raw stage. (key, message, help).
pub(super) fn untagged_problem(raw: &Yaml, inner: &str) -> Option<(String, String, String)> {
    let ids = |v: &Yaml| v.is_string() || v.as_sequence().is_some_and(|s| s.iter().all(Yaml::is_string));
    let shown = |v: &Yaml| serde_yaml::to_string(v).unwrap_or_default().trim().replace('\n', " ");
    if inner.contains("untagged enum InputsSpec") {
        let help = "write `inputs: { ROLE: STAGE }`, `inputs: { ROLE: [STAGE, ..] }` or `inputs: [STAGE, ..]`";
        let v = raw.get("inputs")?;
        let bad = match v {
            Yaml::Mapping(m) => m.iter().find(|(_, x)| !ids(x)).map(|(k, x)| {
                let k = k.as_str().map(str::to_string).unwrap_or_else(|| shown(k));
                (
                    format!("inputs.{k}"),
                    format!(
                        "input `{k}` must name a stage id or a list of them (it is `{}`)",
                        shown(x)
                    ),
                )
            }),
            Yaml::Sequence(s) => s.iter().position(|x| !x.is_string()).map(|i| {
                (
                    format!("inputs[{i}]"),
                    format!("inputs[{i}] must be a stage id (it is `{}`)", shown(&s[i])),
                )
            }),
            _ => None,
        };
        let (k, m) = bad.unwrap_or_else(|| {
            (
                "inputs".into(),
                format!("inputs must be a list or a mapping (it is `{}`)", shown(v)),
            )
        });
        return Some((k, m, help.into()));
    }
    if inner.contains("untagged enum OneOrMany") {
        let v = raw.get("params_file")?;
        return Some((
            "params_file".into(),
            format!("params_file must be a path or a list of paths (it is `{}`)", shown(v)),
            "write `params_file: stages/X.yaml` or `params_file: [SECTION=stages/X.yaml, stages/Y.yaml]`".into(),
        ));
    }
    None
}

pub use super::context::Arity;

/// The input roles kind `kind` reads, with their arity, as its [`Kind`] declares them;
/// None for an unknown kind or one whose params name their roles ([`Roles::Named`]).
pub fn roles(kind: &str, params: &Json) -> Option<Vec<(&'static str, Arity)>> {
    crate::stages::registry().get(kind)?.roles.fixed(params)
}

/// Problems with a stage's resolved inputs against its kind's roles: (message, help).
pub fn check_roles(kind: &str, params: &Json, inputs: &[(String, Vec<String>)]) -> Vec<(String, String)> {
    let Some(k) = crate::stages::registry().get(kind).copied() else {
        return vec![];
    };
    if let Roles::Named(read) = k.roles {
        return read(params).map(|r| free_roles(kind, &r, inputs)).unwrap_or_default();
    }
    let Some(want) = roles(kind, params) else { return vec![] };
    let allowed = if want.is_empty() {
        "none (this kind reads no inputs)".to_string()
    } else {
        want.iter().map(|(r, _)| *r).collect::<Vec<_>>().join(", ")
    };
    let mut out = Vec::new();
    for (role, ids) in inputs {
        match want.iter().find(|(r, _)| r == role) {
            None => out.push((
                format!("input role `{role}` is not read by kind `{kind}`"),
                format!("roles of `{kind}`: {allowed}; write `inputs: {{ ROLE: STAGE }}`"),
            )),
            Some((_, Arity::One | Arity::OptionalOne)) if ids.len() != 1 => out.push((
                format!(
                    "input `{role}` must name exactly one stage (it names {}: {})",
                    ids.len(),
                    ids.join(", ")
                ),
                "name one stage, or one matrix member (e.g. `col-dem-prep-a0.4`)".into(),
            )),
            _ => {}
        }
    }
    for (role, arity) in &want {
        if matches!(arity, Arity::One | Arity::Many) && !inputs.iter().any(|(r, _)| r == role) {
            out.push((
                format!("missing required input `{role}` of kind `{kind}`"),
                format!("add `inputs: {{ {role}: STAGE }}`; roles of `{kind}`: {allowed}"),
            ));
        }
    }
    out
}

/// Kinds whose params name their roles (`plot`, `sweep-compare`): each role the params
/// read must be an input, and each input must be read (an unread role is a typo or a
/// leftover).
fn free_roles(kind: &str, read: &[String], inputs: &[(String, Vec<String>)]) -> Vec<(String, String)> {
    let mut out = Vec::new();
    for r in read {
        if !inputs.iter().any(|(role, _)| role == r) {
            out.push((
                format!("the {kind} stage reads role `{r}`, which is not under `inputs:`"),
                format!("add `inputs: {{ {r}: STAGE }}` (a matrix base id fans in all its members)"),
            ));
        }
    }
    for (role, _) in inputs {
        if !read.contains(role) {
            out.push((
                format!("input role `{role}` is not read by the {kind} stage's params"),
                format!("roles it reads: {}; remove the input or use it", read.join(", ")),
            ));
        }
    }
    out
}

/// One message per root cause: the same problem found in several stages (a bad value in
/// a shared stage file, or in both profiles) is printed once, naming every stage.
pub fn dedupe(d: Diagnostics) -> Diagnostics {
    // Group on (file, line, key without the stage prefix, message).
    let mut groups: BTreeMap<(String, Option<usize>, String, String), (usize, Vec<String>, Diagnostic)> =
        BTreeMap::new();
    for (i, x) in d.0.into_iter().enumerate() {
        let (stage, rest) = split_stage_key(&x.key);
        let g = groups
            .entry((x.file.display().to_string(), x.line, rest.clone(), x.message.clone()))
            .or_insert_with(|| (i, Vec::new(), x.clone()));
        if let Some(s) = stage
            && !g.1.contains(&s)
        {
            g.1.push(s);
        }
    }
    let mut v: Vec<(usize, Diagnostic)> = groups
        .into_values()
        .map(|(i, stages, mut x)| {
            if stages.len() > 1 {
                let (_, rest) = split_stage_key(&x.key);
                x.key = format!("stages[{}]{rest}", stages.join(", "));
            }
            (i, x)
        })
        .collect();
    v.sort_by_key(|(i, _)| *i);
    Diagnostics(v.into_iter().map(|(_, x)| x).collect())
}

/// `stages[ID].rest` → (Some(ID), ".rest"); anything else → (None, key).
fn split_stage_key(key: &str) -> (Option<String>, String) {
    if let Some(inner) = key.strip_prefix("stages[")
        && let Some(end) = inner.find(']')
    {
        return (Some(inner[..end].to_string()), inner[end + 1..].to_string());
    }
    (None, key.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids() {
        for ok in ["psd-col", "col-dem-prep-a0.4", "A_1", "0x"] {
            assert!(check_id(ok).is_ok(), "{ok}");
        }
        for bad in [
            "",
            "../../../escaped-laws",
            "sub/laws",
            ".hidden",
            "a..b",
            "x\ny",
            "a b",
            "-x",
            "é",
            &"a".repeat(101),
        ] {
            assert!(check_id(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn numbers() {
        let v: Yaml = serde_yaml::from_str(
            "a: .nan\nb: {c: -.inf}\nd: 1e308\ne: 2.5e3\nf: [1.0, .inf]\nseed: 18446744073709551615",
        )
        .unwrap();
        let keys: Vec<String> = bad_numbers(&v).into_iter().map(|b| b.0).collect();
        assert_eq!(keys, ["a", "b.c", "d", "f[1]"]);
    }

    #[test]
    fn role_table() {
        let p = serde_json::json!({});
        assert!(check_roles("psd-figure", &p, &[("psd".into(), vec!["x".into()])]).is_empty());
        assert_eq!(check_roles("psd-figure", &p, &[]).len(), 1);
        assert_eq!(check_roles("psd", &p, &[("psd".into(), vec!["x".into()])]).len(), 1);
        assert!(check_roles("dem-column-prep", &serde_json::json!({"packing": "hex"}), &[]).is_empty());
        assert_eq!(
            check_roles("dem-shear", &p, &[("psd".into(), vec!["a".into(), "b".into()])]).len(),
            1
        );
        let dem = serde_json::json!({"method": "dem"});
        assert!(check_roles("column-collapse", &dem, &[("column".into(), vec!["a".into()])]).is_empty());
        let mpm = serde_json::json!({"method": "mpm"});
        assert_eq!(
            check_roles("column-collapse", &mpm, &[("column".into(), vec!["a".into()])]).len(),
            1
        );
    }
}

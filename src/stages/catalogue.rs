//! The kind tables of the documentation, generated from the kinds' own declarations
//! ([`super::kind::Kind`]): the roles table and the kinds table of `docs/pipeline.md`, and
//! the reference of what each kind publishes, `docs/kinds.md`. `tests/kinds_doc.rs` checks
//! that the files hold what this module generates (`GRANREPRO_UPDATE_DOCS=1` rewrites
//! them).

use std::fmt::Write;

use super::kind::{Kind, Roles};
use crate::pipeline::context::Arity;

/// Marks around the generated part of a document.
pub fn marks(name: &str) -> (String, String) {
    (
        format!("<!-- generated: {name} (from the kinds' declarations; do not edit by hand) -->"),
        format!("<!-- end generated: {name} -->"),
    )
}

/// A kind's roles, as the docs show them: required roles bold.
pub fn roles_text(k: &Kind) -> String {
    let show = |r: &[(&str, Arity)]| {
        if r.is_empty() {
            return "none".to_string();
        }
        r.iter()
            .map(|(name, a)| match a {
                Arity::One => format!("**`{name}`**"),
                Arity::Many => format!("**`{name}`** (one or more)"),
                Arity::OptionalOne => format!("`{name}`"),
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    match k.roles {
        Roles::Fixed(r) => show(r),
        Roles::ByParams(f) => format!("{} (by params)", show(&f(&serde_json::json!({})))),
        Roles::ByMethod(by) => by
            .iter()
            .map(|(m, r)| format!("{}: {}", m.key(), if r.is_empty() { "none".into() } else { show(r) }))
            .collect::<Vec<_>>()
            .join("; "),
        Roles::Named(_) => "free names: exactly the roles its params read".to_string(),
    }
}

/// A kind's top-level parameters (from its schema's defaults; required ones named by the
/// schema when it has no default for them).
pub fn params_text(k: &Kind) -> String {
    match (k.params)(&serde_json::json!({})) {
        Ok(serde_json::Value::Object(m)) if !m.is_empty() => {
            m.keys().map(|x| format!("`{x}`")).collect::<Vec<_>>().join(", ")
        }
        Ok(_) => "none".to_string(),
        Err(problems) => {
            let need: Vec<String> = problems
                .iter()
                .filter_map(|p| p.message.split('`').nth(1).map(|f| format!("`{f}`")))
                .collect();
            if need.is_empty() {
                "see the kind's params struct".to_string()
            } else {
                format!("required: {}", need.join(", "))
            }
        }
    }
}

fn cell(s: &str) -> String {
    s.replace('|', "\\|")
}

/// The kinds table of `docs/pipeline.md`.
pub fn kinds_table(kinds: &[Kind]) -> String {
    let mut s =
        String::from("| kind | v | what it does | inputs (required **bold**) | estimate |\n|---|---|---|---|---|\n");
    for k in kinds {
        let _ = writeln!(
            s,
            "| [`{n}`](kinds.md#{n}) | {} | {} | {} | {} |",
            k.version,
            cell(k.about),
            roles_text(k),
            if k.cost.is_some() { "cost model" } else { "as measured" },
            n = k.name,
        );
    }
    s
}

/// `docs/kinds.md`: each kind's roles and everything it publishes by name.
pub fn reference(kinds: &[Kind]) -> String {
    let mut s = String::from(
        "# Stage kinds: what each reads and publishes\n\n\
         Generated from each kind's declaration in `src/stages/` (`Kind { roles, outputs, reads, cost }`); \
         `tests/kinds_doc.rs` keeps it current. A `plot`, `sweep-compare`, `power-law-fit` or \
         `snapshot` stage may name only what its inputs publish here, and so may a row of \
         `stages/ledger.yaml`: anything else is refused at load, before any stage runs. A name \
         ending in `*` is a family (`x*`: every name that starts with `x`).\n",
    );
    for k in kinds {
        let o = &k.outputs;
        let _ = write!(
            s,
            "\n## {}\n\nv{} · {}\n\n- params: {}\n- inputs: {}\n",
            k.name,
            k.version,
            k.about,
            params_text(k),
            roles_text(k)
        );
        let list = |v: &[&str]| v.iter().map(|x| format!("`{x}`")).collect::<Vec<_>>().join(", ");
        if !o.scalars.is_empty() {
            let _ = writeln!(s, "- scalars: {}", list(o.scalars));
        }
        for t in o.tables {
            let _ = writeln!(s, "- table `{}`: {}", t.name, list(t.columns));
        }
        if !o.measurements.is_empty() {
            let _ = writeln!(s, "- measurements: {}", list(o.measurements));
        }
        if !o.texts.is_empty() {
            let _ = writeln!(s, "- texts: {}", list(o.texts));
        }
        if o.scalars.is_empty() && o.tables.is_empty() && o.measurements.is_empty() && o.texts.is_empty() {
            s.push_str("- publishes figures only\n");
        }
    }
    s
}

/// Replace the generated part `name` of `doc` by `body` (None when the marks are missing).
pub fn splice(doc: &str, name: &str, body: &str) -> Option<String> {
    let (begin, end) = marks(name);
    let a = doc.find(&begin)? + begin.len();
    let b = doc[a..].find(&end)? + a;
    Some(format!("{}\n{}{}", &doc[..a], body, &doc[b..]))
}

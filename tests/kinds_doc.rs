//! Contract: the kind tables of `docs/pipeline.md` and the reference `docs/kinds.md` are
//! what the kinds declare (`src/stages/catalogue.rs` generates them). A kind added,
//! renamed or given a new role or output without its documentation fails here; run with
//! `GRANREPRO_UPDATE_DOCS=1` to rewrite the generated parts.

use granrepro::stages::{catalogue, registry};

fn current(path: &str, want: &str) {
    let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(path);
    let have = std::fs::read_to_string(&file).unwrap_or_default();
    if have == want {
        return;
    }
    if std::env::var_os("GRANREPRO_UPDATE_DOCS").is_some() {
        std::fs::write(&file, want).unwrap();
        return;
    }
    panic!("{path} is not what the kinds declare: run `GRANREPRO_UPDATE_DOCS=1 cargo test --test kinds_doc`");
}

#[test]
fn the_kind_documents_are_current() {
    let kinds: Vec<_> = registry().into_values().collect();
    current("docs/kinds.md", &catalogue::reference(&kinds));
    let path = "docs/pipeline.md";
    let doc = std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(path)).unwrap();
    let spliced = catalogue::splice(&doc, "kinds", &catalogue::kinds_table(&kinds))
        .expect("docs/pipeline.md has the generated `kinds` marks");
    current(path, &spliced);
}

#[test]
fn every_solver_kind_declares_its_cost() {
    // A kind with a pre-flight stability table runs a solver: `plan --estimate` must be
    // able to scale its measured quick time to another profile.
    for (name, k) in registry() {
        assert!(!k.about.is_empty(), "kind `{name}` has no `about`");
        assert!(
            k.explain.is_none() || k.cost.is_some(),
            "solver kind `{name}` declares no cost model"
        );
    }
}

/// Every measurement a kind's own file pushes with a literal id (`out.claims.push(Claim::…(
/// "id"`) is in its declared outputs, whichever branch pushes it. The check the runner
/// makes after a stage runs caught `dem-pile-prep`'s `height` only at the paper profile's
/// 13,000 grains, after 65 CPU-minutes: the branch never runs at quick size.
#[test]
fn every_literal_measurement_a_kind_pushes_is_declared() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut missing = Vec::new();
    for (name, k) in registry::registry() {
        let Ok(src) = std::fs::read_to_string(root.join(k.source)) else {
            continue;
        };
        let mut rest = src.as_str();
        while let Some(i) = rest.find("out.claims.push(") {
            rest = &rest[i + "out.claims.push(".len()..];
            let t = rest.trim_start();
            let Some(t) = t.strip_prefix("Claim::") else { continue };
            let Some(open) = t.find('(') else { continue };
            let arg = t[open + 1..].trim_start();
            let Some(arg) = arg.strip_prefix('"') else { continue }; // a formatted id
            let id = &arg[..arg.find('"').unwrap_or(0)];
            if !k
                .outputs
                .measurements
                .iter()
                .any(|d| granrepro::stages::kind::covers(d, id))
            {
                missing.push(format!("{name} ({}): measurement `{id}`", k.source));
            }
        }
    }
    assert!(
        missing.is_empty(),
        "pushed but not declared in the kind's outputs:\n{}",
        missing.join("\n")
    );
}

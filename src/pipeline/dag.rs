//! The stage graph: the closure of stages a target needs, and DOT / Mermaid renderings
//! (the topological order itself is [`super::order`]).

use std::collections::BTreeSet;

use super::spec::Pipeline;

/// The target that names the chapter's headline results: the stages the claims ledger's
/// headline rows read (`headline:` in `stages/ledger.yaml`, both sides of a comparison and
/// every ensemble member present in the profile). A stage of that id takes precedence.
pub const HEADLINE: &str = "headline";

/// The stages a target names: a stage, the members of a matrix base id, or [`HEADLINE`].
pub fn members(p: &Pipeline, target: &str) -> Vec<String> {
    let m = p.members(target);
    if !m.is_empty() || target != HEADLINE {
        return m.into_iter().map(str::to_string).collect();
    }
    let Ok(Some((ledger, ..))) = crate::claims::ledger::read(&p.root) else {
        return vec![];
    };
    let read: BTreeSet<&str> = ledger
        .claims
        .iter()
        .filter(|r| r.headline.is_some())
        .flat_map(|r| r.measure.all_stages())
        .collect();
    p.stages
        .iter()
        .filter(|s| read.contains(s.id.as_str()))
        .map(|s| s.id.clone())
        .collect()
}

/// Ids (in topological order) of `targets` and everything they need. Empty targets =
/// the whole pipeline but its on-demand studies (`on_demand: true`, run only when named).
/// Unknown targets are returned as the error.
pub fn closure(p: &Pipeline, targets: &[String]) -> Result<Vec<String>, Vec<String>> {
    if targets.is_empty() {
        return Ok(p.stages.iter().filter(|s| !s.on_demand).map(|s| s.id.clone()).collect());
    }
    let mut want: BTreeSet<String> = BTreeSet::new();
    let mut unknown = Vec::new();
    let mut stack: Vec<String> = Vec::new();
    for t in targets {
        let m = members(p, t);
        if m.is_empty() {
            unknown.push(t.clone());
        }
        stack.extend(m);
    }
    if !unknown.is_empty() {
        return Err(unknown);
    }
    while let Some(id) = stack.pop() {
        if want.insert(id.clone())
            && let Some(s) = p.get(&id)
        {
            for (_, ids) in &s.inputs {
                stack.extend(ids.iter().cloned());
            }
        }
    }
    Ok(p.stages
        .iter()
        .filter(|s| want.contains(&s.id))
        .map(|s| s.id.clone())
        .collect())
}

/// The reverse edges: each stage id to the ids of the stages that read it, in pipeline
/// order.
pub fn readers(p: &Pipeline) -> std::collections::BTreeMap<String, Vec<String>> {
    let mut out: std::collections::BTreeMap<String, Vec<String>> = Default::default();
    for s in &p.stages {
        for (_, ids) in &s.inputs {
            for id in ids {
                out.entry(id.clone()).or_default().push(s.id.clone());
            }
        }
    }
    out
}

fn quote(s: &str) -> String {
    s.replace('"', "\\\"")
}

/// Graphviz DOT of the pipeline (edges point from input to consumer).
pub fn to_dot(p: &Pipeline) -> String {
    let mut s = String::from("digraph granrepro {\n  rankdir=LR;\n  node [shape=box, fontname=\"Helvetica\"];\n");
    for st in &p.stages {
        s.push_str(&format!(
            "  \"{}\" [label=\"{}\\n({})\"];\n",
            quote(&st.id),
            quote(&st.id),
            quote(&st.kind)
        ));
    }
    for st in &p.stages {
        for (_, ids) in &st.inputs {
            for d in ids {
                s.push_str(&format!("  \"{}\" -> \"{}\";\n", quote(d), quote(&st.id)));
            }
        }
    }
    s.push_str("}\n");
    s
}

/// Mermaid flowchart of the pipeline.
pub fn to_mermaid(p: &Pipeline) -> String {
    let node = |id: &str| id.replace(|c: char| !c.is_ascii_alphanumeric(), "_");
    let mut s = String::from("flowchart LR\n");
    for st in &p.stages {
        s.push_str(&format!("  {}[\"{} ({})\"]\n", node(&st.id), st.id, st.kind));
    }
    for st in &p.stages {
        for (_, ids) in &st.inputs {
            for d in ids {
                s.push_str(&format!("  {} --> {}\n", node(d), node(&st.id)));
            }
        }
    }
    s
}

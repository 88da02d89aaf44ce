//! The stage graph: topological order (with the cycle named when there is one), the
//! closure of stages a target needs, and DOT / Mermaid renderings.

use std::collections::{BTreeSet, HashMap};

use super::spec::{Pipeline, Stage};

/// Topological order of `stages` (indices), inputs first, ties broken by file order.
/// On a cycle, returns the ids along it (first id repeated at the end).
pub fn topo_order(stages: &[Stage]) -> Result<Vec<usize>, Vec<String>> {
    let idx: HashMap<&str, usize> = stages.iter().enumerate().map(|(i, s)| (s.id.as_str(), i)).collect();
    let deps: Vec<Vec<usize>> = stages
        .iter()
        .map(|s| {
            s.inputs
                .iter()
                .flat_map(|(_, ids)| ids.iter())
                .filter_map(|d| idx.get(d.as_str()).copied())
                .collect()
        })
        .collect();
    // 0 = unvisited, 1 = on stack, 2 = done. Iterative DFS keeps file order stable.
    let mut state = vec![0u8; stages.len()];
    let mut order = Vec::with_capacity(stages.len());
    for root in 0..stages.len() {
        if state[root] != 0 {
            continue;
        }
        let mut stack: Vec<(usize, usize)> = vec![(root, 0)];
        state[root] = 1;
        while let Some(&mut (node, ref mut next)) = stack.last_mut() {
            if *next < deps[node].len() {
                let d = deps[node][*next];
                *next += 1;
                match state[d] {
                    0 => {
                        state[d] = 1;
                        stack.push((d, 0));
                    }
                    1 => {
                        let pos = stack.iter().position(|&(n, _)| n == d).unwrap();
                        let mut cycle: Vec<String> = stack[pos..].iter().map(|&(n, _)| stages[n].id.clone()).collect();
                        // The stack runs consumer → input; print it in data-flow order.
                        cycle.reverse();
                        cycle.push(cycle[0].clone());
                        return Err(cycle);
                    }
                    _ => {}
                }
            } else {
                state[node] = 2;
                order.push(node);
                stack.pop();
            }
        }
    }
    Ok(order)
}

/// Ids (in topological order) of `targets` and everything they need. Empty targets =
/// the whole pipeline. Unknown targets are returned as the error.
pub fn closure(p: &Pipeline, targets: &[String]) -> Result<Vec<String>, Vec<String>> {
    if targets.is_empty() {
        return Ok(p.stages.iter().map(|s| s.id.clone()).collect());
    }
    let mut want: BTreeSet<String> = BTreeSet::new();
    let mut unknown = Vec::new();
    let mut stack: Vec<String> = Vec::new();
    for t in targets {
        let m = p.members(t);
        if m.is_empty() {
            unknown.push(t.clone());
        }
        stack.extend(m.into_iter().map(str::to_string));
    }
    if !unknown.is_empty() {
        return Err(unknown);
    }
    while let Some(id) = stack.pop() {
        if want.insert(id.clone()) {
            if let Some(s) = p.get(&id) {
                for (_, ids) in &s.inputs {
                    stack.extend(ids.iter().cloned());
                }
            }
        }
    }
    Ok(p.stages
        .iter()
        .filter(|s| want.contains(&s.id))
        .map(|s| s.id.clone())
        .collect())
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

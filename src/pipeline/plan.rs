//! `granrepro plan`: the stages a target needs, in a valid order (inputs first), with
//! their cache keys, their inputs and whether the cache already holds them — for Slurm
//! job arrays, Snakemake (see [`super::export`]) or any other engine. The keys and the
//! cached/would-run verdicts are the dry run's (`run --dry-run`), not a second
//! computation.

use serde_json::{Value, json};

use super::run::{Outcome, Project, RunError, RunOptions, run};
use super::spec::Pipeline;

/// One stage of a plan.
#[derive(Debug, Clone, PartialEq)]
pub struct Planned {
    /// Stage id.
    pub id: String,
    /// Stage kind.
    pub kind: String,
    /// Cache key (depends on the keys of every input).
    pub key: String,
    /// Ids of the stages it reads (all earlier in the plan).
    pub inputs: Vec<String>,
    /// Is a valid entry for `key` in the cache now?
    pub cached: bool,
    /// Why it would run (`never ran`, what changed), when not cached.
    pub why: Option<String>,
}

/// The stages `targets` need (all when empty), inputs first, with keys. Unknown targets
/// are a [`RunError::BadInput`].
pub fn plan(p: &Pipeline, proj: &Project, targets: &[String]) -> Result<Vec<Planned>, RunError> {
    let opts = RunOptions {
        targets: targets.to_vec(),
        dry_run: true,
        jobs: 1,
        quiet: true,
        ..RunOptions::default()
    };
    let summary = run(p, proj, &opts)?;
    Ok(summary
        .stages
        .into_iter()
        .map(|s| {
            let st = p.get(&s.id).expect("planned stage is in the pipeline");
            let (cached, why) = match s.outcome {
                Outcome::Cached => (true, None),
                Outcome::WouldRun(w) => (false, Some(w)),
                Outcome::Served(from) => (true, Some(format!("served {from}"))),
                other => (false, Some(format!("{other:?}"))),
            };
            Planned {
                id: s.id,
                kind: st.kind.clone(),
                key: s.key,
                inputs: st.inputs.iter().flat_map(|(_, v)| v.iter().cloned()).collect(),
                cached,
                why,
            }
        })
        .collect())
}

/// The plan as one JSON document (stable shape: `profile`, `pipeline`, `cache`, `stages`).
pub fn to_json(p: &Pipeline, proj: &Project, stages: &[Planned]) -> Value {
    json!({
        "profile": p.profile,
        "pipeline": abs(&p.path),
        "cache": abs(proj.cache.root()),
        "stages": stages.iter().map(|s| json!({
            "id": s.id, "kind": s.kind, "key": s.key, "inputs": s.inputs,
            "cached": s.cached, "why": s.why,
        })).collect::<Vec<_>>(),
    })
}

fn abs(p: &std::path::Path) -> String {
    std::path::absolute(p)
        .unwrap_or_else(|_| p.to_path_buf())
        .display()
        .to_string()
}

/// The plan as text: one line per stage (order, state, id, key, inputs).
pub fn to_text(stages: &[Planned]) -> String {
    let mut s = String::new();
    for (i, st) in stages.iter().enumerate() {
        let inputs = if st.inputs.is_empty() {
            String::new()
        } else {
            format!("  <- {}", st.inputs.join(", "))
        };
        s.push_str(&format!(
            "{:>3}  {:<9} {:<34} {}{inputs}\n",
            i + 1,
            if st.cached { "cached" } else { "to run" },
            st.id,
            st.key
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: &str = "version: 1\nstages:\n  - id: psd-a\n    kind: psd\n    params: { n: 300, seed: 1 }\n  - id: fig-a\n    kind: psd-figure\n    inputs: { psd: psd-a }\n  - id: laws\n    kind: reference-laws\n";

    #[test]
    fn plan_orders_inputs_first_with_the_run_keys() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("pipeline.yaml");
        std::fs::write(&path, P).unwrap();
        let p = crate::pipeline::load(&path, "quick", &[]).unwrap();
        let proj = Project::new(dir.path());
        let st = plan(&p, &proj, &["fig-a".to_string()]).unwrap();
        let ids: Vec<&str> = st.iter().map(|s| s.id.as_str()).collect();
        assert_eq!(ids, ["psd-a", "fig-a"]);
        let keys = crate::pipeline::run::key_records(&p);
        for s in &st {
            assert_eq!(s.key, keys[&s.id].1);
            assert!(!s.cached);
        }
        assert_eq!(st[1].inputs, ["psd-a"]);
        assert!(matches!(
            plan(&p, &proj, &["nope".to_string()]),
            Err(RunError::BadInput(_))
        ));
    }
}

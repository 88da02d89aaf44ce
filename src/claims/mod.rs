//! The ledger of the chapter's claims (`stages/ledger.yaml`): one row per result the
//! chapter reports, each judged once, here, on the measurement it names.
//!
//! Stages make measurements (their published `measurements`: id, what is measured, our
//! value; and their scalars). They never judge the chapter. A ledger row names:
//! - the chapter's words and value with its stated ±, and the tolerance rule;
//! - its kind: *quantitative* (a number of the chapter our simulation could miss),
//!   *qualitative* (a direction only, "decreases", counted apart) or *check* (a number our
//!   inputs decide: a preparation target, a value tuned to it);
//! - the measurement it reads: a stage (or the members of an ensemble) and one of its
//!   measurements or scalars, with the scalar holding its standard error where the
//!   measurement has one (an OLS fit).
//!
//! [`judge`] turns the rows and the published results into verdicts (mean, spread,
//! reproduced / not resolved / missed) and propagates the *calibrated* flag from the
//! tuned stages up the stage graph. The report's counts and its headline table, the
//! golden snapshot `golden/claims-ledger.snap` and `granrepro claims` all read that one
//! evaluation.

pub mod judge;
pub mod ledger;

use std::collections::BTreeMap;
use std::path::Path;

pub use ledger::{Kind, LEDGER_FILE, Ledger, Measure, Reduced, Row, Tolerance, Tuned, check, read, validate};

/// The profile's stage graph as `id → the stages it reads`.
pub fn graph(p: &crate::pipeline::Pipeline) -> BTreeMap<String, Vec<String>> {
    p.stages
        .iter()
        .map(|s| {
            (
                s.id.clone(),
                s.inputs.iter().flat_map(|(_, v)| v.iter().cloned()).collect(),
            )
        })
        .collect()
}

/// Judge the ledger of `p`'s project on the results published in `dir`
/// (`reports/<profile>`); None when the project has no ledger (or it cannot be read: the
/// loader has refused it before anything ran).
pub fn evaluate_dir(p: &crate::pipeline::Pipeline, dir: &Path) -> Option<Vec<judge::Judged>> {
    let (l, ..) = read(&p.root).ok()??;
    // each published result read once (the rows read a stage several times)
    let published: BTreeMap<&str, serde_json::Value> = p
        .stages
        .iter()
        .filter_map(|s| {
            let b = std::fs::read(dir.join(format!("{}.json", s.id))).ok()?;
            Some((s.id.as_str(), serde_json::from_slice(&b).ok()?))
        })
        .collect();
    let read_result = |id: &str| published.get(id).cloned();
    let ancestors = judge::ancestors(&graph(p));
    let mut j = judge::judge(&l, &read_result, &ancestors);
    mark_reduced(&mut j, &l.reduced, &p.profile, &ancestors);
    // The ledger's diagnoses were written on the quick profile's results: at another
    // profile they are shown as such, never as that profile's own diagnosis, unless the
    // row has one examined there (`diagnosis_at`).
    if p.profile != "quick" {
        for r in &mut j {
            if let Some(d) = r.row.diagnosis_at.get(&p.profile) {
                r.row.diagnosis = Some(d.clone());
            } else if let Some(d) = &r.row.diagnosis {
                r.row.diagnosis = Some(format!(
                    "diagnosed at the quick size, not yet re-examined at the {} size: {d}",
                    p.profile
                ));
            }
        }
    }
    Some(j)
}

/// Mark the rows that read a scene `profile` runs reduced (or a stage downstream of one):
/// their verdicts test the pipeline at that size, not the chapter.
pub fn mark_reduced(
    j: &mut [judge::Judged],
    reduced: &[Reduced],
    profile: &str,
    ancestors: &BTreeMap<String, std::collections::BTreeSet<String>>,
) {
    for r in j.iter_mut() {
        let mut why: Vec<judge::NotComparable> = Vec::new();
        for s in r.row.measure.all_stages() {
            for anc in ancestors.get(s).into_iter().flatten() {
                for e in reduced.iter().filter(|e| e.profile == profile && e.matches(anc)) {
                    if !why.iter().any(|w| w.scene == e.scene) {
                        why.push(judge::NotComparable {
                            scene: e.scene.clone(),
                            why: e.why.clone(),
                        });
                    }
                }
            }
        }
        r.not_comparable = why;
    }
}

//! `granrepro status`: each stage of the profile fresh in the cache, stale (with the
//! reasons: which params, versions or inputs changed) or missing. The committed results
//! (`results/<profile>/`) have their own states (`super::store::status`).

use serde_json::Value;

use super::cache::KeyRecord;
use super::keys::{key_records, stale_reasons};
use super::project::Project;
use super::spec::Pipeline;

/// Freshness of one stage, for `status`.
#[derive(Debug, Clone)]
pub enum Freshness {
    /// Cached entry valid for the current key.
    Fresh,
    /// Ran before with other inputs; the reasons.
    Stale(Vec<String>),
    /// Never ran (or the entry is gone).
    Missing,
}

/// Status of every stage.
pub fn status(p: &Pipeline, proj: &Project) -> Vec<(String, Freshness)> {
    let keys = key_records(p);
    p.stages
        .iter()
        .map(|s| {
            let (rec, key) = &keys[&s.id];
            let f = if proj.cache.verify(&proj.cache.entry_dir(key), key).is_ok() {
                match published_elsewhere(proj, &p.profile, &s.id, key) {
                    Some(why) => Freshness::Stale(vec![why]),
                    None => Freshness::Fresh,
                }
            } else {
                match std::fs::read(proj.state_file(&p.profile, &s.id))
                    .ok()
                    .and_then(|b| serde_json::from_slice::<KeyRecord>(&b).ok())
                {
                    Some(old) => Freshness::Stale(stale_reasons(&old, rec)),
                    None => Freshness::Missing,
                }
            };
            (s.id.clone(), f)
        })
        .collect()
}

/// When `reports/` holds another run of a stage than the cache entry `key` (e.g. one
/// made with `--set`), say so: the reports are not what the pipeline now gives.
fn published_elsewhere(proj: &Project, profile: &str, id: &str, key: &str) -> Option<String> {
    let rec: Value =
        serde_json::from_slice(&std::fs::read(proj.report_dir(profile).join(format!("{id}.record.json"))).ok()?)
            .ok()?;
    let published = rec.get("key").and_then(|k| k.as_str())?;
    if published == key {
        return None;
    }
    let over = rec
        .get("overrides")
        .and_then(|o| o.as_array())
        .map(|a| a.iter().filter_map(|x| x.as_str()).collect::<Vec<_>>().join(", "))
        .unwrap_or_default();
    Some(if over.is_empty() {
        "cached, but reports/ hold another run; `granrepro run` publishes this one".to_string()
    } else {
        format!("cached, but reports/ hold a run with --set {over}; `granrepro run` publishes the pipeline's values")
    })
}

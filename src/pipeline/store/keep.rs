//! `granrepro keep`: write `results/<profile>/` from the cache (see the parent module doc).

use std::collections::BTreeMap;
use std::path::Path;

use serde::Serialize;
use serde_json::Value;

use super::{Caps, LOCK, Lock, Locked, PARTIAL, STORE, dir_of, hash_bytes, read_lock, verify};
use crate::pipeline::fsio;
use crate::pipeline::keys::key_records;
use crate::pipeline::project::Project;
use crate::pipeline::publish;
use crate::pipeline::spec::Pipeline;
use crate::provenance::sources;

/// What [`keep`] did.
#[derive(Debug, Default)]
pub struct Kept {
    /// Stages kept from this cache (new or refreshed).
    pub kept: Vec<String>,
    /// Stages whose previously committed files were carried over (no complete entry here).
    pub carried: Vec<String>,
    /// Stages with nothing to keep.
    pub missing: Vec<String>,
    /// Carried stages whose recorded source closure grew to this build's, the files it adds
    /// unchanged since their run ([`super::widen`]).
    pub widened: Vec<String>,
    /// Carried from the former lock but no longer current (stale, changed code, corrupt).
    pub not_current: Vec<String>,
    /// Files left out: (stage, name, bytes).
    pub left_out: Vec<(String, String, u64)>,
    /// Figures over the cap published in their compact form: (stage, name, bytes, compact
    /// bytes).
    pub compacted: Vec<(String, String, u64, u64)>,
    /// Bytes written under `results/<profile>/`.
    pub bytes: u64,
}

/// Where [`keep`] writes and which stages it keeps: the profile's whole run (its stages but
/// the on-demand studies) in `results/<profile>/`, or one on-demand study (the on-demand
/// stages it needs) in `results/<study>/`.
pub fn keep_dir(p: &Pipeline, study: Option<&str>) -> anyhow::Result<(std::path::PathBuf, Vec<String>)> {
    let Some(study) = study else {
        let whole = crate::pipeline::dag::closure(p, &[]).expect("the whole run names no unknown stage");
        return Ok((dir_of(&p.root, &p.profile), whole));
    };
    let named = p.stages.iter().find(|s| s.base_id == study || s.id == study);
    anyhow::ensure!(
        named.is_some_and(|s| s.on_demand),
        "`{study}` is not an on-demand study of {} (profile `{}`)\n  help: `keep --stage` takes a stage declared `on_demand: true`; `keep` alone keeps the profile's run",
        p.path.display(),
        p.profile
    );
    anyhow::ensure!(
        !crate::pipeline::spec::PROFILES.contains(&study),
        "the study `{study}` would be kept in results/{study}/, the directory of the profile `{study}`\n  help: rename the study's stage in {}",
        p.path.display()
    );
    let need = crate::pipeline::dag::closure(p, &[study.to_string()])
        .map_err(|u| anyhow::anyhow!("unknown stage(s): {}", u.join(", ")))?;
    let ids = need
        .into_iter()
        .filter(|id| p.get(id).is_some_and(|s| s.on_demand))
        .collect();
    Ok((p.root.join("results").join(study), ids))
}

/// Write `results/<profile>/` (or `results/<study>/`, see [`keep_dir`]) for every kept stage
/// with a complete cache entry under its current key; other stages keep their committed
/// files. Built beside the old directory and swapped in by renames, so a reader never sees
/// half of it.
pub fn keep(p: &Pipeline, proj: &Project, caps: Caps, study: Option<&str>) -> anyhow::Result<Kept> {
    let (dir, ids) = keep_dir(p, study)?;
    let wanted: std::collections::BTreeSet<&str> = ids.iter().map(String::as_str).collect();
    let old = read_lock(&dir)?.unwrap_or_default();
    let bad = verify(&dir, &old);
    anyhow::ensure!(
        bad.is_empty(),
        "the committed results do not match their lock:\n  {}\n  help: restore {} from version control (`git checkout -- {}`) before keeping new results",
        bad.join("\n  "),
        dir.display(),
        dir.display()
    );
    let keys = key_records(p);
    let kinds = crate::stages::registry::registry();
    let parent = dir.parent().expect("results/<profile> has a parent");
    fsio::create_dir_all(parent)?;
    let staging = tempfile::Builder::new()
        .prefix(&format!(".tmp-{}-", p.profile))
        .tempdir_in(parent)
        .map_err(fsio::err_at("cannot create a temp directory in", parent))?;
    let st = staging.path();
    let publish_dir =
        tempfile::tempdir_in(parent).map_err(fsio::err_at("cannot create a temp directory in", parent))?;
    fsio::create_dir_all(&st.join(STORE))?;
    let errors = atlas_errors(p, proj, &keys);
    let methods = publish::stage_methods(p);
    let measured = publish::Measured {
        methods: &methods,
        profile: &p.profile,
        errors: &errors,
        atlas: p.atlas().map(|a| a.0),
    };
    let mut lock = Lock {
        profile: p.profile.clone(),
        stages: BTreeMap::new(),
        closures: BTreeMap::new(),
    };
    let mut out = Kept::default();
    for s in p.stages.iter().filter(|s| wanted.contains(s.id.as_str())) {
        let (rec, key) = &keys[&s.id];
        let entry = proj.cache.entry_dir(key);
        let complete_here = proj.cache.verify(&entry, key).is_ok() && !entry.join(PARTIAL).exists();
        if complete_here {
            let mut l = Locked {
                key: key.clone(),
                record: rec.clone(),
                store: BTreeMap::new(),
                published: BTreeMap::new(),
                left_out: BTreeMap::new(),
                // The closure the entry was computed by (its run record); an entry older
                // than that record field is locked with this build's.
                sources: {
                    let now = kinds.get(s.kind.as_str()).and_then(|k| sources::closure(k.source));
                    let run = run_record(&entry);
                    match (built_by(run.as_ref()), now) {
                        // recorded by an older closure rule: this build's, where git shows
                        // the files it adds unchanged since the run (super::widen)
                        (Some(rec), Some(now)) => {
                            super::widen::widened(&proj.root, &rec, &now, started_at(run.as_ref())).unwrap_or(rec)
                        }
                        (Some(rec), None) => rec,
                        (None, now) => now.unwrap_or_default(),
                    }
                },
                wall_s: None,
                closure: None,
            };
            store_entry(&entry, &st.join(STORE).join(key), key, caps, &mut l, &mut out, &s.id)?;
            l.wall_s = std::fs::read(entry.join("record.json"))
                .ok()
                .and_then(|b| serde_json::from_slice::<Value>(&b).ok())
                .and_then(|v| v.get("wall_s").and_then(Value::as_f64));
            publish::publish(
                &proj.cache,
                publish_dir.path(),
                &s.id,
                key,
                &s.overrides,
                Some(&measured),
            )?;
            let set = publish_dir.path().join(".sets").join(&s.id);
            for f in sorted_files(&set)? {
                let bytes = fsio::read(&set.join(&f))?;
                let n = bytes.len() as u64;
                let csv_cap = if f.ends_with(".csv") {
                    caps.csv_of(&s.id, &f)
                } else {
                    caps.of(&f)
                };
                if f.ends_with(".parquet") {
                    continue; // the store holds the tables
                }
                let h = hash_bytes(&bytes);
                if store_holds_twin(&s.id, &f, &h, &l.store) {
                    // the store holds the figure or the run record: committed once (listed
                    // with its hash)
                    l.left_out.insert(f.clone(), h);
                    continue;
                }
                // a snapshot figure over the cap: its compact form instead
                if n > csv_cap
                    && !bulky(&f)
                    && let Some(compact) = compact_figure(&f, &bytes, caps.file)
                {
                    l.left_out.insert(f, h);
                    publish_compact(st, &s.id, compact, n, &mut l, &mut out)?;
                    continue;
                }
                if n > csv_cap || bulky(&f) {
                    l.left_out.insert(f.clone(), h);
                    out.left_out.push((s.id.clone(), f, n));
                    continue;
                }
                fsio::write_new(&st.join(&f), &bytes)?;
                l.published.insert(f, h);
                out.bytes += n;
            }
            lock.stages.insert(s.id.clone(), l);
            out.kept.push(s.id.clone());
        } else if let Some(l) = old.stages.get(&s.id) {
            let (from, to) = (dir.join(STORE).join(&l.key), st.join(STORE).join(&l.key));
            let mut l = l.clone();
            if let Some(now) = kinds.get(s.kind.as_str()).and_then(|k| sources::closure(k.source))
                && let Some(w) =
                    super::widen::widened(&proj.root, &l.sources, &now, started_at(run_record(&from).as_ref()))
            {
                l.sources = w;
                out.widened.push(s.id.clone());
            }
            // The figure cap applies to what is carried too: a store figure over it (kept
            // under an older, larger cap) leaves the store, hash kept, and is published in
            // its compact form; the entry's manifest no longer lists it.
            let big: Vec<(String, String)> = l
                .store
                .iter()
                .filter(|(n, _)| {
                    n.ends_with(".svg")
                        && std::fs::metadata(from.join(n.as_str())).map(|m| m.len()).unwrap_or(0) > caps.of(n)
                })
                .map(|(n, h)| (n.clone(), h.clone()))
                .collect();
            for (n, h) in &big {
                let bytes = fsio::read(&from.join(n))?;
                l.store.remove(n);
                l.left_out.insert(format!("{STORE}/{n}"), h.clone());
                let name = publish::published_name(&s.id, n);
                if let Some(compact) = compact_figure(&name, &bytes, caps.file)
                    && !l.published.contains_key(&compact.0)
                {
                    publish_compact(st, &s.id, compact, bytes.len() as u64, &mut l, &mut out)?;
                }
            }
            let manifest = if big.is_empty() {
                None
            } else {
                let mut m: Value = serde_json::from_slice(&fsio::read(&from.join("manifest.json"))?)?;
                if let Some(files) = m.get_mut("files").and_then(Value::as_object_mut) {
                    for (n, _) in &big {
                        files.remove(n);
                    }
                }
                let bytes = serde_json::to_vec_pretty(&m)?;
                l.store.insert("manifest.json".into(), hash_bytes(&bytes));
                Some(bytes)
            };
            if !to.exists() {
                fsio::create_dir_all(&to)?;
                for n in l.store.keys() {
                    match (&manifest, n.as_str()) {
                        (Some(m), "manifest.json") => {
                            fsio::write_new(&to.join(n), m)?;
                            out.bytes += m.len() as u64;
                        }
                        _ => copy(&from.join(n), &to.join(n), &mut out.bytes)?,
                    }
                }
            }
            // The size policy applies to what is carried too: a published CSV over the
            // cap (kept under an older, larger cap) moves to the left-out list, hash kept.
            let published = std::mem::take(&mut l.published);
            for (n, h) in published {
                if st.join(&n).exists() {
                    l.published.insert(n, h); // the compact form written above
                    continue;
                }
                let size = std::fs::metadata(dir.join(&n)).map(|m| m.len()).unwrap_or(0);
                if n.ends_with(".csv") && size > caps.csv_of(&s.id, &n) {
                    out.left_out.push((s.id.clone(), n.clone(), size));
                    l.left_out.insert(n, h);
                    continue;
                }
                if store_holds_twin(&s.id, &n, &h, &l.store) {
                    l.left_out.insert(n, h);
                    continue;
                }
                // a compact form in an earlier layout: compacted again from itself (the
                // same markers; `crate::report::compact`)
                if n.ends_with(".compact.svg") {
                    let bytes = fsio::read(&dir.join(&n))?;
                    let (again, merged) = crate::report::compact::compact_svg(&String::from_utf8_lossy(&bytes));
                    if merged > 0 {
                        fsio::write_new(&st.join(&n), again.as_bytes())?;
                        out.bytes += again.len() as u64;
                        l.published.insert(n, hash_bytes(again.as_bytes()));
                        continue;
                    }
                }
                copy(&dir.join(&n), &st.join(&n), &mut out.bytes)?;
                l.published.insert(n, h);
            }
            lock.stages.insert(s.id.clone(), l);
            out.carried.push(s.id.clone());
        } else {
            out.missing.push(s.id.clone());
        }
    }
    drop(publish_dir);
    // The ledger and the index, judged on what is kept and fresh: a carried result whose
    // key or code changed since is shown as committed, marked, and judges no claim.
    fsio::write_new(&st.join(LOCK), &lock_bytes(&lock)?)?;
    let not_current: BTreeMap<String, String> = super::status(p, st, &lock)
        .into_iter()
        .filter_map(|(id, c)| c.describe().map(|d| (id, d)))
        .collect();
    out.not_current = not_current.keys().cloned().collect();
    // The status above already verified every kept file: judge without a second pass (a
    // study holds no claim of the ledger: not judged).
    let judged = match study {
        None => super::judged_without(p, st, &not_current.keys().cloned().collect()),
        Some(_) => None,
    };
    if let Some(j) = &judged {
        crate::report::ledger::write_files(st, j)?;
    }
    crate::report::html::write_index_of(
        st,
        &p.profile,
        &ids,
        judged.as_deref(),
        None,
        p.atlas(),
        &not_current,
        &crate::pipeline::publish::stage_methods(p),
    )?;
    // Swap: old aside, new in place, old removed.
    let staging = staging.keep();
    let trash = parent.join(format!(
        ".trash-{}-{}-{}",
        p.profile,
        std::process::id(),
        fsio::unique()
    ));
    if dir.exists() {
        std::fs::rename(&dir, &trash).map_err(fsio::err_at("cannot move aside", &dir))?;
    }
    if let Err(e) = std::fs::rename(&staging, &dir) {
        let _ = std::fs::rename(&trash, &dir);
        return Err(fsio::at("cannot move the new results to", &dir, e).into());
    }
    if trash.exists() {
        std::fs::remove_dir_all(&trash).map_err(fsio::err_at("cannot remove", &trash))?;
    }
    Ok(out)
}

/// The run record of the cache entry in `dir`.
fn run_record(dir: &Path) -> Option<Value> {
    serde_json::from_slice(&std::fs::read(dir.join("record.json")).ok()?).ok()
}

/// When the run started [Unix s].
fn started_at(rec: Option<&Value>) -> Option<f64> {
    rec?.get("started_unix_s")?.as_f64()
}

/// The source closure the run recorded.
fn built_by(rec: Option<&Value>) -> Option<BTreeMap<String, String>> {
    serde_json::from_value(rec?.get("sources")?.clone()).ok()
}

/// Copy a cache entry into the store by the size policy, with a manifest of what it kept.
fn store_entry(
    from: &Path,
    to: &Path,
    key: &str,
    caps: Caps,
    l: &mut Locked,
    out: &mut super::Kept,
    id: &str,
) -> anyhow::Result<()> {
    // Two stages with one key (the same work declared twice: calib-prep-a0.4 is
    // col-dem-prep-a0.4) share one store entry, written once.
    let shared = to.exists();
    fsio::create_dir_all(to)?;
    let manifest: Value = serde_json::from_slice(&fsio::read(&from.join("manifest.json"))?)?;
    let files: BTreeMap<String, String> = serde_json::from_value(manifest["files"].clone())?;
    let mut kept = serde_json::Map::new();
    for (name, h) in &files {
        let twin = name.strip_suffix(".csv").map(|b| format!("{b}.parquet"));
        let size = std::fs::metadata(from.join(name)).map(|m| m.len()).unwrap_or(0);
        if twin.is_some_and(|t| files.contains_key(&t)) || bulky(name) || size > caps.of(name) {
            l.left_out.insert(format!("{STORE}/{name}"), h.clone());
            if size > caps.of(name) {
                out.left_out.push((id.to_string(), format!("{STORE}/{name}"), size));
            }
            continue;
        }
        if !shared {
            copy(&from.join(name), &to.join(name), &mut out.bytes)?;
        }
        l.store.insert(name.clone(), h.clone());
        kept.insert(name.clone(), Value::String(h.clone()));
    }
    if let Some(r) = manifest.get("record").and_then(Value::as_str) {
        if !shared {
            copy(&from.join("record.json"), &to.join("record.json"), &mut out.bytes)?;
        }
        l.store.insert("record.json".into(), r.to_string());
    }
    let mut m = manifest.clone();
    m["files"] = Value::Object(kept);
    m["key"] = Value::String(key.to_string());
    let bytes = serde_json::to_vec_pretty(&m)?;
    if !shared {
        fsio::write_new(&to.join("manifest.json"), &bytes)?;
        out.bytes += bytes.len() as u64;
    }
    l.store.insert("manifest.json".into(), hash_bytes(&bytes));
    Ok(())
}

/// A published figure over the size cap as its compact form (`ID.compact.svg` for `ID.svg`;
/// `crate::report::compact`), when that has markers to merge and fits under `cap`.
fn compact_figure(name: &str, bytes: &[u8], cap: u64) -> Option<(String, Vec<u8>)> {
    let stem = name.strip_suffix(".svg")?;
    let text = std::str::from_utf8(bytes).ok()?;
    let (small, merged) = crate::report::compact::compact_svg(text);
    (merged > 0 && (small.len() as u64) <= cap).then(|| (format!("{stem}.compact.svg"), small.into_bytes()))
}

/// Does the store keep what `published` (a file of stage `id`, of hash `hash`) is the twin
/// of (`crate::pipeline::publish::published_name`)? A figure: its stamped twin (the footer
/// differs, the index shows the store's copy). The run record `ID.record.json`: the
/// store's `record.json` byte for byte (a record stamped with overrides differs, and is
/// published).
fn store_holds_twin(id: &str, published: &str, hash: &str, store: &BTreeMap<String, String>) -> bool {
    if published == publish::published_name(id, "record.json") {
        return store.get("record.json").is_some_and(|h| h == hash);
    }
    published.ends_with(".svg")
        && store
            .keys()
            .any(|n| n.ends_with(".svg") && publish::published_name(id, n) == published)
}

/// Publish `small`, the compact form `name` of a figure of stage `id` that was `size` bytes.
fn publish_compact(
    st: &Path,
    id: &str,
    (name, small): (String, Vec<u8>),
    size: u64,
    l: &mut Locked,
    out: &mut Kept,
) -> anyhow::Result<()> {
    fsio::write_new(&st.join(&name), &small)?;
    out.bytes += small.len() as u64;
    out.compacted
        .push((id.to_string(), name.clone(), size, small.len() as u64));
    l.published.insert(name, hash_bytes(&small));
    Ok(())
}

/// Per-particle snapshot tables and per-instant field files: left out whatever their size
/// (regenerated by running the stage; the figures drawn from them are kept).
fn bulky(name: &str) -> bool {
    name.contains("snapshots.")
        || name.ends_with("-snapshots.csv")
        || [".vtp", ".vtu", ".vtk", ".pvd"].iter().any(|e| name.ends_with(e))
}

fn copy(from: &Path, to: &Path, bytes: &mut u64) -> anyhow::Result<()> {
    let b = fsio::read(from)?;
    *bytes += b.len() as u64;
    fsio::write_new(to, &b)?;
    Ok(())
}

fn sorted_files(dir: &Path) -> anyhow::Result<Vec<String>> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .map_err(fsio::err_at("cannot read", dir))?
        .flatten()
        .filter(|e| e.path().is_file())
        .map(|e| e.file_name().to_string_lossy().to_string())
        .collect();
    v.sort();
    Ok(v)
}

/// The profile's measured errors for the figures' footers: the atlas stage's table.
fn atlas_errors(
    p: &Pipeline,
    proj: &Project,
    keys: &std::collections::HashMap<String, (crate::pipeline::cache::KeyRecord, String)>,
) -> crate::report::measured::ProfileErrors {
    p.atlas()
        .and_then(|(id, table)| {
            std::fs::read_to_string(proj.cache.entry_dir(&keys[id].1).join(format!("{table}.csv"))).ok()
        })
        .map(|t| crate::report::measured::parse_profile_csv(&t))
        .unwrap_or_default()
}

/// The lock as written: JSON indented by one space per level, one key per line as before (a
/// diff reviewers can read), about 85 % of the two-space form: the lock is the largest
/// file of the committed results after the figures.
fn lock_bytes(lock: &Lock) -> anyhow::Result<Vec<u8>> {
    let mut out = Vec::new();
    let mut ser = serde_json::Serializer::with_formatter(&mut out, serde_json::ser::PrettyFormatter::with_indent(b" "));
    lock.packed().serialize(&mut ser)?;
    Ok(out)
}

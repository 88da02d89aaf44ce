//! Publishing a stage's outputs to `reports/<profile>/` as one set.
//!
//! Layout (for stage `X` of profile `P`, in `D = reports/P`):
//! - `D/.sets/X@<content-id>/`: one published set — `X.csv`, `X.parquet`, `X.svg`,
//!   `X.json`, `X.record.json`, `X-NAME` — written completely before it is used;
//! - `D/.sets/X`: a symlink naming the current set, switched by one atomic rename;
//! - `D/X.csv`, `D/X.json`, …: symlinks `.sets/X/X.csv`, … (stable once created).
//!
//! So every path under `D` shows one run's files: switching the set switches all of them
//! at once. A reader that wants several files of one set with no switch in between
//! resolves `D/.sets/X` once (readlink) and reads inside that directory; the previous set
//! is kept until the next switch for readers that resolved it just before.
//! Only files listed in the cache entry's manifest are published; files granrepro did
//! not make are never touched.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::io;
use std::path::{Path, PathBuf};

use serde_json::Value;

use super::cache::Cache;
use super::fsio;

/// Directory of the published sets inside a profile's report directory.
pub const SETS: &str = ".sets";

/// Published name of an entry file for stage `id`.
pub(crate) fn published_name(id: &str, file: &str) -> String {
    match file {
        "result.json" => format!("{id}.json"),
        "record.json" => format!("{id}.record.json"),
        "table.parquet" => format!("{id}.parquet"),
        "table.csv" => format!("{id}.csv"),
        "figure.svg" => format!("{id}.svg"),
        other => format!("{id}-{other}"),
    }
}

/// `--set` overrides of a stage, as `key=value` strings, stamped on what is published.
fn stamp(file: &str, id: &str, bytes: Vec<u8>, overrides: &[String], path: &Path) -> io::Result<Vec<u8>> {
    if file.ends_with(".svg") && !overrides.is_empty() {
        return Ok(mark_svg(bytes, overrides));
    }
    if file != "result.json" && file != "record.json" {
        return Ok(bytes);
    }
    let mut v: Value =
        serde_json::from_slice(&bytes).map_err(|e| fsio::at("cannot parse", path, io::Error::other(e)))?;
    if file == "result.json" {
        // The entry may be shared by stages doing the same work: stamp our id.
        v["stage"] = Value::String(id.to_string());
    }
    if !overrides.is_empty() {
        v["overrides"] = serde_json::json!(overrides);
        if file == "record.json" {
            let note = format!(
                "OVERRIDDEN on the command line (--set): {} — not the values in pipeline.yaml",
                overrides.join(", ")
            );
            match v.get_mut("notes").and_then(|n| n.as_array_mut()) {
                Some(a) => a.insert(0, Value::String(note)),
                None => v["notes"] = serde_json::json!([note]),
            }
        }
    }
    serde_json::to_vec_pretty(&v).map_err(|e| fsio::at("cannot serialize", path, io::Error::other(e)))
}

/// Write "OVERRIDDEN (--set …)" in red across the top of a published figure.
fn mark_svg(bytes: Vec<u8>, overrides: &[String]) -> Vec<u8> {
    let Ok(text) = String::from_utf8(bytes.clone()) else {
        return bytes;
    };
    let Some(end) = text.rfind("</svg>") else { return bytes };
    let esc = |s: &str| s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;");
    let mark = format!(
        "<text x=\"6\" y=\"14\" font-family=\"sans-serif\" font-size=\"12\" fill=\"#b00020\">OVERRIDDEN (--set {}): not the values in pipeline.yaml</text>\n",
        esc(&overrides.join(", "))
    );
    let mut out = text[..end].to_string();
    out.push_str(&mark);
    out.push_str(&text[end..]);
    out.into_bytes()
}

/// The profile's measured errors (from the `wp-summary` stage) to stamp on what is
/// published: a footer line under every figure and a `measured` block in `ID.json`
/// (`crate::report::measured`).
pub struct Measured<'a> {
    /// Profile name.
    pub profile: &'a str,
    /// Methods each stage's numbers come from ([`stage_methods`]).
    pub methods: &'a HashMap<String, Vec<&'static str>>,
    /// Method → its measured error at the profile's setting.
    pub errors: &'a crate::report::measured::ProfileErrors,
    /// The atlas stage the errors come from: its own numbers are no method's simulation.
    pub atlas: Option<&'a str>,
}

/// The methods each stage's numbers come from, read off the graph: the method its params
/// name (`method:`), else its kind's declared method, else those of the stages feeding its
/// `wp` role (the work-precision study it is stamped with), else the union over its inputs,
/// nearest solver stages first, in input order.
pub fn stage_methods(p: &crate::pipeline::Pipeline) -> HashMap<String, Vec<&'static str>> {
    let mut out: HashMap<String, Vec<&'static str>> = HashMap::new();
    for s in &p.stages {
        // stages are in topological order: every input is already resolved
        let own = s
            .params
            .get("method")
            .and_then(Value::as_str)
            .and_then(crate::engines::Method::parse)
            .or_else(|| p.kinds.get(s.kind.as_str()).and_then(|k| k.method));
        let ms: Vec<&'static str> = if let Some(m) = own {
            vec![m.key()]
        } else {
            let wp: Vec<&String> = s
                .inputs
                .iter()
                .filter(|(r, _)| r == "wp")
                .flat_map(|(_, v)| v)
                .collect();
            let from: Vec<&String> = if wp.is_empty() {
                s.inputs.iter().flat_map(|(_, v)| v).collect()
            } else {
                wp
            };
            let mut v: Vec<&'static str> = Vec::new();
            for id in from {
                for m in out.get(id).into_iter().flatten() {
                    if !v.contains(m) {
                        v.push(m);
                    }
                }
            }
            v
        };
        out.insert(s.id.clone(), ms);
    }
    out
}

/// Publish the cache entry `key` as stage `id`'s set in `dir` (= `reports/<profile>`).
pub fn publish(
    cache: &Cache,
    dir: &Path,
    id: &str,
    key: &str,
    overrides: &[String],
    measured: Option<&Measured>,
) -> io::Result<()> {
    let entry = cache.entry_dir(key);
    let files = cache
        .entry_files(key)
        .map_err(|why| fsio::at("cannot publish the cache entry", &entry, io::Error::other(why)))?;
    // the stage's methods, from the pipeline's graph
    let stamp_of = measured.map(|m| {
        let ms = if m.atlas == Some(id) {
            vec![]
        } else {
            m.methods.get(id).cloned().unwrap_or_default()
        };
        (
            crate::report::measured::footer_line(m.profile, &ms, m.errors),
            crate::report::measured::json_block(m.profile, &ms, m.errors),
        )
    });
    let sets = dir.join(SETS);
    fsio::create_dir_all(&sets)?;
    fsio::set_mode(dir, fsio::DIR_MODE)?;
    let _lock = fsio::lock(&sets.join(".locks").join(format!("{id}.lock")))?;
    // 1. The set's content, in memory (small: tables, figures, JSON).
    let mut content: BTreeMap<String, Vec<u8>> = BTreeMap::new();
    for f in &files {
        let src = entry.join(f);
        let mut bytes = stamp(f, id, fsio::read(&src)?, overrides, &src)?;
        if let Some((line, block)) = &stamp_of {
            if f.ends_with(".svg") {
                bytes = crate::report::measured::stamp_svg(bytes, line);
            } else if f == "result.json" {
                let mut v: Value =
                    serde_json::from_slice(&bytes).map_err(|e| fsio::at("cannot parse", &src, io::Error::other(e)))?;
                v["measured"] = block.clone();
                bytes = serde_json::to_vec_pretty(&v)
                    .map_err(|e| fsio::at("cannot serialize", &src, io::Error::other(e)))?;
            }
        }
        content.insert(published_name(id, f), bytes);
    }
    let mut h = blake3::Hasher::new();
    for (n, b) in &content {
        h.update(n.as_bytes())
            .update(&[0])
            .update(&(b.len() as u64).to_le_bytes())
            .update(b);
    }
    let set_name = format!("{id}@{}", &h.finalize().to_hex()[..16]);
    // 2. Write it completely under a temp name, then give it its final name.
    let set_dir = sets.join(&set_name);
    if !set_dir.is_dir() {
        let staging = sets.join(format!(".tmp-{id}-{}-{}", std::process::id(), fsio::unique()));
        fsio::create_dir_all(&staging)?;
        fsio::set_mode(&staging, fsio::DIR_MODE)?;
        for (n, b) in &content {
            fsio::write_new(&staging.join(n), b)?;
        }
        if let Err(e) = std::fs::rename(&staging, &set_dir) {
            let _ = std::fs::remove_dir_all(&staging);
            if !set_dir.is_dir() {
                return Err(fsio::at(&format!("cannot move {} to", staging.display()), &set_dir, e));
            }
        }
    }
    // 3. Switch the stage's pointer to it (one rename).
    let pointer = sets.join(id);
    let previous = std::fs::read_link(&pointer).ok();
    replace_symlink(Path::new(&set_name), &pointer)?;
    // 4. Stable flat names; drop flat names of files the new set does not have.
    for n in content.keys() {
        let target = Path::new(SETS).join(id).join(n);
        let flat = dir.join(n);
        let current = std::fs::read_link(&flat).ok();
        if let Some(other) = current.as_deref().and_then(owner_of).filter(|o| o != id) {
            // `a` with an extra file `b.csv` and a stage `b` … both publish `a-b.csv`.
            return Err(fsio::at(
                &format!("stage `{id}` cannot publish"),
                &flat,
                io::Error::other(format!(
                    "that name is already published by stage `{other}`; rename one of the stages"
                )),
            ));
        }
        if current.as_deref() != Some(target.as_path()) {
            replace_symlink(&target, &flat)?;
        }
    }
    for (flat, name) in flat_links_of(dir, id) {
        if !content.contains_key(&name) {
            std::fs::remove_file(&flat).map_err(fsio::err_at("cannot remove", &flat))?;
        }
    }
    // 5. Keep the current and the previous set; remove older ones.
    let keep: HashSet<String> = [
        Some(set_name.clone()),
        previous.map(|p| p.to_string_lossy().to_string()),
    ]
    .into_iter()
    .flatten()
    .collect();
    for old in sets_of(&sets, id) {
        if !keep.contains(&old) {
            let p = sets.join(&old);
            std::fs::remove_dir_all(&p).map_err(fsio::err_at("cannot remove", &p))?;
        }
    }
    Ok(())
}

/// Remove staging directories and temp links (`.tmp-*`) older than `age` that killed
/// runs left in `dir` (= `reports/<profile>`) and its `.sets/`; returns how many.
pub fn sweep_stale(dir: &Path, age: std::time::Duration) -> usize {
    let mut n = 0;
    for d in [dir.to_path_buf(), dir.join(SETS)] {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let p = e.path();
            if !e.file_name().to_string_lossy().starts_with(".tmp-") || !fsio::older_than(&p, age) {
                continue;
            }
            let removed = if e.file_type().is_ok_and(|t| t.is_dir()) {
                std::fs::remove_dir_all(&p)
            } else {
                std::fs::remove_file(&p)
            };
            n += usize::from(removed.is_ok());
        }
    }
    n
}

/// Make `link` a symlink to `target`, atomically replacing whatever `link` was.
#[cfg(unix)]
fn replace_symlink(target: &Path, link: &Path) -> io::Result<()> {
    let parent = link.parent().unwrap_or(Path::new("."));
    let tmp = parent.join(format!(".tmp-link-{}-{}", std::process::id(), fsio::unique()));
    std::os::unix::fs::symlink(target, &tmp).map_err(fsio::err_at("cannot create the symlink", &tmp))?;
    std::fs::rename(&tmp, link).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        fsio::at("cannot replace", link, e)
    })
}

#[cfg(not(unix))]
fn replace_symlink(_target: &Path, link: &Path) -> io::Result<()> {
    Err(fsio::at(
        "cannot publish",
        link,
        io::Error::other("publishing reports as a set needs symlinks (a unix system)"),
    ))
}

/// The stage a flat symlink target `.sets/<id>/<file>` belongs to.
fn owner_of(target: &Path) -> Option<String> {
    let rest = target.strip_prefix(SETS).ok()?;
    let mut parts = rest.components();
    let id = parts.next()?.as_os_str().to_string_lossy().to_string();
    (parts.count() == 1).then_some(id)
}

/// Names of the set directories of stage `id` in `sets`.
fn sets_of(sets: &Path, id: &str) -> Vec<String> {
    let prefix = format!("{id}@");
    std::fs::read_dir(sets)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| n.starts_with(&prefix))
        .collect()
}

/// Flat symlinks of `dir` pointing into stage `id`'s current set: (path, file name).
fn flat_links_of(dir: &Path, id: &str) -> Vec<(PathBuf, String)> {
    let prefix = Path::new(SETS).join(id);
    std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let t = std::fs::read_link(e.path()).ok()?;
            let rest = t.strip_prefix(&prefix).ok()?;
            (rest.components().count() == 1).then(|| (e.path(), rest.to_string_lossy().to_string()))
        })
        .collect()
}

/// Ids that have a published set in `dir`.
pub fn published_ids(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir.join(SETS))
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.file_type().is_ok_and(|t| t.is_symlink()))
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| !n.starts_with('.'))
        .collect()
}

/// Withdraw stage `id`'s published outputs (its flat names, pointer and sets); returns
/// the flat paths removed.
pub fn unpublish(dir: &Path, id: &str) -> io::Result<Vec<PathBuf>> {
    let sets = dir.join(SETS);
    if !sets.join(id).is_symlink() {
        return Ok(vec![]);
    }
    let _lock = fsio::lock(&sets.join(".locks").join(format!("{id}.lock")))?;
    let mut removed = Vec::new();
    for (flat, _) in flat_links_of(dir, id) {
        std::fs::remove_file(&flat).map_err(fsio::err_at("cannot remove", &flat))?;
        removed.push(flat);
    }
    let pointer = sets.join(id);
    std::fs::remove_file(&pointer).map_err(fsio::err_at("cannot remove", &pointer))?;
    for old in sets_of(&sets, id) {
        let p = sets.join(&old);
        std::fs::remove_dir_all(&p).map_err(fsio::err_at("cannot remove", &p))?;
    }
    Ok(removed)
}

/// Withdraw the outputs of every published stage not in `ids` (stages removed from or
/// renamed in the pipeline); returns the ids withdrawn.
pub fn drop_removed(dir: &Path, ids: &HashSet<&str>) -> io::Result<Vec<String>> {
    let mut gone = Vec::new();
    for id in published_ids(dir) {
        if !ids.contains(id.as_str()) {
            unpublish(dir, &id)?;
            gone.push(id);
        }
    }
    Ok(gone)
}

/// The first bytes of every `index.html` granrepro writes.
pub const INDEX_MARK: &str = "<!doctype html><html><head><meta charset=\"utf-8\"><title>granrepro — ";

/// Remove everything granrepro published in `dir` (= `reports/<profile>`): the flat
/// symlinks into `.sets/`, `.sets/` itself and a generated `index.html`; then `dir` if
/// it is empty. Returns what was removed; other files are never touched.
pub fn clean_reports(dir: &Path) -> io::Result<Vec<PathBuf>> {
    let mut removed = Vec::new();
    let Ok(rd) = std::fs::read_dir(dir) else {
        return Ok(removed);
    };
    for e in rd.flatten() {
        let p = e.path();
        let ours = match std::fs::read_link(&p) {
            Ok(t) => t.starts_with(SETS),
            Err(_) => {
                e.file_name() == "index.html" && std::fs::read(&p).is_ok_and(|b| b.starts_with(INDEX_MARK.as_bytes()))
            }
        };
        if ours {
            std::fs::remove_file(&p).map_err(fsio::err_at("cannot remove", &p))?;
            removed.push(p);
        }
    }
    let sets = dir.join(SETS);
    if sets.is_dir() {
        std::fs::remove_dir_all(&sets).map_err(fsio::err_at("cannot remove", &sets))?;
        removed.push(sets);
    }
    if std::fs::read_dir(dir).is_ok_and(|mut r| r.next().is_none()) {
        std::fs::remove_dir(dir).map_err(fsio::err_at("cannot remove", dir))?;
        removed.push(dir.to_path_buf());
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::stage_methods;

    /// Methods come from the graph: the kind's or params' method, else the `wp` input's,
    /// else the inputs' (through stages that only read). The name heuristic this replaces
    /// gave table 4.1 no method (its inputs `psd-col` and `fig4-03` name none).
    #[test]
    fn methods_are_read_off_the_graph() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let p = crate::pipeline::load(&root.join("pipeline.yaml"), "quick", &[]).unwrap();
        let m = stage_methods(&p);
        let of = |id: &str| m.get(id).cloned().unwrap_or_else(|| panic!("{id}"));
        assert_eq!(of("fig4-03"), ["dem"]);
        assert_eq!(of("col-mpm-a0.4"), ["mpm"]);
        assert_eq!(of("col-dem-a0.4"), ["dem"]);
        assert_eq!(of("shear-cd"), ["cd"]);
        assert!(of("psd-col").is_empty() && of("laws").is_empty());
        assert_eq!(of("tab4-01"), ["dem"]);
        // a figure of DEM and MPM runs stamped with the DEM work-precision study
        assert_eq!(of("fig4-13"), ["dem"]);
        // a plot of MPM runs only
        let mpm_only = p
            .stages
            .iter()
            .find(|s| {
                s.kind == "plot"
                    && !s.inputs.is_empty()
                    && s.inputs.iter().all(|(_, v)| v.iter().all(|i| i.starts_with("col-mpm")))
            })
            .map(|s| s.id.clone());
        if let Some(id) = mpm_only {
            assert_eq!(of(&id), ["mpm"], "{id}");
        }
    }
}

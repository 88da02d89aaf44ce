//! Content-addressed stage cache.
//!
//! **What goes into a key** (the [`KeyRecord`], hashed with BLAKE3 as canonical JSON):
//! the stage kind, that kind's solver version, the canonical params (every default
//! filled, keys sorted — `--set` overrides included), the profile, and the keys of the
//! input stages by role. Keys nest through inputs (as cargo's `DepFingerprint`), so a
//! change anywhere upstream reaches every dependant and nothing else. The key is computed
//! before the stage runs.
//!
//! **What never goes in**: the stage id (two stages with the same work share an entry),
//! wall times, absolute paths, the thread count (results are bit-identical across thread
//! counts by construction) and the caption.
//!
//! **Where entries live**: `.granrepro/cache/<key>/`, holding the artifacts, `result.json`,
//! `record.json` (the run record) and `manifest.json` (BLAKE3 of every artifact and of
//! the record; [`Cache::manifest_hash`] covers the artifacts only, so it is the same for
//! identical work whatever the wall time). Files are 0644, directories 0755. An
//! entry is written into a sibling temp directory, each file fsynced, then renamed into
//! place: a killed run leaves only a `.tmp-*` directory that is never read. On read the
//! manifest is checked file by file; a missing, partial or corrupt entry is reported,
//! removed and recomputed, never used.
//!
//! **Many processes, one cache** (on one machine or a shared filesystem with working
//! `flock`): an entry, once complete, is never removed or replaced by a writer. A writer
//! moves its finished temp directory into place under an advisory lock per key
//! (`.locks/<key>.lock`); when a complete entry is already there it discards its own
//! copy. Readers take no lock: an entry directory appears by one rename, complete, so a
//! reader sees all of it or nothing. A corrupt entry is removed only under the key's
//! lock, after verifying it again, by renaming it aside first. Temp and trash
//! directories older than [`STALE_TMP_AGE`] (left by killed runs) are swept at the start
//! of each run.
//!
//! **Known limits**: the code of a kind is not hashed — bump its `version` when its
//! numerics change. Two processes computing the same key both compute it (the second
//! result is discarded, not waited for).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use polars::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::context::Output;
use super::fsio;
pub use super::fsio::write_atomic;

/// The canonical description of a stage's work; its hash is the cache key.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct KeyRecord {
    /// Stage kind.
    pub kind: String,
    /// Kind's solver version.
    pub version: u32,
    /// Canonical params.
    pub params: Value,
    /// Profile.
    pub profile: String,
    /// Input keys by role (ids kept for messages; they are not hashed).
    pub inputs: Vec<(String, Vec<(String, String)>)>,
}

impl KeyRecord {
    /// BLAKE3 of the canonical JSON (input ids excluded).
    pub fn key(&self) -> String {
        let inputs: Vec<(String, Vec<String>)> = self
            .inputs
            .iter()
            .map(|(r, v)| (r.clone(), v.iter().map(|(_, k)| k.clone()).collect()))
            .collect();
        let canon = serde_json::json!({
            "kind": self.kind, "version": self.version, "params": self.params,
            "profile": self.profile, "inputs": inputs,
        });
        let bytes = serde_json::to_vec(&super::spec::canonical(canon)).expect("json");
        blake3::hash(&bytes).to_hex()[..32].to_string()
    }
}

/// The manifest of an entry: BLAKE3 of every artifact, and separately of the run record
/// (which holds wall times, so it is verified but kept out of the content hash).
#[derive(Debug, Serialize, Deserialize)]
struct Manifest {
    key: String,
    files: BTreeMap<String, String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    record: Option<String>,
}

impl Manifest {
    /// Every file the entry holds (artifacts and the record), with its hash.
    fn all_files(&self) -> impl Iterator<Item = (&str, &str)> {
        self.files
            .iter()
            .map(|(n, h)| (n.as_str(), h.as_str()))
            .chain(self.record.as_deref().map(|h| ("record.json", h)))
    }
}

/// Result of looking an entry up.
#[derive(Debug)]
pub enum Lookup {
    /// Valid entry.
    Fresh(PathBuf),
    /// No entry.
    Missing,
    /// An entry exists but failed validation (it has been removed).
    Corrupt(String),
}

/// Temp (`.tmp-*`) and trash (`.trash-*`) directories older than this are left over
/// from killed runs and are removed at the start of a run.
pub const STALE_TMP_AGE: Duration = Duration::from_secs(3600);

/// The cache directory.
#[derive(Debug, Clone)]
pub struct Cache {
    root: PathBuf,
}

fn hash_file(p: &Path) -> std::io::Result<String> {
    Ok(blake3::hash(&fsio::read(p)?).to_hex().to_string())
}

/// A file name a stage may give an artifact: one path component of safe characters.
pub fn safe_file_name(name: &str) -> bool {
    !name.is_empty()
        && !name.starts_with('.')
        && !name.contains("..")
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-'))
}

impl Cache {
    /// Cache rooted at `dir` (usually `<project>/.granrepro/cache`).
    pub fn new(dir: impl Into<PathBuf>) -> Cache {
        Cache { root: dir.into() }
    }
    /// Root directory.
    pub fn root(&self) -> &Path {
        &self.root
    }
    /// Directory of an entry.
    pub fn entry_dir(&self, key: &str) -> PathBuf {
        self.root.join(key)
    }
    fn lock_path(&self, key: &str) -> PathBuf {
        self.root.join(".locks").join(format!("{key}.lock"))
    }

    /// Look an entry up and verify it against its manifest. A corrupt entry is removed
    /// (under the key's lock, after checking again, so a complete entry that a
    /// concurrent writer has just put in place is never the one removed).
    pub fn lookup(&self, key: &str) -> Lookup {
        let dir = self.entry_dir(key);
        if !dir.exists() {
            return Lookup::Missing;
        }
        match self.verify(&dir, key) {
            Ok(()) => Lookup::Fresh(dir),
            Err(why) => {
                if let Ok(_lock) = fsio::lock(&self.lock_path(key)) {
                    match self.verify(&dir, key) {
                        Ok(()) => return Lookup::Fresh(dir),
                        Err(_) if dir.exists() => {
                            let _ = fsio::discard_dir(&dir);
                        }
                        Err(_) => return Lookup::Missing,
                    }
                }
                Lookup::Corrupt(why)
            }
        }
    }

    /// Check without side effects.
    pub fn verify(&self, dir: &Path, key: &str) -> Result<(), String> {
        let m = read_manifest(dir)?;
        if m.key != key {
            return Err(format!("manifest key {} does not match the entry {key}", m.key));
        }
        for (name, h) in m.all_files() {
            if !safe_file_name(name) {
                return Err(format!("manifest names an unsafe file `{name}`"));
            }
            match hash_file(&dir.join(name)) {
                Ok(got) if got == h => {}
                Ok(_) => return Err(format!("{name}: content does not match its manifest hash")),
                Err(_) => return Err(format!("{name}: missing")),
            }
        }
        Ok(())
    }

    /// Names of the files an entry holds, from its manifest (artifacts and the record).
    /// Anything else found in the directory is not part of the entry.
    pub fn entry_files(&self, key: &str) -> Result<Vec<String>, String> {
        Ok(read_manifest(&self.entry_dir(key))?
            .all_files()
            .map(|(n, _)| n.to_string())
            .collect())
    }

    /// The content hash of an entry: BLAKE3 of its key and artifact hashes — not of the
    /// run record, so identical work gives an identical hash whatever its wall time.
    pub fn manifest_hash(&self, key: &str) -> Option<String> {
        let m = read_manifest(&self.entry_dir(key)).ok()?;
        let files: BTreeMap<&str, &str> = m
            .files
            .iter()
            .filter(|(n, _)| n.as_str() != "record.json")
            .map(|(n, h)| (n.as_str(), h.as_str()))
            .collect();
        let canon = serde_json::json!({ "key": m.key, "files": files });
        Some(blake3::hash(&serde_json::to_vec(&canon).ok()?).to_hex().to_string())
    }

    /// Remove `.tmp-*` / `.trash-*` directories older than `age` (left by killed runs);
    /// returns how many were removed.
    pub fn sweep_stale(&self, age: Duration) -> usize {
        let Ok(rd) = std::fs::read_dir(&self.root) else {
            return 0;
        };
        let mut n = 0;
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().to_string();
            if (name.starts_with(".tmp-") || name.starts_with(".trash-"))
                && fsio::older_than(&e.path(), age)
                && std::fs::remove_dir_all(e.path()).is_ok()
            {
                n += 1;
            }
        }
        n
    }

    /// Write an entry and return its directory. The entry is built in a temp directory
    /// and moved into place under the key's lock; if a complete entry is already there
    /// (a concurrent run, or a forced re-run of the same work) it is kept and this copy
    /// is discarded — a complete entry is never removed or replaced by a writer.
    ///
    /// `replace` (a forced re-run): a complete entry already under `key` whose artifacts
    /// differ from this run's is replaced by this one rather than kept, and the names of the
    /// differing files are returned — with deterministic stages an empty list (the old
    /// entry, byte-identical, stays), so a forced re-run doubles as a reproducibility check.
    /// Without `replace` the list is empty.
    pub fn store(
        &self,
        key: &str,
        stage: &str,
        profile: &str,
        out: &mut Output,
        record: &Value,
        replace: bool,
    ) -> anyhow::Result<(PathBuf, Vec<String>)> {
        fsio::create_dir_all(&self.root)?;
        let tmp = tempfile::Builder::new()
            .prefix(&format!(".tmp-{key}-"))
            .tempdir_in(&self.root)
            .map_err(fsio::err_at("cannot create a temp directory in", &self.root))?;
        fsio::set_mode(tmp.path(), fsio::DIR_MODE)?;
        let mut files: BTreeMap<String, String> = BTreeMap::new();
        let mut put = |name: &str, bytes: &[u8]| -> anyhow::Result<()> {
            anyhow::ensure!(
                safe_file_name(name),
                "stage `{stage}` produced a file named `{name}`: names must be one path component of [A-Za-z0-9._-], not starting with '.'"
            );
            anyhow::ensure!(
                !files.contains_key(name),
                "stage `{stage}` produced two files named `{name}`"
            );
            fsio::write_new(&tmp.path().join(name), bytes)?;
            files.insert(name.to_string(), blake3::hash(bytes).to_hex().to_string());
            Ok(())
        };
        for (name, df) in out.tables.iter_mut() {
            let mut pq = Vec::new();
            ParquetWriter::new(&mut pq).finish(df)?;
            put(&format!("{name}.parquet"), &pq)?;
            let mut csv = Vec::new();
            CsvWriter::new(&mut csv).finish(df)?;
            put(&format!("{name}.csv"), &csv)?;
        }
        for (name, svg) in &out.figures {
            put(&format!("{name}.svg"), svg.as_bytes())?;
        }
        for (name, bytes) in &out.files {
            put(name, bytes)?;
        }
        let result = result_json(stage, profile, out);
        put("result.json", &serde_json::to_vec_pretty(&result)?)?;
        let rec_bytes = serde_json::to_vec_pretty(record)?;
        fsio::write_new(&tmp.path().join("record.json"), &rec_bytes)?;
        let manifest = Manifest {
            key: key.to_string(),
            files,
            record: Some(blake3::hash(&rec_bytes).to_hex().to_string()),
        };
        let changed = match replace.then(|| read_manifest(&self.entry_dir(key))) {
            Some(Ok(old)) => {
                let names: std::collections::BTreeSet<&String> =
                    old.files.keys().chain(manifest.files.keys()).collect();
                names
                    .into_iter()
                    .filter(|n| old.files.get(*n) != manifest.files.get(*n))
                    .cloned()
                    .collect()
            }
            _ => Vec::new(),
        };
        fsio::write_new(
            &tmp.path().join("manifest.json"),
            &serde_json::to_vec_pretty(&manifest)?,
        )?;
        // Only an entry whose artifacts differ is replaced: removing an identical one would
        // pull it from under a concurrent reader for nothing (tests/concurrency.rs races
        // forced and unforced runs of deterministic stages on one cache).
        if !changed.is_empty() {
            let _lock = fsio::lock(&self.lock_path(key))?;
            fsio::discard_dir(&self.entry_dir(key))?;
        }
        Ok((self.commit(key, tmp.keep())?, changed))
    }

    /// Remove the entries of `profile` (every entry, temp directory and lock when
    /// `None`); returns how many entries were removed. Only directories named like keys,
    /// `.tmp-*`, `.trash-*` and `.locks` are touched.
    pub fn clean(&self, profile: Option<&str>) -> std::io::Result<usize> {
        let Ok(rd) = std::fs::read_dir(&self.root) else {
            return Ok(0);
        };
        let mut n = 0;
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().to_string();
            let path = e.path();
            let is_key = name.len() == 32 && name.chars().all(|c| c.is_ascii_hexdigit());
            let is_scratch = name.starts_with(".tmp-") || name.starts_with(".trash-") || name == ".locks";
            let remove = match profile {
                None => is_key || is_scratch,
                Some(p) => is_key && entry_profile(&path).as_deref() == Some(p),
            };
            if remove {
                std::fs::remove_dir_all(&path).map_err(fsio::err_at("cannot remove", &path))?;
                n += usize::from(is_key);
            }
        }
        if std::fs::read_dir(&self.root).is_ok_and(|mut r| r.next().is_none()) {
            let _ = std::fs::remove_dir(&self.root);
        }
        Ok(n)
    }

    /// Move a finished temp directory into place as the entry `key` (see [`Cache::store`]).
    fn commit(&self, key: &str, tmp: PathBuf) -> std::io::Result<PathBuf> {
        let dest = self.entry_dir(key);
        let _lock = fsio::lock(&self.lock_path(key))?;
        for _ in 0..3 {
            match std::fs::rename(&tmp, &dest) {
                Ok(()) => return Ok(dest),
                Err(_) if self.verify(&dest, key).is_ok() => {
                    // Someone else's complete entry: keep it, drop ours.
                    let _ = std::fs::remove_dir_all(&tmp);
                    return Ok(dest);
                }
                Err(_) if dest.exists() => fsio::discard_dir(&dest)?, // partial or corrupt: replace
                Err(e) => {
                    let _ = std::fs::remove_dir_all(&tmp);
                    return Err(fsio::at(&format!("cannot move {} to", tmp.display()), &dest, e));
                }
            }
        }
        let _ = std::fs::remove_dir_all(&tmp);
        Err(fsio::at(
            "cannot put the cache entry in place at",
            &dest,
            std::io::Error::other("it kept changing under the lock"),
        ))
    }
}

/// The profile recorded in an entry's run record.
fn entry_profile(dir: &Path) -> Option<String> {
    let v: Value = serde_json::from_slice(&std::fs::read(dir.join("record.json")).ok()?).ok()?;
    v.get("profile")?.as_str().map(str::to_string)
}

fn read_manifest(dir: &Path) -> Result<Manifest, String> {
    let bytes =
        std::fs::read(dir.join("manifest.json")).map_err(|_| "manifest.json missing (partial entry)".to_string())?;
    serde_json::from_slice(&bytes).map_err(|e| format!("manifest.json unreadable: {e}"))
}

/// The stable JSON shape of a stage's scalars and claims.
pub fn result_json(stage: &str, profile: &str, out: &Output) -> Value {
    let scalars: serde_json::Map<String, Value> = out
        .scalars
        .iter()
        .map(|(k, v)| {
            (
                k.clone(),
                serde_json::Number::from_f64(*v)
                    .map(Value::Number)
                    .unwrap_or(Value::Null),
            )
        })
        .collect();
    serde_json::json!({
        "stage": stage,
        "profile": profile,
        "scalars": scalars,
        "claims": out.claims.iter().map(claim_json).collect::<Vec<_>>(),
        "checks": out.checks.iter().map(claim_json).collect::<Vec<_>>(),
    })
}

fn claim_json(c: &crate::pipeline::context::Claim) -> Value {
    serde_json::json!({
        "id": c.id, "statement": c.statement,
        "paper": finite(c.paper), "ours": finite(c.ours), "tolerance": finite(c.tolerance), "pass": c.pass,
        "calibrated": c.calibrated,
    })
}

fn finite(v: f64) -> Value {
    serde_json::Number::from_f64(v)
        .map(Value::Number)
        .unwrap_or(Value::Null)
}

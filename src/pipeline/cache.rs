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
//! `flock`): an entry, once complete, is never removed or replaced by a writer (except
//! by a forced re-run whose artifacts differ, see [`Cache::store`]), and never removed by
//! `clean` while a process uses it. Each key has two lock files:
//! - `.locks/<key>.use`, held *shared* by every process using the entry: a run takes it
//!   ([`Cache::hold`]) for every key of its plan (its stages and their inputs) before it
//!   looks any of them up, and keeps it until it has published them; [`Cache::store`]
//!   holds it while its temp directory exists. `clean` takes it *exclusively without
//!   waiting*: a key whose lock is held is kept (and reported), never waited for.
//! - `.locks/<key>.lock`, held *exclusively* for the moment an entry is put in place or
//!   removed. A writer moves its finished temp directory into place under it; when a
//!   complete entry is already there it discards its own copy.
//!
//! Readers take no other lock: an entry directory appears by one rename, complete, so a
//! reader sees all of it or nothing. A corrupt entry is removed only under the key's
//! lock, after verifying it again, by renaming it aside first. Temp and trash
//! directories older than [`STALE_TMP_AGE`] whose key nobody holds (left by killed runs)
//! are swept at the start of each run. Lock files are unlinked only by `clean`, while it
//! holds both exclusively, and every locker checks after acquiring that the file it
//! locked is still the one at the path (`fsio::lock`), so unlinking never lets two
//! processes hold one lock. An entry that vanishes anyway (removed by hand, by a process
//! on a filesystem without `flock`) while a run needs it as an input is recomputed by
//! that run, at most a few times (`run`).
//!
//! **Known limits**: the code of a kind is not hashed — bump its `version` when its
//! numerics change. Two processes computing the same key both compute it (the second
//! result is discarded, not waited for). A run keeps one open file per key of its plan
//! (a few hundred for the whole pipeline). `clean` during a run leaves the run's entries
//! in place; a second `clean` after the run removes them.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use polars::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::context::{Output, RESULT_KEYS};
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
        let bytes = serde_json::to_vec(&super::yaml::canonical(canon)).expect("json");
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

/// Entries marked in use by this process ([`Cache::hold`]); released on drop.
#[derive(Debug)]
pub struct InUse {
    _locks: Vec<fsio::Lock>,
}

/// What [`Cache::clean`] did.
#[derive(Debug, Default)]
pub struct Cleaned {
    /// Entries removed.
    pub removed: usize,
    /// Entries kept because a running process is using them: key, and the stage named in
    /// the entry's run record when it is readable.
    pub in_use: Vec<(String, Option<String>)>,
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
    /// The lock that serialises putting `key`'s entry in place or removing it (exclusive,
    /// held for a rename or a removal).
    fn lock_path(&self, key: &str) -> PathBuf {
        self.root.join(".locks").join(format!("{key}.lock"))
    }
    /// The lock that says `key`'s entry is in use (shared, held by every run that reads or
    /// writes it; see [`Cache::hold`]).
    fn use_path(&self, key: &str) -> PathBuf {
        self.root.join(".locks").join(format!("{key}.use"))
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

    /// Is the entry still there: its manifest readable and every file it lists present?
    /// A cheap check (nothing hashed) for an entry verified earlier, which another process
    /// may have removed since.
    pub fn present(&self, key: &str) -> Result<(), String> {
        let dir = self.entry_dir(key);
        for (name, _) in read_manifest(&dir)?.all_files() {
            if !safe_file_name(name) || !dir.join(name).is_file() {
                return Err(format!("{name}: missing"));
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

    /// A temp directory for building `key`'s entry, with the key's in-use lock (held while
    /// the directory exists, so no `clean` removes it under the writer).
    fn scratch(&self, key: &str) -> std::io::Result<(fsio::Lock, tempfile::TempDir)> {
        let in_use = fsio::lock_shared(&self.use_path(key))?;
        fsio::create_dir_all(&self.root)?;
        let tmp = tempfile::Builder::new()
            .prefix(&format!(".tmp-{key}-"))
            .tempdir_in(&self.root)
            .map_err(fsio::err_at("cannot create a temp directory in", &self.root))?;
        fsio::set_mode(tmp.path(), fsio::DIR_MODE)?;
        Ok((in_use, tmp))
    }

    /// Put a verified entry from another store (the committed results, `pipeline::store`)
    /// in place under `key`: its manifest and the files it lists are copied into a temp
    /// directory, plus `extra` files (not in the manifest), then renamed into place under the
    /// key's lock. An entry already in place is kept. The source is verified first.
    pub fn import(&self, key: &str, from: &Path, extra: &[(&str, &[u8])]) -> anyhow::Result<PathBuf> {
        Cache::new(from.parent().unwrap_or(from))
            .verify(from, key)
            .map_err(|why| anyhow::anyhow!("{}: {why}", from.display()))?;
        let (_in_use, tmp) = self.scratch(key)?;
        let names: Vec<String> = read_manifest(from)
            .map_err(anyhow::Error::msg)?
            .all_files()
            .map(|(n, _)| n.to_string())
            .chain(std::iter::once("manifest.json".to_string()))
            .collect();
        for n in &names {
            fsio::write_new(&tmp.path().join(n), &fsio::read(&from.join(n))?)?;
        }
        for (n, b) in extra {
            anyhow::ensure!(safe_file_name(n), "unsafe extra file name `{n}`");
            fsio::write_new(&tmp.path().join(n), b)?;
        }
        let dir = self.entry_dir(key);
        let _lock = fsio::lock(&self.lock_path(key))?;
        if self.verify(&dir, key).is_err() {
            if dir.exists() {
                fsio::discard_dir(&dir)?;
            }
            std::fs::rename(tmp.keep(), &dir).map_err(fsio::err_at("cannot move an imported entry to", &dir))?;
        }
        Ok(dir)
    }

    /// Remove the entry under `key` (under its lock): a committed partial entry that a
    /// stage must now recompute in full.
    pub fn remove(&self, key: &str) -> std::io::Result<()> {
        let dir = self.entry_dir(key);
        let _lock = fsio::lock(&self.lock_path(key))?;
        if dir.exists() { fsio::discard_dir(&dir) } else { Ok(()) }
    }

    /// Remove `.tmp-*` / `.trash-*` directories older than `age` (left by killed runs)
    /// whose key no process is using; returns how many were removed.
    pub fn sweep_stale(&self, age: Duration) -> usize {
        let Ok(rd) = std::fs::read_dir(&self.root) else {
            return 0;
        };
        let mut n = 0;
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().to_string();
            if !(name.starts_with(".tmp-") || name.starts_with(".trash-")) || !fsio::older_than(&e.path(), age) {
                continue;
            }
            // A live writer of that key holds its `.use` lock: not stale, however old.
            let _guard = match scratch_key(&name) {
                Some(k) => match fsio::try_lock(&self.use_path(k)) {
                    Ok(Some(l)) => Some(l),
                    _ => continue,
                },
                None => None,
            };
            if std::fs::remove_dir_all(e.path()).is_ok() {
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
        // The temp directory lives while this is held, so no `clean` removes it under us.
        let (_in_use, tmp) = self.scratch(key)?;
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
        // forced and unforced runs of deterministic stages on one cache) — unless the code
        // that built it changed: a forced re-run by other sources that reproduces the
        // artifacts byte for byte replaces the record, which says what built the entry
        // (the committed results' lock reads it), and reports no differing artifact.
        let rebuilt_by_other_code = replace
            && changed.is_empty()
            && std::fs::read(self.entry_dir(key).join("record.json"))
                .ok()
                .and_then(|b| serde_json::from_slice::<Value>(&b).ok())
                .is_some_and(|old| old.get("sources") != record.get("sources"));
        if !changed.is_empty() || rebuilt_by_other_code {
            let _lock = fsio::lock(&self.lock_path(key))?;
            fsio::discard_dir(&self.entry_dir(key))?;
        }
        Ok((self.commit(key, tmp.keep())?, changed))
    }

    /// Mark the entries `keys` as in use by this process until the returned guard is
    /// dropped: a shared lock on each key's `.locks/<key>.use`. [`Cache::clean`] and the
    /// stale sweep leave an entry in use (and its temp and trash directories) alone. A run
    /// takes this before it looks any of its entries up, and keeps it until it has
    /// published them. Waits only while a `clean` is removing one of these entries.
    pub fn hold<'a>(&self, keys: impl IntoIterator<Item = &'a str>) -> std::io::Result<InUse> {
        let keys: std::collections::BTreeSet<&str> = keys.into_iter().collect();
        let locks = keys
            .into_iter()
            .map(|k| fsio::lock_shared(&self.use_path(k)))
            .collect::<std::io::Result<_>>()?;
        Ok(InUse { _locks: locks })
    }

    /// Remove the entries of `profile` (every entry, with its temp and trash directories
    /// and its lock files, when `None`) that no process is using. Each key is taken with a
    /// non-blocking exclusive lock on its `.use` file first: an entry in use by a run (see
    /// [`Cache::hold`]) is kept and reported in [`Cleaned::in_use`], never waited for.
    /// Lock files are unlinked only while held ([`fsio::Lock::unlink`]); `.locks` and the
    /// cache directory are removed only when empty. Only directories named like keys,
    /// `.tmp-<key>-*`, `.trash-<key>-*` and `.locks/<key>.{lock,use}` are touched.
    pub fn clean(&self, profile: Option<&str>) -> std::io::Result<Cleaned> {
        let mut done = Cleaned::default();
        let Ok(rd) = std::fs::read_dir(&self.root) else {
            return Ok(done);
        };
        // key -> its temp and trash directories (the entry itself is `root/key`)
        let mut keys: BTreeMap<String, Vec<PathBuf>> = BTreeMap::new();
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().to_string();
            if is_key(&name) {
                keys.entry(name).or_default();
            } else if let Some(k) = scratch_key(&name) {
                keys.entry(k.to_string()).or_default().push(e.path());
            }
        }
        if profile.is_none() {
            for e in std::fs::read_dir(self.root.join(".locks"))
                .into_iter()
                .flatten()
                .flatten()
            {
                let name = e.file_name().to_string_lossy().to_string();
                if let Some(k) = name.strip_suffix(".lock").or_else(|| name.strip_suffix(".use"))
                    && is_key(k)
                {
                    keys.entry(k.to_string()).or_default();
                }
            }
        }
        for (key, scratch) in keys {
            let entry = self.entry_dir(&key);
            let has_entry = entry.is_dir();
            if let Some(p) = profile
                && (!has_entry || entry_profile(&entry).as_deref() != Some(p))
            {
                continue;
            }
            // Every writer of `key` holds its `.use` lock shared, so holding it exclusively
            // means nobody is reading, writing or committing this entry.
            let Some(in_use) = fsio::try_lock(&self.use_path(&key))? else {
                if has_entry {
                    done.in_use.push((key.clone(), entry_stage(&entry)));
                }
                continue;
            };
            let Some(commit) = fsio::try_lock(&self.lock_path(&key))? else {
                if has_entry {
                    done.in_use.push((key.clone(), entry_stage(&entry)));
                }
                continue;
            };
            if has_entry {
                fsio::discard_dir(&entry)?;
                done.removed += 1;
            }
            for d in scratch {
                match std::fs::remove_dir_all(&d) {
                    Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                        return Err(fsio::at("cannot remove", &d, e));
                    }
                    _ => {}
                }
            }
            if profile.is_none() {
                commit.unlink()?;
                in_use.unlink()?;
            }
        }
        let _ = std::fs::remove_dir(self.root.join(".locks")); // only when empty
        let _ = std::fs::remove_dir(&self.root); // only when empty
        Ok(done)
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

/// Is `name` a cache key (32 hex digits)?
fn is_key(name: &str) -> bool {
    name.len() == 32 && name.chars().all(|c| c.is_ascii_hexdigit())
}

/// The key of a temp (`.tmp-<key>-*`) or trash (`.trash-<key>-*`) directory name.
fn scratch_key(name: &str) -> Option<&str> {
    let rest = name.strip_prefix(".tmp-").or_else(|| name.strip_prefix(".trash-"))?;
    let k = rest.get(..32)?;
    (is_key(k) && rest[32..].starts_with('-')).then_some(k)
}

/// The stage recorded in an entry's run record (for messages).
fn entry_stage(dir: &Path) -> Option<String> {
    let v: Value = serde_json::from_slice(&std::fs::read(dir.join("record.json")).ok()?).ok()?;
    v.get("stage")?.as_str().map(str::to_string)
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

/// The stable JSON shape of a stage's scalars, measurements and checks. A stage's
/// `claims` are published as measurements (id, what is measured, our value): the chapter's
/// value, the tolerance and the verdict belong to the ledger (`crate::claims`), which
/// judges each claim once. Checks (inputs, identities) keep their own verdict.
pub fn result_json(stage: &str, profile: &str, out: &Output) -> Value {
    let mut v = result_json_fixed(stage, profile, out);
    if let Some(m) = v.as_object_mut() {
        for (k, t) in &out.texts {
            if !RESULT_KEYS.contains(&k.as_str()) {
                m.insert(k.clone(), Value::String(t.clone()));
            }
        }
    }
    v
}

fn result_json_fixed(stage: &str, profile: &str, out: &Output) -> Value {
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
        "measurements": out.claims.iter().map(measurement_json).collect::<Vec<_>>(),
        "checks": out.checks.iter().map(claim_json).collect::<Vec<_>>(),
    })
}

fn measurement_json(c: &crate::pipeline::context::Claim) -> Value {
    serde_json::json!({ "id": c.id, "statement": c.statement, "ours": finite(c.ours) })
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A cache in a temp directory holding one complete entry; returns its key.
    fn one_entry(dir: &Path) -> (Cache, String) {
        let cache = Cache::new(dir.join("cache"));
        let key = "0123456789abcdef0123456789abcdef".to_string();
        let mut out = Output::default();
        out.scalar("x", 1.0);
        let record = serde_json::json!({ "stage": "psd-col", "profile": "quick" });
        cache.store(&key, "psd-col", "quick", &mut out, &record, false).unwrap();
        assert!(matches!(cache.lookup(&key), Lookup::Fresh(_)));
        (cache, key)
    }

    #[test]
    fn clean_skips_an_entry_in_use_and_removes_it_once_released() {
        let tmp = tempfile::tempdir().unwrap();
        let (cache, key) = one_entry(tmp.path());
        let held = cache.hold([key.as_str()]).unwrap();
        let cleaned = cache.clean(None).unwrap();
        assert_eq!(cleaned.removed, 0);
        assert_eq!(cleaned.in_use, vec![(key.clone(), Some("psd-col".to_string()))]);
        assert!(
            cache.verify(&cache.entry_dir(&key), &key).is_ok(),
            "the entry in use was touched"
        );
        assert!(
            cache.use_path(&key).is_file(),
            "the lock file a process holds was removed"
        );
        drop(held);
        let cleaned = cache.clean(None).unwrap();
        assert_eq!((cleaned.removed, cleaned.in_use.len()), (1, 0));
        assert!(
            !cache.root().exists(),
            "entry, lock files and the cache directory are all gone"
        );
    }

    #[test]
    fn a_profile_clean_skips_an_entry_in_use_too() {
        let tmp = tempfile::tempdir().unwrap();
        let (cache, key) = one_entry(tmp.path());
        let _held = cache.hold([key.as_str()]).unwrap();
        assert_eq!(cache.clean(Some("quick")).unwrap().in_use.len(), 1);
        assert!(cache.verify(&cache.entry_dir(&key), &key).is_ok());
    }

    #[test]
    fn clean_keeps_the_temp_directory_of_a_live_writer_and_removes_a_dead_ones() {
        let tmp = tempfile::tempdir().unwrap();
        let cache = Cache::new(tmp.path().join("cache"));
        let key = "fedcba9876543210fedcba9876543210";
        let scratch = cache.root().join(format!(".tmp-{key}-abc123"));
        std::fs::create_dir_all(&scratch).unwrap();
        std::fs::write(scratch.join("table.csv"), "x\n1\n").unwrap();
        let held = cache.hold([key]).unwrap(); // what `store` holds while it writes there
        cache.clean(None).unwrap();
        assert!(
            scratch.join("table.csv").is_file(),
            "a live writer's temp directory was removed"
        );
        drop(held); // the writer died
        cache.clean(None).unwrap();
        assert!(!scratch.exists());
    }

    #[test]
    fn a_lock_whose_file_was_unlinked_by_its_holder_is_taken_on_the_new_file() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join(".locks").join("k.use");
        let first = fsio::try_lock(&path).unwrap().unwrap();
        // Another locker opens the same file and waits on it.
        let waiter = {
            let path = path.clone();
            std::thread::spawn(move || fsio::lock_shared(&path).unwrap())
        };
        std::thread::sleep(Duration::from_millis(100));
        first.unlink().unwrap();
        let got = waiter.join().unwrap();
        // It holds the file now at the path, so an exclusive locker of the path is excluded.
        assert!(path.is_file());
        assert!(fsio::try_lock(&path).unwrap().is_none(), "two holders of one lock path");
        drop(got);
        assert!(fsio::try_lock(&path).unwrap().is_some());
    }
}

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
//! `record.json` (the run record) and `manifest.json` (BLAKE3 of every artifact). An
//! entry is written into a sibling temp directory, each file fsynced, then renamed into
//! place: a killed run leaves only a `.tmp-*` directory that is never read. On read the
//! manifest is checked file by file; a missing, partial or corrupt entry is reported,
//! removed and recomputed, never used.
//!
//! **Known limits**: the code of a kind is not hashed — bump its `version` when its
//! numerics change. Two processes computing the same key race benignly (the second
//! rename fails and its copy is dropped).

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use polars::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::context::Output;

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
        let inputs: Vec<(String, Vec<String>)> = self.inputs.iter().map(|(r, v)| (r.clone(), v.iter().map(|(_, k)| k.clone()).collect())).collect();
        let canon = serde_json::json!({
            "kind": self.kind, "version": self.version, "params": self.params,
            "profile": self.profile, "inputs": inputs,
        });
        let bytes = serde_json::to_vec(&super::spec::canonical(canon)).expect("json");
        blake3::hash(&bytes).to_hex()[..32].to_string()
    }
}

/// The manifest of an entry.
#[derive(Debug, Serialize, Deserialize)]
struct Manifest {
    key: String,
    files: BTreeMap<String, String>,
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

/// The cache directory.
#[derive(Debug, Clone)]
pub struct Cache {
    root: PathBuf,
}

fn hash_file(p: &Path) -> std::io::Result<String> {
    let bytes = std::fs::read(p)?;
    Ok(blake3::hash(&bytes).to_hex().to_string())
}

/// Write bytes to `path` atomically: a temp file in the same directory, fsync, rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let dir = path.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir)?;
    let mut tmp = tempfile::NamedTempFile::new_in(dir)?;
    tmp.write_all(bytes)?;
    tmp.as_file().sync_all()?;
    tmp.persist(path).map_err(|e| e.error)?;
    Ok(())
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

    /// Look an entry up and verify it against its manifest.
    pub fn lookup(&self, key: &str) -> Lookup {
        let dir = self.entry_dir(key);
        if !dir.exists() {
            return Lookup::Missing;
        }
        match self.verify(&dir, key) {
            Ok(()) => Lookup::Fresh(dir),
            Err(why) => {
                let _ = std::fs::remove_dir_all(&dir);
                Lookup::Corrupt(why)
            }
        }
    }

    /// Check without side effects.
    pub fn verify(&self, dir: &Path, key: &str) -> Result<(), String> {
        let mpath = dir.join("manifest.json");
        let bytes = std::fs::read(&mpath).map_err(|_| "manifest.json missing (partial entry)".to_string())?;
        let m: Manifest = serde_json::from_slice(&bytes).map_err(|e| format!("manifest.json unreadable: {e}"))?;
        if m.key != key {
            return Err(format!("manifest key {} does not match the entry {key}", m.key));
        }
        for (name, h) in &m.files {
            match hash_file(&dir.join(name)) {
                Ok(got) if &got == h => {}
                Ok(_) => return Err(format!("{name}: content does not match its manifest hash")),
                Err(_) => return Err(format!("{name}: missing")),
            }
        }
        Ok(())
    }

    /// BLAKE3 of an entry's manifest: the content hash of all its artifacts.
    pub fn manifest_hash(&self, key: &str) -> Option<String> {
        hash_file(&self.entry_dir(key).join("manifest.json")).ok()
    }

    /// Write an entry atomically and return its directory.
    pub fn store(&self, key: &str, stage: &str, profile: &str, out: &mut Output, record: &Value) -> anyhow::Result<PathBuf> {
        std::fs::create_dir_all(&self.root)?;
        let tmp = tempfile::Builder::new().prefix(&format!(".tmp-{key}-")).tempdir_in(&self.root)?;
        let mut files: BTreeMap<String, String> = BTreeMap::new();
        let mut put = |name: &str, bytes: &[u8]| -> anyhow::Result<()> {
            let p = tmp.path().join(name);
            let mut f = std::fs::File::create(&p)?;
            f.write_all(bytes)?;
            f.sync_all()?;
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
        put("record.json", &serde_json::to_vec_pretty(record)?)?;
        let manifest = Manifest { key: key.to_string(), files };
        let mut f = std::fs::File::create(tmp.path().join("manifest.json"))?;
        f.write_all(&serde_json::to_vec_pretty(&manifest)?)?;
        f.sync_all()?;
        let dest = self.entry_dir(key);
        let tmp_path = tmp.keep();
        if dest.exists() {
            // A concurrent run (or a forced re-run) produced it: replace.
            let _ = std::fs::remove_dir_all(&dest);
        }
        std::fs::rename(&tmp_path, &dest)?;
        Ok(dest)
    }
}

/// The stable JSON shape of a stage's scalars and claims.
pub fn result_json(stage: &str, profile: &str, out: &Output) -> Value {
    let scalars: serde_json::Map<String, Value> = out
        .scalars
        .iter()
        .map(|(k, v)| (k.clone(), serde_json::Number::from_f64(*v).map(Value::Number).unwrap_or(Value::Null)))
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
    serde_json::Number::from_f64(v).map(Value::Number).unwrap_or(Value::Null)
}

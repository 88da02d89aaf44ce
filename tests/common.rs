//! Helpers shared by the integration tests: throw-away projects in temp directories.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// A temp project holding `pipeline.yaml` (and optional stage files).
pub struct TempProject {
    pub dir: tempfile::TempDir,
}

impl TempProject {
    pub fn new(pipeline: &str) -> TempProject {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("pipeline.yaml"), pipeline).unwrap();
        TempProject { dir }
    }
    pub fn path(&self) -> &Path {
        self.dir.path()
    }
    pub fn pipeline(&self) -> PathBuf {
        self.dir.path().join("pipeline.yaml")
    }
    pub fn write(&self, rel: &str, text: &str) {
        let p = self.dir.path().join(rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    }
    /// Run the CLI binary in this project; returns (exit code, stdout, stderr).
    pub fn cli(&self, args: &[&str]) -> (i32, String, String) {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_granrepro"))
            .arg("--pipeline")
            .arg(self.pipeline())
            .args(args)
            .output()
            .unwrap();
        (
            out.status.code().unwrap_or(-1),
            String::from_utf8_lossy(&out.stdout).into(),
            String::from_utf8_lossy(&out.stderr).into(),
        )
    }
}

/// A small pipeline: two PSDs, a figure of the first, a table reading the first.
pub const SMALL: &str = r#"version: 1
stages:
  - id: psd-a
    kind: psd
    params: { n: 300, seed: 1 }
  - id: psd-b
    kind: psd
    params: { n: 200, seed: 2 }
  - id: fig-a
    kind: psd-figure
    inputs: { psd: psd-a }
  - id: tab
    kind: material-table
    params: { table: tab4-02 }
    inputs: { psd: psd-a }
  - id: laws
    kind: reference-laws
"#;

/// Run options of the pipeline tests: 2 jobs, no progress bars.
pub fn opts() -> granrepro::pipeline::RunOptions {
    granrepro::pipeline::RunOptions {
        jobs: 2,
        quiet: true,
        ..Default::default()
    }
}

/// Ids sorted, as owned strings (for comparing a run's stages).
pub fn sorted(v: Vec<&str>) -> Vec<String> {
    let mut v: Vec<String> = v.into_iter().map(String::from).collect();
    v.sort();
    v
}

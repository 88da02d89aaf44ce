//! Where a project keeps its cache, state and reports.

use std::path::{Path, PathBuf};

use super::cache::Cache;

/// Where a project keeps its cache, state and reports.
#[derive(Debug, Clone)]
pub struct Project {
    /// Directory of pipeline.yaml.
    pub root: PathBuf,
    /// The cache.
    pub cache: Cache,
    /// `.granrepro/state`: the last key record of each stage per profile (for `status`).
    pub state: PathBuf,
    /// `reports/`.
    pub reports: PathBuf,
}

impl Project {
    /// Project rooted at the directory of the pipeline file.
    pub fn new(root: &Path) -> Project {
        Project {
            root: root.to_path_buf(),
            cache: Cache::new(root.join(".granrepro").join("cache")),
            state: root.join(".granrepro").join("state"),
            reports: root.join("reports"),
        }
    }
    /// The same project with its cache at `dir` (`--cache DIR` / `GRANREPRO_CACHE`: one
    /// content-addressed cache shared by many processes or machines).
    pub fn with_cache(mut self, dir: &Path) -> Project {
        self.cache = Cache::new(dir);
        self
    }
    pub(crate) fn state_file(&self, profile: &str, id: &str) -> PathBuf {
        self.state.join(profile).join(format!("{id}.json"))
    }
    /// `reports/<profile>/`.
    pub fn report_dir(&self, profile: &str) -> PathBuf {
        self.reports.join(profile)
    }
}

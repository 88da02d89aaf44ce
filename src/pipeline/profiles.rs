//! Loading a pipeline: every profile validated (a bad value in the `paper` layer is an
//! error of a `quick` run too), each problem reported once, then the claims ledger
//! (`stages/ledger.yaml`) checked. What one
//! profile resolves to is [`super::spec`]'s.

use std::path::{Path, PathBuf};

use super::check;
use super::diag::{Diagnostic, Diagnostics};
use super::load::load_profile;
use super::spec::{Override, PROFILES, Pipeline};

/// Load and validate a pipeline for a profile, applying `--set` overrides to that profile.
/// Every profile is validated (a bad value in the `paper` layer is an error of a `quick`
/// run too), and the same problem is reported once.
pub fn load(path: &Path, profile: &str, sets: &[Override]) -> Result<Pipeline, Diagnostics> {
    let mut diags = Diagnostics::default();
    let root = path.parent().filter(|r| !r.as_os_str().is_empty());
    let root = root.map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from("."));
    if !PROFILES.contains(&profile) {
        diags.push(
            Path::new("<command line>"),
            None,
            "--profile",
            format!("unknown profile `{profile}`"),
            format!("allowed: {}", PROFILES.join(", ")),
        );
        return Err(diags);
    }
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) => {
            diags.push(
                path,
                None,
                "",
                format!("cannot read the pipeline file {}: {e}", path.display()),
                "pass --pipeline PATH, or run from the directory holding pipeline.yaml",
            );
            return Err(diags);
        }
    };
    load_text(path, &text, &root, profile, sets)
}

/// [`load`] from a pipeline text already read (`path` names it in messages; stage files
/// are relative to `root`).
pub fn load_text(
    path: &Path,
    text: &str,
    root: &Path,
    profile: &str,
    sets: &[Override],
) -> Result<Pipeline, Diagnostics> {
    let main = load_profile(path, text, root, profile, sets);
    let mut all: Vec<Diagnostic> = main.as_ref().err().map(|d| d.0.clone()).unwrap_or_default();
    // The other profiles are checked as the files write them: `--set` applies to the run's
    // profile only, and may name a stage that only that profile has (`col-dem-a8` is paper's).
    for other in PROFILES.iter().filter(|p| **p != profile) {
        if let Err(d) = load_profile(path, text, root, other, &[]) {
            for mut x in d.0 {
                if !all.contains(&x) {
                    x.message = format!("{} (profile `{other}`)", x.message);
                    all.push(x);
                }
            }
        }
    }
    if all.is_empty() {
        all.extend(crate::claims::check(root)); // stages/ledger.yaml, crate::claims
        if let Ok(p) = &main {
            // What each row reads, against its stage kind's declared outputs.
            let kind_of = |id: &str| p.get(id).and_then(|s| p.kinds.get(s.kind.as_str()).copied());
            all.extend(crate::claims::ledger::check_outputs(root, &kind_of));
        }
    }
    match main {
        Ok(p) if all.is_empty() => Ok(p),
        _ => Err(check::dedupe(Diagnostics(all))),
    }
}

//! `granrepro clean` of the cache and the state: only what granrepro made, and never an
//! entry a running `granrepro` is using (see the cache's module doc, "Many processes, one
//! cache"): those are kept and named, and a `clean` after that run removes them.

use super::run::Project;

/// `clean` of the cache and state: the entries and state of `profile` (all when `None`).
/// Returns one line per thing removed, and one naming the entries kept because in use.
pub fn clean_state(proj: &Project, profile: Option<&str>) -> std::io::Result<Vec<String>> {
    let mut msgs = Vec::new();
    let cleaned = proj.cache.clean(profile)?;
    let n = cleaned.removed;
    if n > 0 {
        msgs.push(format!(
            "removed {n} cache entr{} {}from {}",
            if n == 1 { "y" } else { "ies" },
            profile.map(|p| format!("of profile `{p}` ")).unwrap_or_default(),
            proj.cache.root().display()
        ));
    }
    if !cleaned.in_use.is_empty() {
        let k = cleaned.in_use.len();
        let names: Vec<String> = cleaned
            .in_use
            .iter()
            .map(|(key, id)| id.clone().unwrap_or_else(|| key.clone()))
            .collect();
        msgs.push(format!(
            "kept {k} cache entr{} in use by a running granrepro: {}; `granrepro clean` again once it has finished removes {}",
            if k == 1 { "y" } else { "ies" },
            names.join(", "),
            if k == 1 { "it" } else { "them" }
        ));
    }
    let profiles: Vec<&str> = match profile {
        Some(p) => vec![p],
        None => super::spec::PROFILES.to_vec(),
    };
    for p in profiles {
        let dir = proj.state.join(p);
        let Ok(rd) = std::fs::read_dir(&dir) else { continue };
        let mut k = 0;
        for e in rd.flatten() {
            if e.file_name().to_string_lossy().ends_with(".json") {
                std::fs::remove_file(e.path()).map_err(super::fsio::err_at("cannot remove", &e.path()))?;
                k += 1;
            }
        }
        let _ = std::fs::remove_dir(&dir);
        if k > 0 {
            msgs.push(format!(
                "removed the state of {k} stage(s) of profile `{p}` from {}",
                dir.display()
            ));
        }
    }
    for d in [proj.state.clone(), proj.root.join(".granrepro")] {
        let _ = std::fs::remove_dir(&d); // only when empty
    }
    if msgs.is_empty() {
        msgs.push("nothing to remove".into());
    }
    Ok(msgs)
}

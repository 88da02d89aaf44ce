//! The loader proper: one profile of `pipeline.yaml` read, merged layer by layer, checked
//! against each kind's declaration and ordered (see [`super::spec`] for the types and the
//! layering rules). Every problem is collected with file, line and key; nothing runs until
//! the whole pipeline is valid.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use serde_yaml::{Mapping, Value as Yaml};

use super::check;
use super::diag::{Diagnostics, locate, locate_stage};
use super::load_hints::{section_of, with_variants};
use super::spec::*;
use super::yaml::{canonical, merge, set_path, to_json, yaml_scalar_string};
use crate::stages::registry;

pub(crate) fn load_profile(
    path: &Path,
    text: &str,
    root: &Path,
    profile: &str,
    sets: &[Override],
) -> Result<Pipeline, Diagnostics> {
    let mut diags = Diagnostics::default();
    let root = root.to_path_buf();
    let text = text.to_string();
    let file: PipelineFile = match serde_yaml::from_str::<Yaml>(&text) {
        Err(e) => {
            let line = check::error_line(&e, &text);
            diags.push(
                path,
                line,
                "",
                format!("YAML syntax error: {e}"),
                "fix the YAML syntax (indentation, ':' after keys, matching quotes)",
            );
            return Err(diags);
        }
        Ok(v) => match serde_path_to_error::deserialize::<_, PipelineFile>(v) {
            Ok(f) => f,
            Err(e) => {
                let inner = e.inner().to_string();
                let field = inner.split('`').nth(1).unwrap_or("");
                let line = if inner.starts_with("unknown field") {
                    locate(&text, &[field], 1)
                } else {
                    locate(&text, &[&e.path().to_string()], 1)
                };
                diags.push(
                    path,
                    line,
                    if inner.starts_with("unknown field") {
                        field.to_string()
                    } else {
                        e.path().to_string()
                    },
                    inner,
                    "top-level keys: version, description, stages",
                );
                return Err(diags);
            }
        },
    };
    if file.version != 1 {
        diags.push(
            path,
            locate(&text, &["version"], 1),
            "version",
            format!("unsupported pipeline version {}", file.version),
            "allowed: 1",
        );
    }
    let kinds = registry();
    let mut stages: Vec<Stage> = Vec::new();
    let mut seen_base: HashMap<String, usize> = HashMap::new();
    // Matrix of each base id (for pairing inputs).
    let mut base_matrix: HashMap<String, (String, Vec<String>)> = HashMap::new();
    let mut pending_inputs: Vec<(usize, Option<InputsSpec>, Option<(String, String)>, Option<usize>)> = Vec::new();
    // Stages that exist but were rejected: their dependants are not told "no such stage".
    let mut rejected: std::collections::HashSet<String> = std::collections::HashSet::new();
    // Stages an empty profile matrix leaves out of this profile: where that is written.
    let mut absent: HashMap<String, (Option<usize>, String)> = HashMap::new();
    // What each stage's params name of its inputs, located in the file that wrote the key.
    let mut stage_reads: Vec<Vec<super::reads::Located>> = Vec::new();
    let known = known_ids(&file.stages);
    let swept_on = check::matrix_keys(&file.stages);
    let sets: Vec<Override> = sets.iter().map(|s| s.resolve(&known)).collect();
    let sets = sets.as_slice();

    for (si, raw) in file.stages.iter().enumerate() {
        let raw_id = raw.get("id").and_then(|v| v.as_str()).map(str::to_string);
        let line = raw_id.as_deref().and_then(|id| locate_stage(&text, id));
        let label = raw_id.clone().unwrap_or_else(|| format!("#{si}"));
        let mut entry: StageEntry = match serde_path_to_error::deserialize(raw.clone()) {
            Ok(e) => e,
            Err(e) => {
                let inner = e.inner().to_string();
                let (key, l) = if inner.starts_with("unknown field") {
                    let f = inner.split('`').nth(1).unwrap_or("").to_string();
                    let l = line.and_then(|ln| locate(&text, &[&f], ln)).or(line);
                    (f, l)
                } else {
                    (e.path().to_string(), line)
                };
                let (key, message, help) = match check::untagged_problem(raw, &inner) {
                    Some((k, m, h)) => (k, m, h),
                    None => (
                        key,
                        inner,
                        "stage keys: id, kind, caption, params_file, params, profiles, inputs, matrix, on_demand"
                            .into(),
                    ),
                };
                let l = line
                    .and_then(|ln| locate(&text, &key.split('.').collect::<Vec<_>>(), ln))
                    .or(l);
                diags.push(path, l, format!("stages[{label}].{key}"), message, help);
                rejected.extend(raw_id);
                continue;
            }
        };
        if let Err(why) = check::check_id(&entry.id) {
            let l = line.or_else(|| locate(&text, &["id"], 1));
            diags.push(path, l, format!("stages[#{si}].id"), why, check::ID_HELP);
            rejected.insert(entry.id.clone());
            continue;
        }
        let kind = match kinds.get(entry.kind.as_str()) {
            Some(k) => *k,
            None => {
                let l = line.and_then(|ln| locate(&text, &["kind"], ln));
                diags.push(
                    path,
                    l,
                    format!("stages[{}].kind", entry.id),
                    format!("unknown stage kind `{}`", entry.kind),
                    format!("known kinds: {}", kinds.keys().cloned().collect::<Vec<_>>().join(", ")),
                );
                rejected.insert(entry.id.clone());
                continue;
            }
        };
        if let Some(prev) = seen_base.insert(entry.id.clone(), si) {
            diags.push(
                path,
                line,
                format!("stages[{}].id", entry.id),
                format!("duplicate stage id (also entry #{prev})"),
                "give every stage a unique id",
            );
            continue;
        }
        match super::profile_matrix::profile_matrix(&mut entry, profile, &text, line, path, &mut diags) {
            super::profile_matrix::ProfileMatrix::Bad => {
                rejected.insert(entry.id.clone());
                continue;
            }
            super::profile_matrix::ProfileMatrix::Absent(at, key) => {
                absent.insert(entry.id.clone(), (at, key));
                continue;
            }
            super::profile_matrix::ProfileMatrix::Resolved => {}
        }
        for p in entry.profiles.keys() {
            if !PROFILES.contains(&p.as_str()) {
                let l = line.and_then(|ln| locate(&text, &["profiles", p], ln));
                diags.push(
                    path,
                    l,
                    format!("stages[{}].profiles.{p}", entry.id),
                    format!("unknown profile `{p}`"),
                    format!("allowed: {}", PROFILES.join(", ")),
                );
            }
        }
        // Layers of params.
        let mut layers: Vec<Layer> = Vec::new();
        let files: Vec<String> = match &entry.params_file {
            None => vec![],
            Some(OneOrMany::One(s)) => vec![s.clone()],
            Some(OneOrMany::Many(v)) => v.clone(),
        };
        let mut file_ok = true;
        for spec in files {
            let (sub, rel) = match spec.split_once('=') {
                Some((k, p)) => (Some(k.trim().to_string()), p.trim().to_string()),
                None => (None, spec.trim().to_string()),
            };
            // Stage files live inside the project, so the project (and its committed
            // results) stands alone: no absolute path, no `..`.
            let escapes = Path::new(&rel).is_absolute()
                || Path::new(&rel)
                    .components()
                    .any(|c| matches!(c, std::path::Component::ParentDir));
            if escapes {
                let l = line.and_then(|ln| locate(&text, &["params_file"], ln));
                diags.push(
                    path,
                    l,
                    format!("stages[{}].params_file", entry.id),
                    format!("`{rel}` is outside the project"),
                    "stage files live inside the project: a path relative to the directory of pipeline.yaml, without `..` (copy the file into stages/)",
                );
                file_ok = false;
                continue;
            }
            let fpath = root.join(&rel);
            let ftext = match std::fs::read_to_string(&fpath) {
                Ok(t) => t,
                Err(e) => {
                    let l = line.and_then(|ln| locate(&text, &["params_file"], ln));
                    diags.push(
                        path,
                        l,
                        format!("stages[{}].params_file", entry.id),
                        format!("cannot read `{}`: {e}", fpath.display()),
                        "paths are relative to the directory of pipeline.yaml",
                    );
                    file_ok = false;
                    continue;
                }
            };
            let mut fv: Yaml = match serde_yaml::from_str(&ftext) {
                Ok(v) => v,
                Err(e) => {
                    diags.push(
                        &fpath,
                        check::error_line(&e, &ftext),
                        "",
                        format!("YAML syntax error: {e}"),
                        "fix the YAML syntax",
                    );
                    file_ok = false;
                    continue;
                }
            };
            if matches!(fv, Yaml::Null) {
                fv = Yaml::Mapping(Mapping::new());
            }
            let Yaml::Mapping(mut fm) = fv else {
                diags.push(
                    &fpath,
                    Some(1),
                    "",
                    "a stage file must be a mapping of parameters",
                    "write `key: value` lines",
                );
                file_ok = false;
                continue;
            };
            let fprof = fm.remove(Yaml::String("profiles".into()));
            let prefix: Vec<String> = sub.iter().cloned().collect();
            let wrap = |m: Yaml| -> Yaml {
                match &sub {
                    Some(k) => {
                        let mut outer = Mapping::new();
                        outer.insert(Yaml::String(k.clone()), m);
                        Yaml::Mapping(outer)
                    }
                    None => m,
                }
            };
            layers.push(Layer {
                file: fpath.clone(),
                text: Some(ftext.clone()),
                prefix: prefix.clone(),
                anchor: 1,
                value: wrap(Yaml::Mapping(fm)),
                section: None,
            });
            if let Some(fp) = fprof {
                let Yaml::Mapping(pm) = fp else {
                    diags.push(
                        &fpath,
                        locate(&ftext, &["profiles"], 1),
                        "profiles",
                        "must be a mapping `quick: {..}` / `paper: {..}`",
                        "",
                    );
                    continue;
                };
                for (k, _) in pm.iter() {
                    let ks = yaml_scalar_string(k);
                    if !PROFILES.contains(&ks.as_str()) {
                        diags.push(
                            &fpath,
                            locate(&ftext, &["profiles", &ks], 1),
                            format!("profiles.{ks}"),
                            format!("unknown profile `{ks}`"),
                            format!("allowed: {}", PROFILES.join(", ")),
                        );
                    }
                }
                if let Some(over) = pm.get(Yaml::String(profile.into())) {
                    let anchor = locate(&ftext, &["profiles", profile], 1).unwrap_or(1);
                    if !over.is_mapping() && !over.is_null() {
                        diags.push(
                            &fpath,
                            Some(anchor),
                            format!("profiles.{profile}"),
                            "a profile's section must be a mapping of parameters",
                            "write `key: value` lines under it",
                        );
                        file_ok = false;
                        continue;
                    }
                    if over.is_mapping() {
                        // (an empty `quick:` changes nothing)
                        layers.push(Layer {
                            file: fpath.clone(),
                            text: Some(ftext.clone()),
                            prefix: prefix.clone(),
                            anchor,
                            value: wrap(over.clone()),
                            section: Some(format!("profiles.{profile}")),
                        });
                    }
                }
            }
        }
        if !file_ok {
            rejected.insert(entry.id.clone());
            continue;
        }
        if let Some(p) = &entry.params {
            let anchor = line.and_then(|ln| locate(&text, &["params"], ln)).unwrap_or(1);
            layers.push(Layer {
                file: path.to_path_buf(),
                text: Some(text.clone()),
                prefix: vec![],
                anchor,
                value: Yaml::Mapping(p.clone()),
                section: None,
            });
        }
        if let Some(p) = entry.profiles.get(profile) {
            let anchor = line
                .and_then(|ln| locate(&text, &["profiles", profile], ln))
                .unwrap_or(1);
            layers.push(Layer {
                file: path.to_path_buf(),
                text: Some(text.clone()),
                prefix: vec![],
                anchor,
                value: Yaml::Mapping(p.clone()),
                section: Some(format!("profiles.{profile}")),
            });
        }
        // Matrix expansion. A matrix key that is not a parameter of the kind only names
        // the members and pairs them with an input swept on the same key.
        let mut sets_param = false;
        let members: Vec<(String, Option<(String, String, Yaml)>)> = match &entry.matrix {
            None => vec![(entry.id.clone(), None)],
            Some(m) if m.len() == 1 => {
                let (k, vals) = m.iter().next().unwrap();
                let l = line.and_then(|ln| locate(&text, &["matrix"], ln));
                if vals.is_empty() {
                    diags.push(
                        path,
                        l,
                        format!("stages[{}].matrix.{k}", entry.id),
                        "empty value list",
                        "give at least one value",
                    );
                    rejected.insert(entry.id.clone());
                    continue;
                }
                if let Some(bad) = vals
                    .iter()
                    .find(|v| !matches!(v, Yaml::Number(_) | Yaml::String(_) | Yaml::Bool(_)))
                {
                    let shown = serde_json::to_string(&serde_yaml::to_string(bad).unwrap_or_default().trim())
                        .unwrap_or_default();
                    diags.push(
                        path,
                        l,
                        format!("stages[{}].matrix.{k}", entry.id),
                        format!("matrix value {shown} is not a number, string or boolean"),
                        "matrix values name the members (`<id>-<key><value>`): use scalars",
                    );
                    rejected.insert(entry.id.clone());
                    continue;
                }
                let bad_ids: Vec<String> = vals
                    .iter()
                    .filter_map(|v| check::check_id(&format!("{}-{}{}", entry.id, k, yaml_scalar_string(v))).err())
                    .collect();
                if !bad_ids.is_empty() {
                    diags.push(
                        path,
                        l,
                        format!("stages[{}].matrix.{k}", entry.id),
                        format!("matrix member id: {}", bad_ids.join("; ")),
                        check::ID_HELP,
                    );
                    rejected.insert(entry.id.clone());
                    continue;
                }
                // The key is checked as a `--set` key is (the kind's schema reads it), and
                // each value against the parameter's type, before any member id is formed.
                let mut base = Yaml::Mapping(Mapping::new());
                for layer in &layers {
                    merge(&mut base, &layer.value);
                }
                let pairs = entry
                    .inputs
                    .as_ref()
                    .is_some_and(|i| input_refs(i).iter().any(|r| swept_on.get(*r) == Some(k)));
                let refs = entry.inputs.as_ref().map(input_refs).unwrap_or_default();
                match check::matrix_key(&kind, &base, k, vals, pairs, &refs) {
                    Ok(role) => sets_param = role == check::MatrixKey::Param,
                    Err((message, help)) => {
                        diags.push(path, l, format!("stages[{}].matrix.{k}", entry.id), message, help);
                        rejected.insert(entry.id.clone());
                        continue;
                    }
                }
                base_matrix.insert(
                    entry.id.clone(),
                    (k.clone(), vals.iter().map(yaml_scalar_string).collect()),
                );
                vals.iter()
                    .map(|v| {
                        let vs = yaml_scalar_string(v);
                        (format!("{}-{}{}", entry.id, k, vs), Some((k.clone(), vs, v.clone())))
                    })
                    .collect()
            }
            Some(_) => {
                let l = line.and_then(|ln| locate(&text, &["matrix"], ln));
                diags.push(
                    path,
                    l,
                    format!("stages[{}].matrix", entry.id),
                    "a matrix takes exactly one key",
                    "sweep one parameter per stage; chain stages for more",
                );
                rejected.insert(entry.id.clone());
                continue;
            }
        };
        let first_member = pending_inputs.len();
        for (mid, mval) in members {
            let mut merged = Yaml::Mapping(Mapping::new());
            for layer in &layers {
                merge(&mut merged, &layer.value);
            }
            let mut mlayers: Vec<(PathBuf, Option<String>, Vec<String>, usize, Yaml)> = layers
                .iter()
                .map(|l| {
                    (
                        l.file.clone(),
                        l.text.clone(),
                        l.prefix.clone(),
                        l.anchor,
                        l.value.clone(),
                    )
                })
                .collect();
            if let Some((k, _, v)) = mval.as_ref().filter(|_| sets_param) {
                let v = super::yaml::matrix_value(&merged, k, v);
                set_path(&mut merged, k, v.clone());
                let mut m = Yaml::Mapping(Mapping::new());
                set_path(&mut m, k, v);
                let anchor = line.and_then(|ln| locate(&text, &["matrix"], ln)).unwrap_or(1);
                mlayers.push((path.to_path_buf(), Some(text.clone()), vec![], anchor, m));
            }
            let mut overrides = Vec::new();
            for s in sets.iter().filter(|s| s.stage == mid || s.stage == entry.id) {
                overrides.push(s.show());
                set_path(&mut merged, &s.key, s.value.clone());
                let mut m = Yaml::Mapping(Mapping::new());
                set_path(&mut m, &s.key, s.value.clone());
                mlayers.push((PathBuf::from("<command line>"), None, vec![], 0, m));
            }
            // NaN, inf and absurd magnitudes first: they are the root cause of whatever
            // the kind's schema would say next ("invalid type: null", a step limit of 0).
            let bad = check::bad_numbers(&merged);
            if !bad.is_empty() {
                for (key, value, allowed) in bad {
                    let (file, l) = attribute(&mlayers, &key, path, line);
                    diags.push(
                        &file,
                        l,
                        format!("stages[{mid}].params.{key}"),
                        format!("value {value} is not allowed"),
                        allowed,
                    );
                }
                rejected.insert(mid.clone());
                rejected.insert(entry.id.clone());
                continue;
            }
            let json = match to_json(&merged) {
                Ok(j) => j,
                Err(e) => {
                    diags.push(
                        path,
                        line,
                        format!("stages[{mid}].params"),
                        format!("params cannot be read: {e}"),
                        "keys must be strings",
                    );
                    continue;
                }
            };
            let params = match (kind.params)(&json) {
                Ok(p) => canonical(p),
                Err(problems) => {
                    for pr in problems {
                        let (file, l) = attribute(&mlayers, &pr.key, path, line);
                        let help = if pr.allowed.is_empty() {
                            format!("see the `{}` kind's parameters in docs/pipeline.md", kind.name)
                        } else {
                            pr.allowed.clone()
                        };
                        let mut message = with_variants(&json, &pr.key, &pr.message, &pr.allowed);
                        if let Some(sec) = section_of(&layers, &mlayers[layers.len()..], &pr.key) {
                            message = format!("{message} (set under `{sec}` of that file)");
                        }
                        diags.push(&file, l, format!("stages[{mid}].params.{}", pr.key), message, help);
                    }
                    rejected.insert(mid.clone());
                    rejected.insert(entry.id.clone());
                    continue;
                }
            };
            let located = kind
                .reads
                .map(|f| f(&params))
                .unwrap_or_default()
                .into_iter()
                .map(|read| {
                    let (file, line) = attribute(&mlayers, &read.key, path, line);
                    super::reads::Located { read, file, line }
                })
                .collect();
            stage_reads.push(located);
            let idx = stages.len();
            stages.push(Stage {
                id: mid.clone(),
                base_id: entry.id.clone(),
                kind: kind.name.to_string(),
                version: kind.version,
                caption: entry.caption.clone(),
                params,
                inputs: vec![],
                line,
                overrides,
                on_demand: entry.on_demand,
            });
            pending_inputs.push((idx, None, mval.as_ref().map(|(k, vs, _)| (k.clone(), vs.clone())), line));
        }
        // Attach the raw inputs spec to the members we just pushed (a rejected member
        // pushed nothing: counting from the matrix would hand its inputs to the previous
        // stage, which then reports roles it never declared).
        for p in pending_inputs[first_member..].iter_mut() {
            p.1 = entry.inputs.as_ref().map(|i| match i {
                InputsSpec::List(v) => InputsSpec::List(v.clone()),
                InputsSpec::Map(m) => InputsSpec::Map(
                    m.iter()
                        .map(|(k, v)| {
                            (
                                k.clone(),
                                match v {
                                    OneOrMany::One(s) => OneOrMany::One(s.clone()),
                                    OneOrMany::Many(v) => OneOrMany::Many(v.clone()),
                                },
                            )
                        })
                        .collect(),
                ),
            });
        }
    }
    // A matrix member may not take the id of another stage.
    let mut seen_ids: HashMap<&str, &Stage> = HashMap::new();
    for st in &stages {
        if let Some(prev) = seen_ids.insert(st.id.as_str(), st) {
            let other = if prev.base_id != prev.id {
                format!("a member of `{}`", prev.base_id)
            } else {
                "a stage".into()
            };
            diags.push(
                path,
                st.line,
                format!("stages[{}].id", st.id),
                format!("duplicate stage id `{}` (also {other})", st.id),
                "rename the stage or change the matrix values",
            );
        }
    }
    // Unknown stages named by --set.
    for s in sets {
        if !stages.iter().any(|st| st.id == s.stage || st.base_id == s.stage) && !seen_base.contains_key(&s.stage) {
            diags.push(
                Path::new("<command line>"),
                None,
                format!("--set {}.{}", s.stage, s.key),
                format!("no stage `{}`", s.stage),
                "use an id from `granrepro list`",
            );
        }
    }
    // Resolve inputs.
    let ids: HashMap<String, usize> = stages.iter().enumerate().map(|(i, s)| (s.id.clone(), i)).collect();
    let mut declared_inputs: std::collections::HashSet<usize> = std::collections::HashSet::new();
    for (idx, spec, mval, line) in pending_inputs {
        let Some(spec) = spec else { continue };
        declared_inputs.insert(idx);
        let pairs: Vec<(String, Vec<String>)> = match spec {
            InputsSpec::List(v) => v.into_iter().map(|id| (id.clone(), vec![id])).collect(),
            InputsSpec::Map(m) => m
                .into_iter()
                .map(|(k, v)| {
                    (
                        k,
                        match v {
                            OneOrMany::One(s) => vec![s],
                            OneOrMany::Many(v) => v,
                        },
                    )
                })
                .collect(),
        };
        let mut resolved = Vec::new();
        // Reads a stage rejected above: its problems are reported there, not again here.
        let mut tainted = false;
        let n_diags = diags.0.len();
        for (role, refs) in pairs {
            let mut out = Vec::new();
            for r in refs {
                if ids.contains_key(&r) {
                    out.push(r);
                    continue;
                }
                let members: Vec<&Stage> = stages.iter().filter(|s| s.base_id == r).collect();
                // A rejected stage, or a member of a rejected matrix stage.
                let of_rejected = rejected.contains(&r)
                    || rejected
                        .iter()
                        .any(|b| r.len() > b.len() + 1 && r.starts_with(b.as_str()) && r.as_bytes()[b.len()] == b'-');
                if of_rejected {
                    tainted = true;
                }
                if members.is_empty() && of_rejected {
                    continue; // already reported where it is defined
                }
                if members.is_empty()
                    && let Some((al, key)) = absent.get(&r)
                {
                    let sid = stages[idx].id.clone();
                    diags.push(
                        path,
                        *al,
                        key.clone(),
                        format!("an empty list leaves `{r}` out of the `{profile}` profile, but `{sid}` reads it (input `{role}`)"),
                        "give this profile's matrix its values, or leave the reading stage out of the profile too",
                    );
                    continue;
                }
                if members.is_empty() {
                    let l = line.and_then(|ln| locate(&text, &["inputs"], ln));
                    let sid = stages[idx].id.clone();
                    diags.push(
                        path,
                        l,
                        format!("stages[{sid}].inputs"),
                        format!("missing input: no stage `{r}` (input `{role}`)"),
                        "name an existing stage id (or a matrix base id)",
                    );
                    continue;
                }
                // Pair matrix members on the same key and value; otherwise fan in all.
                match (&mval, base_matrix.get(&r)) {
                    (Some((k, v)), Some((uk, _))) if k == uk => {
                        let m = format!("{r}-{k}{v}");
                        if ids.contains_key(&m) {
                            out.push(m);
                        } else if rejected.contains(&m) {
                            tainted = true;
                        } else {
                            let sid = stages[idx].id.clone();
                            diags.push(
                                path,
                                line,
                                format!("stages[{sid}].inputs"),
                                format!("missing input: `{r}` has no member for {k} = {v}"),
                                format!("add {v} to the matrix of `{r}`"),
                            );
                        }
                    }
                    _ => out.extend(members.iter().map(|s| s.id.clone())),
                }
            }
            resolved.push((role, out));
        }
        if !tainted && diags.0.len() == n_diags {
            let st = &stages[idx];
            for (message, help) in check::check_roles(&st.kind, &st.params, &resolved) {
                let l = line.and_then(|ln| locate(&text, &["inputs"], ln)).or(line);
                diags.push(path, l, format!("stages[{}].inputs", st.id), message, help);
            }
            // Only once the roles are right: a scalar of a misnamed input means nothing.
            if diags.0.len() == n_diags {
                let kind_of = |id: &str| ids.get(id).and_then(|&i| kinds.get(stages[i].kind.as_str()));
                for (file, l, key, message, help) in super::reads::check(&st.id, &stage_reads[idx], &resolved, kind_of)
                {
                    diags.push(&file, l, key, message, help);
                }
            }
        }
        stages[idx].inputs = resolved;
    }
    // Stages declaring no inputs at all still need their required roles.
    for (i, st) in stages.iter().enumerate() {
        if st.inputs.is_empty() && !declared_inputs.contains(&i) {
            for (message, help) in check::check_roles(&st.kind, &st.params, &[]) {
                diags.push(path, st.line, format!("stages[{}].inputs", st.id), message, help);
            }
        }
    }
    if !diags.is_empty() {
        return Err(diags);
    }
    // Topological order; report a cycle by name.
    let ids: Vec<&str> = stages.iter().map(|s| s.id.as_str()).collect();
    let inputs: Vec<Vec<&str>> = stages
        .iter()
        .map(|s| {
            s.inputs
                .iter()
                .flat_map(|(_, ids)| ids.iter().map(String::as_str))
                .collect()
        })
        .collect();
    match super::order::topo_order(&ids, &inputs) {
        Ok(order) => {
            let mut stages: Vec<Stage> = order.into_iter().map(|i| stages[i].clone()).collect();
            let index: HashMap<String, usize> = stages.iter().enumerate().map(|(i, s)| (s.id.clone(), i)).collect();
            inherit_overrides(&mut stages, &index);
            Ok(Pipeline {
                path: path.to_path_buf(),
                root,
                profile: profile.to_string(),
                stages,
                index,
                kinds,
            })
        }
        Err(cycle) => {
            let l = locate_stage(
                &text,
                stages
                    .iter()
                    .find(|s| s.id == cycle[0])
                    .map(|s| s.base_id.as_str())
                    .unwrap_or(""),
            );
            diags.push(
                path,
                l,
                "stages",
                format!("cycle: {}", cycle.join(" -> ")),
                "remove one of these inputs so the stages form a DAG",
            );
            Err(diags)
        }
    }
}

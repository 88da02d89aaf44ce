//! Contract: the pipeline loader (`granrepro::pipeline::load`, what `run --dry-run` and every
//! other command call first) answers any mutation of the shipped `pipeline.yaml` and
//! `stages/` files with `Ok`, or with bad-input diagnostics (exit 2) that name the mutated
//! file and the key (or the line) — never a panic, and it writes nothing.
//!
//! A seeded generator of ours (ChaCha8, case `i` is seed `i`, so a failure replays by its
//! number). The project is copied once to a temp directory; each case cuts its
//! `pipeline.yaml` to one random stage and everything upstream (so a case loads a few
//! stages, not 184), then rewrites one or two files with mutations of types, ranges, keys,
//! anchors and aliases, nesting, matrices and inputs, made on the parsed YAML so most
//! cases get past the parser into kind validation and matrix expansion (the test counts
//! how many do), and restores them after. Each case runs under `catch_unwind`; a failure
//! prints the mutation, and the mutated files of the first failure in full. A mutation
//! that changes a value or a key must be named by a diagnostic in its file (the key or the
//! value); a removal or a text edit may surface elsewhere, and must only be placed (a file
//! of the project, and a key or a line).
//! `LOADER_PROP_CASES` sets the number of cases (default 2000).

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_yaml::{Mapping, Value as Yaml};

/// Relative paths of the project's YAML files (pipeline.yaml first), and their texts.
fn project_files(root: &Path) -> Vec<(String, String)> {
    fn walk(dir: &Path, rel: &str, out: &mut Vec<(String, String)>) {
        let mut entries: Vec<_> = std::fs::read_dir(dir).unwrap().flatten().collect();
        entries.sort_by_key(|e| e.file_name());
        for e in entries {
            let name = format!("{rel}/{}", e.file_name().to_string_lossy());
            if e.path().is_dir() {
                walk(&e.path(), &name, out);
            } else if name.ends_with(".yaml") {
                out.push((name, std::fs::read_to_string(e.path()).unwrap()));
            }
        }
    }
    let mut out = vec![(
        "pipeline.yaml".to_string(),
        std::fs::read_to_string(root.join("pipeline.yaml")).unwrap(),
    )];
    walk(&root.join("stages"), "stages", &mut out);
    out
}

/// Every file under `dir`, relative.
fn tree(dir: &Path) -> BTreeSet<PathBuf> {
    let mut out = BTreeSet::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            if e.path().is_dir() {
                todo.push(e.path());
            } else {
                out.insert(e.path().strip_prefix(dir).unwrap().to_path_buf());
            }
        }
    }
    out
}

/// One mutation: which file, what was done, and the names a good message may use for the
/// place (the key, or the old or new value); empty for text-level mutations, where the
/// file (and a line) is enough.
struct Mutation {
    file: String,
    what: String,
    names: Vec<String>,
}

/// Keys the generator adds or renames to: parameters of several kinds, stage-entry keys,
/// profile names, and typos.
const VOCAB: &[&str] = &[
    "a", "mu_r", "n", "seed", "dem", "mpm", "ppc", "run", "matrix", "inputs", "params", "profiles", "quick", "paper",
    "id", "kind", "params_file", "caption", "grain", "kn", "dt", "area_m2", "packing", "psd", "column", "x",
    "d_min_mm",
];

fn scalar(rng: &mut ChaCha8Rng) -> Yaml {
    let s = |v: &str| Yaml::String(v.to_string());
    match rng.random_range(0..16) {
        0 => s("big"),
        1 => Yaml::Number((-1).into()),
        2 => Yaml::Number(0.into()),
        3 => Yaml::Number(1e300.into()),
        4 => Yaml::Number(f64::NAN.into()),
        5 => Yaml::Number(f64::NEG_INFINITY.into()),
        6 => Yaml::Bool(rng.random()),
        7 => Yaml::Null,
        8 => s("a/b"),
        9 => s(""),
        10 => Yaml::Number(u64::MAX.into()),
        11 => Yaml::Number((rng.random_range(-5.0..5.0f64)).into()),
        12 => Yaml::Number(rng.random_range(0..20u64).into()),
        13 => s("../x"),
        14 => s(VOCAB[rng.random_range(0..VOCAB.len())]),
        _ => Yaml::Number(1e-300.into()),
    }
}

fn value(rng: &mut ChaCha8Rng, depth: usize) -> Yaml {
    if depth > 2 {
        return scalar(rng);
    }
    match rng.random_range(0..8) {
        0 => Yaml::Sequence((0..rng.random_range(0..3)).map(|_| value(rng, depth + 1)).collect()),
        1 => {
            let mut m = Mapping::new();
            for _ in 0..rng.random_range(0..3) {
                m.insert(VOCAB[rng.random_range(0..VOCAB.len())].into(), value(rng, depth + 1));
            }
            Yaml::Mapping(m)
        }
        _ => scalar(rng),
    }
}

/// Paths of every node (sequence index as a number key, mapping key as a string).
#[derive(Clone, Debug)]
enum Seg {
    Key(Yaml),
    Idx(usize),
}

fn nodes(v: &Yaml, path: &mut Vec<Seg>, out: &mut Vec<Vec<Seg>>) {
    out.push(path.clone());
    match v {
        Yaml::Mapping(m) => {
            for (k, x) in m {
                path.push(Seg::Key(k.clone()));
                nodes(x, path, out);
                path.pop();
            }
        }
        Yaml::Sequence(s) => {
            for (i, x) in s.iter().enumerate() {
                path.push(Seg::Idx(i));
                nodes(x, path, out);
                path.pop();
            }
        }
        _ => {}
    }
}

fn at<'a>(v: &'a mut Yaml, path: &[Seg]) -> &'a mut Yaml {
    let mut cur = v;
    for s in path {
        cur = match (s, cur) {
            (Seg::Key(k), Yaml::Mapping(m)) => m.get_mut(k).unwrap(),
            (Seg::Idx(i), Yaml::Sequence(q)) => &mut q[*i],
            _ => unreachable!(),
        };
    }
    cur
}

fn show(v: &Yaml) -> String {
    match v {
        Yaml::String(s) => s.clone(),
        other => serde_yaml::to_string(other).unwrap_or_default().trim().to_string(),
    }
}

/// The last mapping key on a path (what a message names), as text.
fn leaf(path: &[Seg]) -> Option<String> {
    path.iter().rev().find_map(|s| match s {
        Seg::Key(k) => Some(show(k)),
        Seg::Idx(_) => None,
    })
}

/// A structural mutation of one parsed file.
fn mutate_tree(rng: &mut ChaCha8Rng, doc: &mut Yaml, stage_ids: &[String]) -> (String, Vec<String>) {
    let mut all = Vec::new();
    nodes(doc, &mut vec![], &mut all);
    let path = all[rng.random_range(0..all.len())].clone();
    let name = leaf(&path);
    let mut names: Vec<String> = name.iter().cloned().collect();
    let shown = format!("{path:?}");
    let node = at(doc, &path);
    let old = node.clone();
    names.push(show(&old));
    let what = match rng.random_range(0..10) {
        // types and ranges
        0..=2 => {
            let new = if rng.random_range(0..3) == 0 {
                value(rng, 0)
            } else {
                scalar(rng)
            };
            let removes = new.is_null();
            names.push(show(&new));
            *node = new;
            if removes {
                names.clear(); // a removal surfaces as whatever the default then breaks
            }
            "replace"
        }
        3 => match node.as_f64() {
            Some(x) => {
                let f = [-1.0, 0.0, 1e6, 1e-9, 0.5, 1e20][rng.random_range(0..6)];
                let new = Yaml::Number((x * f).into());
                names.push(show(&new));
                *node = new;
                "scale"
            }
            None => {
                *node = Yaml::Number(rng.random_range(0..5u64).into());
                "to-number"
            }
        },
        // keys: delete, rename, add
        4 => match node {
            Yaml::Mapping(m) if !m.is_empty() => {
                let k = m.keys().nth(rng.random_range(0..m.len())).unwrap().clone();
                m.remove(&k);
                names.clear(); // a removal surfaces as whatever the default then breaks
                "delete-key"
            }
            _ => {
                *node = Yaml::Mapping(Mapping::new());
                names.clear();
                "to-empty-mapping"
            }
        },
        5 => match node {
            Yaml::Mapping(m) if !m.is_empty() => {
                let k = m.keys().nth(rng.random_range(0..m.len())).unwrap().clone();
                let v = m.remove(&k).unwrap();
                let nk = if rng.random() {
                    format!("{}x", show(&k))
                } else {
                    VOCAB[rng.random_range(0..VOCAB.len())].to_string()
                };
                names.extend([show(&k), nk.clone()]);
                m.insert(nk.into(), v);
                "rename-key"
            }
            _ => "noop",
        },
        6 => match node {
            Yaml::Mapping(m) => {
                let k = VOCAB[rng.random_range(0..VOCAB.len())];
                names.push(k.to_string());
                m.insert(k.into(), value(rng, 1));
                "add-key"
            }
            _ => "noop",
        },
        // nesting
        7 => {
            let v = std::mem::take(node);
            *node = match rng.random_range(0..3) {
                0 => Yaml::Sequence(vec![v]),
                1 => {
                    let mut m = Mapping::new();
                    m.insert(VOCAB[rng.random_range(0..VOCAB.len())].into(), v);
                    Yaml::Mapping(m)
                }
                _ => match v {
                    Yaml::Mapping(m) => m.into_iter().next().map(|(_, x)| x).unwrap_or(Yaml::Null),
                    Yaml::Sequence(s) => s.into_iter().next().unwrap_or(Yaml::Null),
                    other => other,
                },
            };
            names.clear(); // the old key's content moved: it may surface as missing
            "nest"
        }
        // matrices and inputs (of the stage entry the node is in, in pipeline.yaml)
        _ => {
            let entry = match path.as_slice() {
                [Seg::Key(k), Seg::Idx(i), ..] if show(k) == "stages" => Some(*i),
                _ => None,
            };
            let Some(i) = entry else {
                return (format!("noop at {shown}"), names);
            };
            let e = at(doc, &path[..2]);
            let Yaml::Mapping(m) = e else {
                return (format!("noop at {shown}"), names);
            };
            if rng.random() {
                let key = match m
                    .get("matrix")
                    .and_then(|x| x.as_mapping())
                    .and_then(|x| x.keys().next())
                {
                    Some(k) if rng.random() => show(k),
                    _ => {
                        let params: Vec<String> = m
                            .get("params")
                            .and_then(|p| p.as_mapping())
                            .map(|p| p.keys().map(show).collect())
                            .unwrap_or_default();
                        if !params.is_empty() && rng.random() {
                            params[rng.random_range(0..params.len())].clone()
                        } else {
                            VOCAB[rng.random_range(0..VOCAB.len())].to_string()
                        }
                    }
                };
                let vals: Vec<Yaml> = (0..rng.random_range(0..4)).map(|_| scalar(rng)).collect();
                let mut mm = Mapping::new();
                mm.insert(key.clone().into(), Yaml::Sequence(vals));
                names.extend(["matrix".to_string(), key]);
                if rng.random_range(0..4) == 0 {
                    let mut p = Mapping::new();
                    p.insert("matrix".into(), Yaml::Mapping(mm));
                    let mut pr = Mapping::new();
                    pr.insert(
                        ["quick", "paper", "slow"][rng.random_range(0..3)].into(),
                        Yaml::Mapping(p),
                    );
                    m.insert("profiles".into(), Yaml::Mapping(pr));
                    return (format!("profile-matrix on stages[{i}]"), names);
                }
                m.insert("matrix".into(), Yaml::Mapping(mm));
                return (format!("matrix on stages[{i}]"), names);
            }
            let r = match rng.random_range(0..3) {
                0 => stage_ids[rng.random_range(0..stage_ids.len())].clone(),
                1 => format!("{}-a0.4", stage_ids[rng.random_range(0..stage_ids.len())]),
                _ => "nope".to_string(),
            };
            let role = ["psd", "column", "runs", "data", "x"][rng.random_range(0..5)];
            let mut inp = m
                .get("inputs")
                .and_then(|x| x.as_mapping())
                .cloned()
                .unwrap_or_default();
            inp.insert(role.into(), Yaml::String(r.clone()));
            m.insert("inputs".into(), Yaml::Mapping(inp));
            names.extend(["inputs".to_string(), role.to_string(), r]);
            return (format!("input {role}: on stages[{i}]"), names);
        }
    };
    if path.is_empty() {
        names.clear(); // the whole file: naming the file (and a line) is enough
    }
    (format!("{what} at {shown}"), names)
}

/// A text-level mutation: anchors and aliases, merge keys, duplicate keys, truncation.
fn mutate_text(rng: &mut ChaCha8Rng, text: &str) -> (String, String) {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let keyed: Vec<usize> = (0..lines.len())
        .filter(|&i| {
            let t = lines[i].trim_start();
            !t.starts_with('#') && t.contains(": ") && !t.ends_with(':')
        })
        .collect();
    if keyed.is_empty() {
        return (format!("{text}\n: :\n"), "broken line".into());
    }
    let pick = |rng: &mut ChaCha8Rng| keyed[rng.random_range(0..keyed.len())];
    let what = match rng.random_range(0..6) {
        0 | 1 => {
            // an anchor on one value, an alias of it on another
            let (i, j) = (pick(rng), pick(rng));
            let (k, v) = lines[i]
                .split_once(": ")
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .unwrap();
            lines[i] = format!("{k}: &anc {v}");
            let kj = lines[j].split_once(": ").map(|(k, _)| k.to_string()).unwrap();
            lines[j] = format!("{kj}: *anc");
            format!("anchor at line {}, alias at line {}", i + 1, j + 1)
        }
        2 => {
            let j = pick(rng);
            let kj = lines[j].split_once(": ").map(|(k, _)| k.to_string()).unwrap();
            lines[j] = format!("{kj}: *undefined");
            format!("undefined alias at line {}", j + 1)
        }
        3 => {
            let i = pick(rng);
            let line = lines[i].clone();
            lines.insert(i + 1, line);
            format!("duplicate key at line {}", i + 2)
        }
        4 => {
            let (i, j) = (pick(rng), pick(rng));
            let (k, v) = lines[i]
                .split_once(": ")
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .unwrap();
            lines[i] = format!("{k}: &m {v}");
            let indent = lines[j].len() - lines[j].trim_start().len();
            let dash = if lines[j].trim_start().starts_with("- ") { 2 } else { 0 };
            lines.insert(j + 1, format!("{}<<: *m", " ".repeat(indent + dash)));
            format!("merge key at line {}", j + 2)
        }
        _ => {
            let cut = rng.random_range(0..text.len().max(1));
            let cut = (0..=cut).rev().find(|c| text.is_char_boundary(*c)).unwrap_or(0);
            return (text[..cut].to_string(), format!("truncated at byte {cut}"));
        }
    };
    (lines.join("\n") + "\n", what)
}

/// Every stage id an entry's `inputs` names.
fn input_refs(e: &Yaml) -> Vec<String> {
    let strs = |v: &Yaml| -> Vec<String> {
        match v {
            Yaml::String(s) => vec![s.clone()],
            Yaml::Sequence(q) => q.iter().filter_map(|x| x.as_str().map(str::to_string)).collect(),
            _ => vec![],
        }
    };
    match e.get("inputs") {
        Some(Yaml::Mapping(m)) => m.values().flat_map(strs).collect(),
        Some(v) => strs(v),
        None => vec![],
    }
}

/// The shipped pipeline cut to one stage and everything upstream of it (a valid pipeline
/// of a few stages: a case then costs milliseconds, not the whole 184-stage load).
fn sub_pipeline(doc: &Yaml, target: usize) -> Yaml {
    let entries = doc["stages"].as_sequence().unwrap();
    let id = |e: &Yaml| e.get("id").and_then(|v| v.as_str()).unwrap_or("").to_string();
    // A reference is a stage id, or a member `<base>-<key><value>` of a matrix stage (the
    // longest base: `col-dem-hex-a6` is a member of `col-dem-hex`, not of `col-dem`).
    let find = |r: &str| {
        entries.iter().position(|e| id(e) == r).or_else(|| {
            (0..entries.len())
                .filter(|&i| entries[i].get("matrix").is_some() && r.starts_with(&format!("{}-", id(&entries[i]))))
                .max_by_key(|&i| id(&entries[i]).len())
        })
    };
    let mut keep = BTreeSet::new();
    let mut todo = vec![target];
    while let Some(i) = todo.pop() {
        if keep.insert(i) {
            todo.extend(input_refs(&entries[i]).iter().filter_map(|r| find(r)));
        }
    }
    let mut out = doc.clone();
    out["stages"] = Yaml::Sequence(keep.into_iter().map(|i| entries[i].clone()).collect());
    out
}

#[test]
fn loader_answers_ok_or_named_bad_input_for_mutated_projects() {
    let cases: u64 = std::env::var("LOADER_PROP_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2000);
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let files = project_files(repo);
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    for (rel, text) in &files {
        let p = root.join(rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    }
    let before = tree(root);
    let pipeline = root.join("pipeline.yaml");
    let mut parsed: Vec<Yaml> = files.iter().map(|(_, t)| serde_yaml::from_str(t).unwrap()).collect();
    let shipped = parsed[0].clone();
    let n_stages = shipped["stages"].as_sequence().unwrap().len();
    // The unmutated project loads.
    granrepro::pipeline::load(&pipeline, "quick", &[]).unwrap_or_else(|d| panic!("{d}"));

    let t0 = std::time::Instant::now();
    let (mut ok, mut refused, mut past_parser) = (0usize, 0usize, 0usize);
    let mut failures: Vec<String> = Vec::new();
    for case in 0..cases {
        let mut rng = ChaCha8Rng::seed_from_u64(case);
        // This case's pipeline: one stage and its upstream closure.
        parsed[0] = sub_pipeline(&shipped, rng.random_range(0..n_stages));
        let sub_text = serde_yaml::to_string(&parsed[0]).unwrap();
        std::fs::write(&pipeline, &sub_text).unwrap();
        let stage_ids: Vec<String> = parsed[0]["stages"]
            .as_sequence()
            .unwrap()
            .iter()
            .filter_map(|e| e.get("id").and_then(|v| v.as_str()).map(str::to_string))
            .collect();
        // Files this pipeline reads (a mutation of another stages/ file cannot matter).
        let used: Vec<usize> = (0..files.len())
            .filter(|&i| i == 0 || sub_text.contains(files[i].0.as_str()))
            .collect();
        let original = |fi: usize| if fi == 0 { sub_text.clone() } else { files[fi].1.clone() };
        let n_mut = if rng.random_range(0..4) == 0 { 2 } else { 1 };
        let mut muts: Vec<Mutation> = Vec::new();
        let mut texts: Vec<(usize, String)> = Vec::new();
        for _ in 0..n_mut {
            // pipeline.yaml half the time, else a stage file the pipeline reads
            let fi = if rng.random() {
                0
            } else {
                used[rng.random_range(0..used.len())]
            };
            let base = texts
                .iter()
                .find(|(i, _)| *i == fi)
                .map(|(_, t)| t.clone())
                .unwrap_or_else(|| original(fi));
            let (text, m) = if rng.random_range(0..5) == 0 {
                let (t, what) = mutate_text(&mut rng, &base);
                (
                    t,
                    Mutation {
                        file: files[fi].0.clone(),
                        what,
                        names: vec![],
                    },
                )
            } else {
                let mut doc: Yaml = serde_yaml::from_str(&base).unwrap_or_else(|_| parsed[fi].clone());
                let (what, names) = mutate_tree(&mut rng, &mut doc, &stage_ids);
                (
                    serde_yaml::to_string(&doc).unwrap(),
                    Mutation {
                        file: files[fi].0.clone(),
                        what,
                        names,
                    },
                )
            };
            texts.retain(|(i, _)| *i != fi);
            texts.push((fi, text));
            muts.push(m);
        }
        for (fi, t) in &texts {
            std::fs::write(root.join(&files[*fi].0), t).unwrap();
        }
        let profile = if rng.random_range(0..4) == 0 { "paper" } else { "quick" };
        let res = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            granrepro::pipeline::load(&pipeline, profile, &[])
        }));
        // The mutations, and the mutated files in full for the first failure.
        let describe = |full: bool| {
            let mut s = format!("case {case} (profile {profile}):");
            for m in &muts {
                s += &format!("\n  {}: {} (names {:?})", m.file, m.what, m.names);
            }
            for (fi, t) in texts.iter().filter(|_| full) {
                s += &format!("\n  --- mutated {} ---\n{}", files[*fi].0, t);
            }
            s
        };
        match res {
            Err(p) => {
                let msg = p
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                failures.push(format!("PANIC {msg}\n{}", describe(failures.is_empty())));
            }
            Ok(Ok(_)) => ok += 1,
            Ok(Err(d)) => {
                refused += 1;
                if !d.0.iter().any(|x| x.message.starts_with("YAML syntax error")) {
                    past_parser += 1;
                }
                let in_project = |f: &Path| f.starts_with(root);
                let unplaced: Vec<String> =
                    d.0.iter()
                        .filter(|x| !in_project(&x.file) || (x.key.is_empty() && x.line.is_none()))
                        .map(|x| x.to_string())
                        .collect();
                // The mutated file is named, and (for a mutation of the parsed tree) the
                // place: its key or its value, in the key or the message.
                // (A removal or a text edit may surface anywhere: placement is enough.)
                let named = muts.iter().any(|m| {
                    m.names.is_empty()
                        || d.0.iter().any(|x| {
                            x.file == root.join(&m.file)
                                && m.names.iter().any(|n| {
                                    !n.is_empty() && (x.key.contains(n.as_str()) || x.message.contains(n.as_str()))
                                })
                        })
                });
                if !unplaced.is_empty() || !named {
                    failures.push(format!(
                        "diagnostics do not name the mutated file and key{}:\n{d}\n{}",
                        if unplaced.is_empty() {
                            String::new()
                        } else {
                            format!(" (unplaced: {unplaced:?})")
                        },
                        describe(failures.is_empty())
                    ));
                }
            }
        }
        for (fi, _) in &texts {
            std::fs::write(root.join(&files[*fi].0), original(*fi)).unwrap();
        }
        assert_eq!(tree(root), before, "case {case}: the loader wrote a file");
        if failures.len() >= 5 {
            break;
        }
    }
    let secs = t0.elapsed().as_secs_f64();
    eprintln!(
        "{cases} cases in {secs:.1} s: {ok} Ok, {refused} refused ({past_parser} past the YAML parser), {} failures",
        failures.len()
    );
    assert!(
        failures.is_empty(),
        "{} failing case(s):\n\n{}",
        failures.len(),
        failures.join("\n\n")
    );
    // The generator must reach validation, not only the parser.
    assert!(
        past_parser * 2 > refused,
        "only {past_parser} of {refused} refusals got past the YAML parser"
    );
}

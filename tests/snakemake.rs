//! The exported Snakefile runs: `granrepro export snakemake` of a small quick sub-DAG,
//! `snakemake -j 2` over a shared cache directory, then `granrepro run` assembles the
//! reports from that cache without recomputing, bit-identical to a plain `granrepro run`.
//!
//! Needs `snakemake` (on PATH, or the path in SNAKEMAKE), so the test is `#[ignore]`d: a
//! plain `cargo test` lists it as ignored with that reason instead of passing it unrun.
//! `.ci/run` installs snakemake into a virtual environment and runs it with `--ignored`;
//! run that way, a missing snakemake fails the test.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Cheap stages (each well under a second) with one dependency edge (psd-col feeds
/// tab4-02 and fig4-01b).
const TARGETS: [&str; 4] = ["fig4-01b", "tab4-02", "laws", "psd-shear"];

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_granrepro")
}

/// A copy of the repository's pipeline and stage files in a temp directory.
fn project() -> tempfile::TempDir {
    let src = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(src.join("pipeline.yaml"), dir.path().join("pipeline.yaml")).unwrap();
    copy_dir(&src.join("stages"), &dir.path().join("stages"));
    dir
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            copy_dir(&p, &to.join(e.file_name()));
        } else {
            std::fs::copy(&p, to.join(e.file_name())).unwrap();
        }
    }
}

fn granrepro(dir: &Path, args: &[&str]) -> (i32, String, String) {
    let out = Command::new(bin())
        .current_dir(dir)
        .env_remove("GRANREPRO_CACHE")
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

fn stage_args(cmd: &[&'static str]) -> Vec<&'static str> {
    let mut v = cmd.to_vec();
    for t in TARGETS {
        v.extend(["--stage", t]);
    }
    v
}

/// The snakemake to use, or None (with the reason) when there is none.
fn snakemake() -> Result<PathBuf, String> {
    let exe = std::env::var_os("SNAKEMAKE")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("snakemake"));
    match Command::new(&exe).arg("--version").output() {
        Ok(o) if o.status.success() => Ok(exe),
        Ok(o) => Err(format!(
            "`{} --version` failed: {}",
            exe.display(),
            String::from_utf8_lossy(&o.stderr)
        )),
        Err(e) => Err(format!("`{}` not runnable: {e}", exe.display())),
    }
}

/// Published tables, figures and scalars of a report directory (not the run records,
/// which hold wall times, nor the index).
fn published(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| !n.starts_with('.') && !n.ends_with(".record.json") && n != "index.html")
        .map(|n| {
            let b = std::fs::read(dir.join(&n)).unwrap();
            (n, b)
        })
        .collect();
    v.sort();
    v
}

#[test]
#[ignore = "needs snakemake on PATH; .ci/run installs it"]
fn snakemake_runs_the_exported_sub_dag_bit_identical_to_granrepro_run() {
    // Ignored by a plain `cargo test` (its summary counts it as ignored, with the reason);
    // run on purpose (`cargo test --test snakemake -- --ignored`, as .ci/run does), a
    // missing snakemake is a failure, never a silent pass.
    let smk = snakemake().unwrap_or_else(|why| {
        panic!(
            "snakemake is required by this test (.ci/run installs it with pip into a venv; or `pip install snakemake`, or set SNAKEMAKE=/path/to/snakemake): {why}"
        )
    });
    let a = project();
    let shared = tempfile::tempdir().unwrap();
    let cache = shared.path().join("cache"); // does not exist yet: created by the first worker
    let cache_s = cache.to_str().unwrap();

    // Export with the shared cache baked into the rules.
    let mut args = vec!["--cache", cache_s];
    args.extend(stage_args(&["export", "snakemake", "--profile", "quick"]));
    let (code, snakefile, err) = granrepro(a.path(), &args);
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        snakefile.matches("\nrule stage_").count(),
        5,
        "psd-col, psd-shear, tab4-02, fig4-01b, laws:\n{snakefile}"
    );
    std::fs::write(a.path().join("Snakefile"), &snakefile).unwrap();

    let out = Command::new(&smk)
        .current_dir(a.path())
        .args(["-s", "Snakefile", "-j", "2"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "snakemake failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );

    // Every planned key is in the shared cache, and every marker in place.
    let (code, plan, err) = granrepro(a.path(), &{
        let mut v = vec!["--cache", cache_s];
        v.extend(stage_args(&["plan", "--json"]));
        v
    });
    assert_eq!(code, 0, "{err}");
    let plan: serde_json::Value = serde_json::from_str(&plan).unwrap();
    let stages = plan["stages"].as_array().unwrap();
    assert_eq!(stages.len(), 5);
    for s in stages {
        let (id, key) = (s["id"].as_str().unwrap(), s["key"].as_str().unwrap());
        assert_eq!(s["cached"], true, "{id} not in the shared cache after snakemake");
        assert!(
            cache.join(key).join("manifest.json").is_file(),
            "{id}: no entry {key} in {cache_s}"
        );
        assert!(
            a.path()
                .join(".granrepro/markers/quick")
                .join(format!("{id}.{key}.done"))
                .is_file(),
            "{id}: no marker"
        );
    }
    assert!(
        !a.path().join(".granrepro/cache").exists(),
        "workers wrote to the project cache, not the shared one"
    );

    // A second snakemake has nothing to do.
    let again = Command::new(&smk)
        .current_dir(a.path())
        .args(["-s", "Snakefile", "-j", "2", "--dry-run"])
        .output()
        .unwrap();
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&again.stdout),
        String::from_utf8_lossy(&again.stderr)
    );
    assert!(again.status.success() && said.contains("Nothing to be done"), "{said}");

    // A changed stage (psd-col's seed) is a new key, so a new marker: re-exported,
    // Snakemake would run psd-col and its dependants, nothing else.
    let psd = a.path().join("stages/psd-col.yaml");
    let text = std::fs::read_to_string(&psd).unwrap();
    assert!(
        text.contains("seed: 20150401"),
        "stages/psd-col.yaml changed: update this test"
    );
    std::fs::write(&psd, text.replace("seed: 20150401", "seed: 20150402")).unwrap();
    let mut args = vec!["--cache", cache_s];
    args.extend(stage_args(&["export", "snakemake"]));
    let (code, changed, err) = granrepro(a.path(), &args);
    assert_eq!(code, 0, "{err}");
    std::fs::write(a.path().join("Snakefile.changed"), &changed).unwrap();
    // Memory requests now come from the peaks the workers recorded in their markers.
    assert!(
        snakefile.contains("mem_mb=4000,") && !changed.contains("mem_mb=4000,"),
        "{changed}"
    );
    let dry = Command::new(&smk)
        .current_dir(a.path())
        .args(["-s", "Snakefile.changed", "-j", "2", "--dry-run"])
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&dry.stdout).to_string() + &String::from_utf8_lossy(&dry.stderr);
    assert!(dry.status.success(), "{said}");
    for r in ["stage_psd_col", "stage_tab4_02", "stage_fig4_01b"] {
        assert!(said.contains(&format!("rule {r}:")), "{r} should rerun:\n{said}");
    }
    for r in ["stage_laws", "stage_psd_shear"] {
        assert!(!said.contains(&format!("rule {r}:")), "{r} should not rerun:\n{said}");
    }
    std::fs::write(&psd, text).unwrap();

    // `granrepro run` assembles reports/ from the shared cache without recomputing.
    std::fs::remove_dir_all(a.path().join("reports")).ok();
    let mut args = vec!["--cache", cache_s];
    args.extend(stage_args(&["run", "--quiet"]));
    let (code, out, err) = granrepro(a.path(), &args);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("0 ran, 5 cached"), "{out}\n{err}");

    // A plain run in another project, own cache: the same tables, figures and scalars.
    let b = project();
    let (code, out, err) = granrepro(b.path(), &stage_args(&["run", "--quiet"]));
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("5 ran, 0 cached"), "{out}");
    let (pa, pb) = (
        published(&a.path().join("reports/quick")),
        published(&b.path().join("reports/quick")),
    );
    let names: Vec<&str> = pb.iter().map(|(n, _)| n.as_str()).collect();
    assert!(
        names.contains(&"tab4-02.csv")
            && names.contains(&"tab4-02.parquet")
            && names.contains(&"fig4-01b.svg")
            && names.contains(&"psd-shear.parquet"),
        "{names:?}"
    );
    assert_eq!(pa.len(), pb.len(), "{names:?}");
    for ((na, ba), (nb, bb)) in pa.iter().zip(&pb) {
        assert_eq!(na, nb);
        assert!(ba == bb, "{na} differs between the snakemake run and `granrepro run`");
    }
}

#[test]
fn export_and_plan_refuse_bad_input_with_exit_2() {
    let a = project();
    let (code, out, err) = granrepro(a.path(), &["export", "snakemake", "--stage", "no-such-stage"]);
    assert_eq!(code, 2, "{out}{err}");
    assert!(err.contains("no-such-stage") && out.is_empty(), "{err}");
    let (code, _, err) = granrepro(a.path(), &["plan", "--json", "--stage", "no-such-stage"]);
    assert_eq!(code, 2);
    assert!(err.contains("no-such-stage"), "{err}");
    let missing = a.path().join("no/such/parent/cache");
    let (code, out, err) = granrepro(a.path(), &["--cache", missing.to_str().unwrap(), "export", "snakemake"]);
    assert_eq!(code, 2, "{out}{err}");
    assert!(
        err.contains("--cache") && err.contains("does not exist") && out.is_empty(),
        "{err}"
    );
    let out = Command::new(bin())
        .current_dir(a.path())
        .env("GRANREPRO_CACHE", &missing)
        .args(["run", "--stage", "laws"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("GRANREPRO_CACHE"));
    assert!(
        !a.path().join("reports").exists() && !a.path().join(".granrepro").exists(),
        "nothing may be written on bad input"
    );
}

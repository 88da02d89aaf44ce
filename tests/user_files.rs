//! Safe with the user's files (issue 8): nothing written or removed before validation,
//! `clean` removes only what granrepro made, reports are published as sets listed from
//! the pipeline, nothing stale is shown, modes are 0644/0755, errors name their path,
//! run records are stable, `--set` reaches dotted ids.

mod common;
use common::{SMALL, TempProject};
use std::path::Path;

fn read(p: impl AsRef<Path>) -> String {
    std::fs::read_to_string(p.as_ref()).unwrap_or_else(|e| panic!("{}: {e}", p.as_ref().display()))
}

/// Finding 3: `simulate bad.yaml --out .` overwrote the project's pipeline.yaml although
/// the scene was rejected (the generated file was written before validation).
#[test]
fn simulate_writes_nothing_for_a_bad_scene_and_points_at_its_line() {
    let t = TempProject::new(SMALL);
    t.write("bad.yaml", "# a scene\npsd:\n  n: -3\n");
    let (code, _, err) = t.cli(&[
        "simulate",
        t.path().join("bad.yaml").to_str().unwrap(),
        "--out",
        t.path().to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{err}");
    assert_eq!(read(t.pipeline()), SMALL, "the project's pipeline.yaml was overwritten");
    assert!(
        err.contains("bad.yaml:3") && err.contains("psd.n"),
        "should name the scene file's line and key: {err}"
    );
    assert!(!t.path().join(".granrepro").exists() && !t.path().join("reports").exists());
}

/// Finding 3: a valid scene must not write into a non-empty directory it did not make.
#[test]
fn simulate_refuses_a_non_empty_directory_it_did_not_make() {
    let t = TempProject::new(SMALL);
    t.write("ok.yaml", "psd: { n: 50 }\nrun: {}\n");
    let (code, _, err) = t.cli(&[
        "simulate",
        t.path().join("ok.yaml").to_str().unwrap(),
        "--out",
        t.path().to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("non-empty directory"), "{err}");
    assert_eq!(read(t.pipeline()), SMALL);
}

/// The same for a CD scene: it was routed past the DEM's safe path and wrote (and ran)
/// into any directory, the project's own included.
#[test]
fn cd_simulate_refuses_a_non_empty_directory_it_did_not_make() {
    let t = TempProject::new(SMALL);
    t.write("cd.yaml", "engine: cd\nscene: shear\npsd: { n: 50 }\ngrains: 20\n");
    let (code, _, err) = t.cli(&[
        "simulate",
        t.path().join("cd.yaml").to_str().unwrap(),
        "--out",
        t.path().to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("non-empty directory"), "{err}");
    assert_eq!(read(t.pipeline()), SMALL, "the project's pipeline.yaml was overwritten");
    assert!(!t.path().join(".granrepro").exists());
}

/// A CD shear scene runs psd → cd-shear → its figure, the project's fig4-25 declaration
/// built in: μ* against I with the fitted line and the chapter's 0.22 in the legend.
#[test]
fn cd_shear_simulate_draws_the_declared_figure() {
    let t = TempProject::new(SMALL);
    t.write(
        "cd.yaml",
        "engine: cd\nscene: shear\npsd: { n: 60 }\ngrains: 60\nshear: { inertial_numbers: [0.01, 0.1], strain: 0.3 }\n",
    );
    let out = t.path().join("sim");
    let (code, _, err) = t.cli(&[
        "simulate",
        t.path().join("cd.yaml").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(code, 0, "{err}");
    let svg = read(out.join("reports/quick/figure.svg"));
    assert!(
        svg.contains("stated (§4.4.1): μ* = 0.220") && svg.contains("fit μ = μ_min + b I"),
        "{svg:.300}"
    );
    let fig: serde_json::Value = serde_json::from_str(&read(out.join("reports/quick/figure.json"))).unwrap();
    assert_eq!(
        fig["scalars"]["panel0_points"].as_f64(),
        Some(2.0),
        "one point per inertial number"
    );
}

/// Finding 3: `clean --reports --pipeline missing.yaml` deleted a reports/ folder.
#[test]
fn clean_with_a_missing_pipeline_removes_nothing() {
    let t = TempProject::new(SMALL);
    t.write("reports/paper.pdf", "%PDF");
    let missing = t.path().join("missing.yaml");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_granrepro"))
        .args(["clean", "--reports", "--pipeline"])
        .arg(&missing)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing.yaml"));
    assert!(t.path().join("reports/paper.pdf").exists(), "a user's file was deleted");
}

/// Finding 3: `clean --reports` deleted the tracked reports/README.md and every profile.
#[test]
fn clean_removes_only_what_granrepro_made_for_the_profile_asked() {
    let t = TempProject::new(SMALL);
    for profile in ["quick", "paper"] {
        let (code, _, err) = t.cli(&["run", "--stage", "psd-a", "--quiet", "--profile", profile]);
        assert_eq!(code, 0, "{err}");
    }
    t.write("reports/README.md", "# our reports\n");
    t.write("reports/quick/notes.txt", "mine\n");
    let (code, out, err) = t.cli(&["clean", "--reports", "--profile", "quick"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("removed"), "should say what it removed: {out}");
    let r = t.path().join("reports");
    assert!(
        r.join("README.md").exists() && r.join("quick/notes.txt").exists(),
        "unrelated files removed"
    );
    assert!(!r.join("quick/psd-a.csv").exists() && !r.join("quick/index.html").exists());
    assert!(
        r.join("paper/psd-a.csv").exists(),
        "another profile's reports were removed"
    );
    // The paper entry is still cached; the quick one is gone.
    let (_, out, _) = t.cli(&["status", "--profile", "paper"]);
    assert!(out.contains("fresh    psd-a"), "{out}");
    let (_, out, _) = t.cli(&["status"]);
    assert!(out.contains("missing  psd-a"), "{out}");
    // Everything: still never README.md.
    let (code, _, err) = t.cli(&["clean", "--reports"]);
    assert_eq!(code, 0, "{err}");
    assert!(r.join("README.md").exists() && !r.join("paper").exists() && !t.path().join(".granrepro").exists());
}

/// Finding 2: an id may not escape reports/ (`../../../escaped-laws` wrote outside the
/// project, exit 0).
#[test]
fn ids_cannot_escape_reports() {
    let t = TempProject::new("version: 1\nstages:\n  - id: ../../../escaped-laws\n    kind: reference-laws\n");
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("../../../escaped-laws"), "{err}");
    assert!(!t.path().join("reports").exists() && !t.path().join(".granrepro").exists());
}

/// Finding 4: the index listed stages from the directory listing, so a removed stage
/// stayed listed; its outputs stay behind too.
#[test]
fn removed_stages_leave_the_index_and_the_reports() {
    let t = TempProject::new(SMALL);
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 0, "{err}");
    assert!(read(t.path().join("reports/quick/index.html")).contains("id=\"tab\""));
    let without_tab = SMALL.replace(
        "  - id: tab\n    kind: material-table\n    params: { table: tab4-02 }\n    inputs: { psd: psd-a }\n",
        "",
    );
    assert_ne!(without_tab, SMALL);
    std::fs::write(t.pipeline(), without_tab).unwrap();
    let (code, _, err) = t.cli(&["run", "--stage", "laws", "--quiet"]);
    assert_eq!(code, 0, "{err}");
    let index = read(t.path().join("reports/quick/index.html"));
    assert!(!index.contains("id=\"tab\""), "removed stage still listed");
    assert!(
        index.contains("id=\"fig-a\""),
        "a stage not run this time must stay listed"
    );
    assert!(
        !t.path().join("reports/quick/tab.csv").exists(),
        "stale outputs of a removed stage kept"
    );
}

/// Finding 4: an unlisted stray file inside a cache entry was published.
#[test]
fn only_manifest_files_are_published() {
    let t = TempProject::new(SMALL);
    let (code, _, err) = t.cli(&["run", "--stage", "psd-a", "--quiet"]);
    assert_eq!(code, 0, "{err}");
    let p = granrepro::pipeline::load(&t.pipeline(), "quick", &[]).unwrap();
    let key = granrepro::pipeline::run::key_records(&p)["psd-a"].1.clone();
    std::fs::write(
        t.path().join(".granrepro/cache").join(&key).join("stray.txt"),
        "not ours",
    )
    .unwrap();
    let (code, _, err) = t.cli(&["run", "--stage", "psd-a", "--quiet"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        !t.path().join("reports/quick/psd-a-stray.txt").exists(),
        "a stray file was published"
    );
}

const FIT: &str = "version: 1\nstages:\n  - id: laws\n    kind: reference-laws\n  - id: fit\n    kind: power-law-fit\n    params: { x: a, y: lube2005_runout }\n    inputs: { data: laws }\n";

/// Finding 4: after a failed stage, stdout printed the previous run's scalars and
/// "claim … (pass)" next to exit 1.
#[test]
fn a_failed_stage_shows_nothing_stale() {
    let t = TempProject::new(FIT);
    let (code, out, err) = t.cli(&["run", "--stage", "fit"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("fit: "), "headline scalars expected: {out}");
    // A name the input does not publish is refused at load (exit 2) since kinds declare
    // their outputs; a run-time failure: no point left to fit.
    let (code, _, err) = t.cli(&["run", "--stage", "fit", "--set", "fit.y=no_such_column"]);
    assert_eq!(code, 2, "{err}");
    let (code, out, err) = t.cli(&["run", "--stage", "fit", "--set", "fit.x_min=1e9"]);
    assert_eq!(code, 1, "{err}");
    assert!(
        !out.contains("fit: ") && !out.contains("claim"),
        "stale results printed after a failure: {out}"
    );
    assert!(
        !t.path().join("reports/quick/fit.json").exists(),
        "the failed stage's old report is still on show"
    );
    assert!(!read(t.path().join("reports/quick/index.html")).contains("id=\"fit\""));
}

/// Finding 4: after `run --set psd-a.seed=7`, `status` said fresh while the reports held
/// the override, and nothing marked it.
#[test]
fn overrides_are_marked_and_status_says_so() {
    let t = TempProject::new(SMALL);
    let (code, _, err) = t.cli(&["run", "--stage", "psd-a", "--quiet"]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = t.cli(&["run", "--stage", "psd-a", "--quiet", "--set", "psd-a.seed=7"]);
    assert_eq!(code, 0, "{err}");
    let res: serde_json::Value = serde_json::from_str(&read(t.path().join("reports/quick/psd-a.json"))).unwrap();
    assert_eq!(res["overrides"][0], "psd-a.seed=7", "{res}");
    let rec: serde_json::Value = serde_json::from_str(&read(t.path().join("reports/quick/psd-a.record.json"))).unwrap();
    assert_eq!(rec["overrides"][0], "psd-a.seed=7");
    assert!(
        read(t.path().join("reports/quick/index.html")).contains("OVERRIDDEN"),
        "index does not mark the override"
    );
    let (_, out, _) = t.cli(&["status"]);
    let line = out.lines().find(|l| l.contains("psd-a")).unwrap_or_default();
    assert!(line.contains("stale") && line.contains("psd-a.seed=7"), "{out}");
    // A figure computed from the overridden input is marked too.
    let (code, _, err) = t.cli(&["run", "--stage", "fig-a", "--quiet", "--set", "psd-a.seed=7"]);
    assert_eq!(code, 0, "{err}");
    let fig: serde_json::Value = serde_json::from_str(&read(t.path().join("reports/quick/fig-a.json"))).unwrap();
    assert_eq!(fig["overrides"][0], "psd-a.seed=7", "{fig}");
    assert!(
        read(t.path().join("reports/quick/fig-a.svg")).contains("OVERRIDDEN (--set psd-a.seed=7)"),
        "the figure is not marked"
    );
}

/// Finding 7: reports and state were created 0600.
#[cfg(unix)]
#[test]
fn reports_state_and_cache_are_world_readable() {
    use std::os::unix::fs::PermissionsExt;
    let t = TempProject::new(SMALL);
    let (code, _, err) = t.cli(&["run", "--stage", "fig-a", "--quiet"]);
    assert_eq!(code, 0, "{err}");
    let mode = |p: &Path| {
        std::fs::metadata(p)
            .unwrap_or_else(|e| panic!("{}: {e}", p.display()))
            .permissions()
            .mode()
            & 0o777
    };
    let q = t.path().join("reports/quick");
    for f in [
        "fig-a.json", "fig-a.record.json", "fig-a.svg", "psd-a.csv", "index.html",
    ] {
        assert_eq!(mode(&q.join(f)), 0o644, "{f}");
    }
    assert_eq!(mode(&t.path().join(".granrepro/state/quick/fig-a.json")), 0o644);
    let p = granrepro::pipeline::load(&t.pipeline(), "quick", &[]).unwrap();
    let entry = t
        .path()
        .join(".granrepro/cache")
        .join(&granrepro::pipeline::run::key_records(&p)["fig-a"].1);
    assert_eq!(mode(&entry), 0o755);
    assert_eq!(mode(&entry.join("record.json")), 0o644);
    assert_eq!(mode(&q), 0o755);
    assert_eq!(mode(&q.join(".sets/fig-a")), 0o755);
}

/// Finding 10: errors without a path ("File exists (os error 17)").
#[test]
fn io_errors_name_their_path() {
    let t = TempProject::new(SMALL);
    t.write(".granrepro/cache", "a file where the cache directory goes");
    let (code, _, err) = t.cli(&["run", "--stage", "psd-a", "--quiet"]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains(".granrepro/cache"), "{err}");
    let t = TempProject::new(SMALL);
    t.write("reports", "a file where reports/ goes");
    let (code, _, err) = t.cli(&["run", "--stage", "psd-a", "--quiet"]);
    assert_ne!(code, 0, "{err}");
    assert!(err.contains("reports"), "{err}");
}

/// Finding 11: a run record's input `manifest_blake3` changed between identical runs.
#[test]
fn input_manifest_hash_is_stable_between_identical_runs() {
    let hash = || {
        let t = TempProject::new(SMALL);
        let (code, _, err) = t.cli(&["run", "--stage", "fig-a", "--quiet"]);
        assert_eq!(code, 0, "{err}");
        let rec: serde_json::Value =
            serde_json::from_str(&read(t.path().join("reports/quick/fig-a.record.json"))).unwrap();
        rec["inputs"][0]["manifest_blake3"].as_str().unwrap().to_string()
    };
    assert_eq!(hash(), hash());
}

/// Finding 9: `.tmp-*` directories of killed runs were never cleaned.
#[test]
fn stale_temp_directories_are_swept() {
    let t = TempProject::new(SMALL);
    let cache = t.path().join(".granrepro/cache");
    let (old, young) = (cache.join(".tmp-deadbeef-old"), cache.join(".tmp-deadbeef-young"));
    std::fs::create_dir_all(&old).unwrap();
    std::fs::create_dir_all(&young).unwrap();
    let two_hours_ago = std::time::SystemTime::now() - std::time::Duration::from_secs(7200);
    std::fs::File::open(&old).unwrap().set_modified(two_hours_ago).unwrap();
    // The same for a publishing run killed while staging a set.
    let staging = t.path().join("reports/quick/.sets/.tmp-psd-a-1-2");
    std::fs::create_dir_all(&staging).unwrap();
    std::fs::File::open(&staging)
        .unwrap()
        .set_modified(two_hours_ago)
        .unwrap();
    let (code, _, err) = t.cli(&["run", "--stage", "psd-a", "--quiet"]);
    assert_eq!(code, 0, "{err}");
    assert!(!old.exists(), "a stale temp directory was kept");
    assert!(
        young.exists(),
        "a temp directory in use may belong to a running process"
    );
    assert!(!staging.exists(), "a stale staging directory of reports was kept");
}

/// Finding 6: `--set` split at the first '.', so it could not reach `p-d_min_mm0.9`.
#[test]
fn set_reaches_matrix_members_with_dotted_ids() {
    let t = TempProject::new("version: 1\nstages:\n  - id: p\n    kind: psd\n    matrix: { d_min_mm: [0.9, 0.92] }\n");
    let (code, out, err) = t.cli(&["params", "p-d_min_mm0.9", "--set", "p-d_min_mm0.9.n=77"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("n: 77"), "{out}");
    let (_, out, _) = t.cli(&["params", "p-d_min_mm0.92"]);
    assert!(!out.contains("n: 77"), "{out}");
    // A base id still applies to every member; a nested key after a dotted id works.
    let (code, out, err) = t.cli(&["params", "p-d_min_mm0.92", "--set", "p.seed=5"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("seed: 5"), "{out}");
}

/// Two stages may not publish the same file name (`f`'s extra table `grains` is
/// `f-grains.csv`, and so is stage `f-grains`'s main table): the run fails naming both
/// instead of one silently replacing the other.
#[test]
fn a_published_name_clash_is_an_error() {
    let t = TempProject::new(
        "version: 1\nstages:\n  - id: p\n    kind: psd\n  - id: f\n    kind: psd-figure\n    inputs: { psd: p }\n  - id: f-grains\n    kind: psd\n",
    );
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("f-grains.csv") && err.contains("already published by stage"),
        "{err}"
    );
}

//! The stiff and extreme scene catalogue (`stages/extreme/`, issue 12): every scene either
//! runs stably to the end (exit 0, no watchdog trip, energy balance within its bound) or is
//! refused at validation (exit 2, nothing written) with the binding time scale (or bound),
//! the limit and the fix in the message. The expectation is the first line of each file:
//! `# expect: runs` or `# expect: refused | text | text …` (texts the message must hold).
//!
//! Beside the catalogue, the refused frictionless MPM base, forced past validation through
//! the library, really leaves the grid. (The refused DEM rolling spring, forced past
//! validation, does not diverge here: the rolling moment is capped at μ_r r f_n with
//! μ_r ≤ 10, reached at θ_r ~ 1e-8 rad, so the unstable elastic branch is clipped — the
//! refusal rests on the linear analysis of docs/definitions.md c.2, as the other DEM rows.)

use std::path::{Path, PathBuf};

fn catalogue() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("stages/extreme")
}

/// Every scene in the catalogue has a test below (a new file without one fails here).
#[test]
fn every_catalogue_scene_is_tested() {
    let mut files: Vec<String> = std::fs::read_dir(catalogue())
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
        .filter(|n| n.ends_with(".yaml"))
        .collect();
    files.sort();
    let mut tested: Vec<String> = TESTED.iter().map(|s| format!("{s}.yaml")).collect();
    tested.sort();
    assert_eq!(
        files, tested,
        "stages/extreme/*.yaml and the tests in tests/extreme.rs differ"
    );
}

/// Run one scene and check its stated expectation.
fn check(name: &str) {
    let file = catalogue().join(format!("{name}.yaml"));
    let text = std::fs::read_to_string(&file).unwrap();
    let first = text.lines().next().unwrap_or("");
    let expect = first
        .strip_prefix("# expect: ")
        .unwrap_or_else(|| panic!("{name}: first line must be `# expect: …`"));
    let out = tempfile::tempdir().unwrap();
    let dir = out.path().join("out");
    let t0 = std::time::Instant::now();
    let r = std::process::Command::new(env!("CARGO_BIN_EXE_granrepro"))
        .args([
            "simulate",
            file.to_str().unwrap(),
            "--out",
            dir.to_str().unwrap(),
            "--quiet",
        ])
        .output()
        .unwrap();
    let code = r.status.code().unwrap_or(-1);
    let err = String::from_utf8_lossy(&r.stderr).into_owned();
    eprintln!("{name}: exit {code} in {:.1} s\n{err}", t0.elapsed().as_secs_f64());
    let mut parts = expect.split(" | ");
    match parts.next().unwrap().trim() {
        "refused" => {
            assert_eq!(
                code, 2,
                "{name}: expected a refusal at validation (exit 2), got {code}\n{err}"
            );
            assert!(
                !dir.exists() || std::fs::read_dir(&dir).unwrap().next().is_none(),
                "{name}: refused but wrote {}",
                dir.display()
            );
            assert!(
                err.contains(&format!("{name}.yaml")),
                "{name}: the message must name the file\n{err}"
            );
            for needle in parts {
                assert!(
                    err.contains(needle.trim()),
                    "{name}: message lacks `{}`\n{err}",
                    needle.trim()
                );
            }
        }
        "runs" => {
            assert_eq!(code, 0, "{name}: expected a stable run, got exit {code}\n{err}");
            energy_bound(name, &dir.join("reports/quick"));
        }
        other => panic!("{name}: unknown expectation `{other}`"),
    }
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

/// The energy bound of a completed run, per engine.
fn energy_bound(name: &str, reports: &Path) {
    let dem = reports.join("collapse.json");
    let csv = reports.join("collapse.csv");
    let pile = reports.join("pile.csv");
    if name.starts_with("dem-") {
        // D07: E_0 = E_p + E_k + E_rot + elastic + dissipated within 1 % at every sample
        let j = json(&dem);
        let c = j["checks"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["id"] == "energy-balance")
            .expect("energy-balance check");
        let res = c["ours"].as_f64().unwrap();
        eprintln!("{name}: max |balance residual|/E_0 = {res:.2e}");
        assert!(
            c["pass"].as_bool().unwrap() && res <= 0.01,
            "{name}: energy balance {res}"
        );
        assert!(j["scalars"]["max_overlap_fraction"].as_f64().unwrap() < 0.05);
    } else if name.starts_with("mpm-") {
        // the MPM watchdog bound: E_p + E_k + E_el + plastic + wall work ≤ E(0) + 5 % E_p(0)
        let t = std::fs::read_to_string(&csv).unwrap();
        let mut lines = t.lines();
        let head: Vec<&str> = lines.next().unwrap().split(',').collect();
        let col = |k: &str| head.iter().position(|h| *h == k).unwrap();
        let idx: Vec<usize> = ["ep_j", "ek_j", "elastic_j", "plastic_work_j", "wall_friction_work_j"]
            .iter()
            .map(|k| col(k))
            .collect();
        let rows: Vec<Vec<f64>> = lines
            .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
            .collect();
        let total = |r: &Vec<f64>| idx.iter().map(|&i| r[i]).sum::<f64>();
        let (e0, ep0) = (total(&rows[0]), rows[0][col("ep_j")]);
        let rise = rows.iter().map(|r| (total(r) - e0) / ep0).fold(f64::MIN, f64::max);
        eprintln!(
            "{name}: max energy rise / E_p(0) = {rise:.2e} over {} samples",
            rows.len()
        );
        assert!(
            rise <= 0.05 && rows.iter().all(|r| r.iter().all(|x| x.is_finite())),
            "{name}: energy rise {rise}"
        );
        let j = json(&dem);
        assert!(
            j["scalars"]["t_end_over_tau_c"].as_f64().unwrap() >= 0.99,
            "{name}: did not reach its end time"
        );
    } else if name.starts_with("cd-") {
        // Moreau–Jean (θ = ½) books every impulse's work; the run's own watchdog stops any
        // rise above 1e-3 E (exit 1). Here: all variants converged and stayed within the
        // penetration bound, and dissipation is positive.
        let t = std::fs::read_to_string(&pile).unwrap();
        let mut lines = t.lines();
        let head: Vec<&str> = lines.next().unwrap().split(',').collect();
        let col = |k: &str| head.iter().position(|h| *h == k).unwrap();
        for l in lines {
            let r: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            assert_eq!(r[col("unconverged_steps")], 0.0, "{name}: unconverged steps");
            assert!(r[col("max_penetration_d")] < 0.01, "{name}: penetration");
            assert!(
                r[col("dissipated_j_m")] > 0.0 && r[col("ek_final_over_ek0")] < 1.0,
                "{name}: energy"
            );
        }
    } else {
        panic!("{name}: unknown engine prefix");
    }
}

macro_rules! scenes {
    ($($f:ident => $name:literal),* $(,)?) => {
        const TESTED: &[&str] = &[$($name),*];
        $( #[test] fn $f() { check($name); } )*
    };
}

scenes! {
    chapter_rolling_spring_at_1e_6_is_refused => "dem-chapter-rolling-spring-dt1e-6",
    chapter_rolling_spring_at_stable_step_runs => "dem-chapter-rolling-spring-stable",
    chapter_rolling_law_with_implicit_dashpot_at_1e_6_runs => "dem-chapter-rolling-implicit-dt1e-6",
    explicit_rolling_dashpot_is_refused => "dem-explicit-rolling-dashpot",
    tall_column_a10_runs => "dem-a10",
    flat_column_a0_2_runs => "dem-a0.2",
    polydispersity_r6_at_psd_col_step_is_refused => "dem-r6-refused",
    polydispersity_r6_runs => "dem-r6",
    frictionless_grains_run => "dem-mu0",
    friction_one_runs => "dem-mu1",
    restitution_near_zero_runs => "dem-restitution0.01",
    restitution_one_runs => "dem-restitution1.0",
    nan_in_scene_is_refused => "dem-nan",
    negative_in_scene_is_refused => "dem-negative",
    mpm_stiff_e_x100_runs => "mpm-e-x100",
    mpm_stiff_e_x100_fixed_step_is_refused => "mpm-e-x100-fixed-dt",
    mpm_soft_e_div100_runs => "mpm-e-div100",
    mpm_one_ppc_runs => "mpm-ppc1",
    mpm_hundred_ppc_runs => "mpm-ppc100",
    mpm_points_leaving_the_grid_is_refused => "mpm-leaves-grid",
    cd_step_passing_grains_through_is_refused => "cd-pass-through",
    cd_small_pile_runs => "cd-pile-small",
}

// ---- the refusals are needed: forced past validation, these runs fail ---------------

#[test]
fn refused_frictionless_mpm_base_really_leaves_the_grid() {
    use granrepro::mpm::column::{CollapseOptions, ColumnSpec, build, run_collapse};
    use granrepro::mpm::{MpmError, MpmParams};
    let p = MpmParams {
        wall_friction: 0.0,
        ..MpmParams::quick()
    };
    let spec = ColumnSpec::from_area(0.4, 1.0e-3);
    assert!(granrepro::mpm::preflight::containment(&p, spec).is_err());
    // forced past validation (no geostatic stage: release at once)
    let mut col = build(&p, spec).unwrap();
    granrepro::mpm::column::release(&mut col);
    let opts = CollapseOptions {
        max_time_tau: 60.0,
        min_time_tau: 59.0,
        ..CollapseOptions::default()
    };
    let r = run_collapse(col, None, &p, &opts);
    eprintln!("{:?}", r.as_ref().map(|r| r.runout).map_err(|e| e.to_string()));
    assert!(matches!(r, Err(MpmError::LeftGrid { .. })), "{:?}", r.map(|r| r.runout));
    // with the table's base friction the same column is contained
    let q = MpmParams::quick();
    assert!(granrepro::mpm::preflight::containment(&q, spec).is_ok());
}

// ---- leave-out proof: a scene pays only for what it uses ------------------------------

use granrepro::dem::{DemParams, RollingDamping, State, Wall, World};

/// A small bed of grains on a floor against a left wall (walls with friction), `steps` steps.
fn bed(p: DemParams, steps: u64) -> World {
    let r = 0.5e-3;
    let mut s = State::new();
    for row in 0..3 {
        for col in 0..8 {
            let x = (2.0 * col as f64 + (row % 2) as f64) * 1.01 * r + r;
            s.insert(
                x,
                r + row as f64 * 1.9 * r,
                r * (1.0 - 0.01 * (col % 3) as f64),
                p.density,
            );
            let k = s.len() - 1;
            s.vx[k] = 0.05 * ((k % 5) as f64 - 2.0);
            s.w[k] = 10.0 * ((k % 3) as f64 - 1.0);
        }
    }
    let mut w = World::new(p, s, vec![Wall::floor(0.0), Wall::left(0.0)], None).unwrap();
    w.run(steps).unwrap();
    w
}

#[test]
fn a_scene_without_rolling_or_ledger_never_runs_those_paths() {
    let steps = 2000;
    let mut off = DemParams::default();
    off.rolling.enabled = false;
    off.ledger = false;
    let w = bed(off.clone(), steps);
    eprintln!("off: {:?}", w.paths);
    assert_eq!(
        (w.paths.rolling_forces, w.paths.rolling_dashpot, w.paths.ledger),
        (0, 0, 0)
    );
    // the counters do count: every force pass (steps + the initial one) and two dashpot
    // sweeps per step when the terms are on
    let on = bed(DemParams::default(), steps);
    eprintln!("on: {:?}", on.paths);
    assert_eq!(on.paths.rolling_forces, steps + 1);
    assert_eq!(on.paths.ledger, steps + 1);
    assert_eq!(on.paths.rolling_dashpot, 2 * steps);
    // explicit dashpot: rolling forces, no implicit sweep
    let mut ex = DemParams::default();
    ex.dt = 1e-9;
    ex.rolling.damping = RollingDamping::Explicit;
    let e = bed(ex, 100);
    assert_eq!((e.paths.rolling_forces, e.paths.rolling_dashpot), (101, 0));
}

#[test]
fn rolling_spring_without_dashpot_skips_the_dashpot_sweep_bit_identically() {
    // c_r = 0 (col-dem-no-rolling-damper): no implicit sweep is run, and the state is the
    // same to the bit as with the explicit rule (nothing to damp either way)
    let mut imp = DemParams::default();
    imp.rolling.cr = 0.0;
    let mut exp = imp.clone();
    exp.rolling.damping = RollingDamping::Explicit;
    let (a, b) = (bed(imp, 3000), bed(exp, 3000));
    assert_eq!(a.paths.rolling_dashpot, 0);
    assert!(a.paths.rolling_forces > 0);
    assert_eq!(a.state.x, b.state.x);
    assert_eq!(a.state.w, b.state.w);
    assert_eq!(a.ledger.rolling.to_bits(), b.ledger.rolling.to_bits());
}

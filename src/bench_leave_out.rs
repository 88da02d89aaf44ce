//! `granrepro bench leave-out`: what each pipeline stage pays for (issue 12).
//!
//! 1. From the resolved parameters of every simulating stage (quick profile unless
//!    `--profile`), the optional physics terms and outputs it enables: rolling resistance
//!    (spring, implicit dashpot), energy ledger, wall friction, μ(I), snapshots, VTK.
//! 2. The cost of each physics configuration, measured in one sitting on one scene per
//!    engine, as configured against the same scene with every option on. Cost is the CPU
//!    time of the process, run on one worker thread (Linux `/proc/self/task/*/schedstat`,
//!    ns; wall time where unavailable): on a machine shared with other jobs, wall time of one
//!    configuration against another mostly measures the neighbours.
//!    - DEM: the settled 2924-grain reference column of `bench dem`, gate open, the same
//!      steps for each configuration, run in interleaved rounds (A B C … A B C …) and the
//!      best round kept, so a load change on the shared machine hits all alike;
//!    - MPM: the a = 1 column of `bench mpm`, Mohr–Coulomb against μ(I);
//!    - CD: the Siconos deposit of `bench cd`, rolling resistance off against on.
//!    Output writing is timed once per engine (one VTK snapshot of the bench scene).
//!
//! Counting, not timing, proves that an option left out is not executed: see
//! `World::paths` and the test `a_scene_without_rolling_or_ledger_never_runs_those_paths`.

use std::time::Instant;

use serde_json::{Value, json};

use crate::dem::World;
use crate::pipeline::Pipeline;

/// Optional terms and outputs of one stage.
#[derive(Debug, Clone, Default)]
pub struct Enabled {
    /// Stage id.
    pub id: String,
    /// Engine (dem, mpm, cd).
    pub engine: &'static str,
    /// Rolling resistance: None, Some(false) spring only, Some(true) spring + dashpot.
    pub rolling: Option<bool>,
    /// Energy ledger.
    pub ledger: bool,
    /// Wall friction > 0.
    pub wall_friction: bool,
    /// μ(I) rheology (MPM).
    pub mu_i: bool,
    /// Snapshots per run.
    pub snapshots: usize,
    /// VTK files.
    pub vtk: bool,
}

fn f(v: &Value, path: &str) -> Option<f64> {
    v.pointer(path).and_then(Value::as_f64)
}
fn b(v: &Value, path: &str) -> Option<bool> {
    v.pointer(path).and_then(Value::as_bool)
}
fn n(v: &Value, path: &str) -> usize {
    v.pointer(path).and_then(Value::as_array).map(|a| a.len()).unwrap_or(0)
}

/// What a stage's resolved parameters enable (None: not a simulating stage).
pub fn enabled(id: &str, kind: &str, p: &Value) -> Option<Enabled> {
    let mut e = Enabled {
        id: id.to_string(),
        ..Default::default()
    };
    // A study kind names its method (`method: dem`); a method's own kinds carry its prefix.
    let method = p.get("method").and_then(Value::as_str);
    let is = |m: &str| method.map_or(kind.starts_with(&format!("{m}-")), |x| x == m);
    if p.get("dem").is_some() && is("dem") {
        e.engine = "dem";
        if b(p, "/dem/rolling/enabled").unwrap_or(false) {
            e.rolling = Some(f(p, "/dem/rolling/cr").unwrap_or(0.0) > 0.0);
        }
        e.ledger = b(p, "/dem/ledger").unwrap_or(false);
        e.wall_friction = f(p, "/dem/wall/friction").unwrap_or(0.0) > 0.0;
        e.snapshots = n(p, "/run/snapshots");
    } else if p.get("mpm").is_some() && is("mpm") {
        e.engine = "mpm";
        let model = p.pointer("/mpm/material/model");
        e.mu_i = model.is_some_and(|m| m.get("mu_i_linear").is_some() || m.get("mu_i_jop").is_some());
        e.wall_friction = f(p, "/mpm/wall_friction").unwrap_or(0.0) > 0.0;
        e.ledger = true; // the MPM energies are always computed (watchdog)
        e.snapshots = n(p, "/run/snapshot_tau");
    } else if p.get("cd").is_some() && is("cd") {
        e.engine = "cd";
        e.rolling = (f(p, "/cd/rolling_friction").unwrap_or(0.0) > 0.0).then_some(false);
        e.wall_friction = f(p, "/cd/wall_friction").unwrap_or(0.0) > 0.0;
        e.ledger = true; // the CD ledger is part of the step (watchdog)
    } else {
        return None;
    }
    e.vtk = b(p, "/vtk").unwrap_or(false);
    Some(e)
}

/// CPU time of this process, all threads [s] (sum of `/proc/self/task/*/schedstat`, ns
/// resolution; wall clock if /proc is unavailable).
fn thread_cpu_s() -> f64 {
    let tasks = std::fs::read_dir("/proc/self/task").ok().map(|d| {
        d.filter_map(|e| e.ok())
            .filter_map(|e| std::fs::read_to_string(e.path().join("schedstat")).ok())
            .filter_map(|t| t.split_whitespace().next().and_then(|x| x.parse::<f64>().ok()))
            .sum::<f64>()
    });
    match tasks {
        Some(ns) if ns > 0.0 => ns * 1e-9,
        _ => {
            static START: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
            START.get_or_init(Instant::now).elapsed().as_secs_f64()
        }
    }
}

/// DEM configuration: (rolling on, dashpot c_r > 0, ledger).
type DemCfg = (bool, bool, bool);

fn dem_label(c: DemCfg) -> String {
    let mut parts = Vec::new();
    if c.0 {
        parts.push(if c.1 { "rolling+dashpot" } else { "rolling spring" });
    }
    if c.2 {
        parts.push("ledger");
    }
    if parts.is_empty() {
        "none".into()
    } else {
        parts.join(" + ")
    }
}

/// Seconds per step of each DEM configuration on the bench column (best of `rounds`).
fn time_dem(cfgs: &[DemCfg], steps: u64, rounds: usize) -> Result<(Vec<f64>, usize, f64), String> {
    use crate::dem::bench::{BenchCase, bench_scene};
    let mut base = bench_scene(BenchCase::Full, crate::dem::bench::LAMMPS_DT).map_err(|e| e.to_string())?;
    for w in base.walls.iter_mut() {
        if w.name == "gate" {
            w.active = false;
        }
    }
    base.run(200).map_err(|e| e.to_string())?;
    let mk = |c: DemCfg| -> World {
        let mut w = base.clone();
        w.params.rolling.enabled = c.0;
        if !c.1 {
            w.params.rolling.cr = 0.0;
        }
        w.params.ledger = c.2;
        w.invalidate_forces();
        w
    };
    let mut best = vec![f64::INFINITY; cfgs.len()];
    for _ in 0..rounds {
        for (k, &c) in cfgs.iter().enumerate() {
            let mut w = mk(c);
            let t = thread_cpu_s();
            w.run(steps).map_err(|e| e.to_string())?;
            best[k] = best[k].min((thread_cpu_s() - t) / steps as f64);
        }
    }
    // one VTK snapshot of the scene (positions, radius, velocity), rendered
    let s = &base.state;
    let t = thread_cpu_s();
    let doc = crate::vtk::polydata(&s.x, &s.y, &[("radius", crate::vtk::Field::Scalar(&s.r))]);
    std::hint::black_box(&doc);
    Ok((best, s.len(), thread_cpu_s() - t))
}

fn time_mpm(steps: u64, rounds: usize) -> Result<(f64, f64, usize), String> {
    use crate::mpm::column::{ColumnSpec, build, release};
    use crate::mpm::{Model, MpmParams};
    let run = |model: Model| -> Result<(f64, usize), String> {
        let mut p = MpmParams::default();
        p.material.model = model;
        let mut col = build(&p, ColumnSpec::from_area(1.0, 0.01)).map_err(|e| e.to_string())?;
        release(&mut col);
        let dt = col.solver.dt(&col.state);
        for _ in 0..5 {
            col.solver.step(&mut col.state, dt).map_err(|e| e.to_string())?;
        }
        let t = thread_cpu_s();
        for _ in 0..steps {
            col.solver.step(&mut col.state, dt).map_err(|e| e.to_string())?;
        }
        Ok(((thread_cpu_s() - t) / steps as f64, col.state.points.len()))
    };
    let (mut mc, mut mui, mut pts) = (f64::INFINITY, f64::INFINITY, 0);
    for _ in 0..rounds {
        let a = run(Model::MohrCoulomb)?;
        let b = run(Model::MuILinear { mu_min: 0.408, b: 1.0 })?;
        mc = mc.min(a.0);
        mui = mui.min(b.0);
        pts = a.1;
    }
    Ok((mc, mui, pts))
}

fn time_cd(steps: u64, rounds: usize) -> Result<(f64, f64), String> {
    use crate::cd::pile::{DropSpec, drop};
    let spec = DropSpec {
        ncol: 25,
        nrow: 20,
        scale: 1.0,
        seed: 1,
    };
    let (mut off, mut on) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..rounds {
        let p = crate::cd::bench::siconos_params();
        let t = thread_cpu_s();
        drop(&spec, &p, steps).map_err(|e| e.to_string())?;
        let t1 = thread_cpu_s();
        let q = crate::cd::CdParams {
            rolling_friction: 0.1,
            ..p
        };
        drop(&spec, &q, steps).map_err(|e| e.to_string())?;
        off = off.min((t1 - t) / steps as f64);
        on = on.min((thread_cpu_s() - t1) / steps as f64);
    }
    Ok((off, on))
}

/// Run the leave-out benchmark for a loaded pipeline; prints JSON lines and a Markdown
/// table. Returns the exit code.
pub fn run(p: &Pipeline, steps: u64) -> i32 {
    match rayon::ThreadPoolBuilder::new().num_threads(1).build() {
        Ok(pool) => pool.install(|| run_on_one_thread(p, steps)),
        Err(e) => {
            eprintln!("error: bench leave-out: {e}");
            1
        }
    }
}

fn run_on_one_thread(p: &Pipeline, steps: u64) -> i32 {
    let rows: Vec<Enabled> = p
        .stages
        .iter()
        .filter_map(|s| enabled(&s.id, &s.kind, &s.params))
        .collect();
    let dem_cfgs: Vec<DemCfg> = vec![
        (false, false, false),
        (true, false, false),
        (true, true, false),
        (false, false, true),
        (true, false, true),
        (true, true, true),
    ];
    let rounds = 3;
    eprintln!(
        "timing DEM ({} configurations × {rounds} rounds × {steps} steps), MPM and CD …",
        dem_cfgs.len()
    );
    let (dem_t, grains, vtk_dem) = match time_dem(&dem_cfgs, steps, rounds) {
        Ok(v) => v,
        Err(e) => {
            eprintln!("error: bench leave-out (DEM): {e}");
            return 1;
        }
    };
    let mpm = time_mpm((steps / 10).max(20), rounds);
    let cd = time_cd(400, rounds);
    let all_on = dem_t[dem_t.len() - 1];
    for (c, t) in dem_cfgs.iter().zip(&dem_t) {
        println!(
            "{}",
            json!({"bench": "leave-out", "engine": "dem", "config": dem_label(*c), "grains": grains, "cpu_s_per_step": t, "vs_all_on": t / all_on})
        );
    }
    let (mc, mui, pts) = match mpm {
        Ok(v) => v,
        Err(e) => {
            eprintln!("error: bench leave-out (MPM): {e}");
            return 1;
        }
    };
    println!(
        "{}",
        json!({"bench": "leave-out", "engine": "mpm", "config": "mohr-coulomb", "points": pts, "cpu_s_per_step": mc, "vs_all_on": mc / mui})
    );
    println!(
        "{}",
        json!({"bench": "leave-out", "engine": "mpm", "config": "mu(I)", "points": pts, "cpu_s_per_step": mui, "vs_all_on": 1.0})
    );
    let (cd_off, cd_on) = match cd {
        Ok(v) => v,
        Err(e) => {
            eprintln!("error: bench leave-out (CD): {e}");
            return 1;
        }
    };
    println!(
        "{}",
        json!({"bench": "leave-out", "engine": "cd", "config": "no rolling", "cpu_s_per_step": cd_off, "vs_all_on": cd_off / cd_on})
    );
    println!(
        "{}",
        json!({"bench": "leave-out", "engine": "cd", "config": "rolling", "cpu_s_per_step": cd_on, "vs_all_on": 1.0})
    );
    // the per-stage table
    let yes = |x: bool| if x { "yes" } else { "–" };
    println!("\n| stage | engine | rolling | ledger | wall friction | μ(I) | snapshots | VTK | step cost vs all on |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for r in &rows {
        let roll = match r.rolling {
            None => "–",
            Some(false) => {
                if r.engine == "cd" {
                    "yes (μ_r)"
                } else {
                    "spring"
                }
            }
            Some(true) => "spring + dashpot",
        };
        let cost = match r.engine {
            "dem" => {
                let c = (r.rolling.is_some(), r.rolling == Some(true), r.ledger);
                let k = dem_cfgs.iter().position(|x| *x == c).unwrap_or(dem_cfgs.len() - 1);
                format!("{:.2} ({})", dem_t[k] / all_on, dem_label(c))
            }
            "mpm" => format!("{:.2}", if r.mu_i { 1.0 } else { mc / mui }),
            _ => format!("{:.2}", if r.rolling.is_some() { 1.0 } else { cd_off / cd_on }),
        };
        let vtk = if r.vtk && r.engine == "dem" {
            format!("yes ({:.0} ms each)", 1e3 * vtk_dem)
        } else {
            yes(r.vtk).to_string()
        };
        println!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.id,
            r.engine,
            roll,
            yes(r.ledger),
            yes(r.wall_friction),
            yes(r.mu_i),
            r.snapshots,
            vtk,
            cost
        );
    }
    println!(
        "\nAll on (process CPU time, one worker thread): DEM rolling + dashpot + ledger {:.3e} s/step ({grains} grains); MPM μ(I) {:.3e} s/step ({pts} points); CD rolling {:.3e} s/step (Siconos deposit 25×20). Wall friction is a coefficient of the same contact law (no separate path, no cost).",
        all_on, mui, cd_on
    );
    0
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    use super::enabled;

    /// A study kind (`pile-run`, `column-collapse`) is classified by its `method:`, not by a
    /// kind-name prefix: before, a CD or MPM pile got no leave-out row (its kind has no
    /// `cd-`/`mpm-` prefix).
    #[test]
    fn a_study_kind_is_classified_by_its_method() {
        let cd = enabled(
            "pile-cd-g",
            "pile-run",
            &json!({ "method": "cd", "cd": { "rolling_friction": 0.1 } }),
        )
        .expect("a CD pile simulates");
        assert_eq!((cd.engine, cd.rolling), ("cd", Some(false)));
        let mpm = enabled(
            "col-mpm-a1",
            "column-collapse",
            &json!({ "method": "mpm", "mpm": { "wall_friction": 0.3 } }),
        )
        .expect("an MPM column simulates");
        assert_eq!(mpm.engine, "mpm");
        assert!(mpm.wall_friction);
        // A DEM block alone does not make a CD stage a DEM one.
        let cd_with_dem = enabled("x", "pile-run", &json!({ "method": "cd", "dem": {}, "cd": {} })).unwrap();
        assert_eq!(cd_with_dem.engine, "cd");
        // A method's own kinds keep their prefix; a drawing kind simulates nothing.
        assert_eq!(
            enabled("p", "dem-column-prep", &json!({ "dem": {} })).unwrap().engine,
            "dem"
        );
        assert!(enabled("fig", "plot", &json!({ "panels": [] })).is_none());
    }
}

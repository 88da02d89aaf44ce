//! `granrepro bench`: particle-, point- and contact-steps per second of each engine, the
//! DEM team crossover and the cost-growth table (JSON lines, optional phase tables and SVG).

use std::path::PathBuf;

use super::args::{BenchCaseArg, BenchEngine};

/// Options of `granrepro bench`.
pub struct BenchOpts {
    pub(super) phases: bool,
    pub(super) threads: Vec<usize>,
    pub(super) dt: Option<f64>,
    pub(super) case: Vec<BenchCaseArg>,
    pub(super) repeat: usize,
    pub(super) svg: Option<PathBuf>,
    pub(super) max_n: usize,
    pub(super) lattice_order: bool,
    pub(super) sorted: bool,
    pub(super) dem_only: bool,
    pub(super) dense_size: String,
    pub(super) scene_out: Option<PathBuf>,
}

/// A LAMMPS-style timer table: section, seconds, share of the total.
fn print_phase_table(title: &str, rows: &[(&str, f64)], steps: u64) {
    let total: f64 = rows.iter().map(|r| r.1).sum();
    println!("{title}");
    println!(
        "  {:<14} {:>10} {:>12} {:>7}",
        "section", "time [s]", "per step [us]", "%total"
    );
    for (name, t) in rows {
        println!(
            "  {:<14} {:>10.4} {:>12.3} {:>6.1}%",
            name,
            t,
            1e6 * t / steps.max(1) as f64,
            100.0 * t / total.max(1e-300)
        );
    }
    println!(
        "  {:<14} {:>10.4} {:>12.3} {:>6.1}%",
        "total",
        total,
        1e6 * total / steps.max(1) as f64,
        100.0
    );
}

/// The machine a sitting ran on, as one JSON line: the CPU as the kernel names it (vendor,
/// family, model, clock), its cores, and the widest vector instructions it offers, which is
/// the width the MPM stress block and the DEM pair filter dispatch to at run time
/// (`mpm::stress_block`, `dem::passes`: AVX-512, else AVX2, else SSE2). Figures from two
/// machines are only comparable with this line beside them (issue 27 item 4: the same code
/// ran 17.0 M point-steps/s on one machine and 11.4 M on another).
fn machine_line(cores: usize) -> serde_json::Value {
    let info = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let field = |k: &str| {
        info.lines()
            .find(|l| l.split(':').next().is_some_and(|n| n.trim() == k))
            .and_then(|l| l.split_once(':'))
            .map(|(_, v)| v.trim().to_string())
    };
    #[cfg(target_arch = "x86_64")]
    let simd = if std::arch::is_x86_feature_detected!("avx512f") {
        "avx512"
    } else if std::arch::is_x86_feature_detected!("avx2") {
        "avx2"
    } else {
        "sse2"
    };
    #[cfg(not(target_arch = "x86_64"))]
    let simd = "scalar";
    serde_json::json!({
        "bench": "machine",
        "cpu": field("model name"),
        "vendor": field("vendor_id"),
        "family": field("cpu family"),
        "model": field("model"),
        "mhz": field("cpu MHz").and_then(|v| v.parse::<f64>().ok()),
        "cores": cores,
        "simd": simd,
    })
}

pub(super) fn bench(engine: BenchEngine, steps: Option<u64>, o: &BenchOpts) -> i32 {
    let all = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    if matches!(engine, BenchEngine::CdDense) && parse_dense_size(&o.dense_size).is_none() {
        // refused before anything is printed
        eprintln!(
            "error: bench cd-dense: --dense-size {:?}: expected COLSxROWS with COLS >= 2, ROWS >= 1 (e.g. 40x25)",
            o.dense_size
        );
        return 2;
    }
    println!("{}", machine_line(all));
    let threads: Vec<usize> = if !o.threads.is_empty() {
        o.threads.iter().map(|&t| t.max(1)).collect()
    } else if all > 1 {
        vec![1, all]
    } else {
        vec![1]
    };
    match engine {
        BenchEngine::Scaling => bench_scaling(steps, o),
        BenchEngine::DemCrossover => bench_dem_crossover(steps, o, all),
        BenchEngine::Dem => {
            use crate::dem::bench::{BenchCase, run};
            let steps = steps.unwrap_or(20_000);
            let cases: Vec<BenchCase> = if o.case.is_empty() {
                vec![
                    BenchCase::NoRollingNoLedger,
                    BenchCase::RollingNoLedger,
                    BenchCase::Full,
                ]
            } else {
                o.case
                    .iter()
                    .map(|c| match c {
                        BenchCaseArg::Full => BenchCase::Full,
                        BenchCaseArg::RollingNoLedger => BenchCase::RollingNoLedger,
                        BenchCaseArg::NoRolling => BenchCase::NoRollingNoLedger,
                    })
                    .collect()
            };
            for case in cases {
                for &t in &threads {
                    let mut best: Option<crate::dem::bench::BenchResult> = None;
                    for _ in 0..o.repeat.max(1) {
                        match run(case, t, steps, o.dt) {
                            Ok(r) => {
                                let tm = &r.timers;
                                println!(
                                    "{}",
                                    serde_json::json!({
                                        "bench": "dem-column", "case": case.name(),
                                        "threads": r.threads, "particles": r.grains, "steps": r.steps, "dt": r.dt,
                                        "preflight_limit_s": r.preflight_limit_s,
                                        "wall_s": r.wall_s, "cpu_s": r.cpu_s, "particle_steps_per_s": r.particle_steps_per_s,
                                        "best_block_particle_steps_per_s": r.best_block_particle_steps_per_s,
                                        "pairs_per_grain": r.pairs_per_grain, "contacts_per_grain": r.contacts_per_grain, "rebuilds": r.rebuilds,
                                        "neighbors_s": tm.neighbors, "contacts_s": tm.contacts, "gather_s": tm.gather, "walls_s": tm.walls,
                                        "rolling_s": tm.rolling, "integrate_s": tm.integrate, "ledger_s": tm.ledger, "digest": r.digest,
                                    })
                                );
                                if best.as_ref().is_none_or(|b| r.wall_s < b.wall_s) {
                                    best = Some(r);
                                }
                            }
                            Err(e) => {
                                eprintln!("error: bench dem: {e}");
                                return 1;
                            }
                        }
                    }
                    if let (true, Some(r)) = (o.phases, best) {
                        let tm = &r.timers;
                        let other = (r.wall_s - tm.total()).max(0.0);
                        print_phase_table(
                            &format!(
                                "dem-column {} | {} thread(s) | {} grains x {} steps, dt = {:.2e} s | {:.3} M particle-steps/s",
                                case.name(),
                                r.threads,
                                r.grains,
                                r.steps,
                                r.dt,
                                r.particle_steps_per_s / 1e6
                            ),
                            &[
                                ("neighbour", tm.neighbors),
                                ("contact pairs", tm.contacts),
                                ("force gather", tm.gather),
                                ("walls", tm.walls),
                                ("rolling solve", tm.rolling),
                                ("integrate", tm.integrate),
                                ("ledger", tm.ledger),
                                ("other", other + tm.watchdog),
                            ],
                            r.steps,
                        );
                    }
                }
            }
            0
        }
        BenchEngine::Cd => {
            let steps = steps.unwrap_or(2000);
            for (ncol, nrow) in [(25, 20), (40, 25)] {
                for &t in &threads {
                    match crate::cd::bench::run(ncol, nrow, t, steps) {
                        Ok(r) => println!("{}", cd_line("cd-pile", &r)),
                        Err(e) => {
                            eprintln!("error: bench cd: {e}");
                            return 1;
                        }
                    }
                }
            }
            0
        }
        BenchEngine::CdDense => bench_cd_dense(steps.unwrap_or(400), &threads, o),
        BenchEngine::Mpm => {
            for &t in &threads {
                let mut best: Option<crate::mpm::bench::BenchResult> = None;
                for _ in 0..o.repeat.max(1) {
                    let r = crate::mpm::bench::run(t, steps, 5.0);
                    let ph = &r.phases;
                    println!(
                        "{}",
                        serde_json::json!({
                            "bench": "mpm-column", "case": "a1-16ppc-2mm-mc",
                            "threads": r.threads, "points": r.points, "steps": r.steps,
                            "wall_s": r.wall_s, "point_steps_per_s": r.point_steps_per_s,
                            "p2g_s": r.p2g_s(), "grid_update_s": ph.grid_update.as_secs_f64(), "stress_s": r.stress_s(),
                            "g2p_s": r.g2p_s(), "relocate_s": ph.relocate.as_secs_f64(),
                        })
                    );
                    if best.as_ref().is_none_or(|b| r.point_steps_per_s > b.point_steps_per_s) {
                        best = Some(r);
                    }
                }
                if let (true, Some(r)) = (o.phases, best) {
                    let ph = &r.phases;
                    let other = (r.wall_s - ph.total().as_secs_f64()).max(0.0);
                    print_phase_table(
                        &format!(
                            "mpm-column a1-16ppc-2mm-mc | {} thread(s) | {} points x {} steps | best of {}: {:.3} M point-steps/s",
                            r.threads,
                            r.points,
                            r.steps,
                            o.repeat.max(1),
                            r.point_steps_per_s / 1e6
                        ),
                        &[
                            ("P2G", r.p2g_s()),
                            ("grid update", ph.grid_update.as_secs_f64()),
                            ("stress", r.stress_s()),
                            ("G2P", r.g2p_s()),
                            ("relocation", ph.relocate.as_secs_f64()),
                            ("other", other),
                        ],
                        r.steps,
                    );
                }
            }
            0
        }
        BenchEngine::LeaveOut => 2, // needs the pipeline: dispatched in run_cli
    }
}

/// `bench dem-crossover`: µs per step on 1 thread and on `all` threads (team forced on)
/// by grain count, best of `--repeat`, alternating the two at each size.
fn bench_dem_crossover(steps: Option<u64>, o: &BenchOpts, all: usize) -> i32 {
    use crate::dem::bench::{BenchCase, GrainOrder, bench_dt, bench_scene, scaling_point_with};
    let (dt, _) = bench_dt(BenchCase::Full);
    let base = match bench_scene(BenchCase::Full, dt) {
        Ok(w) => w,
        Err(e) => {
            eprintln!("error: bench dem-crossover: {e}");
            return 1;
        }
    };
    let multi = o.threads.iter().copied().max().unwrap_or(all).max(2);
    println!(
        "dem-crossover | rolling + ledger | best of {} | µs per step",
        o.repeat.max(1)
    );
    println!(
        "  {:>6} {:>10} {:>10} {:>8}",
        "grains",
        "1 thread",
        format!("{multi} threads"),
        "speed-up"
    );
    for n in [250usize, 500, 750, 1000, 1500, 2000, 2924, 5848] {
        let st = steps.unwrap_or((2_000_000 / n as u64).clamp(200, 5000));
        let (mut t1, mut t2) = (f64::INFINITY, f64::INFINITY);
        for _ in 0..o.repeat.max(1) {
            for (t, best) in [(1, &mut t1), (multi, &mut t2)] {
                match scaling_point_with(&base, n, t, st, Some(0), GrainOrder::Lattice) {
                    Ok(p) => *best = best.min(p.s_per_step),
                    Err(e) => {
                        eprintln!("error: bench dem-crossover ({n}): {e}");
                        return 1;
                    }
                }
            }
        }
        println!(
            "{}",
            serde_json::json!({"bench": "dem-crossover", "n": n, "steps": st, "s_per_step_1": t1, "threads": multi, "s_per_step_multi": t2})
        );
        println!("  {:>6} {:>10.1} {:>10.1} {:>7.2}x", n, 1e6 * t1, 1e6 * t2, t1 / t2);
    }
    0
}

/// `bench scaling`: seconds per step against size for the three engines, one thread. The
/// DEM's grains are shuffled (as a mixed flow leaves them) unless `--lattice-order`; its
/// row goes on to 1e6 grains with `--max-n 1000000`, the MPM's and CD's stop at 1e5.
fn bench_scaling(steps: Option<u64>, o: &BenchOpts) -> i32 {
    use crate::dem::bench::{GrainOrder, SCALING_SHUFFLE_SEED};
    use crate::report::plot::{Chart, Series, Style};
    let threads = o.threads.first().copied().unwrap_or(1).max(1);
    let dem_sizes: Vec<usize> = [1_000usize, 3_000, 10_000, 30_000, 100_000, 1_000_000]
        .into_iter()
        .filter(|&n| n <= o.max_n)
        .collect();
    let sizes: Vec<usize> = if o.dem_only {
        Vec::new()
    } else {
        dem_sizes.iter().copied().filter(|&n| n <= 100_000).collect()
    };
    let order = if o.lattice_order {
        GrainOrder::Lattice
    } else if o.sorted {
        GrainOrder::Sorted(SCALING_SHUFFLE_SEED)
    } else {
        GrainOrder::Shuffled(SCALING_SHUFFLE_SEED)
    };
    let order_name = match order {
        GrainOrder::Lattice => "lattice",
        GrainOrder::Shuffled(_) => "shuffled",
        GrainOrder::Sorted(_) => "sorted",
    };
    // work per size ~ n × steps: fewer steps for the big ones, at least 20
    let steps_for = |n: usize, base: u64| steps.unwrap_or((base * 10_000 / n as u64).clamp(20, base * 10));
    let best = |f: &mut dyn FnMut() -> f64| (0..o.repeat.max(1)).map(|_| f()).fold(f64::INFINITY, f64::min);
    let mut rows: Vec<(&str, usize, f64, String)> = Vec::new();
    // DEM
    let (dt, _) = crate::dem::bench::bench_dt(crate::dem::bench::BenchCase::Full);
    let base = match crate::dem::bench::bench_scene(crate::dem::bench::BenchCase::Full, dt) {
        Ok(w) => w,
        Err(e) => {
            eprintln!("error: bench scaling: {e}");
            return 1;
        }
    };
    for &n in &dem_sizes {
        // 2·10⁷ grain-steps a size (at least 20 steps)
        let st = steps.unwrap_or((20_000_000 / n as u64).clamp(20, 20_000));
        let mut extra = String::new();
        let mut err = None;
        let mut fastest = f64::INFINITY;
        let s = best(
            &mut || match crate::dem::bench::scaling_point(&base, n, threads, st, order) {
                Ok(p) if p.s_per_step >= fastest => p.s_per_step,
                Ok(p) => {
                    fastest = p.s_per_step;
                    extra = format!(
                        "{:.2} pairs, {:.2} contacts per grain, {} order, cpu/wall {:.2}",
                        p.pairs_per_grain,
                        p.contacts_per_grain,
                        order_name,
                        p.cpu_s_per_step / p.s_per_step
                    );
                    p.s_per_step
                }
                Err(e) => {
                    err = Some(e.to_string());
                    f64::NAN
                }
            },
        );
        if let Some(e) = err {
            eprintln!("error: bench scaling (dem, {n}): {e}");
            return 1;
        }
        println!(
            "{}",
            serde_json::json!({"bench": "scaling", "engine": "dem", "n": n, "threads": threads, "steps": st, "s_per_step": s, "note": extra})
        );
        rows.push(("DEM", n, s, extra));
    }
    // MPM
    for &n in &sizes {
        let st = steps_for(n, 20);
        let mut pts = 0;
        let s = best(&mut || {
            let (p, s) = crate::mpm::bench::scaling_point(n, threads, st);
            pts = p;
            s
        });
        println!(
            "{}",
            serde_json::json!({"bench": "scaling", "engine": "mpm", "n": pts, "threads": threads, "steps": st, "s_per_step": s})
        );
        rows.push(("MPM", pts, s, String::new()));
    }
    // CD: the Siconos deposit, ncol × nrow ≈ n with ncol/nrow = 1.6 as its 40 × 25 case
    for &n in &sizes {
        let ncol = ((n as f64 * 1.6).sqrt().round() as usize).max(2);
        let nrow = (n / ncol).max(1);
        let st = steps_for(n, 20);
        let mut extra = String::new();
        let mut pts = ncol * nrow;
        let mut err = None;
        let s = best(&mut || match crate::cd::bench::run(ncol, nrow, threads, st) {
            Ok(r) => {
                pts = r.particles;
                extra = format!(
                    "{:.0} contacts, {:.1} NLGS sweeps per step",
                    r.contacts,
                    r.iterations as f64 / r.steps.max(1) as f64
                );
                r.wall_s / r.steps.max(1) as f64
            }
            Err(e) => {
                err = Some(e.to_string());
                f64::NAN
            }
        });
        if let Some(e) = err {
            eprintln!("error: bench scaling (cd, {n}): {e}");
            return 1;
        }
        println!(
            "{}",
            serde_json::json!({"bench": "scaling", "engine": "cd", "n": pts, "threads": threads, "steps": st, "s_per_step": s, "note": extra})
        );
        rows.push(("CD", pts, s, extra));
    }
    println!("cost growth, {threads} thread(s): wall time per step");
    println!(
        "  {:<5} {:>8} {:>12} {:>14} {:>8}  ",
        "engine", "n", "ms/step", "ns/(n·step)", "vs 1e3"
    );
    for eng in ["DEM", "MPM", "CD"] {
        let r: Vec<_> = rows.iter().filter(|r| r.0 == eng).collect();
        let Some(first) = r.first() else { continue };
        let unit0 = first.2 / first.1 as f64;
        for x in &r {
            let unit = x.2 / x.1 as f64;
            println!(
                "  {:<5} {:>8} {:>12.3} {:>14.1} {:>8.2}  {}",
                x.0,
                x.1,
                1e3 * x.2,
                1e9 * unit,
                unit / unit0,
                x.3
            );
        }
    }
    if let Some(path) = &o.svg {
        let series: Vec<Series> = ["DEM", "MPM", "CD"]
            .iter()
            .enumerate()
            .map(|(c, eng)| {
                Series::new(
                    format!("{eng} (measured)"),
                    Style::LinePoints,
                    rows.iter().filter(|r| r.0 == *eng).map(|r| (r.1 as f64, r.2)).collect(),
                    c,
                )
            })
            .chain(rows.iter().find(|r| r.0 == "DEM").map(|r| {
                let k = r.2 / r.1 as f64;
                Series::new(
                    "linear in n (through DEM at 1e3)",
                    Style::Dashed,
                    dem_sizes.iter().map(|&n| (n as f64, k * n as f64)).collect(),
                    7,
                )
            }))
            .collect();
        let chart = Chart::log_log(
            format!("Cost growth: wall time per step vs size ({threads} thread(s))"),
            format!(
                "granrepro bench scaling; DEM: settled column with rolling resistance + ledger, grains in {order_name} order; MPM: GIMP + Mohr-Coulomb column; CD: Siconos deposit"
            ),
            "grains / material points",
            "wall time per step [s]",
            series,
        );
        match chart
            .to_svg()
            .map_err(|e| e.to_string())
            .and_then(|svg| std::fs::write(path, svg).map_err(|e| e.to_string()))
        {
            Ok(()) => println!("figure: {}", path.display()),
            Err(e) => {
                eprintln!("error: {}: {e}", path.display());
                return 1;
            }
        }
    }
    0
}

/// `bench cd-dense`: the CD engine on the dense deposit, at rest and kicked (13 mgd), one
/// JSON line per case, sweep order (key, coloured) and thread count with
/// contact·iterations/s and sweeps per step.
fn bench_cd_dense(steps: u64, threads: &[usize], o: &BenchOpts) -> i32 {
    use crate::cd::bench::{dense_scene, deposit_width, run_scene};
    let Some((ncol, nrow)) = parse_dense_size(&o.dense_size) else {
        return 2; // refused in `bench` before the machine line
    };
    let settle_s = 6.0;
    for (case, kick) in [("rest", 0.0), ("kick13mgd", 13.0)] {
        let scene = match dense_scene(ncol, nrow, settle_s, kick) {
            Ok(s) => s,
            Err(e) => {
                eprintln!("error: bench cd-dense: {e}");
                return 1;
            }
        };
        let name = format!("dense-{ncol}x{nrow}-{case}");
        if let Some(dir) = &o.scene_out {
            let path = dir.join(format!("cd-{name}.csv"));
            let st = &scene.0;
            let mut csv = String::from("x,y,r,m,vx,vy\n");
            for i in 0..st.len() {
                csv.push_str(&format!(
                    "{:e},{:e},{:e},{:e},{:e},{:e}\n",
                    st.x[i], st.y[i], st.r[i], st.m[i], st.vx[i], st.vy[i]
                ));
            }
            if let Err(e) = std::fs::create_dir_all(dir).and_then(|_| std::fs::write(&path, csv)) {
                eprintln!("error: bench cd-dense: writing {}: {e}", path.display());
                return 2;
            }
        }
        for (order, coloured) in [("key", false), ("coloured", true)] {
            for &t in threads {
                match run_scene(&name, &scene, deposit_width(ncol), t, steps, coloured) {
                    Ok(r) => {
                        let mut line = cd_line("cd-dense", &r);
                        line["sweeps_per_step"] = serde_json::json!(r.iterations as f64 / r.steps.max(1) as f64);
                        line["sweep_order"] = serde_json::json!(order);
                        println!("{line}")
                    }
                    Err(e) => {
                        eprintln!("error: bench cd-dense: {e}");
                        return 1;
                    }
                }
            }
        }
    }
    0
}

/// `--dense-size COLSxROWS` (COLS ≥ 2, ROWS ≥ 1).
fn parse_dense_size(s: &str) -> Option<(usize, usize)> {
    s.split_once('x')
        .and_then(|(c, r)| Some((c.parse::<usize>().ok()?, r.parse::<usize>().ok()?)))
        .filter(|&(c, r)| c >= 2 && r >= 1)
}

/// The JSON line of one CD measurement (`bench cd`, `bench cd-dense`).
fn cd_line(bench: &str, r: &crate::cd::bench::BenchResult) -> serde_json::Value {
    serde_json::json!({
        "bench": bench, "case": r.case, "threads": r.threads, "particles": r.particles,
        "contacts": r.contacts, "contacts_last": r.contacts_last, "steps": r.steps,
        "iterations": r.iterations, "wall_s": r.wall_s, "contact_iterations_per_s": r.contact_iterations_per_s,
        "unconverged": r.unconverged, "max_residual": r.max_residual,
        "packing_fraction": r.packing_fraction, "ke_over_mgd": r.ke_over_mgd,
        "detect_s": r.timers.detect, "solve_s": r.timers.solve, "update_s": r.timers.update,
    })
}

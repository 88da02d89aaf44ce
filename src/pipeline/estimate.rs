//! `granrepro plan --profile paper --estimate`: the CPU budget of a profile, estimated from
//! measured quick-profile runs, not guessed.
//!
//! **How**: for every stage, the quick run's record (the cache entry of its current quick
//! key, else `reports/quick/<id>.record.json`) gives wall time × threads. That is scaled
//! by the ratio of the solver's work between the two profiles, computed from each
//! profile's resolved parameters:
//! - DEM: grains × steps. Grains ∝ the column area (`area_m2`, own or of the `column`
//!   input) or the PSD size (`n` of the `psd` input: shear cell, pile). Steps ∝
//!   √stiffness_factor / dt (the step is dt/√factor) × simulated time, which changes
//!   between profiles only for the shear test (∝ strain × Σ_P P^-½: γ̇ ∝ I√P) and the
//!   pile (`max_time`); work-precision sums its variants (√factor / dt_fraction) × members;
//!   a calibration point is bounded by the larger of its shear-test and column ratios.
//! - MPM: points × steps. Points ∝ area × PPC / h²; steps ∝ 1/Δt — fixed, or
//!   c_p / (Courant · h) (c_p from the resolved material, table 4.3's E; at run time E
//!   comes from the DEM calibration, 6× lower in the quick profile, so the quick run
//!   took ≈ 2.4× fewer steps than this assumes and a fixed-Δt paper stage is
//!   underestimated by up to that factor); the work-precision sweep sums its
//!   (PPC, h, Courant) grid and reference.
//! - CD: grains × steps, steps ∝ strain × Σ_I 1/I / h (shear) or Σ_variants time / h.
//!
//! **Not modelled**: contacts per grain, solver iterations (NLGS sweeps, settling that
//! takes longer in a bigger sample), memory bandwidth, parallel efficiency. Read the
//! result as good to a factor of 2–3, not better.

use std::collections::HashMap;

use serde_json::{Value, json};

use super::export::Measured;
use super::profiles::load;
use super::run::{Project, key_records};
use super::spec::{Pipeline, Stage};
use crate::stages::kind::{CostCtx, Work};

/// A night on the cluster [h].
pub const NIGHT_H: f64 = 12.0;

/// One stage's estimate.
#[derive(Debug, Clone)]
pub struct Row {
    /// Stage id.
    pub id: String,
    /// Family (matrix base id).
    pub family: String,
    /// Kind.
    pub kind: String,
    /// Quick run: wall [s] and threads, when measured.
    pub quick: Option<Measured>,
    /// Work ratio target / quick (1 for bookkeeping stages).
    pub scale: f64,
    /// What the ratio is made of.
    pub basis: String,
}

impl Row {
    /// Estimated wall [s] at the quick run's thread count.
    pub fn wall_s(&self) -> Option<f64> {
        self.quick.map(|m| m.wall_s * self.scale)
    }
    /// Estimated CPU-hours (wall × threads).
    pub fn cpu_h(&self) -> Option<f64> {
        self.quick.map(|m| m.wall_s * self.scale * m.threads as f64 / 3600.0)
    }
}

/// The estimate of a profile.
#[derive(Debug, Clone)]
pub struct Estimate {
    /// Profile estimated.
    pub profile: String,
    /// Stages in plan order.
    pub rows: Vec<Row>,
    /// Longest dependency chain of estimated walls [s] and its last stage.
    pub critical: (f64, String),
}

impl Estimate {
    /// Total estimated CPU-hours of the measured stages.
    pub fn total_cpu_h(&self) -> f64 {
        self.rows.iter().filter_map(Row::cpu_h).sum()
    }
    /// Threads of a worker (the quick runs' thread count).
    pub fn threads(&self) -> usize {
        self.rows
            .iter()
            .filter_map(|r| r.quick.map(|m| m.threads))
            .max()
            .unwrap_or(1)
    }
    /// Workers of `threads()` cores that finish in one night (if the longest chain fits).
    pub fn workers_for_night(&self) -> usize {
        let wall: f64 = self.rows.iter().filter_map(Row::wall_s).sum();
        (wall / 3600.0 / NIGHT_H).ceil().max(1.0) as usize
    }
    /// Stages without a quick run record.
    pub fn unmeasured(&self) -> Vec<&str> {
        self.rows
            .iter()
            .filter(|r| r.quick.is_none())
            .map(|r| r.id.as_str())
            .collect()
    }
    /// The estimated wall of one stage, as export uses it.
    pub fn measured(&self, id: &str) -> Option<Measured> {
        let r = self.rows.iter().find(|r| r.id == id)?;
        Some(Measured {
            wall_s: r.wall_s()?,
            threads: r.quick?.threads,
        })
    }
    /// Families: (family, kind, stages, quick CPU-h, estimated CPU-h, bases).
    fn families(&self) -> Vec<(String, String, usize, f64, f64, String, bool)> {
        let mut out: Vec<(String, String, usize, f64, f64, String, bool)> = Vec::new();
        for r in &self.rows {
            let q = r.quick.map(|m| m.wall_s * m.threads as f64 / 3600.0).unwrap_or(0.0);
            match out.iter_mut().find(|f| f.0 == r.family) {
                Some(f) => {
                    f.2 += 1;
                    f.3 += q;
                    f.4 += r.cpu_h().unwrap_or(0.0);
                    f.6 |= r.quick.is_none();
                }
                None => out.push((
                    r.family.clone(),
                    r.kind.clone(),
                    1,
                    q,
                    r.cpu_h().unwrap_or(0.0),
                    r.basis.clone(),
                    r.quick.is_none(),
                )),
            }
        }
        out
    }
    /// JSON.
    pub fn to_json(&self) -> Value {
        json!({
            "profile": self.profile,
            "method": "quick-profile run records (wall × threads) × the ratio of solver work (DEM/CD grains × steps, MPM points × steps) from each profile's resolved parameters; see src/pipeline/estimate.rs",
            "stages": self.rows.iter().map(|r| json!({
                "id": r.id, "family": r.family, "kind": r.kind,
                "quick_wall_s": r.quick.map(|m| m.wall_s), "threads": r.quick.map(|m| m.threads),
                "scale": r.scale, "basis": r.basis, "wall_s": r.wall_s(), "cpu_h": r.cpu_h(),
            })).collect::<Vec<_>>(),
            "total_cpu_h": self.total_cpu_h(),
            "critical_path_h": self.critical.0 / 3600.0, "critical_path_ends_at": self.critical.1,
            "worker_threads": self.threads(), "workers_for_12h": self.workers_for_night(),
            "unmeasured": self.unmeasured(),
        })
    }
    /// Text table.
    pub fn to_text(&self) -> String {
        let mut s = format!(
            "Estimated CPU-hours of the {} profile: the quick profile's measured runs (wall × threads)\n\
             scaled by each solver's work — DEM/CD grains × steps, MPM points × steps — computed from\n\
             both profiles' resolved parameters (method: src/pipeline/estimate.rs). Not modelled:\n\
             contacts per grain, solver iterations, longer settling, parallel efficiency: good to a\n\
             factor of 2–3.\n\n",
            self.profile
        );
        s.push_str(&format!(
            "{:<26} {:<22} {:>6} {:>11} {:>12}  {}\n",
            "family", "kind", "stages", "quick CPU-h", "est. CPU-h", "work ratio (per stage)"
        ));
        for (fam, kind, n, q, e, basis, missing) in self.families() {
            let est = if missing {
                format!("{e:.2}+?")
            } else {
                format!("{e:.2}")
            };
            s.push_str(&format!("{fam:<26} {kind:<22} {n:>6} {q:>11.3} {est:>12}  {basis}\n"));
        }
        s.push_str(&format!(
            "\ntotal: {:.0} CPU-hours ({} cores per worker, as measured); longest dependency chain {:.1} h (ending at {}).\n",
            self.total_cpu_h(),
            self.threads(),
            self.critical.0 / 3600.0,
            self.critical.1
        ));
        let wall_h: f64 = self.rows.iter().filter_map(Row::wall_s).sum::<f64>() / 3600.0;
        let chain_h = self.critical.0 / 3600.0;
        if chain_h <= NIGHT_H {
            s.push_str(&format!(
                "overnight ({NIGHT_H} h): {} workers of {} cores.\n",
                self.workers_for_night(),
                self.threads()
            ));
        } else {
            s.push_str(&format!(
                "not overnight at {} threads per stage: the chain alone takes {chain_h:.1} h > {NIGHT_H} h (a stage runs on\n\
                 one worker; more threads per stage shorten it only as far as the engine scales). {} workers of {}\n\
                 cores finish everything in about the chain's time.\n",
                self.threads(),
                (wall_h / chain_h).ceil().max(1.0),
                self.threads(),
            ));
        }
        let um = self.unmeasured();
        if !um.is_empty() {
            s.push_str(&format!(
                "not measured (no quick run record; `granrepro run --stage ID` first, then re-estimate): {}\n",
                um.join(", ")
            ));
        }
        s
    }
}

/// Estimate the stages `targets` need (all when empty) of profile `p.profile`.
pub fn estimate(p: &Pipeline, proj: &Project, targets: &[String]) -> Result<Estimate, String> {
    let ids = super::dag::closure(p, targets)
        .map_err(|u| format!("unknown stage(s): {} (see `granrepro list`)", u.join(", ")))?;
    let q = load(&p.path, "quick", &[]).map_err(|d| d.to_string())?;
    let qkeys = key_records(&q);
    let mut rows = Vec::new();
    for id in &ids {
        let st = p.get(id).expect("closure id");
        let quick = q
            .get(id)
            .and_then(|qs| entry_record(proj, &qkeys[&qs.id].1))
            .or_else(|| super::export::measured_from_record(&proj.report_dir("quick"), id));
        let (scale, basis) = match (q.get(id).and_then(|qs| work(&q, qs)), work(p, st)) {
            (Some((wq, max_of)), Some((wp, _))) if wq.len() == wp.len() && wq.iter().all(|(_, x)| *x > 0.0) => {
                let ratios: Vec<f64> = wp.iter().zip(&wq).map(|((_, a), (_, b))| a / b).collect();
                let scale = if max_of {
                    ratios.iter().fold(0.0f64, |a, &b| a.max(b))
                } else {
                    ratios.iter().product()
                };
                let parts: Vec<String> = wp
                    .iter()
                    .zip(&ratios)
                    .map(|((n, _), r)| format!("{n} ×{}", short(*r)))
                    .collect();
                (
                    scale,
                    parts.join(if max_of { " | " } else { ", " }) + if max_of { " (larger)" } else { "" },
                )
            }
            _ => (1.0, "bookkeeping: as measured".to_string()),
        };
        rows.push(Row {
            id: id.clone(),
            family: st.base_id.clone(),
            kind: st.kind.clone(),
            quick,
            scale,
            basis,
        });
    }
    // Longest chain of estimated walls (plan order is topological).
    let wall: HashMap<&str, f64> = rows
        .iter()
        .map(|r| (r.id.as_str(), r.wall_s().unwrap_or(0.0)))
        .collect();
    let mut finish: HashMap<String, f64> = HashMap::new();
    let mut critical = (0.0, String::new());
    for id in &ids {
        let st = p.get(id).unwrap();
        let start = st
            .inputs
            .iter()
            .flat_map(|(_, v)| v.iter())
            .filter_map(|d| finish.get(d))
            .fold(0.0f64, |a, &b| a.max(b));
        let f = start + wall[id.as_str()];
        if f > critical.0 {
            critical = (f, id.clone());
        }
        finish.insert(id.clone(), f);
    }
    Ok(Estimate {
        profile: p.profile.clone(),
        rows,
        critical,
    })
}

/// Wall and threads from the run record inside a cache entry.
fn entry_record(proj: &Project, key: &str) -> Option<Measured> {
    super::export::measured_from_record_file(&proj.cache.entry_dir(key).join("record.json"))
}

/// What a kind's cost model sees of stage `st`: its params, and its inputs' by role
/// (recursively: a pile run reaches its preparation's grading).
fn cost_ctx<'a>(p: &'a Pipeline, st: &'a Stage) -> CostCtx<'a> {
    CostCtx {
        params: &st.params,
        inputs: Box::new(move |role: &str| {
            st.inputs
                .iter()
                .filter(|(r, _)| r == role)
                .flat_map(|(_, ids)| ids.iter())
                .filter_map(|id| p.get(id))
                .map(|s| cost_ctx(p, s))
                .collect()
        }),
    }
}

/// A ratio, short.
fn short(r: f64) -> String {
    if r >= 10.0 {
        format!("{r:.0}")
    } else {
        format!("{r:.2}")
    }
}

/// A stage's work as its kind's cost model gives it (see [`crate::stages::kind::Work`]).
/// None: not a solver stage (bookkeeping, as measured).
fn work(p: &Pipeline, st: &Stage) -> Option<Work> {
    (p.kinds.get(st.kind.as_str())?.cost?)(&cost_ctx(p, st))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn num(v: &Value, path: &str) -> Option<f64> {
        path.split('.').try_fold(v, |v, k| v.get(k))?.as_f64()
    }

    fn list(v: &Value, key: &str) -> Vec<f64> {
        v.get(key)
            .and_then(|x| x.as_array())
            .map(|a| a.iter().filter_map(|x| x.as_f64()).collect())
            .unwrap_or_default()
    }

    /// The shipped pipeline.yaml at `profile`.
    fn shipped(profile: &str) -> Pipeline {
        load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("pipeline.yaml"),
            profile,
            &[],
        )
        .unwrap()
    }

    /// The shear test's ratio, worked by hand from stages/shear-dem.yaml and psd-shear.yaml.
    /// A run's steps ∝ strain × √(k_n/P) (time ∝ P^-½ at fixed I, Δt ∝ k_n^-½), so at a
    /// fixed κ = k_n/P every pressure costs the same, √κ × strain. Paper: 8 dense and 3
    /// loose runs at κ = 1e4, γ = 3, and the fixed-stiffness check at k × 0.1, 1 and 4 kPa;
    /// quick: 2 dense runs at κ = 1600, γ = 2. Grains 1078/400.
    #[test]
    fn paper_shear_test_scales_by_grains_times_steps() {
        let (p, q, dir) = (shipped("paper"), shipped("quick"), tempfile::tempdir().unwrap());
        let proj = Project::new(dir.path());
        std::fs::create_dir_all(proj.report_dir("quick")).unwrap();
        std::fs::write(
            proj.report_dir("quick").join("fig4-03.record.json"),
            r#"{"wall_s": 100.0, "threads": 2}"#,
        )
        .unwrap();
        let e = estimate(&p, &proj, &["fig4-03".to_string()]).unwrap();
        let row = e.rows.iter().find(|r| r.id == "fig4-03").unwrap();
        let n = |pl: &Pipeline| num(&pl.get("psd-shear").unwrap().params, "n").unwrap();
        let kn = num(&p.get("fig4-03").unwrap().params, "dem.grain.kn").unwrap();
        let paper = 11.0 * 3.0 * 1e4f64.sqrt() + 3.0 * ((0.1 * kn / 1e3).sqrt() + (0.1 * kn / 4e3).sqrt());
        let quick = 2.0 * 2.0 * 1600f64.sqrt();
        let want = n(&p) / n(&q) * paper / quick;
        assert!(
            want > 10.0,
            "the paper shear test is much bigger than the quick one: {want}"
        );
        assert!((row.scale - want).abs() < 1e-9 * want, "{} vs {want}", row.scale);
        assert!((row.cpu_h().unwrap() - 100.0 * want * 2.0 / 3600.0).abs() < 1e-9 * want);
        // Stages it needs without a record are listed, not guessed.
        assert!(e.unmeasured().contains(&"calib-dem"));
        // A bookkeeping stage keeps its measured time.
        let e = estimate(&p, &proj, &["psd-shear".to_string()]).unwrap();
        assert_eq!(e.rows[0].scale, 1.0);
        assert!(estimate(&p, &proj, &["nope".to_string()]).is_err());
    }

    /// The pile runs scale by grains (the prep's `grains`, else its PSD's) × steps: the quick
    /// pile is 250 grains, not psd-pile's quick 1500, and the DEM step grows by √10 with
    /// the quick profile's softened contacts.
    #[test]
    fn paper_pile_runs_scale_by_the_piles_grains() {
        let (p, q, dir) = (shipped("paper"), shipped("quick"), tempfile::tempdir().unwrap());
        let proj = Project::new(dir.path());
        std::fs::create_dir_all(proj.report_dir("quick")).unwrap();
        for id in ["pile-dem-g", "fig4-23"] {
            std::fs::write(
                proj.report_dir("quick").join(format!("{id}.record.json")),
                r#"{"wall_s": 10.0, "threads": 1}"#,
            )
            .unwrap();
        }
        let e = estimate(&p, &proj, &["pile-dem-g".to_string()]).unwrap();
        let par = |pl: &Pipeline, id: &str, k: &str| num(&pl.get(id).unwrap().params, k).unwrap();
        let grains = |pl: &Pipeline| match par(pl, "fig4-23", "grains") {
            n if n > 0.0 => n,
            _ => par(pl, "psd-pile", "n"),
        };
        assert_eq!(grains(&q), 250.0);
        assert_eq!(grains(&p), par(&p, "psd-pile", "n"));
        let steps = |pl: &Pipeline| {
            let v = &pl.get("pile-dem-g").unwrap().params;
            par(pl, "pile-dem-g", "stiffness_factor").sqrt() / par(pl, "pile-dem-g", "dem.dt")
                * list(v, "energies_mgd").len() as f64
                * par(pl, "pile-dem-g", "stop.t_max")
        };
        let want = grains(&p) / grains(&q) * steps(&p) / steps(&q);
        let row = e.rows.iter().find(|r| r.id == "pile-dem-g").unwrap();
        assert!(want > 100.0, "{want}");
        assert!((row.scale - want).abs() < 1e-9 * want, "{} vs {want}", row.scale);
        let prep = e.rows.iter().find(|r| r.id == "fig4-23").unwrap();
        assert!(prep.basis.contains("grains ×52"), "{}", prep.basis);
    }
}

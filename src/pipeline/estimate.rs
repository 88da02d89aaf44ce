//! `granrepro plan --profile paper --estimate`: the CPU budget of a profile, measured where
//! it has run and estimated from measured quick-profile runs where it has not, never guessed.
//!
//! **Measured first**: a stage whose current key has a run record at the profile itself —
//! in the cache, or in the committed results (`results/<profile>/store/<key>/record.json`,
//! which a fresh clone has) — counts with that record's wall × threads, and is done: it is
//! not in what is still to run.
//!
//! **Else, as run before**: a stage the committed results hold under an older key (its
//! inputs, parameters or code changed since: `status` calls it stale) is estimated by that
//! run's own record at this profile, scaled by the work ratio (below) of its current params
//! over the params it ran with, which the lock records: a step or a sweep reduced since
//! costs what is left of it.
//!
//! **Else estimated**: for every other stage, the quick run's record (the cache entry of its current quick
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
    /// This profile's own run of the current key (cache or committed results): wall [s]
    /// and threads. When present the stage is done and its cost is this, not an estimate.
    pub own: Option<Measured>,
    /// Not run under its current key, but kept in the committed results under an older
    /// one: that run's wall [s] and threads, its estimate.
    pub earlier: Option<Measured>,
    /// For a stage with neither record: the mean run of its family's members that ran at
    /// this profile (an ensemble's or sweep's siblings), used as its estimate.
    pub peers: Option<Measured>,
    /// Work ratio target / quick (1 for bookkeeping stages).
    pub scale: f64,
    /// What the ratio is made of.
    pub basis: String,
}

impl Row {
    /// Wall [s]: as run at this profile, else estimated at the quick run's thread count.
    pub fn wall_s(&self) -> Option<f64> {
        self.own
            .or(self.earlier)
            .map(|m| m.wall_s)
            .or(self.quick.map(|m| m.wall_s * self.scale))
            .or(self.peers.map(|m| m.wall_s))
    }
    /// CPU-hours (wall × threads): as run at this profile, else estimated.
    pub fn cpu_h(&self) -> Option<f64> {
        match (self.own.or(self.earlier), self.quick, self.peers) {
            (Some(m), _, _) | (None, None, Some(m)) => Some(m.wall_s * m.threads as f64 / 3600.0),
            (None, Some(m), _) => Some(m.wall_s * self.scale * m.threads as f64 / 3600.0),
            (None, None, None) => None,
        }
    }
    /// Estimated CPU-hours of a stage not yet run at this profile (None when it has run, or
    /// has no quick record either).
    pub fn to_run_cpu_h(&self) -> Option<f64> {
        if self.own.is_some() { None } else { self.cpu_h() }
    }
}

/// One family's line of the table.
#[derive(Debug, Clone, Default)]
struct Family {
    family: String,
    kind: String,
    basis: String,
    stages: usize,
    /// Stages that ran at this profile.
    done: usize,
    quick_cpu_h: f64,
    done_cpu_h: f64,
    to_run_cpu_h: f64,
    /// A stage with no record at either profile.
    unknown: bool,
    /// Stages to run estimated by their earlier run at this profile.
    earlier: usize,
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
    /// Total CPU-hours: as run where a stage has run at this profile, else estimated (stages
    /// without any record add nothing). `0.0 +` keeps an empty sum from printing as "-0".
    pub fn total_cpu_h(&self) -> f64 {
        0.0 + self.rows.iter().filter_map(Row::cpu_h).sum::<f64>()
    }
    /// CPU-hours already run at this profile, and over how many stages.
    pub fn done_cpu_h(&self) -> (f64, usize) {
        let done: Vec<f64> = self
            .rows
            .iter()
            .filter(|r| r.own.is_some())
            .filter_map(Row::cpu_h)
            .collect();
        (0.0 + done.iter().sum::<f64>(), done.len())
    }
    /// Estimated CPU-hours still to run, over how many stages (those with a record).
    pub fn to_run_cpu_h(&self) -> (f64, usize) {
        let left: Vec<f64> = self.rows.iter().filter_map(Row::to_run_cpu_h).collect();
        (0.0 + left.iter().sum::<f64>(), left.len())
    }
    /// Of what is still to run: CPU-hours estimated by this profile's own earlier runs
    /// (older keys), and over how many stages.
    pub fn earlier_cpu_h(&self) -> (f64, usize) {
        let e: Vec<f64> = self
            .rows
            .iter()
            .filter(|r| r.own.is_none() && r.earlier.is_some())
            .filter_map(Row::cpu_h)
            .collect();
        (0.0 + e.iter().sum::<f64>(), e.len())
    }
    /// Threads of a worker (the quick runs' thread count).
    pub fn threads(&self) -> usize {
        self.rows
            .iter()
            .filter_map(|r| r.own.or(r.earlier).or(r.quick).map(|m| m.threads))
            .max()
            .unwrap_or(1)
    }
    /// Workers of `threads()` cores that finish in one night (if the longest chain fits).
    pub fn workers_for_night(&self) -> usize {
        let wall: f64 = self.rows.iter().filter_map(Row::wall_s).sum();
        (wall / 3600.0 / NIGHT_H).ceil().max(1.0) as usize
    }
    /// Stages with no run record at this profile and none at the quick one.
    pub fn unmeasured(&self) -> Vec<&str> {
        self.rows
            .iter()
            .filter(|r| r.own.is_none() && r.earlier.is_none() && r.quick.is_none() && r.peers.is_none())
            .map(|r| r.id.as_str())
            .collect()
    }
    /// The estimated wall of one stage, as export uses it.
    pub fn measured(&self, id: &str) -> Option<Measured> {
        let r = self.rows.iter().find(|r| r.id == id)?;
        Some(Measured {
            wall_s: r.wall_s()?,
            threads: r.own.or(r.earlier).or(r.quick).or(r.peers)?.threads,
        })
    }
    /// Families, in plan order.
    fn families(&self) -> Vec<Family> {
        let mut out: Vec<Family> = Vec::new();
        for r in &self.rows {
            let q = r.quick.map(|m| m.wall_s * m.threads as f64 / 3600.0).unwrap_or(0.0);
            let done = if r.own.is_some() { r.cpu_h().unwrap_or(0.0) } else { 0.0 };
            let at = match out.iter().position(|f| f.family == r.family) {
                Some(i) => i,
                None => {
                    out.push(Family {
                        family: r.family.clone(),
                        kind: r.kind.clone(),
                        basis: r.basis.clone(),
                        ..Family::default()
                    });
                    out.len() - 1
                }
            };
            let f = &mut out[at];
            f.stages += 1;
            f.quick_cpu_h += q;
            f.done += usize::from(r.own.is_some());
            f.done_cpu_h += done;
            f.to_run_cpu_h += r.to_run_cpu_h().unwrap_or(0.0);
            f.unknown |= r.own.is_none() && r.earlier.is_none() && r.quick.is_none() && r.peers.is_none();
            f.earlier += usize::from(r.own.is_none() && r.earlier.is_some());
        }
        out
    }
    /// JSON.
    pub fn to_json(&self) -> Value {
        json!({
            "profile": self.profile,
            "method": "a stage that ran at this profile (cache or committed results): its own record (wall × threads); else the committed results' run of it under an older key; else quick-profile run records (wall × threads) × the ratio of solver work (DEM/CD grains × steps, MPM points × steps) from each profile's resolved parameters; else its family's mean at this profile; see src/pipeline/estimate.rs",
            "stages": self.rows.iter().map(|r| json!({
                "id": r.id, "family": r.family, "kind": r.kind,
                "quick_wall_s": r.quick.map(|m| m.wall_s), "threads": r.own.or(r.quick).map(|m| m.threads),
                "scale": r.scale, "basis": r.basis, "wall_s": r.wall_s(), "cpu_h": r.cpu_h(),
                "ran_at_profile": r.own.is_some(), "earlier_run_wall_s": r.earlier.map(|m| m.wall_s),
            })).collect::<Vec<_>>(),
            "total_cpu_h": self.total_cpu_h(),
            "done_cpu_h": self.done_cpu_h().0, "done_stages": self.done_cpu_h().1,
            "to_run_cpu_h": self.to_run_cpu_h().0, "to_run_stages": self.to_run_cpu_h().1,
            "to_run_from_earlier_runs_cpu_h": self.earlier_cpu_h().0,
            "critical_path_h": self.critical.0 / 3600.0, "critical_path_ends_at": self.critical.1,
            "worker_threads": self.threads(), "workers_for_12h": self.workers_for_night(),
            "unmeasured": self.unmeasured(),
        })
    }
    /// Text table.
    pub fn to_text(&self) -> String {
        let mut s = format!(
            "CPU-hours of the {} profile. \"ran\": stages whose current key has run at this profile\n\
             (cache or committed results), counted as run (wall × threads). \"to run\": the others, at\n\
             their own earlier run at this profile (kept under an older key), else estimated from\n\
             the quick profile's measured runs scaled by each solver's work — DEM/CD\n\
             grains × steps, MPM points × steps — from both profiles' resolved parameters (method:\n\
             src/pipeline/estimate.rs). Not modelled: contacts per grain, solver iterations, longer\n\
             settling, parallel efficiency: an estimate is good to a factor of 2–3.\n\n",
            self.profile
        );
        s.push_str(&format!(
            "{:<26} {:<22} {:>6} {:>5} {:>10} {:>11} {:>12}  {}\n",
            "family", "kind", "stages", "ran", "ran CPU-h", "quick CPU-h", "to run CPU-h", "work ratio (per stage)"
        ));
        for f in self.families() {
            let left = if f.unknown {
                format!("{:.2}+?", f.to_run_cpu_h)
            } else {
                format!("{:.2}", f.to_run_cpu_h)
            };
            s.push_str(&format!(
                "{:<26} {:<22} {:>6} {:>5} {:>10.2} {:>11.3} {:>12}  {}\n",
                f.family,
                f.kind,
                f.stages,
                f.done,
                f.done_cpu_h,
                f.quick_cpu_h,
                left,
                if f.earlier > 0 {
                    format!("{} as run here under an older key; else {}", f.earlier, f.basis)
                } else {
                    f.basis
                }
            ));
        }
        let ((done_h, done_n), (left_h, left_n)) = (self.done_cpu_h(), self.to_run_cpu_h());
        let (early_h, early_n) = self.earlier_cpu_h();
        let unknown = self.unmeasured().len();
        s.push_str(&format!(
            "\nran at this profile: {done_n} of {} stages, {done_h:.1} CPU-hours. To run: {left_n} stages, about {left_h:.1} CPU-hours{}{}.\n",
            self.rows.len(),
            if early_n > 0 {
                format!(" ({early_n} stages, {early_h:.1} CPU-hours, as they ran here under an older key)")
            } else {
                String::new()
            },
            if unknown > 0 { format!(", and {unknown} with no record at either profile (below)") } else { String::new() },
        ));
        s.push_str(&format!(
            "total: {:.1} CPU-hours ({} cores per worker, as measured); longest dependency chain {:.1} h (ending at {}).\n",
            self.total_cpu_h(),
            self.threads(),
            self.critical.0 / 3600.0,
            if self.critical.1.is_empty() { "—" } else { self.critical.1.as_str() }
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
                "not measured (no run record at this profile or the quick one; `granrepro run --stage ID` first, then re-estimate): {}\n",
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
    let keys = key_records(p);
    let dir = super::store::dir_of(&p.root, &p.profile);
    let committed = dir.join(super::store::STORE);
    // an unreadable lock only loses the earlier runs' estimates (`status` reports it)
    let lock = super::store::read_lock(&dir).ok().flatten();
    let mut rows = Vec::new();
    for id in &ids {
        let st = p.get(id).expect("closure id");
        let quick = q
            .get(id)
            .and_then(|qs| entry_record(proj, &qkeys[&qs.id].1))
            .or_else(|| super::export::measured_from_record(&proj.report_dir("quick"), id));
        let (scale, basis) = match (q.get(id).and_then(|qs| work(&q, qs)), work(p, st)) {
            (Some(wq), Some(wp)) => ratio(&wp, &wq),
            _ => None,
        }
        .unwrap_or_else(|| (1.0, "bookkeeping: as measured".to_string()));
        let key = &keys[id.as_str()].1;
        let own = entry_record(proj, key)
            .or_else(|| super::export::measured_from_record_file(&committed.join(key).join("record.json")));
        // the earlier run, scaled by the work its current params ask over the params it
        // ran with (a step or a sweep changed since: the new cost, not the old one)
        let earlier = lock
            .as_ref()
            .and_then(|l| l.stages.get(id.as_str()))
            .filter(|l| &l.key != key)
            .and_then(|l| {
                let m = super::export::measured_from_record_file(&committed.join(&l.key).join("record.json"))
                    .or(l.wall_s.map(|wall_s| Measured { wall_s, threads: 1 }))?;
                let then = Stage {
                    params: l.record.params.clone(),
                    ..st.clone()
                };
                let r = match (work(p, st), work(p, &then)) {
                    (Some(now), Some(was)) => ratio(&now, &was).map_or(1.0, |(r, _)| r),
                    _ => 1.0,
                };
                Some(Measured {
                    wall_s: m.wall_s * r,
                    threads: m.threads,
                })
            });
        rows.push(Row {
            id: id.clone(),
            family: st.base_id.clone(),
            kind: st.kind.clone(),
            quick,
            own,
            earlier,
            peers: None,
            scale,
            basis,
        });
    }
    // A stage with no record at either profile: its family's runs at this profile, if any.
    let mut ran: HashMap<String, (f64, usize, usize)> = HashMap::new();
    for r in rows.iter() {
        if let Some(m) = r.own {
            let e = ran.entry(r.family.clone()).or_default();
            *e = (e.0 + m.wall_s, e.1.max(m.threads), e.2 + 1);
        }
    }
    for r in rows
        .iter_mut()
        .filter(|r| r.own.is_none() && r.earlier.is_none() && r.quick.is_none())
    {
        if let Some(&(wall, threads, n)) = ran.get(&r.family) {
            r.peers = Some(Measured {
                wall_s: wall / n as f64,
                threads,
            });
            r.basis = format!("mean of the family's {n} run(s) at this profile");
        }
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

/// The work ratio `a / b` of two cost models' work (a product of per-factor ratios, or
/// their largest for a `max_of` model), and what it is made of; None when the factors do
/// not pair up or one is not positive.
fn ratio((wa, max_of): &Work, (wb, _): &Work) -> Option<(f64, String)> {
    if wa.len() != wb.len() || !wb.iter().all(|(_, x)| *x > 0.0) {
        return None;
    }
    let ratios: Vec<f64> = wa.iter().zip(wb).map(|((_, a), (_, b))| a / b).collect();
    let scale = if *max_of {
        ratios.iter().fold(0.0f64, |a, &b| a.max(b))
    } else {
        ratios.iter().product()
    };
    let parts: Vec<String> = wa
        .iter()
        .zip(&ratios)
        .map(|((n, _), r)| format!("{n} ×{}", short(*r)))
        .collect();
    Some((
        scale,
        parts.join(if *max_of { " | " } else { ", " }) + if *max_of { " (larger)" } else { "" },
    ))
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

    fn row(id: &str, family: &str, quick: Option<f64>, own: Option<f64>, scale: f64) -> Row {
        let m = |w: f64| Measured { wall_s: w, threads: 1 };
        Row {
            id: id.into(),
            family: family.into(),
            kind: "k".into(),
            quick: quick.map(m),
            own: own.map(m),
            earlier: None,
            peers: None,
            scale,
            basis: String::new(),
        }
    }

    /// A stage that ran at the profile counts as run, at its own wall (not the quick run
    /// scaled), and is not in what is left; an estimate counts only where it has not run.
    #[test]
    fn a_stage_run_at_the_profile_counts_as_run_not_as_estimated() {
        let e = Estimate {
            profile: "paper".into(),
            rows: vec![
                row("a", "f", Some(3600.0), Some(7200.0), 10.0), // ran: 2 h, not 10 h
                row("b", "f", Some(3600.0), None, 3.0),          // to run: 3 h
                row("c", "g", None, None, 1.0),                  // no record
            ],
            critical: (0.0, String::new()),
        };
        assert_eq!(e.done_cpu_h(), (2.0, 1));
        assert_eq!(e.to_run_cpu_h(), (3.0, 1));
        assert_eq!(e.total_cpu_h(), 5.0);
        assert_eq!(e.unmeasured(), ["c"]);
        // kept under an older key: to run, at that run's cost (not the quick run scaled)
        let mut e = e;
        e.rows[2].earlier = Some(Measured {
            wall_s: 1800.0,
            threads: 2,
        });
        assert_eq!(e.done_cpu_h(), (2.0, 1));
        assert_eq!(e.to_run_cpu_h(), (4.0, 2));
        assert_eq!(e.earlier_cpu_h(), (1.0, 1));
        assert!(e.unmeasured().is_empty());
        assert!(e.to_text().contains(
            "To run: 2 stages, about 4.0 CPU-hours (1 stages, 1.0 CPU-hours, as they ran here under an older key)"
        ));
        e.rows[2].earlier = None;
        let t = e.to_text();
        assert!(t.contains("ran at this profile: 1 of 3 stages, 2.0 CPU-hours. To run: 1 stages, about 3.0 CPU-hours, and 1 with no record"), "{t}");
    }

    /// Nothing measured: the totals read 0, not "-0" (an empty f64 sum is −0.0).
    #[test]
    fn an_empty_estimate_prints_zero_not_minus_zero() {
        let e = Estimate {
            profile: "paper".into(),
            rows: vec![row("c", "g", None, None, 1.0)],
            critical: (0.0, String::new()),
        };
        let t = e.to_text();
        assert!(!t.contains("-0"), "{t}");
        assert!(t.contains("total: 0.0 CPU-hours"), "{t}");
        assert!(t.contains("(ending at —)"), "{t}");
    }

    fn copy_tree(from: &std::path::Path, to: &std::path::Path) {
        std::fs::create_dir_all(to).unwrap();
        for e in std::fs::read_dir(from).unwrap() {
            let e = e.unwrap();
            if e.file_type().unwrap().is_dir() {
                copy_tree(&e.path(), &to.join(e.file_name()));
            } else {
                std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
            }
        }
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
        // the shipped pipeline and stages, copied where no committed paper results are
        let dir = tempfile::tempdir().unwrap();
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        std::fs::copy(root.join("pipeline.yaml"), dir.path().join("pipeline.yaml")).unwrap();
        copy_tree(&root.join("stages"), &dir.path().join("stages"));
        let at = |profile: &str| load(&dir.path().join("pipeline.yaml"), profile, &[]).unwrap();
        let (p, q) = (at("paper"), at("quick"));
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
        // the estimate from the quick record
        let q = row.quick.unwrap();
        assert_eq!((q.wall_s, q.threads), (100.0, 2));
        let est = q.wall_s * row.scale * q.threads as f64 / 3600.0;
        assert!((est - 100.0 * want * 2.0 / 3600.0).abs() < 1e-9 * want);
        assert!(row.own.is_none(), "nothing ran at paper size here");
        assert!((row.cpu_h().unwrap() - est).abs() < 1e-9 * want);
        // Stages it needs without a record are listed, not guessed.
        assert!(e.unmeasured().contains(&"calib-dem"));
        // A bookkeeping stage keeps its measured time.
        let e = estimate(&p, &proj, &["psd-shear".to_string()]).unwrap();
        assert_eq!(e.rows[0].scale, 1.0);
        assert!(estimate(&p, &proj, &["nope".to_string()]).is_err());
    }

    /// A stage kept in the committed results under an older key is estimated by that run's
    /// record, scaled by the work its current params ask over the params it ran with (here
    /// the CD shear sweep: steps ∝ Σ_I 1/I, so leaving the slow inertial numbers out costs
    /// what is left), and counted as to run, not as run.
    #[test]
    fn a_stage_kept_under_an_older_key_costs_its_run_scaled_by_the_work_left() {
        use crate::pipeline::cache::KeyRecord;
        use crate::pipeline::store::{Lock, Locked};
        let dir = tempfile::tempdir().unwrap();
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        std::fs::copy(root.join("pipeline.yaml"), dir.path().join("pipeline.yaml")).unwrap();
        copy_tree(&root.join("stages"), &dir.path().join("stages"));
        let p = load(&dir.path().join("pipeline.yaml"), "paper", &[]).unwrap();
        let st = p.get("shear-cd").unwrap();
        // it ran with one more inertial number, I = 1e-3, than the current sweep
        let now: Vec<f64> = list(&st.params["shear"], "inertial_numbers");
        let mut was = st.params.clone();
        let mut ran = now.clone();
        ran.insert(0, 1.0e-3);
        was["shear"]["inertial_numbers"] = serde_json::json!(ran);
        let inv = |v: &[f64]| v.iter().map(|i| 1.0 / i).sum::<f64>();
        let want = 3600.0 * inv(&now) / inv(&ran);
        assert!(want < 0.5 * 3600.0, "the slow point is most of the work: {want}");
        let lock = Lock {
            profile: "paper".into(),
            stages: [(
                "shear-cd".to_string(),
                Locked {
                    key: "0".repeat(32),
                    record: KeyRecord {
                        kind: st.kind.clone(),
                        version: st.version,
                        params: was,
                        profile: "paper".into(),
                        inputs: vec![],
                    },
                    store: Default::default(),
                    published: Default::default(),
                    left_out: Default::default(),
                    sources: Default::default(),
                    closure: None,
                    wall_s: Some(3600.0),
                },
            )]
            .into(),
            closures: Default::default(),
        };
        let res = dir.path().join("results").join("paper");
        std::fs::create_dir_all(&res).unwrap();
        std::fs::write(res.join("lock.json"), serde_json::to_vec(&lock).unwrap()).unwrap();
        let e = estimate(&p, &Project::new(dir.path()), &["shear-cd".to_string()]).unwrap();
        let row = e.rows.iter().find(|r| r.id == "shear-cd").unwrap();
        assert!(row.own.is_none());
        let got = row.earlier.unwrap().wall_s;
        assert!((got - want).abs() < 1e-9 * want, "{got} vs {want}");
        assert_eq!(
            e.to_run_cpu_h().1,
            e.rows.len() - e.done_cpu_h().1 - e.unmeasured().len()
        );
        assert!((e.earlier_cpu_h().0 - want / 3600.0).abs() < 1e-9);
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

//! Column-collapse driver (docs/definitions.md SC-COL, D01–D07): open the gate of a
//! prepared column and run with a time series (t, L, H via `crate::analysis::front`,
//! energies, ledger) and snapshots at requested times, until a stop criterion. Reports wall
//! time per run for the work-precision sweep.

use crate::analysis::cloud::Cloud;
use crate::analysis::front::{Body, Link, front, lengths_for_gaps};
use crate::analysis::gathered_front::gathered_d;
use crate::analysis::inertial::{Grain, coarse_grained};
use crate::analysis::stop::{StopRule, Verdict};
use crate::analysis::thick_front::ThickRule;
use crate::dem::energy::Ledger;
use crate::dem::error::DemError;
use crate::dem::params::DemParams;
use crate::dem::preflight::Preflight;
use crate::dem::prep::{Column, box_walls};
use crate::dem::state::State;
use crate::dem::timers::PhaseTimers;
use crate::dem::world::World;
use crate::math::Real;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Collapse run settings. Times are in units of τ_c = √(H_0/g) (D05).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CollapseParams {
    /// Hard end [τ_c]. UNSPEC; 10 (the chapter's columns stop by ≈ 4 τ_c).
    pub t_max: Real,
    /// Never stop before this [τ_c].
    pub t_min: Real,
    /// Stop when (E_k + E_rot) < `stop_ke_ratio` · E_p(0) after `t_min`. UNSPEC: 1e-6.
    pub stop_ke_ratio: Real,
    /// Time-series interval [τ_c].
    pub sample_every: Real,
    /// Snapshot times [τ_c] (e.g. [1, 3] for figs 4.7/4.9); the final state is always kept.
    pub snapshots: Vec<Real>,
    /// Contact-graph gap δ_c for the main mass, in mean diameters (D01: 0.01).
    pub link_gap: Real,
    /// Domain end: a floor-level right wall far away keeps escaping grains [L_0 multiples].
    /// 0 = no right wall (the floor is infinite).
    pub right_wall_at: Real,
    /// The stated stop rule shared with the MPM (`crate::analysis::stop`): kinetic energy
    /// AND front speed below thresholds, bounded in time. When set it replaces `t_min`,
    /// `t_max` and `stop_ke_ratio` (the energy-only rule, kept for the calibration runs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stop: Option<StopRule>,
    /// Extra linking gaps [d̄] whose L(t) is recorded beside the main one (D01 sensitivity).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub link_gap_sensitivity: Vec<Real>,
    /// Coarse-graining cell of the inertial-number statistics [d̄] (D08).
    #[serde(skip_serializing_if = "crate::analysis::inertial::is_default_cell")]
    pub inertial_cell: Real,
    /// The thick-deposit front (`analysis::thick_front`, the MPM's rule), reported beside
    /// the chapter's contact rule at rest as `runout_thick_norm`.
    #[serde(skip_serializing_if = "ThickRule::is_default")]
    pub front: ThickRule,
}

impl CollapseParams {
    /// The stop rule in force.
    pub fn rule(&self) -> StopRule {
        self.stop.unwrap_or(StopRule {
            ke_ratio: self.stop_ke_ratio,
            front_speed: f64::INFINITY,
            window: 0.0,
            t_min: self.t_min,
            t_max: self.t_max,
        })
    }
}

impl Default for CollapseParams {
    fn default() -> Self {
        Self {
            t_max: 10.0,
            t_min: 1.0,
            stop_ke_ratio: 1e-6,
            sample_every: 0.01,
            snapshots: vec![],
            link_gap: 0.01,
            right_wall_at: 0.0,
            stop: None,
            link_gap_sensitivity: vec![],
            inertial_cell: 3.0,
            front: ThickRule::default(),
        }
    }
}

/// One row of the time series.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// Time since release [s].
    pub t: Real,
    /// Run-out L(t): right edge of the main mass [m] (D01).
    pub length: Real,
    /// Height H(t) of the main mass [m] (D03).
    pub height: Real,
    /// The gathered length over every grain (D01, `analysis::gathered_front`, bins and
    /// layer of one d̄): the rule the MPM columns use, so the two methods compare on one [m].
    #[serde(default)]
    pub length_gathered: Real,
    /// Grains in the main mass.
    pub n_main: usize,
    /// E_p [J/m].
    pub ep: Real,
    /// E_kx [J/m].
    pub ekx: Real,
    /// E_ky [J/m].
    pub eky: Real,
    /// E_rot [J/m].
    pub erot: Real,
    /// Stored elastic energy [J/m].
    pub elastic: Real,
    /// Cumulative dissipation split (zeros if the ledger is off).
    pub ledger: Ledger,
    /// Energy balance residual E_0 − (E_p+E_k+E_rot+elastic+dissipated) [J/m].
    pub residual: Real,
    /// Coarse-grained inertial-number statistics (D08, `crate::analysis::inertial`).
    pub inertial: crate::analysis::inertial::Stats,
}

/// Grain positions and velocities at one time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Snapshot {
    /// Time since release [s].
    pub t: Real,
    /// Grain state.
    pub state: State,
}

impl Snapshot {
    /// ParaView `.vtp` document (radius, velocity, spin).
    pub fn to_vtp(&self) -> String {
        use crate::vtk::{Field, polydata};
        let s = &self.state;
        polydata(
            &s.x,
            &s.y,
            &[
                ("radius", Field::Scalar(&s.r)),
                ("velocity", Field::Vector(&s.vx, &s.vy)),
                ("spin", Field::Scalar(&s.w)),
            ],
        )
    }
}

/// Why the run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// Kinetic energy fell below the threshold.
    AtRest,
    /// `t_max` reached.
    TimeLimit,
}

/// Result of one collapse run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CollapseResult {
    /// L_0 [m].
    pub l0: Real,
    /// H_0 [m].
    pub h0: Real,
    /// τ_c = √(H_0/g) [s].
    pub tau_c: Real,
    /// Time series.
    pub samples: Vec<Sample>,
    /// Snapshots at the requested times, then the final state.
    pub snapshots: Vec<Snapshot>,
    /// Why the run stopped.
    pub stop: StopReason,
    /// Steps taken.
    pub steps: u64,
    /// Time step [s].
    pub dt: Real,
    /// Wall time of the run [s].
    pub wall_s: f64,
    /// Phase timers (zero unless the world kept them: `World::timing`).
    pub timers: PhaseTimers,
    /// Pre-flight table of the run.
    pub preflight: Preflight,
    /// Largest overlap / d seen at the samples.
    pub max_overlap_fraction: Real,
    /// L(t) [m] for each gap of `link_gap_sensitivity`, one row per sample.
    pub gap_lengths: Vec<Vec<Real>>,
    /// d̄ (volume mean) of the column [m].
    pub d_mean: Real,
}

impl CollapseResult {
    /// Final run-out L_f [m].
    pub fn runout(&self) -> Real {
        self.samples.last().map(|s| s.length).unwrap_or(self.l0)
    }
    /// Normalised run-out ΔL = (L_f − L_0)/L_0 (D02).
    pub fn delta_l(&self) -> Real {
        (self.runout() - self.l0) / self.l0
    }
}

/// The grains of a state as an analysis [`Cloud`].
pub fn cloud(s: &State, t: Real) -> Cloud {
    Cloud {
        t,
        x: s.x.clone(),
        y: s.y.clone(),
        half: s.r.clone(),
        mass: s.m.clone(),
        vx: s.vx.clone(),
        vy: s.vy.clone(),
    }
}

fn sample(w: &World, t0: Real, gap: Real, grain: Grain) -> Sample {
    let s = &w.state;
    let body = Body {
        x: &s.x,
        y: &s.y,
        half: &s.r,
        mass: &s.m,
    };
    let f = front(&body, Link::Contact { gap });
    let inertial = coarse_grained(&cloud(s, w.t - t0), grain);
    let b = w.balance();
    let e = b.energies;
    Sample {
        t: w.t - t0,
        length: f.length,
        height: f.height,
        length_gathered: gathered_d(&body, grain.d),
        n_main: f.n_main,
        ep: e.ep,
        ekx: e.ekx,
        eky: e.eky,
        erot: e.erot,
        elastic: e.elastic(),
        ledger: w.ledger,
        residual: if w.params.ledger { b.residual } else { 0.0 },
        inertial,
    }
}

/// Open the gate of `column` and run the collapse with `params`.
pub fn collapse(column: &Column, params: &DemParams, cp: &CollapseParams) -> Result<CollapseResult, DemError> {
    let mut walls = box_walls(column.l0);
    walls[2].active = false; // gate removed instantly at t = 0 (UNSPEC removal speed)
    if cp.right_wall_at > 0.0 {
        walls.push(crate::dem::walls::Wall::right("far", cp.right_wall_at * column.l0));
    }
    let mut w = column.world(params, walls)?;
    let preflight = w.preflight()?;
    let g = params.gravity.max(1e-12);
    let tau_c = (column.h0 / g).sqrt();
    let d_mean = column.state.volume_mean_diameter();
    let gap = cp.link_gap * d_mean;
    let ep0 = w.energies().ep;
    let mut snaps: Vec<Real> = cp.snapshots.iter().map(|s| s * tau_c).collect();
    snaps.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let mut snapshots = Vec::new();
    let grain = Grain {
        cell: cp.inertial_cell * d_mean,
        d: d_mean,
        rho_s: params.density,
        g,
    };
    let gaps: Vec<Real> = cp.link_gap_sensitivity.iter().map(|k| k * d_mean).collect();
    let gap_row = |w: &World| {
        lengths_for_gaps(
            &Body {
                x: &w.state.x,
                y: &w.state.y,
                half: &w.state.r,
                mass: &w.state.m,
            },
            &gaps,
        )
    };
    let rule = cp.rule();
    let mut gap_lengths = vec![gap_row(&w)];
    let mut samples = vec![sample(&w, 0.0, gap, grain)];
    let dt_sample = (cp.sample_every * tau_c).max(params.dt);
    let started = Instant::now();
    let mut next_snap = 0;
    let mut max_ov: Real = 0.0;
    let stop = loop {
        let mut t_next = w.t + dt_sample;
        if next_snap < snaps.len() && snaps[next_snap] < t_next {
            t_next = snaps[next_snap].max(w.t);
        }
        w.run_until(t_next)?;
        while next_snap < snaps.len() && snaps[next_snap] <= w.t + 0.5 * params.dt {
            snapshots.push(Snapshot {
                t: w.t,
                state: w.state_by_id(),
            });
            next_snap += 1;
        }
        max_ov = max_ov.max(w.info.max_overlap_fraction);
        let smp = sample(&w, 0.0, gap, grain);
        let ke = smp.ekx + smp.eky + smp.erot;
        samples.push(smp);
        gap_lengths.push(gap_row(&w));
        let t: Vec<Real> = samples.iter().map(|v| v.t).collect();
        let l: Vec<Real> = samples.iter().map(|v| v.length).collect();
        let h: Vec<Real> = samples.iter().map(|v| v.height).collect();
        match rule.verdict(&t, &l, &h, ke / ep0, tau_c, d_mean) {
            Verdict::AtRest => break StopReason::AtRest,
            Verdict::TimeLimit => break StopReason::TimeLimit,
            Verdict::Running => {}
        }
    };
    let wall_s = started.elapsed().as_secs_f64();
    snapshots.push(Snapshot {
        t: w.t,
        state: w.state_by_id(),
    });
    Ok(CollapseResult {
        l0: column.l0,
        h0: column.h0,
        tau_c,
        samples,
        snapshots,
        stop,
        steps: w.steps,
        dt: params.dt,
        wall_s,
        timers: w.timers,
        preflight,
        max_overlap_fraction: max_ov,
        gap_lengths,
        d_mean,
    })
}

/// Mean and sample standard deviation (0 for a single value).
pub fn mean_std(v: &[Real]) -> (Real, Real) {
    let n = v.len() as Real;
    let m = v.iter().sum::<Real>() / n.max(1.0);
    let s = if v.len() > 1 {
        (v.iter().map(|x| (x - m) * (x - m)).sum::<Real>() / (n - 1.0)).sqrt()
    } else {
        0.0
    };
    (m, s)
}

/// One accuracy setting of the DEM work-precision sweep.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Variant {
    /// Label for tables.
    pub label: String,
    /// Factor on k_n, k_t, k_r (1 = table 4.2).
    pub stiffness_factor: Real,
    /// Δt as a fraction of the smallest collision time t_c at that stiffness.
    pub dt_fraction: Real,
}

/// Outcome of one variant: an ensemble of perturbed starts from the column re-settled at
/// the variant's own stiffness and step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WorkPrecisionRow {
    /// The variant.
    pub variant: Variant,
    /// Δt used [s].
    pub dt: Real,
    /// ΔL = (L_f − L_0)/L_0 of each member.
    pub delta_l: Vec<Real>,
    /// Mean ΔL over the members.
    pub mean: Real,
    /// Sample standard deviation of ΔL over the members (the chaotic spread).
    pub spread: Real,
    /// Mean H_f / L_0.
    pub h_final_over_l0: Real,
    /// |mean − mean_ref| / mean_ref, reference = the first variant.
    pub error: Real,
    /// Standard error of that difference, √(s²/n + s_ref²/n_ref) / mean_ref.
    pub error_spread: Real,
    /// Mean wall time of one collapse [s].
    pub wall_s: f64,
    /// Wall time of the re-settling at this stiffness [s].
    pub settle_wall_s: f64,
    /// Steps of one collapse (member 0).
    pub steps: u64,
    /// Duration of each member: its stop time (the stop rule's instant) / τ_c [-].
    pub duration: Vec<Real>,
    /// Final potential energy of each member, E_p(end)/E_p(0) [-].
    pub ep_final: Vec<Real>,
}

/// Run each variant as an ensemble (first variant = reference, the finest): the column is
/// re-settled at the variant's stiffness and step, then collapsed from `members` starts
/// (member 0 as settled, the others with every grain moved by ≤ `perturbation` m, seeded).
pub fn work_precision(
    column: &Column,
    base: &DemParams,
    cp: &CollapseParams,
    variants: &[Variant],
    members: usize,
    perturbation: Real,
    seed: u64,
) -> Result<Vec<WorkPrecisionRow>, DemError> {
    use rayon::prelude::*;
    let mut rows: Vec<WorkPrecisionRow> = Vec::new();
    for v in variants {
        let mut p = base.softened(v.stiffness_factor);
        let (r_min, _, _) = column.state.radius_stats();
        let sizes = crate::dem::preflight::SizeClasses {
            r_min,
            r_mean: r_min,
            r_max: r_min,
        };
        let tc = crate::dem::preflight::time_scales(&p, sizes, false, 1.0)[0].value;
        p.dt = v.dt_fraction * tc;
        let t0 = Instant::now();
        let settled = column.resettled(&p, 1e-6, 0.3)?;
        let settle_wall_s = t0.elapsed().as_secs_f64();
        let runs: Vec<Result<CollapseResult, DemError>> = (0..members.max(1))
            .into_par_iter()
            .map(|k| collapse(&settled.perturbed(k, perturbation, seed), &p, cp))
            .collect();
        let runs = runs.into_iter().collect::<Result<Vec<_>, _>>()?;
        let delta_l: Vec<Real> = runs.iter().map(|r| r.delta_l()).collect();
        let n = delta_l.len() as Real;
        let (mean, spread) = mean_std(&delta_l);
        let hf = runs
            .iter()
            .map(|r| r.samples.last().map(|s| s.height / r.l0).unwrap_or(0.0))
            .sum::<Real>()
            / n;
        let (ref_mean, ref_spread, ref_n) = rows
            .first()
            .map(|x| (x.mean, x.spread, x.delta_l.len() as Real))
            .unwrap_or((mean, spread, n));
        let error = if rows.is_empty() {
            0.0
        } else {
            (mean - ref_mean).abs() / ref_mean.abs().max(1e-12)
        };
        let error_spread = (spread * spread / n + ref_spread * ref_spread / ref_n).sqrt() / ref_mean.abs().max(1e-12);
        rows.push(WorkPrecisionRow {
            variant: v.clone(),
            dt: p.dt,
            mean,
            spread,
            h_final_over_l0: hf,
            error,
            error_spread,
            wall_s: runs.iter().map(|r| r.wall_s).sum::<f64>() / n,
            settle_wall_s,
            steps: runs[0].steps,
            delta_l,
            duration: runs
                .iter()
                .map(|r| r.samples.last().map_or(0.0, |s| s.t) / r.tau_c)
                .collect(),
            ep_final: runs
                .iter()
                .map(|r| match (r.samples.first(), r.samples.last()) {
                    (Some(a), Some(b)) if a.ep > 0.0 => b.ep / a.ep,
                    _ => Real::NAN,
                })
                .collect(),
        });
    }
    Ok(rows)
}

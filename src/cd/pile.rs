//! Deposits and piles: the lattice drop of the Siconos reference script (NCOL × NROW
//! disks of 8 radius classes in r ∈ [0.4, 0.6]·s, pitch 1.22·s, in a walled box), the
//! packing-fraction measure used to compare engines, and a small pile impact (grains
//! deposited, then given a horizontal velocity gradient as the chapter's pile is) for the
//! work-precision sweep.

use crate::cd::error::CdError;
use crate::cd::params::CdParams;
use crate::cd::world::{Stats, Timers, World};
use crate::dem::state::State;
use crate::dem::walls::Wall;
use crate::math::{PI, Real};
use crate::sample::rng::SplitMix64;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// The lattice drop of the Siconos reference script `bench/siconos/deposit.py`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DropSpec {
    /// Columns.
    pub ncol: usize,
    /// Rows.
    pub nrow: usize,
    /// Length scale s [m]: radii 0.4 s – 0.6 s (8 classes), pitch 1.22 s, box width
    /// ncol·1.22 s. Siconos' script: s = 1 m.
    pub scale: Real,
    /// Seed of the class choice and the ±0.01 s horizontal jitter.
    pub seed: u64,
}

impl Default for DropSpec {
    fn default() -> Self {
        DropSpec {
            ncol: 25,
            nrow: 20,
            scale: 1.0,
            seed: 1,
        }
    }
}

impl DropSpec {
    /// Box width [m].
    pub fn width(&self) -> Real {
        self.ncol as Real * 1.22 * self.scale
    }
    /// Grains at rest on the lattice, with the floor (y = 0) and side walls.
    pub fn build(&self, density: Real) -> (State, Vec<Wall>) {
        let s = self.scale;
        let mut rng = SplitMix64(self.seed);
        let mut st = State::with_capacity(self.ncol * self.nrow);
        for i in 0..self.ncol {
            for j in 0..self.nrow {
                let c = ((rng.next_f64() * 8.0) as usize).min(7);
                let r = (0.4 + 0.2 * c as Real / 7.0) * s;
                // Box–Muller for the jitter (the script's 0.01·N(0, 1))
                let (u1, u2) = (rng.next_f64().max(1e-300), rng.next_f64());
                let jit = 0.01 * s * (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos();
                st.insert(
                    (i as Real + 0.5) * 1.22 * s + jit,
                    0.61 * s + j as Real * 1.22 * s,
                    r,
                    density,
                );
            }
        }
        let w = self.width();
        (st, vec![Wall::floor(0.0), Wall::left(0.0), Wall::right("right", w)])
    }
}

/// Packing fraction of the deposit's core, measured the same way for every engine:
/// window x ∈ [d̄, W − d̄], y ∈ [d̄, y95 − 2d̄] (y95: 95th percentile of grain tops y + r),
/// covered fraction of a 400 × 400 point raster.
pub fn core_packing_fraction(x: &[Real], y: &[Real], r: &[Real], width: Real) -> Real {
    let n = x.len();
    if n == 0 {
        return 0.0;
    }
    let dbar = 2.0 * r.iter().sum::<Real>() / n as Real;
    let mut tops: Vec<Real> = (0..n).map(|i| y[i] + r[i]).collect();
    tops.sort_by(|a, b| a.total_cmp(b));
    let y95 = tops[((0.95 * n as Real) as usize).min(n - 1)];
    let (x0, x1, y0, y1) = (dbar, width - dbar, dbar, y95 - 2.0 * dbar);
    if x1 <= x0 || y1 <= y0 {
        return Real::NAN;
    }
    let m = 400usize;
    let (dx, dy) = ((x1 - x0) / m as Real, (y1 - y0) / m as Real);
    let mut hit = vec![false; m * m];
    for i in 0..n {
        let (cx, cy, rr) = (x[i], y[i], r[i]);
        let ia = (((cx - rr - x0) / dx).floor().max(0.0)) as usize;
        let ib = (((cx + rr - x0) / dx).ceil().max(0.0) as usize).min(m);
        let ja = (((cy - rr - y0) / dy).floor().max(0.0)) as usize;
        let jb = (((cy + rr - y0) / dy).ceil().max(0.0) as usize).min(m);
        for jj in ja..jb {
            let py = y0 + (jj as Real + 0.5) * dy;
            for ii in ia..ib {
                let px = x0 + (ii as Real + 0.5) * dx;
                if (px - cx).powi(2) + (py - cy).powi(2) <= rr * rr {
                    hit[jj * m + ii] = true;
                }
            }
        }
    }
    hit.iter().filter(|&&h| h).count() as Real / (m * m) as Real
}

/// Result of a drop.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DropResult {
    /// Final grains.
    pub state: State,
    /// Run counters.
    pub stats: Stats,
    /// Active contacts at the end.
    pub contacts_last: usize,
    /// Mean active contacts per step.
    pub contacts_mean: Real,
    /// Core packing fraction at the end.
    pub packing_fraction: Real,
    /// E_k/|E_p − E_p,min-ish| at the end: Σ½mv² / (M g d̄).
    pub ke_over_mgd: Real,
    /// Wall time of the steps [s].
    pub wall_s: f64,
    /// Seconds per phase.
    pub timers: Timers,
}

/// Drop the lattice and run `steps` steps.
pub fn drop(spec: &DropSpec, params: &CdParams, steps: u64) -> Result<DropResult, CdError> {
    let (st, walls) = spec.build(params.density);
    let width = spec.width();
    let mut w = World::new(params.clone(), st, walls, None)?;
    let t0 = Instant::now();
    let mut csum = 0.0;
    for _ in 0..steps {
        let i = w.step()?;
        csum += i.contacts as Real;
    }
    let wall_s = t0.elapsed().as_secs_f64();
    let s = &w.state;
    let e = w.energies();
    let m: Real = s.m.iter().sum();
    let dbar = 2.0 * s.r.iter().sum::<Real>() / s.len() as Real;
    Ok(DropResult {
        packing_fraction: core_packing_fraction(&s.x, &s.y, &s.r, width),
        ke_over_mgd: (e.ek + e.erot) / (m * params.gravity.max(1e-300) * dbar),
        contacts_last: w.last.contacts,
        contacts_mean: csum / steps.max(1) as Real,
        stats: w.stats,
        timers: w.timers,
        state: w.state,
        wall_s,
    })
}

/// Settle a lattice drop for `time` seconds; returns the grains and the box walls.
pub fn settled_deposit(spec: &DropSpec, params: &CdParams, time: Real) -> Result<(State, Vec<Wall>), CdError> {
    let (st, walls) = spec.build(params.density);
    let mut w = World::new(params.clone(), st, walls, None)?;
    let steps = (time / params.dt).ceil() as u64;
    w.run(steps)?;
    let mut s = w.state;
    s.stop();
    Ok((s, w.walls))
}

/// Result of a pile impact.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ImpactResult {
    /// Normalised run-out (L_f − L_0)/L_0, L_f the 95th percentile of x + r (the few
    /// grains ejected ahead of a 200-grain pile do not count), L_0 the box width.
    pub runout: Real,
    /// Shift of the centre of mass along x over the run, / L_0: an integral measure that a
    /// few grains rolling away (disks roll freely on a flat floor) cannot dominate.
    pub com_shift: Real,
    /// Energy dissipated by contacts over the run [J/m].
    pub dissipated: Real,
    /// Kinetic energy given at t = 0 [J/m].
    pub ek0: Real,
    /// Kinetic energy left at the end [J/m].
    pub ek_final: Real,
    /// Run counters.
    pub stats: Stats,
    /// Wall time [s].
    pub wall_s: f64,
}

/// Remove the right wall of a settled deposit and give the grains the chapter's gradient
/// excitation v_x = v0 (y_max − y)/y_max (docs/definitions.md SC-PILE); run for `time`
/// seconds.
pub fn impact(
    state: &State,
    walls: &[Wall],
    width: Real,
    params: &CdParams,
    v0: Real,
    time: Real,
) -> Result<ImpactResult, CdError> {
    let mut s = state.clone();
    let y_max = s.y.iter().cloned().fold(0.0, Real::max);
    for i in 0..s.len() {
        s.vx[i] = v0 * (y_max - s.y[i]) / y_max;
    }
    let walls: Vec<Wall> = walls.iter().filter(|w| w.name != "right").cloned().collect();
    let com = |s: &State| s.x.iter().zip(&s.m).map(|(x, m)| x * m).sum::<Real>() / s.m.iter().sum::<Real>();
    let x0 = com(&s);
    let mut w = World::new(params.clone(), s, walls, None)?;
    let ek0 = w.energies().ek;
    let t0 = Instant::now();
    let steps = (time / params.dt).round() as u64;
    w.run(steps)?;
    let wall_s = t0.elapsed().as_secs_f64();
    let st = &w.state;
    let mut fr: Vec<Real> = (0..st.len()).map(|i| st.x[i] + st.r[i]).collect();
    fr.sort_by(|a, b| a.total_cmp(b));
    let lf = fr[((0.95 * fr.len() as Real) as usize).min(fr.len() - 1)];
    let e = w.energies();
    Ok(ImpactResult {
        runout: (lf - width) / width,
        com_shift: (com(&w.state) - x0) / width,
        dissipated: w.ledger.dissipated(),
        ek0,
        ek_final: e.ek + e.erot,
        stats: w.stats,
        wall_s,
    })
}

/// Excite a pile at rest (grains from the DEM deposit: the same geometry seeds every
/// method) with `profile` carrying `e0` [J/m] and run it with the adaptive step
/// h = min(`params.dt`, 0.4 alert / v_max) until `stop` (docs/definitions.md SC-PILE,
/// PILE-CD).
pub fn run_excited_pile(
    pile: &State,
    params: &CdParams,
    profile: crate::analysis::pile::Profile,
    e0: Real,
    stop: &crate::analysis::pile::StopRule,
) -> Result<crate::analysis::pile::PileRun, CdError> {
    run_excited_pile_frames(pile, params, profile, e0, stop, &Default::default())
}

/// [`run_excited_pile`] taking frames at `frames` (times [s], at sample instants); the run
/// does not stop before the last frame.
pub fn run_excited_pile_frames(
    pile: &State,
    params: &CdParams,
    profile: crate::analysis::pile::Profile,
    e0: Real,
    stop: &crate::analysis::pile::StopRule,
    frames: &crate::analysis::pile::FrameTimes,
) -> Result<crate::analysis::pile::PileRun, CdError> {
    use crate::analysis::front::Link;
    use crate::analysis::pile::{excitation, grain_sample, kinetic, sample_run};
    use crate::dem::pile::grain_frame;
    let mut s = pile.clone();
    s.stop();
    let top = (0..s.len()).map(|i| s.y[i] + s.r[i]).fold(0.0, Real::max);
    let vx = excitation(profile, &s.y, &s.m, top, e0);
    let e0_check = kinetic(&s.m, &vx) / e0;
    s.vx = vx;
    let dbar = 2.0 * s.r.iter().sum::<Real>() / s.len().max(1) as Real;
    let link = Link::Contact { gap: 0.01 * dbar };
    let h_max = params.dt;
    let mut w = World::new(params.clone(), s, vec![Wall::floor(0.0), Wall::left(0.0)], None)?;
    let g = params.gravity;
    let dts = stop.dt_sample(g);
    let mut next = dts;
    let advance = |w: &mut World| -> Result<(), CdError> {
        while w.t < next - 1e-12 {
            let h = w.adapt_dt(h_max).min(next - w.t).max(1e-9);
            w.params.dt = h;
            w.step()?;
        }
        next += dts;
        Ok(())
    };
    let run = sample_run(
        &mut w,
        stop,
        frames,
        e0,
        g,
        |w| w.t,
        |w| grain_sample(w.t, &w.state, link),
        |w| grain_frame(w.t, &w.state),
        advance,
    )?;
    let l0 = run.samples[0].l;
    let crate::analysis::pile::Sampled {
        samples,
        frames: shots,
        stopped,
    } = run;
    let st = &w.state;
    Ok(crate::analysis::pile::PileRun {
        samples,
        l0,
        e0,
        e0_check,
        stopped,
        steps: w.step_count,
        final_bodies: (st.x.clone(), st.y.clone(), st.r.clone()),
        frames: shots,
    })
}

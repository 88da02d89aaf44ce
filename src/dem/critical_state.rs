//! Critical-state simple shear (issue 24 item 1; chapter §4.2.1: 1078 grains, periodic
//! sides, two layers of fixed grains at top and bottom, "sheared until the critical state
//! was reached"; docs/definitions.md SC-SHEAR-DEM).
//!
//! Contract:
//! - **Cell.** Periodic in x (period L_x = `width` d̄ rounded to the layer pitch), no
//!   gravity. `layers` rows of rough wall grains (d̄ each, pitch `layer_pitch` d̄, rows
//!   staggered by half a pitch) at the bottom, fixed; the same at the top, moving as one
//!   rigid body: horizontal velocity v, vertical velocity from M ẏ = F_y − P L_x (pressure
//!   control, speed capped at 0.25 √(P/ρ_s)).
//! - **Stiffness per pressure.** With `kappa` set, each pressure runs at k_n = κ P (per
//!   metre of thickness; k_t, k_r and the step scaled with it as `DemParams::softened`
//!   does), so that every pressure sits at the same distance from the rigid limit. The
//!   rolling dashpot c_r is a material constant and is *not* scaled: its moment c_r θ̇ does
//!   not scale with the normal force, which is why the chosen rolling model may be pressure
//!   dependent where the μ_r = 0 cell is not (tests/dem_shear.rs).
//! - **Preparations.** The lattice is compacted under P with the preparation's sliding
//!   friction (0: dense; high: loose), rolling resistance on or off, then sheared with the
//!   run's own contacts (the contact histories carried over). A critical state forgets its
//!   preparation: the dense and loose runs must reach the same μ* and packing fraction.
//! - **Stress in the bulk.** On `planes` horizontal planes spread over the bulk (the cell
//!   less `bulk_margin` d̄ at each wall), the force that the grains whose centres lie above
//!   a plane exert on those below, per unit length: τ = ΣF_x/L_x, σ_n = −ΣF_y/L_x of the
//!   grains below (the bottom layers included; no gravity, so the sum is the force through
//!   the plane). Averaged over planes and steps. By momentum balance its time average equals
//!   the force on the top layers up to the kinetic flux, which both are reported to show.
//! - **Bulk shear rate.** The least-squares slope of v_x against y over the bulk grains,
//!   averaged over the samples of the steady window: the inertial number of the bulk,
//!   I = γ̇ d̄/√(σ_n/ρ_s), and its ratio to the imposed one (slip at the walls).
//! - **Steady part.** Averages run over γ ∈ [`steady_from`, `strain`]; the drift is the
//!   difference of μ* between the window's second and first halves.
//! - **φ_cs** = atan of the least-squares slope of the bulk τ against σ_n through the origin
//!   over every pressure and preparation (a cohesionless material); the free fit is kept.
//!
//! Deterministic: each (pressure, preparation) is its own cell and steps on one thread;
//! results come out in the declared order at any thread count.

use crate::dem::error::DemError;
use crate::dem::params::DemParams;
use crate::dem::state::{Motion, State};
use crate::dem::world::World;
use crate::math::Real;
use crate::sample::rng::SplitMix64;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use std::time::Instant;

/// How the sample is compacted before it is sheared.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Preparation {
    /// Name shown in tables and figures ("dense", "loose").
    pub name: String,
    /// Sliding friction of the grains during compaction (0 gives the densest packing).
    pub friction: Real,
    /// Rolling resistance on during compaction (as in the run) or off.
    pub rolling: bool,
    /// The pressures this preparation runs at (a subset); absent: all of them.
    pub pressures: Option<Vec<Real>>,
}

impl Default for Preparation {
    fn default() -> Self {
        Self {
            name: "dense".into(),
            friction: 0.0,
            rolling: false,
            pressures: None,
        }
    }
}

/// Extra runs at a fixed contact stiffness (the columns' own contacts), first preparation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FixedStiffnessCheck {
    /// Stiffness factor on the table's contacts (the columns' `stiffness_factor`).
    pub stiffness_factor: Real,
    /// Pressures [Pa] (the columns' base pressures).
    pub pressures: Vec<Real>,
}

impl Default for FixedStiffnessCheck {
    fn default() -> Self {
        Self {
            stiffness_factor: 0.1,
            pressures: vec![1e3, 4e3],
        }
    }
}

/// Settings of the critical-state protocol.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CriticalStateParams {
    /// Normal pressures P [Pa].
    pub pressures: Vec<Real>,
    /// Imposed inertial number I = γ̇ d̄/√(P/ρ_s) (quasi-static: ≤ 1e-3).
    pub inertial_number: Real,
    /// Shear strain γ to reach.
    pub strain: Real,
    /// Start of the steady window (strain); averages over [steady_from, strain].
    pub steady_from: Real,
    /// κ = k_n/P per pressure (k_n per metre of thickness); absent: the given contacts.
    pub kappa: Option<Real>,
    /// Cell width L_x in mean diameters.
    pub width: Real,
    /// Rows of wall grains at each side.
    pub layers: usize,
    /// Wall grain pitch as a multiple of d̄ (gaps make the wall rough).
    pub layer_pitch: Real,
    /// Distance from each wall's inner row left out of the bulk [d̄].
    pub bulk_margin: Real,
    /// Stress planes in the bulk.
    pub planes: usize,
    /// Preparations; each pressure runs once per preparation.
    pub preparations: Vec<Preparation>,
    /// Runs at the columns' fixed contacts (first preparation), reported beside.
    pub fixed_stiffness_check: Option<FixedStiffnessCheck>,
    /// Longest compaction before shearing, in t_P = d̄ √(ρ_s/P) (stops earlier once the
    /// sample carries P with the wall at rest; checked every ½ t_P). In units of t_P, so
    /// that with `kappa` set the runs at P and 4P are the same run on a clock twice as fast.
    pub compaction_periods: Real,
    /// Time-series interval in strain.
    pub sample_strain: Real,
    /// Seed of the initial lattice shuffle.
    pub seed: u64,
}

impl Default for CriticalStateParams {
    fn default() -> Self {
        Self {
            pressures: vec![1e3, 1e4],
            inertial_number: 1e-3,
            strain: 3.0,
            steady_from: 1.0,
            kappa: Some(1e4),
            width: 30.0,
            layers: 2,
            layer_pitch: 1.15,
            bulk_margin: 4.0,
            planes: 8,
            preparations: vec![
                Preparation::default(),
                Preparation {
                    name: "loose".into(),
                    friction: 1.0,
                    rolling: true,
                    pressures: None,
                },
            ],
            fixed_stiffness_check: None,
            compaction_periods: 300.0,
            sample_strain: 0.02,
            seed: 5,
        }
    }
}

/// One run: a pressure, a preparation, a stiffness.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunSpec {
    /// P [Pa].
    pub pressure: Real,
    /// Index into `preparations`.
    pub preparation: usize,
    /// 0: the protocol's runs (κ per pressure); 1: the fixed-stiffness check.
    pub set: usize,
    /// Factor on the given contacts (k_n, k_t, k_r; the step by 1/√factor).
    pub stiffness_factor: Real,
}

impl CriticalStateParams {
    /// Every run, in output order: the pressures × preparations, then the fixed-stiffness
    /// check. `kn` is the given contacts' k_n [N/m].
    pub fn runs(&self, kn: Real) -> Vec<RunSpec> {
        let mut out = Vec::new();
        for &p in &self.pressures {
            for (k, prep) in self.preparations.iter().enumerate() {
                if prep.pressures.as_ref().is_some_and(|ps| !ps.contains(&p)) {
                    continue;
                }
                out.push(RunSpec {
                    pressure: p,
                    preparation: k,
                    set: 0,
                    stiffness_factor: self.kappa.map_or(1.0, |kap| kap * p / kn),
                });
            }
        }
        if let Some(c) = &self.fixed_stiffness_check {
            for &p in &c.pressures {
                out.push(RunSpec {
                    pressure: p,
                    preparation: 0,
                    set: 1,
                    stiffness_factor: c.stiffness_factor,
                });
            }
        }
        out
    }

    /// Relative step count (for `plan --estimate`): Σ over runs of strain × P^-1/2 ×
    /// √factor (steps ∝ simulated time / Δt; at fixed I the time ∝ P^-1/2, Δt ∝ factor^-1/2).
    pub fn relative_steps(&self, kn: Real) -> Real {
        self.runs(kn)
            .iter()
            .map(|r| self.strain * r.pressure.powf(-0.5) * r.stiffness_factor.sqrt())
            .sum()
    }
}

/// One time-series row.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CsSample {
    /// Shear strain γ = x_top/h_0.
    pub strain: Real,
    /// μ = τ/σ_n on the top wall since the previous sample.
    pub mu_wall: Real,
    /// μ = τ/σ_n in the bulk since the previous sample.
    pub mu_bulk: Real,
    /// Bulk packing fraction (area of the grains whose centres lie in the bulk over its area).
    pub packing: Real,
}

/// The result of one run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CsPoint {
    /// Applied pressure P [Pa].
    pub pressure: Real,
    /// Preparation index.
    pub preparation: usize,
    /// 0: protocol; 1: fixed-stiffness check.
    pub set: usize,
    /// Contact stiffness k_n [N/m].
    pub kn: Real,
    /// κ = k_n/P.
    pub kappa: Real,
    /// Time step [s].
    pub dt: Real,
    /// Steps run (compaction and shear).
    pub steps: u64,
    /// Packing fraction of the bulk after compaction.
    pub packing_initial: Real,
    /// Steady-window means: wall τ, σ_n [Pa].
    pub tau_wall: Real,
    /// Steady-window mean σ_n on the wall [Pa].
    pub sigma_wall: Real,
    /// Steady-window mean bulk τ [Pa].
    pub tau_bulk: Real,
    /// Steady-window mean bulk σ_n [Pa].
    pub sigma_bulk: Real,
    /// μ* = τ/σ_n in the bulk.
    pub mu: Real,
    /// μ on the wall.
    pub mu_wall: Real,
    /// Standard error of μ* from 5 consecutive blocks of the window (their s.d./√5).
    pub mu_se: Real,
    /// μ* over the second half of the window minus over the first.
    pub drift: Real,
    /// Largest μ over the samples before the window (the peak of a dense sample).
    pub mu_peak: Real,
    /// Steady-window bulk packing fraction.
    pub packing: Real,
    /// Imposed inertial number (from the wall speed and P).
    pub inertial_imposed: Real,
    /// Inertial number of the bulk (its measured γ̇ and σ_n).
    pub inertial_bulk: Real,
    /// Bulk shear rate over the imposed one (1: no slip at the walls, no band).
    pub shear_rate_ratio: Real,
    /// Steady-window mean coordination number of the sample grains (contacts per grain,
    /// wall grains counted as partners).
    pub coordination: Real,
    /// Steady-window fraction of contacts sliding (|f_t| ≥ 0.98 μ k_n δ).
    pub sliding_fraction: Real,
    /// Steady-window fraction of contacts whose rolling spring sits on its cap (k_r|θ_r| ≥
    /// 0.98 μ_r r_eff k_n δ); 0 without rolling resistance.
    pub rolling_cap_fraction: Real,
    /// Largest local inertial number of the window's mean velocity profile (slope over 3
    /// d̄ at each bin; a shear band's I).
    pub inertial_local_max: Real,
    /// Time series.
    pub series: Vec<CsSample>,
    /// Velocity profile over the steady window: (y/h, ⟨v_x⟩/v) per d̄-high bin between the
    /// walls' inner rows (0: bottom row, 1: top row).
    pub profile: Vec<(Real, Real)>,
    /// Wall time [s].
    pub wall_s: f64,
}

/// The protocol's result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CsResult {
    /// One point per run, in [`CriticalStateParams::runs`] order.
    pub points: Vec<CsPoint>,
    /// φ_cs through the origin over the protocol's runs (set 0) [°].
    pub friction_angle_deg: Real,
    /// Free fit τ = c + tan φ σ_n over set 0: φ [°].
    pub friction_angle_free_deg: Real,
    /// Its intercept c [Pa].
    pub cohesion_free: Real,
    /// φ through the origin per preparation (set 0) [°].
    pub friction_angle_by_preparation: Vec<Real>,
    /// φ through the origin of the fixed-stiffness check (set 1), if run [°].
    pub friction_angle_fixed_stiffness: Option<Real>,
    /// Sample grains (without the wall rows).
    pub grains: usize,
}

struct Cell {
    state: State,
    lx: Real,
    bottom: Vec<usize>,
    top: Vec<usize>,
    /// Sample grains (indices).
    sample: Vec<usize>,
    d_mean: Real,
}

/// The lattice cell: `layers` rows of wall grains at each side, the sample on a loose
/// shuffled lattice between them.
fn build_cell(radii: &[Real], sp: &CriticalStateParams, density: Real) -> Cell {
    let d_mean = 2.0 * radii.iter().sum::<Real>() / radii.len() as Real;
    let r_max = radii.iter().cloned().fold(0.0, Real::max);
    let pitch_l = sp.layer_pitch * d_mean;
    let n_layer = (sp.width * d_mean / pitch_l).round().max(3.0) as usize;
    let lx = n_layer as Real * pitch_l;
    let r_l = 0.5 * d_mean;
    // staggered rows: half a pitch across, and far enough up that they do not touch
    let half = 0.5 * pitch_l;
    let dy_l = (d_mean * d_mean - half * half).max(0.0).sqrt() * 1.001;
    let mut s = State::with_capacity(radii.len() + 2 * sp.layers * n_layer);
    let mut rng = SplitMix64(sp.seed);
    let mut bottom = Vec::new();
    for row in 0..sp.layers {
        for k in 0..n_layer {
            let x = (k as Real + 0.5) * pitch_l + half * (row % 2) as Real;
            bottom.push(s.insert(x % lx, r_l + row as Real * dy_l, r_l, density).0 as usize);
        }
    }
    let pitch = 2.0 * r_max * 1.05;
    let per_row = (lx / pitch).floor() as usize;
    let mut order: Vec<usize> = (0..radii.len()).collect();
    for i in (1..order.len()).rev() {
        let j = (rng.next_f64() * (i + 1) as Real) as usize;
        order.swap(i, j.min(i));
    }
    let y0 = r_l + (sp.layers - 1) as Real * dy_l + r_l + r_max * 1.05;
    let mut y_top: Real = 0.0;
    let mut sample = Vec::with_capacity(radii.len());
    for (k, &g) in order.iter().enumerate() {
        let (row, col) = (k / per_row, k % per_row);
        let x = (col as Real + 0.5 + 0.5 * (row % 2) as Real) * pitch;
        let y = y0 + row as Real * pitch * 0.9;
        sample.push(s.insert(x % lx, y, radii[g], density).0 as usize);
        y_top = y_top.max(y + radii[g]);
    }
    let mut top = Vec::new();
    for row in 0..sp.layers {
        for k in 0..n_layer {
            let x = (k as Real + 0.5) * pitch_l + half * (row % 2) as Real;
            let y = y_top + 1.05 * r_l + row as Real * dy_l;
            top.push(s.insert(x % lx, y, r_l, density).0 as usize);
        }
    }
    for &i in bottom.iter().chain(top.iter()) {
        s.set_motion(i, Motion::Prescribed);
    }
    Cell {
        state: s,
        lx,
        bottom,
        top,
        sample,
        d_mean,
    }
}

/// Mean height of the wall row next to the sample.
fn inner_row_y(s: &State, wall: &[usize], layers: usize, top: bool) -> Real {
    let n = wall.len() / layers;
    // bottom: its last row is innermost; top: its first row
    let row = if top { &wall[..n] } else { &wall[wall.len() - n..] };
    row.iter().map(|&i| s.y[i]).sum::<Real>() / n as Real
}

/// Bulk stress planes and what they accumulate.
struct Planes {
    y: Vec<Real>,
    /// Per plane-gap bin (grains with j planes at or below them): summed force.
    bins: Vec<(Real, Real)>,
}

impl Planes {
    fn new(lo: Real, hi: Real, k: usize) -> Self {
        let y = (0..k).map(|i| lo + (i as Real + 0.5) * (hi - lo) / k as Real).collect();
        Self {
            y,
            bins: vec![(0.0, 0.0); k + 1],
        }
    }

    /// Add this step's forces: Σ over planes of the force on the grains below each.
    fn add(&mut self, w: &World, cell: &Cell) -> (Real, Real) {
        for b in self.bins.iter_mut() {
            *b = (0.0, 0.0);
        }
        for &i in cell.sample.iter().chain(cell.bottom.iter()) {
            let y = w.state.y[i];
            let j = self.y.partition_point(|&yp| yp <= y);
            let f = w.force(i);
            self.bins[j].0 += f.x;
            self.bins[j].1 += f.y;
        }
        // plane k sees bins 0..=k below it
        let (mut cx, mut cy, mut sx, mut sy) = (0.0, 0.0, 0.0, 0.0);
        for k in 0..self.y.len() {
            cx += self.bins[k].0;
            cy += self.bins[k].1;
            sx += cx;
            sy += cy;
        }
        (sx / self.y.len() as Real, sy / self.y.len() as Real)
    }
}

/// Sums over steps of one sample interval.
#[derive(Default, Clone, Copy)]
struct Acc {
    wall_x: Real,
    wall_y: Real,
    bulk_x: Real,
    bulk_y: Real,
    steps: u64,
}

impl Acc {
    fn add(&mut self, o: &Acc) {
        self.wall_x += o.wall_x;
        self.wall_y += o.wall_y;
        self.bulk_x += o.bulk_x;
        self.bulk_y += o.bulk_y;
        self.steps += o.steps;
    }
    /// (τ_wall, σ_wall, τ_bulk, σ_bulk) [Pa].
    fn stresses(&self, lx: Real) -> (Real, Real, Real, Real) {
        let n = self.steps.max(1) as Real * lx;
        (-self.wall_x / n, self.wall_y / n, self.bulk_x / n, -self.bulk_y / n)
    }
}

/// Drive the top rows for `steps` steps at horizontal velocity `v` under pressure `p`.
#[allow(clippy::too_many_arguments)]
fn drive(
    w: &mut World,
    cell: &Cell,
    planes: Option<&mut Planes>,
    m_top: Real,
    p: Real,
    v: Real,
    vy: &mut Real,
    steps: u64,
) -> Result<Acc, DemError> {
    let dt = w.params.dt;
    let v_cap = 0.25 * (p / w.params.density).sqrt();
    let mut acc = Acc::default();
    let mut planes = planes;
    for _ in 0..steps {
        for &i in &cell.top {
            w.state.vx[i] = v;
            w.state.vy[i] = *vy;
        }
        w.run(1)?;
        let (mut fx, mut fy) = (0.0, 0.0);
        for &i in &cell.top {
            let f = w.force(i);
            fx += f.x;
            fy += f.y;
        }
        acc.wall_x += fx;
        acc.wall_y += fy;
        if let Some(pl) = planes.as_deref_mut() {
            let (bx, by) = pl.add(w, cell);
            acc.bulk_x += bx;
            acc.bulk_y += by;
        }
        acc.steps += 1;
        *vy = (*vy + dt * (fy - p * cell.lx) / m_top).clamp(-v_cap, v_cap);
    }
    Ok(acc)
}

/// Packing fraction and v_x–y slope over the sample grains whose centres lie in [lo, hi].
fn bulk_state(s: &State, cell: &Cell, lo: Real, hi: Real) -> (Real, Real) {
    let (mut area, mut n, mut sy, mut sv, mut syy, mut syv): (Real, Real, Real, Real, Real, Real) =
        (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for &i in &cell.sample {
        let y = s.y[i];
        if y >= lo && y < hi {
            area += PI * s.r[i] * s.r[i];
            n += 1.0;
            sy += y;
            sv += s.vx[i];
            syy += y * y;
            syv += y * s.vx[i];
        }
    }
    let var = syy - sy * sy / n.max(1.0);
    let slope = if n > 2.0 && var > 0.0 {
        (syv - sy * sv / n) / var
    } else {
        0.0
    };
    (area / (cell.lx * (hi - lo)), slope)
}

/// Coordination number, sliding fraction and rolling-cap fraction of the current contacts
/// (elastic normal force k_n δ from the positions: quasi-static, the dashpot's share is of
/// order I).
fn contact_stats(w: &World, cell: &Cell, is_sample: &[bool]) -> (Real, Real, Real) {
    let p = &w.params;
    let s = &w.state;
    let (mut n, mut ends, mut slide, mut cap): (Real, Real, Real, Real) = (0.0, 0.0, 0.0, 0.0);
    for (k, h) in w.contact_histories() {
        let (i, j) = (k.i as usize, k.j as usize);
        if !is_sample[i] && !is_sample[j] {
            continue;
        }
        let mut dx = s.x[i] - s.x[j];
        dx -= cell.lx * (dx / cell.lx).round();
        let dy = s.y[i] - s.y[j];
        let delta = s.r[i] + s.r[j] - (dx * dx + dy * dy).sqrt();
        if delta <= 0.0 {
            continue;
        }
        let fn_el = p.grain.kn * delta;
        n += 1.0;
        ends += (is_sample[i] as u8 + is_sample[j] as u8) as Real;
        if h.ft.abs() >= 0.98 * p.grain.friction * fn_el {
            slide += 1.0;
        }
        if p.rolling.enabled && p.rolling.mu_r > 0.0 {
            let r_eff = s.r[i] * s.r[j] / (s.r[i] + s.r[j]);
            if p.rolling.kr * h.rolling.abs() >= 0.98 * p.rolling.mu_r * r_eff * fn_el {
                cap += 1.0;
            }
        }
    }
    let m = n.max(1.0);
    (ends / cell.sample.len() as Real, slide / m, cap / m)
}

/// Run the protocol on `radii` (sample grains) with `params` (gravity off; friction,
/// rolling and stiffness as given, k_n rescaled per pressure when `kappa` is set).
pub fn critical_state_test(radii: &[Real], params: &DemParams, sp: &CriticalStateParams) -> Result<CsResult, DemError> {
    if radii.len() < 20 || sp.pressures.is_empty() || sp.preparations.is_empty() || sp.layers == 0 {
        return Err(DemError::Setup(
            "critical-state shear needs ≥ 20 grains, a pressure, a preparation and a wall row".into(),
        ));
    }
    let mut p = params.clone();
    p.gravity = 0.0;
    p.ledger = false;
    let runs = sp.runs(p.grain.kn);
    let points = runs
        .par_iter()
        .map(|r| run_one(radii, &p, sp, r))
        .collect::<Result<Vec<_>, DemError>>()?;
    let fit = |set: usize, prep: Option<usize>| {
        let q: Vec<&CsPoint> = points
            .iter()
            .filter(|q| q.set == set && prep.is_none_or(|k| q.preparation == k))
            .collect();
        fit_through_origin(&q)
    };
    let set0: Vec<&CsPoint> = points.iter().filter(|q| q.set == 0).collect();
    let (free, c) = fit_free(&set0);
    Ok(CsResult {
        friction_angle_deg: fit(0, None),
        friction_angle_free_deg: free,
        cohesion_free: c,
        friction_angle_by_preparation: (0..sp.preparations.len()).map(|k| fit(0, Some(k))).collect(),
        friction_angle_fixed_stiffness: sp.fixed_stiffness_check.as_ref().map(|_| fit(1, None)),
        grains: radii.len(),
        points,
    })
}

/// Standard error of the bulk μ over `b` consecutive blocks of the window's samples.
fn block_se(window: &[Acc], b: usize, lx: Real) -> Real {
    if window.len() < b || b < 2 {
        return Real::NAN;
    }
    let per = window.len() / b;
    let mus: Vec<Real> = (0..b)
        .map(|k| {
            let mut a = Acc::default();
            for x in &window[k * per..(k + 1) * per] {
                a.add(x);
            }
            let (_, _, t, s) = a.stresses(lx);
            t / s
        })
        .collect();
    let m = mus.iter().sum::<Real>() / b as Real;
    let var = mus.iter().map(|x| (x - m).powi(2)).sum::<Real>() / (b - 1) as Real;
    (var / b as Real).sqrt()
}

fn fit_through_origin(q: &[&CsPoint]) -> Real {
    let sxy: Real = q.iter().map(|q| q.sigma_bulk * q.tau_bulk).sum();
    let sxx: Real = q.iter().map(|q| q.sigma_bulk * q.sigma_bulk).sum();
    (sxy / sxx).atan().to_degrees()
}

fn fit_free(q: &[&CsPoint]) -> (Real, Real) {
    let n = q.len() as Real;
    let mx = q.iter().map(|q| q.sigma_bulk).sum::<Real>() / n;
    let my = q.iter().map(|q| q.tau_bulk).sum::<Real>() / n;
    let cov: Real = q.iter().map(|q| (q.sigma_bulk - mx) * (q.tau_bulk - my)).sum();
    let var: Real = q.iter().map(|q| (q.sigma_bulk - mx).powi(2)).sum();
    if q.len() < 2 || var <= 0.0 {
        return (fit_through_origin(q), 0.0);
    }
    let s = cov / var;
    (s.atan().to_degrees(), my - s * mx)
}

/// One (pressure, preparation, stiffness): compaction, then shear to `sp.strain`.
fn run_one(radii: &[Real], base: &DemParams, sp: &CriticalStateParams, r: &RunSpec) -> Result<CsPoint, DemError> {
    let started = Instant::now();
    let pres = r.pressure;
    let run = base.softened(r.stiffness_factor);
    let prep = &sp.preparations[r.preparation];
    let mut prep_params = run.clone();
    prep_params.grain.friction = prep.friction;
    prep_params.rolling.enabled = run.rolling.enabled && prep.rolling;
    let cell = build_cell(radii, sp, run.density);
    let m_top: Real = cell.top.iter().map(|&i| cell.state.m[i]).sum();
    let dt = run.dt;
    let mut steps = 0u64;
    let mut vy = 0.0;
    // compaction under P in chunks of ½ t_P until the sample carries P (±2 %) with the
    // wall at rest, or `compaction_periods` t_P have passed
    let mut w = World::new(prep_params, cell.state.clone(), vec![], Some(cell.lx))?;
    w.energy_check = false;
    w.preflight()?;
    let t_p = cell.d_mean * (run.density / pres).sqrt();
    let n_chunk = ((0.5 * t_p / dt).round() as u64).max(1);
    let n_max = (sp.compaction_periods * t_p / dt).ceil() as u64;
    let v_cap = 0.25 * (pres / run.density).sqrt();
    loop {
        let a = drive(&mut w, &cell, None, m_top, pres, 0.0, &mut vy, n_chunk)?;
        steps += n_chunk;
        let sig = a.wall_y / (a.steps as Real * cell.lx);
        if ((sig - pres).abs() < 0.02 * pres && vy.abs() < 0.01 * v_cap) || steps >= n_max {
            break;
        }
    }
    // the run's own contacts from here, with the compacted histories
    let hist = w.saved_histories();
    let mut w2 = World::new(run.clone(), w.state.clone(), vec![], Some(cell.lx))?;
    drop(w);
    w2.energy_check = false;
    w2.preflight()?;
    w2.restore_histories(&hist);
    let mut w = w2;
    let y_bot = inner_row_y(&w.state, &cell.bottom, sp.layers, false);
    let y_top = inner_row_y(&w.state, &cell.top, sp.layers, true);
    let h0 = y_top - y_bot;
    let margin = sp.bulk_margin * cell.d_mean;
    let (lo, hi) = (y_bot + margin, y_top - margin);
    if hi - lo < 2.0 * cell.d_mean {
        return Err(DemError::Setup(format!(
            "critical-state shear: the cell is {:.1} d̄ high, too low for a bulk {} d̄ from each wall",
            h0 / cell.d_mean,
            sp.bulk_margin
        )));
    }
    let packing_initial = bulk_state(&w.state, &cell, lo, hi).0;
    let mut planes = Planes::new(lo, hi, sp.planes.max(1));
    let gdot = sp.inertial_number * (pres / run.density).sqrt() / cell.d_mean;
    let v = gdot * h0;
    let n_total = (sp.strain / gdot / dt).ceil() as u64;
    let n_sample = ((sp.sample_strain / gdot / dt).ceil() as u64).max(1);
    let mid = 0.5 * (sp.steady_from + sp.strain);
    let (mut first, mut second) = (Acc::default(), Acc::default());
    let mut window: Vec<Acc> = Vec::new();
    let mut is_sample = vec![false; w.state.len()];
    for &i in &cell.sample {
        is_sample[i] = true;
    }
    let (mut z_sum, mut slide_sum, mut cap_sum): (Real, Real, Real) = (0.0, 0.0, 0.0);
    let (mut pack_sum, mut slope_sum, mut n_win): (Real, Real, Real) = (0.0, 0.0, 0.0);
    let mut mu_peak: Real = 0.0;
    let n_bins = ((h0 / cell.d_mean).round() as usize).max(1);
    let mut prof = vec![(0.0, 0u64); n_bins];
    let mut series = Vec::new();
    let mut done = 0u64;
    while done < n_total {
        let k = n_sample.min(n_total - done);
        let a = drive(&mut w, &cell, Some(&mut planes), m_top, pres, v, &mut vy, k)?;
        done += k;
        let strain = v * done as Real * dt / h0;
        let (tw, sw, tb, sb) = a.stresses(cell.lx);
        let (packing, slope) = bulk_state(&w.state, &cell, lo, hi);
        let mu_bulk = tb / sb;
        series.push(CsSample {
            strain,
            mu_wall: tw / sw,
            mu_bulk,
            packing,
        });
        // a sample belongs to the window when it starts inside it
        let start = v * (done - k) as Real * dt / h0;
        if start >= sp.steady_from - 1e-12 {
            if start < mid {
                first.add(&a)
            } else {
                second.add(&a)
            }
            window.push(a);
            let (z, sl, cp) = contact_stats(&w, &cell, &is_sample);
            z_sum += z;
            slide_sum += sl;
            cap_sum += cp;
            pack_sum += packing;
            slope_sum += slope;
            n_win += 1.0;
            for &i in &cell.sample {
                let f = (w.state.y[i] - y_bot) / h0;
                let b = ((f * n_bins as Real).floor().max(0.0) as usize).min(n_bins - 1);
                prof[b].0 += w.state.vx[i];
                prof[b].1 += 1;
            }
        } else if mu_bulk.is_finite() {
            mu_peak = mu_peak.max(mu_bulk);
        }
    }
    steps += done;
    let mut all = first;
    all.add(&second);
    let (tau_wall, sigma_wall, tau_bulk, sigma_bulk) = all.stresses(cell.lx);
    let mu_of = |a: &Acc| {
        let (_, _, t, s) = a.stresses(cell.lx);
        t / s
    };
    let gdot_bulk = slope_sum / n_win.max(1.0);
    let mu_se = block_se(&window, 5, cell.lx);
    let profile: Vec<(Real, Real)> = prof
        .iter()
        .enumerate()
        .filter(|(_, b)| b.1 > 0)
        .map(|(k, b)| ((k as Real + 0.5) / n_bins as Real, b.0 / (b.1 as Real * v)))
        .collect();
    // γ̇ local = Δ(v_x/v)·v/Δy over neighbours two bins apart
    let gdot_local = profile
        .windows(3)
        .map(|t| (t[2].1 - t[0].1) * v / ((t[2].0 - t[0].0) * h0))
        .fold(0.0, Real::max);
    let kn = run.grain.kn;
    Ok(CsPoint {
        pressure: pres,
        preparation: r.preparation,
        set: r.set,
        kn,
        kappa: kn / pres,
        dt,
        steps,
        packing_initial,
        tau_wall,
        sigma_wall,
        tau_bulk,
        sigma_bulk,
        mu: tau_bulk / sigma_bulk,
        mu_wall: tau_wall / sigma_wall,
        mu_se,
        drift: mu_of(&second) - mu_of(&first),
        mu_peak,
        packing: pack_sum / n_win.max(1.0),
        inertial_imposed: sp.inertial_number,
        inertial_bulk: gdot_bulk * cell.d_mean / (sigma_bulk.max(1e-12) / run.density).sqrt(),
        shear_rate_ratio: gdot_bulk / gdot,
        coordination: z_sum / n_win.max(1.0),
        sliding_fraction: slide_sum / n_win.max(1.0),
        rolling_cap_fraction: cap_sum / n_win.max(1.0),
        inertial_local_max: gdot_local * cell.d_mean / (sigma_bulk.max(1e-12) / run.density).sqrt(),
        series,
        profile,
        wall_s: started.elapsed().as_secs_f64(),
    })
}

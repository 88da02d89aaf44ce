//! Periodic simple-shear test for the critical-state friction angle (docs/definitions.md
//! SC-SHEAR-DEM, stage C1; chapter §4.2.1: 1078 grains, periodic sides, fixed rough grain
//! layers at top and bottom, normal pressure P and velocity v applied to the top layer).
//!
//! Cell: periodic in x (period L_x), no gravity. Bottom layer: fixed grains. Top layer:
//! grains moving as one rigid body with horizontal velocity v and a vertical velocity that
//! follows M ẏ = F_y − P L_x (pressure control). Stresses are the time-averaged force of
//! the sample on the top layer over L_x: σ_n = F_y/L_x, τ = −F_x/L_x. The shear rate is
//! chosen from the target inertial number, γ̇ = I √(P/ρ_s)/d̄ (D08), v = γ̇ h.
//! φ_cs = atan of the least-squares slope of τ̄ against σ̄_n through the origin (a
//! cohesionless material); the free intercept fit is reported too.

use crate::dem::error::DemError;
use crate::dem::params::DemParams;
use crate::dem::state::{Motion, State};
use crate::dem::world::World;
use crate::math::Real;
use crate::sample::rng::SplitMix64;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Shear-test settings (UNSPEC values from the SC-SHEAR-DEM proposal).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ShearParams {
    /// Normal pressures P [Pa]. Proposal {1, 2, 5, 10, 20} kPa.
    pub pressures: Vec<Real>,
    /// Target inertial number I (quasi-static < 1e-3).
    pub inertial_number: Real,
    /// Shear strain γ to reach.
    pub strain: Real,
    /// Average τ, σ_n over strain from this fraction of `strain` on (0.5: last 50 %).
    pub average_from: Real,
    /// Cell width L_x in mean diameters. UNSPEC: 30 (≈ 36 d̄ high with 1078 grains).
    pub width: Real,
    /// Rough-layer grain pitch as a multiple of the layer grain diameter (gaps make the
    /// layer rough but too narrow for a sample grain to pass).
    pub layer_pitch: Real,
    /// Longest compaction at pressure P before shearing [s] (stops earlier once the
    /// sample carries P with the layer at rest).
    pub compaction_time: Real,
    /// Time-series interval in strain.
    pub sample_strain: Real,
    /// Seed of the initial lattice shuffle.
    pub seed: u64,
}

impl ShearParams {
    /// The test's simulated time in relative units (for `plan --estimate`): strain × Σ
    /// P^-1/2 over the pressures, since at a fixed inertial number the shear rate ∝ √P.
    pub fn relative_duration(&self) -> Real {
        self.strain * self.pressures.iter().map(|p| p.powf(-0.5)).sum::<Real>()
    }
}

impl Default for ShearParams {
    fn default() -> Self {
        Self {
            pressures: vec![1e3, 2e3, 5e3, 1e4, 2e4],
            inertial_number: 1e-3,
            strain: 2.0,
            average_from: 0.5,
            width: 30.0,
            layer_pitch: 1.15,
            compaction_time: 0.5,
            sample_strain: 0.01,
            seed: 5,
        }
    }
}

/// One time-series row of a shear run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ShearSample {
    /// Shear strain γ = x_top / h.
    pub strain: Real,
    /// Shear stress τ [Pa] (average since the previous sample).
    pub tau: Real,
    /// Normal stress σ_n [Pa] (average since the previous sample).
    pub sigma_n: Real,
    /// Layer spacing h [m].
    pub height: Real,
}

/// Result at one pressure.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShearPoint {
    /// Applied pressure P [Pa].
    pub pressure: Real,
    /// Mean τ over the averaging window [Pa].
    pub tau: Real,
    /// Mean σ_n over the averaging window [Pa].
    pub sigma_n: Real,
    /// τ/σ_n.
    pub mu: Real,
    /// Achieved inertial number γ̇ d̄ / √(σ_n/ρ_s).
    pub inertial_number: Real,
    /// Shear velocity v [m/s].
    pub velocity: Real,
    /// Time series.
    pub series: Vec<ShearSample>,
    /// Wall time [s].
    pub wall_s: f64,
}

/// Result of the calibration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShearResult {
    /// One point per pressure.
    pub points: Vec<ShearPoint>,
    /// φ_cs from the fit through the origin [deg].
    pub friction_angle_deg: Real,
    /// Free fit τ = c + tanφ σ_n: φ [deg].
    pub friction_angle_free_deg: Real,
    /// Free fit intercept c [Pa].
    pub cohesion_free: Real,
    /// Sample grains (without the layers).
    pub grains: usize,
}

struct Cell {
    state: State,
    lx: Real,
    bottom: Vec<usize>,
    top: Vec<usize>,
    d_mean: Real,
}

fn build_cell(radii: &[Real], sp: &ShearParams, density: Real) -> Cell {
    let d_mean = 2.0 * radii.iter().sum::<Real>() / radii.len() as Real;
    let r_max = radii.iter().cloned().fold(0.0, Real::max);
    let pitch_l = sp.layer_pitch * d_mean;
    let n_layer = (sp.width * d_mean / pitch_l).round().max(3.0) as usize;
    let lx = n_layer as Real * pitch_l;
    let mut s = State::with_capacity(radii.len() + 2 * n_layer);
    let mut rng = SplitMix64(sp.seed);
    let r_l = 0.5 * d_mean;
    let mut bottom = Vec::new();
    for k in 0..n_layer {
        bottom.push(s.insert((k as Real + 0.5) * pitch_l, r_l, r_l, density).0 as usize);
    }
    // sample grains on a loose lattice, shuffled order
    let pitch = 2.0 * r_max * 1.05;
    let per_row = (lx / pitch).floor() as usize;
    let mut order: Vec<usize> = (0..radii.len()).collect();
    for i in (1..order.len()).rev() {
        let j = (rng.next_f64() * (i + 1) as Real) as usize;
        order.swap(i, j.min(i));
    }
    let y0 = 2.0 * r_l + r_max * 1.05;
    let mut y_top: Real = 0.0;
    for (k, &g) in order.iter().enumerate() {
        let (row, col) = (k / per_row, k % per_row);
        let x = (col as Real + 0.5 + 0.5 * (row % 2) as Real) * pitch;
        let y = y0 + row as Real * pitch * 0.9;
        s.insert(x % lx, y, radii[g], density);
        y_top = y_top.max(y + radii[g]);
    }
    let mut top = Vec::new();
    for k in 0..n_layer {
        top.push(
            s.insert((k as Real + 0.5) * pitch_l, y_top + 1.05 * r_l, r_l, density)
                .0 as usize,
        );
    }
    for &i in bottom.iter().chain(top.iter()) {
        s.set_motion(i, Motion::Prescribed);
    }
    Cell {
        state: s,
        lx,
        bottom,
        top,
        d_mean,
    }
}

fn mean_y(s: &State, idx: &[usize]) -> Real {
    idx.iter().map(|&i| s.y[i]).sum::<Real>() / idx.len() as Real
}

/// Drive the top layer for `steps` steps at horizontal velocity `v` under pressure `p`;
/// returns the summed (F_x, F_y) of the sample on the top layer over the steps.
fn drive(
    w: &mut World,
    top: &[usize],
    m_top: Real,
    lx: Real,
    p: Real,
    v: Real,
    vy: &mut Real,
    steps: u64,
    cap: Real,
) -> Result<(Real, Real), DemError> {
    let dt = w.params.dt;
    let (mut sx, mut sy) = (0.0, 0.0);
    for _ in 0..steps {
        for &i in top {
            w.state.vx[i] = v;
            w.state.vy[i] = *vy;
        }
        w.run(1)?;
        let (mut fx, mut fy) = (0.0, 0.0);
        for &i in top {
            let f = w.force(i);
            fx += f.x;
            fy += f.y;
        }
        sx += fx;
        sy += fy;
        // pressure control: M ẏ = F_y − P L_x (force of the sample on the layer pushes up),
        // speed capped at v_cap = cap·√(P/ρ_s) so the layer never slams into the sample
        let v_cap = cap * (p / w.params.density).sqrt();
        *vy = (*vy + dt * (fy - p * lx) / m_top).clamp(-v_cap, v_cap);
    }
    Ok((sx, sy))
}

/// Run the shear test on `radii` (sample grains) at each pressure with `params` (gravity
/// is switched off; rolling, friction and stiffness as given).
pub fn shear_test(radii: &[Real], params: &DemParams, sp: &ShearParams) -> Result<ShearResult, DemError> {
    if radii.len() < 20 || sp.pressures.is_empty() {
        return Err(DemError::Setup(
            "shear test needs ≥ 20 grains and at least one pressure".into(),
        ));
    }
    let mut p = params.clone();
    p.gravity = 0.0;
    p.ledger = false;
    // The pressures are independent cells: run them side by side (each cell is small and
    // steps on one thread, team::TEAM_MIN_GRAINS); results in pressure order, identical to a
    // sequential loop.
    let points = sp
        .pressures
        .par_iter()
        .map(|&pres| shear_point(radii, &p, sp, pres))
        .collect::<Result<Vec<_>, DemError>>()?;
    // fits
    let sxy: Real = points.iter().map(|q| q.sigma_n * q.tau).sum();
    let sxx: Real = points.iter().map(|q| q.sigma_n * q.sigma_n).sum();
    let slope0 = sxy / sxx;
    let n = points.len() as Real;
    let mx = points.iter().map(|q| q.sigma_n).sum::<Real>() / n;
    let my = points.iter().map(|q| q.tau).sum::<Real>() / n;
    let (slope, c) = if points.len() >= 2 {
        let cov: Real = points.iter().map(|q| (q.sigma_n - mx) * (q.tau - my)).sum();
        let var: Real = points.iter().map(|q| (q.sigma_n - mx).powi(2)).sum();
        let s = cov / var;
        (s, my - s * mx)
    } else {
        (slope0, 0.0)
    };
    Ok(ShearResult {
        friction_angle_deg: slope0.atan().to_degrees(),
        friction_angle_free_deg: slope.atan().to_degrees(),
        cohesion_free: c,
        grains: radii.len(),
        points,
    })
}

/// One pressure of the shear test: compaction under `pres`, then shear to `sp.strain`.
fn shear_point(radii: &[Real], p: &DemParams, sp: &ShearParams, pres: Real) -> Result<ShearPoint, DemError> {
    let started = Instant::now();
    let cell = build_cell(radii, sp, p.density);
    let mut w = World::new(p.clone(), cell.state, vec![], Some(cell.lx))?;
    w.energy_check = false;
    w.preflight()?;
    let top = cell.top;
    let m_top: Real = top.iter().map(|&i| w.state.m[i]).sum();
    let dt = p.dt;
    let mut vy = 0.0;
    // compaction under P: in chunks of 1 ms until the sample carries P (±2 %) with the
    // layer at rest, or `compaction_time` has passed
    let n_chunk = ((1e-3 / dt).ceil() as u64).max(1);
    let mut t_comp = 0.0;
    loop {
        let (_, sy) = drive(&mut w, &top, m_top, cell.lx, pres, 0.0, &mut vy, n_chunk, 0.25)?;
        t_comp += n_chunk as Real * dt;
        let sig = sy / (n_chunk as Real * cell.lx);
        let v_cap = 0.25 * (pres / p.density).sqrt();
        if ((sig - pres).abs() < 0.02 * pres && vy.abs() < 0.01 * v_cap) || t_comp >= sp.compaction_time {
            break;
        }
    }
    let h0 = mean_y(&w.state, &top) - mean_y(&w.state, &cell.bottom);
    let gdot = sp.inertial_number * (pres / p.density).sqrt() / cell.d_mean;
    let v = gdot * h0;
    let n_total = (sp.strain / gdot / dt).ceil() as u64;
    let n_sample = ((sp.sample_strain / gdot / dt).ceil() as u64).max(1);
    let mut series = Vec::new();
    let mut done = 0u64;
    let (mut acc_x, mut acc_y, mut acc_n) = (0.0, 0.0, 0u64);
    while done < n_total {
        let k = n_sample.min(n_total - done);
        let (sx, sy) = drive(&mut w, &top, m_top, cell.lx, pres, v, &mut vy, k, 0.25)?;
        done += k;
        let h = mean_y(&w.state, &top) - mean_y(&w.state, &cell.bottom);
        let strain = v * done as Real * dt / h0;
        let smp = ShearSample {
            strain,
            tau: -sx / (k as Real * cell.lx),
            sigma_n: sy / (k as Real * cell.lx),
            height: h,
        };
        series.push(smp);
        if strain >= sp.average_from * sp.strain {
            acc_x += sx;
            acc_y += sy;
            acc_n += k;
        }
    }
    let tau = -acc_x / (acc_n.max(1) as Real * cell.lx);
    let sigma_n = acc_y / (acc_n.max(1) as Real * cell.lx);
    let inertial_number = gdot * cell.d_mean / (sigma_n.max(1e-12) / p.density).sqrt();
    Ok(ShearPoint {
        pressure: pres,
        tau,
        sigma_n,
        mu: tau / sigma_n,
        inertial_number,
        velocity: v,
        series,
        wall_s: started.elapsed().as_secs_f64(),
    })
}

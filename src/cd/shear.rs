//! Periodic plane shear in CD → μ*(I) (docs/definitions.md SC-SHEAR-CD, stage C3; chapter:
//! "Periodic shear tests using CD … reveals a macroscopic friction coefficient of 0.22").
//!
//! Cell: periodic along x (period L_x), no gravity, between two rough layers of glued grains
//! (pitch `layer_pitch`·d̄, gaps narrower than a grain). The bottom layer is a fixed clump;
//! the top layer is a clump with imposed horizontal velocity v and a free vertical velocity
//! under the applied force −p L_x (pressure control solved implicitly inside the NLGS: the
//! plate is one more body of the contact problem). Stresses are the plate's contact impulses
//! per step: σ_n = R_y/(h L_x), τ = −R_x/(h L_x), averaged over the second half of the
//! strain. μ* = τ̄/σ̄_n, I = γ̇ d̄/√(σ̄_n/ρ) with γ̇ = v/H̄ (H̄: mean layer spacing).
//!
//! The sample is compacted once under p (plate speed capped, no shear), then each inertial
//! number starts from that state (points run in parallel, each sequential: deterministic).
//! Step per point, docs/definitions.md c.5: h = 0.02 d_min / max(v, v_floor), v_floor = 0.1
//! √(p/ρ) (the velocity fluctuations of slow dense flow), so every point takes about the
//! same number of steps per unit strain.

use crate::cd::error::CdError;
use crate::cd::params::CdParams;
use crate::cd::world::World;
use crate::dem::state::State;
use crate::math::Real;
use crate::sample::rng::SplitMix64;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Shear-test settings. Everything is UNSPEC in the chapter (docs/definitions.md SC-SHEAR-CD).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ShearCdParams {
    /// Target inertial numbers.
    pub inertial_numbers: Vec<Real>,
    /// Confining pressure p [Pa]. Rigid grains: μ*(I) does not depend on p (only I does);
    /// 1 kPa as the DEM shear test's lowest pressure.
    pub pressure: Real,
    /// Shear strain γ per point.
    pub strain: Real,
    /// Average from this fraction of `strain` on.
    pub average_from: Real,
    /// Cell width L_x in mean diameters.
    pub width: Real,
    /// Rough-layer pitch as a multiple of d̄ (1.15 as the DEM test: too narrow to pass).
    pub layer_pitch: Real,
    /// c.5 Courant-like number: h = courant · d_min / max(v, v_floor).
    pub courant: Real,
    /// v_floor / √(p/ρ).
    pub v_floor: Real,
    /// Longest compaction, in units of t_p = d̄ √(ρ/p).
    pub compaction_tp: Real,
    /// Largest free-flight displacement of the plate in one step, h² p L_x / M, as a fraction
    /// of d_min: sets the plate mass M = max(layer grains' mass, h² p L_x/(plate_drift d_min))
    /// per point. 0.005: far inside the alert distance (0.05 d_min per step), so a step of
    /// separation cannot slam the plate into the sample; at large I (small h) the plate
    /// keeps the layer's own mass and follows dilation quickly.
    pub plate_drift: Real,
    /// Fit μ = μ_min + b I over the points with I ≤ this. 0.1: above it μ(I) bends toward
    /// its saturation value (the Jop form μ_s + (μ_2 − μ_s)/(I_0/I + 1)), so a straight line
    /// through I = 0.3 would tilt and lift μ_min.
    pub fit_max_inertial_number: Real,
    /// Seed of the lattice shuffle.
    pub seed: u64,
}

impl Default for ShearCdParams {
    fn default() -> Self {
        ShearCdParams {
            inertial_numbers: vec![1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.3],
            pressure: 1e3,
            strain: 3.0,
            average_from: 0.5,
            width: 30.0,
            layer_pitch: 1.15,
            courant: 0.02,
            v_floor: 0.1,
            compaction_tp: 400.0,
            plate_drift: 0.005,
            fit_max_inertial_number: 0.1,
            seed: 5,
        }
    }
}

/// One shear point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShearCdPoint {
    /// Target I.
    pub target: Real,
    /// Measured I = γ̇ d̄/√(σ̄_n/ρ).
    pub inertial_number: Real,
    /// μ* = τ̄/σ̄_n.
    pub mu: Real,
    /// Standard error of μ* from 8 blocks of the averaging window.
    pub mu_se: Real,
    /// τ̄ [Pa].
    pub tau: Real,
    /// σ̄_n [Pa].
    pub sigma_n: Real,
    /// Plate velocity v [m/s].
    pub velocity: Real,
    /// Mean step h [s] (c.5 rule, reduced where the fastest grain needs it).
    pub dt: Real,
    /// Steps.
    pub steps: u64,
    /// Mean NLGS sweeps per step.
    pub mean_iterations: Real,
    /// Steps that hit the cap.
    pub unconverged: u64,
    /// Largest interpenetration [fraction of d].
    pub max_penetration: Real,
    /// Solid fraction of the sheared layer (mean).
    pub packing_fraction: Real,
    /// (strain, τ/σ_n) series, one sample per 0.02 strain.
    pub series: Vec<(Real, Real)>,
    /// Wall time [s].
    pub wall_s: f64,
}

/// Result of the test.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShearCdResult {
    /// Points in the order of `inertial_numbers`.
    pub points: Vec<ShearCdPoint>,
    /// Fit μ = μ_min + b I: μ_min.
    pub mu_min: Real,
    /// Fit slope b.
    pub b: Real,
    /// Standard error of μ_min.
    pub mu_min_se: Real,
    /// Standard error of b.
    pub b_se: Real,
    /// Sample grains (without the layers).
    pub grains: usize,
    /// Mean sample grain diameter d̄ [m].
    pub d_mean: Real,
    /// Compaction: packing fraction reached.
    pub compaction_packing: Real,
}

struct Cell {
    world: World,
    lx: Real,
    top_body: usize,
    bottom: Vec<usize>,
    top: Vec<usize>,
    sample: Vec<usize>,
    d_mean: Real,
    m_top: Real,
}

/// Plate mass for step `h`: max(layer mass, h² p L_x / (plate_drift d_min)).
fn set_plate_mass(c: &mut World, tb: usize, m_layer: Real, h: Real, p: Real, lx: Real, drift: Real, d_min: Real) {
    let m = m_layer.max(h * h * p * lx / (drift * d_min));
    c.bodies[tb].inv[1] = 1.0 / m;
    c.info[tb].mass = [m, m, 0.0];
}

fn mean_y(s: &State, idx: &[usize]) -> Real {
    idx.iter().map(|&i| s.y[i]).sum::<Real>() / idx.len() as Real
}

fn sample_packing(c: &Cell) -> Real {
    let s = &c.world.state;
    let h = mean_y(s, &c.top) - mean_y(s, &c.bottom);
    let area: Real = c.sample.iter().map(|&i| crate::math::PI * s.r[i] * s.r[i]).sum();
    area / (c.lx * (h - c.d_mean).max(1e-300))
}

fn build_cell(radii: &[Real], sp: &ShearCdParams, params: &CdParams) -> Result<Cell, CdError> {
    let n = radii.len();
    let d_mean = 2.0 * radii.iter().sum::<Real>() / n as Real;
    let r_max = radii.iter().cloned().fold(0.0, Real::max);
    let pitch_l = sp.layer_pitch * d_mean;
    let n_layer = (sp.width * d_mean / pitch_l).round().max(3.0) as usize;
    let lx = n_layer as Real * pitch_l;
    let rho = params.density;
    let mut s = State::with_capacity(n + 2 * n_layer);
    let r_l = 0.5 * d_mean;
    let mut bottom = Vec::new();
    for k in 0..n_layer {
        bottom.push(s.insert((k as Real + 0.5) * pitch_l, r_l, r_l, rho).0 as usize);
    }
    let mut rng = SplitMix64(sp.seed);
    let mut order: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        let j = ((rng.next_f64() * (i + 1) as Real) as usize).min(i);
        order.swap(i, j);
    }
    let pitch = 2.0 * r_max * 1.02;
    let per_row = ((lx / pitch).floor() as usize).max(1);
    let y0 = 2.0 * r_l + r_max * 1.02;
    let mut y_top: Real = 0.0;
    let mut sample = Vec::new();
    for (k, &g) in order.iter().enumerate() {
        let (row, col) = (k / per_row, k % per_row);
        let x = (col as Real + 0.5 + 0.25 * (row % 2) as Real) * pitch;
        let y = y0 + row as Real * pitch;
        sample.push(s.insert(x % lx, y, radii[g], rho).0 as usize);
        y_top = y_top.max(y + radii[g]);
    }
    let mut top = Vec::new();
    for k in 0..n_layer {
        top.push(s.insert((k as Real + 0.5) * pitch_l, y_top + 1.02 * r_l, r_l, rho).0 as usize);
    }
    let m_top: Real = top.iter().map(|&i| s.m[i]).sum();
    let m_bot: Real = bottom.iter().map(|&i| s.m[i]).sum();
    let mut p = params.clone();
    p.gravity = 0.0;
    let mut world = World::new(p, s, vec![], Some(lx))?;
    world.energy_check = false; // the plate's work and the imposed shear inject energy by design
    world.add_clump(&bottom, [0.0; 3], [m_bot, m_bot, 0.0], [0.0; 3], [0.0; 3]);
    let top_body = world.add_clump(
        &top,
        [0.0, 1.0 / m_top, 0.0],
        [m_top, m_top, 0.0],
        [0.0, -sp.pressure * lx, 0.0],
        [0.0; 3],
    );
    Ok(Cell {
        world,
        lx,
        top_body,
        bottom,
        top,
        sample,
        d_mean,
        m_top,
    })
}

/// Compact under p with the plate speed capped at `v_cap` until σ_n ≈ p (±2 % over 50
/// steps) with the plate at rest, or `t_max` has passed.
fn compact(c: &mut Cell, p: Real, v_cap: Real, t_max: Real) -> Result<(), CdError> {
    let h = c.world.params.dt;
    let tb = c.top_body;
    let mut t = 0.0;
    loop {
        let mut ry = 0.0;
        for _ in 0..50 {
            c.world.bodies[tb].v[0] = 0.0;
            c.world.adapt_dt(h);
            c.world.step()?;
            ry += c.world.reaction[tb][1];
            let vy = &mut c.world.bodies[tb].v[1];
            *vy = vy.clamp(-v_cap, v_cap);
        }
        t += 50.0 * h;
        let sig = ry / (50.0 * h * c.lx); // (adapted steps are shorter: σ_n under-read, never early exit)
        if ((sig - p).abs() < 0.02 * p && c.world.bodies[tb].v[1].abs() < 0.01 * v_cap) || t >= t_max {
            return Ok(());
        }
    }
}

fn shear_point(base: &Cell, target: Real, sp: &ShearCdParams, rho: Real, d_min: Real) -> Result<ShearCdPoint, CdError> {
    let started = Instant::now();
    let p = sp.pressure;
    let sq = (p / rho).sqrt();
    let mut world = base.world.clone();
    let tb = base.top_body;
    let h0 = mean_y(&world.state, &base.top) - mean_y(&world.state, &base.bottom);
    let gdot = target * sq / base.d_mean;
    let v = gdot * h0;
    let h_rule = sp.courant * d_min / v.max(sp.v_floor * sq);
    set_plate_mass(&mut world, tb, base.m_top, h_rule, p, base.lx, sp.plate_drift, d_min);
    world.stats = Default::default();
    let (t_end, t_avg) = (sp.strain / gdot, sp.average_from * sp.strain / gdot);
    let t_sample = 0.02 / gdot;
    let mut series = Vec::new();
    let (mut sx, mut sy, mut st_avg, mut sh, mut sphi, mut nsh) = (0.0, 0.0, 0.0, 0.0, 0.0, 0u64);
    let mut blocks: Vec<(Real, Real)> = Vec::new();
    let t_block = (t_end - t_avg) / 8.0;
    let (mut bx, mut by, mut bt) = (0.0, 0.0, 0.0);
    let (mut wx, mut wy, mut next_sample) = (0.0, 0.0, t_sample);
    let mut t = 0.0;
    let area: Real = base
        .sample
        .iter()
        .map(|&i| crate::math::PI * base.world.state.r[i].powi(2))
        .sum();
    while t < t_end {
        world.bodies[tb].v[0] = v;
        let h = world.adapt_dt(h_rule.min(t_end - t).max(1e-12 * h_rule));
        world.step()?;
        t += h;
        let r = world.reaction[tb];
        wx += r[0];
        wy += r[1];
        if t >= next_sample {
            series.push((t * gdot, if wy > 0.0 { -wx / wy } else { Real::NAN }));
            wx = 0.0;
            wy = 0.0;
            next_sample += t_sample;
            if t > t_avg {
                let s = &world.state;
                let hh = mean_y(s, &base.top) - mean_y(s, &base.bottom);
                sh += hh;
                sphi += area / (base.lx * (hh - base.d_mean));
                nsh += 1;
            }
        }
        if t > t_avg {
            sx += r[0];
            sy += r[1];
            st_avg += h;
            bx += r[0];
            by += r[1];
            bt += h;
            if bt >= t_block {
                blocks.push((bx, by));
                bx = 0.0;
                by = 0.0;
                bt = 0.0;
            }
        }
    }
    let tau = -sx / (st_avg * base.lx);
    let sigma_n = sy / (st_avg * base.lx);
    let h_mean = if nsh > 0 { sh / nsh as Real } else { h0 };
    let mu = tau / sigma_n;
    let mus: Vec<Real> = blocks.iter().filter(|b| b.1 > 0.0).map(|b| -b.0 / b.1).collect();
    let mu_se = if mus.len() >= 2 {
        let m = mus.iter().sum::<Real>() / mus.len() as Real;
        (mus.iter().map(|x| (x - m).powi(2)).sum::<Real>() / ((mus.len() - 1) * mus.len()) as Real).sqrt()
    } else {
        Real::NAN
    };
    let st = world.stats;
    Ok(ShearCdPoint {
        target,
        inertial_number: (v / h_mean) * base.d_mean / (sigma_n.max(1e-300) / rho).sqrt(),
        mu,
        mu_se,
        tau,
        sigma_n,
        velocity: v,
        dt: t / st.steps.max(1) as Real,
        steps: st.steps,
        mean_iterations: st.iterations as Real / st.steps.max(1) as Real,
        unconverged: st.unconverged,
        max_penetration: st.max_penetration,
        packing_fraction: if nsh > 0 { sphi / nsh as Real } else { Real::NAN },
        series,
        wall_s: started.elapsed().as_secs_f64(),
    })
}

/// Weighted least squares μ = a + b I with standard errors (weights 1; scatter from
/// residuals).
pub fn fit_linear(x: &[Real], y: &[Real]) -> (Real, Real, Real, Real) {
    let n = x.len() as Real;
    let mx = x.iter().sum::<Real>() / n;
    let my = y.iter().sum::<Real>() / n;
    let sxx: Real = x.iter().map(|v| (v - mx).powi(2)).sum();
    let sxy: Real = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let b = sxy / sxx;
    let a = my - b * mx;
    if x.len() < 3 {
        return (a, b, Real::NAN, Real::NAN);
    }
    let s2 = x.iter().zip(y).map(|(u, v)| (v - a - b * u).powi(2)).sum::<Real>() / (n - 2.0);
    let b_se = (s2 / sxx).sqrt();
    let a_se = (s2 * (1.0 / n + mx * mx / sxx)).sqrt();
    (a, b, a_se, b_se)
}

/// Run the test on `radii` (sample grains) with solver `params` (its `dt` is replaced per
/// point by the c.5 rule; gravity is switched off).
pub fn shear_test(radii: &[Real], params: &CdParams, sp: &ShearCdParams) -> Result<ShearCdResult, CdError> {
    if radii.len() < 20 || sp.inertial_numbers.is_empty() {
        return Err(CdError::Setup(
            "the CD shear test needs ≥ 20 grains and at least one inertial number".into(),
        ));
    }
    let rho = params.density;
    let sq = (sp.pressure / rho).sqrt();
    let d_min = 2.0 * radii.iter().cloned().fold(Real::INFINITY, Real::min);
    let v_floor = sp.v_floor * sq;
    let mut p = params.clone();
    p.dt = sp.courant * d_min / v_floor;
    let mut cell = build_cell(radii, sp, &p)?;
    let t_p = cell.d_mean / sq;
    let v_cap = 0.5 * p.alert_fraction * d_min / (2.0 * p.dt);
    let tb = cell.top_body;
    set_plate_mass(
        &mut cell.world, tb, cell.m_top, p.dt, sp.pressure, cell.lx, sp.plate_drift, d_min,
    );
    compact(&mut cell, sp.pressure, v_cap.min(v_floor), sp.compaction_tp * t_p)?;
    let compaction_packing = sample_packing(&cell);
    cell.world.stats = Default::default();
    let points: Vec<ShearCdPoint> = sp
        .inertial_numbers
        .par_iter()
        .map(|&i| shear_point(&cell, i, sp, rho, d_min))
        .collect::<Result<Vec<_>, _>>()?;
    let fit: Vec<&ShearCdPoint> = points
        .iter()
        .filter(|q| q.inertial_number <= sp.fit_max_inertial_number * 1.05)
        .collect();
    let fit = if fit.len() >= 2 { fit } else { points.iter().collect() };
    let xs: Vec<Real> = fit.iter().map(|q| q.inertial_number).collect();
    let ys: Vec<Real> = fit.iter().map(|q| q.mu).collect();
    let (mu_min, b, mu_min_se, b_se) = fit_linear(&xs, &ys);
    Ok(ShearCdResult {
        points,
        mu_min,
        b,
        mu_min_se,
        b_se,
        grains: radii.len(),
        d_mean: cell.d_mean,
        compaction_packing,
    })
}

//! Method-agnostic analysis of a pile under horizontal excitation (docs/definitions.md D01,
//! D10–D16, D19, D21): the initial velocity field, the sampled time series every solver
//! records, the stopping rule, and the per-run summary (run-out, duration, transient and
//! decay times).
//!
//! Units: SI inside; the summary also carries the chapter's pile units — lengths / d,
//! times / √(d/g), energies / (m g d) per grain — with d = 2.455 mm, m = 0.0123 kg (D21).

use serde::{Deserialize, Serialize};

use crate::analysis::front::stop_time;

/// The chapter's pile length unit d [m] (D21).
pub const D_NORM: f64 = 2.455e-3;
/// The chapter's grain mass m [kg per m of thickness] (D21).
pub const M_NORM: f64 = 0.0123;
/// End of the transient, t_1 = 7.5 √(d/g) (D12, the chapter's fixed value).
pub const T1_UNITS: f64 = 7.5;

/// Initial velocity profile (D19).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Profile {
    /// v_x = k (y_max − y), largest at the base, zero at the top.
    Gradient,
    /// v_x = V_0 everywhere.
    Uniform,
}

impl Profile {
    /// Name used in tables and captions.
    pub fn name(self) -> &'static str {
        match self {
            Profile::Gradient => "gradient",
            Profile::Uniform => "uniform",
        }
    }
}

/// Horizontal velocities giving Σ ½ m v_x² = `e0` exactly (D19). `y` are centres, `top`
/// the highest body edge (y_max = max(y + half), the edge: D19 leaves centre/edge open).
pub fn excitation(profile: Profile, y: &[f64], m: &[f64], top: f64, e0: f64) -> Vec<f64> {
    let shape: Vec<f64> = match profile {
        Profile::Gradient => y.iter().map(|&yy| (top - yy).max(0.0)).collect(),
        Profile::Uniform => vec![1.0; y.len()],
    };
    let s2: f64 = shape.iter().zip(m).map(|(s, mm)| mm * s * s).sum();
    let k = if s2 > 0.0 { (2.0 * e0 / s2).sqrt() } else { 0.0 };
    shape.iter().map(|s| k * s).collect()
}

/// Σ ½ m v² of a velocity list.
pub fn kinetic(m: &[f64], v: &[f64]) -> f64 {
    m.iter().zip(v).map(|(mm, vv)| 0.5 * mm * vv * vv).sum()
}

/// One sample of a pile run (SI).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// Time since the excitation [s].
    pub t: f64,
    /// Front L (D01) [m].
    pub l: f64,
    /// Height H (D03) [m].
    pub h: f64,
    /// E_k = E_kx + E_ky [J/m].
    pub ek: f64,
    /// ½ Σ m v_x² [J/m].
    pub ekx: f64,
    /// ½ Σ m v_y² [J/m].
    pub eky: f64,
    /// ½ Σ I ω² (grains; 0 for MPM) [J/m].
    pub erot: f64,
}

/// When a pile run stops (docs/definitions.md SC-PILE: "E_k < 1e-4 E_0 and L unchanged for
/// 10 √(d/g)"), in the chapter's units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StopRule {
    /// Sampling interval [√(d/g)].
    pub sample_every: f64,
    /// Never stop before [√(d/g)].
    pub t_min: f64,
    /// Hard end [√(d/g)]; reaching it leaves the run "not stopped" (reported).
    pub t_max: f64,
    /// E_k + E_rot below this fraction of E_0 …
    pub ek_ratio: f64,
    /// … and the front within `still_tol` d over the last `still_time` √(d/g).
    pub still_time: f64,
    /// See `still_time` [d].
    pub still_tol: f64,
}

impl Default for StopRule {
    fn default() -> Self {
        StopRule {
            sample_every: 0.25,
            t_min: 20.0,
            t_max: 250.0,
            ek_ratio: 1e-4,
            still_time: 10.0,
            still_tol: 0.5,
        }
    }
}

impl StopRule {
    /// Whether the run may stop after `samples` (SI), with initial energy `e0` [J/m].
    pub fn done(&self, samples: &[Sample], e0: f64, g: f64) -> bool {
        let tu = (D_NORM / g).sqrt();
        let Some(last) = samples.last() else { return false };
        if last.t < self.t_min * tu || last.ek + last.erot >= self.ek_ratio * e0 {
            return false;
        }
        let t0 = last.t - self.still_time * tu;
        if samples[0].t > t0 {
            return false;
        }
        samples
            .iter()
            .rev()
            .take_while(|s| s.t >= t0)
            .all(|s| (s.l - last.l).abs() <= self.still_tol * D_NORM)
    }
    /// Hard end reached.
    pub fn expired(&self, t: f64, g: f64) -> bool {
        t >= self.t_max * (D_NORM / g).sqrt()
    }
    /// Sampling interval [s].
    pub fn dt_sample(&self, g: f64) -> f64 {
        self.sample_every * (D_NORM / g).sqrt()
    }
}

/// Per-run results in the chapter's units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Input energy [mgd per grain].
    pub e0_mgd: f64,
    /// Input energy [J/m].
    pub e0_j: f64,
    /// Σ ½ m v_x² at t = 0 over E_0 (fig4-24 check: 1).
    pub e0_check: f64,
    /// L_0 [d].
    pub l0: f64,
    /// L_f [d].
    pub lf: f64,
    /// ΔL = (L_f − L_0)/L_0 (D02).
    pub dl: f64,
    /// t_f [√(d/g)] (D10, tolerance 0.5 d).
    pub tf: f64,
    /// v_s = (L_f − L_0)/t_f [√(gd)] (D11).
    pub vs: f64,
    /// E'_kx0 = E_kx(t_1) [mgd per grain] (D13).
    pub ekx0: f64,
    /// τ: E_kx(t_1 + τ) = ½ E'_kx0 [√(d/g)] (D14; NaN if never).
    pub tau: f64,
    /// t'_f = t_f − t_1 [√(d/g)] (D15).
    pub tfp: f64,
    /// Peak of E_ky/E_0 (fig 4.37).
    pub eky_peak: f64,
    /// Whether the stopping rule was met (else the hard end).
    pub stopped: f64,
    /// Simulated time [√(d/g)].
    pub t_end: f64,
}

/// Linear interpolation of `v` at time `t` in sampled (t, v).
pub fn interp(ts: &[f64], vs: &[f64], t: f64) -> f64 {
    if ts.is_empty() {
        return f64::NAN;
    }
    if t <= ts[0] {
        return vs[0];
    }
    for k in 1..ts.len() {
        if ts[k] >= t {
            let f = (t - ts[k - 1]) / (ts[k] - ts[k - 1]).max(1e-300);
            return vs[k - 1] + f * (vs[k] - vs[k - 1]);
        }
    }
    *vs.last().unwrap()
}

/// First time after `t_start` at which `v` falls to `level` (linear interpolation).
pub fn first_crossing(ts: &[f64], vs: &[f64], t_start: f64, level: f64) -> f64 {
    for k in 1..ts.len() {
        if ts[k] <= t_start {
            continue;
        }
        if vs[k] <= level {
            let (t0, v0) = if ts[k - 1] < t_start {
                (t_start, interp(ts, vs, t_start))
            } else {
                (ts[k - 1], vs[k - 1])
            };
            let f = if (v0 - vs[k]).abs() > 0.0 {
                (v0 - level) / (v0 - vs[k])
            } else {
                0.0
            };
            return t0 + f.clamp(0.0, 1.0) * (ts[k] - t0);
        }
    }
    f64::NAN
}

/// Summarise a run: `samples` (SI), L_0 [m], E_0 [J/m], the energy unit (M g d for the
/// whole pile: N m g d for grains, M_total g d for MPM) [J/m], the initial check ratio.
pub fn summarise(samples: &[Sample], l0: f64, e0: f64, unit_j: f64, e0_check: f64, stopped: bool, g: f64) -> Summary {
    let tu = (D_NORM / g).sqrt();
    let t: Vec<f64> = samples.iter().map(|s| s.t / tu).collect();
    let l: Vec<f64> = samples.iter().map(|s| s.l / D_NORM).collect();
    let ekx: Vec<f64> = samples.iter().map(|s| s.ekx / unit_j).collect();
    let lf = l.last().copied().unwrap_or(f64::NAN);
    let l0d = l0 / D_NORM;
    let tf = stop_time(&t, &l, 0.5);
    let ekx0 = interp(&t, &ekx, T1_UNITS);
    let tau = first_crossing(&t, &ekx, T1_UNITS, 0.5 * ekx0) - T1_UNITS;
    let eky_peak = samples.iter().map(|s| s.eky / e0).fold(0.0, f64::max);
    Summary {
        e0_mgd: e0 / unit_j,
        e0_j: e0,
        e0_check,
        l0: l0d,
        lf,
        dl: (lf - l0d) / l0d,
        tf,
        vs: if tf > 0.0 { (lf - l0d) / tf } else { f64::NAN },
        ekx0,
        tau,
        tfp: tf - T1_UNITS,
        eky_peak,
        stopped: if stopped { 1.0 } else { 0.0 },
        t_end: t.last().copied().unwrap_or(0.0),
    }
}

/// Free-surface profile of a set of round bodies: the highest top edge per bin of width
/// `bin` from x = 0 to `l` (NaN for empty bins), as (bin centre, top).
pub fn surface_profile(x: &[f64], y: &[f64], half: &[f64], l: f64, bin: f64) -> Vec<(f64, f64)> {
    let nb = ((l / bin).ceil() as usize).max(1);
    let mut top = vec![f64::NAN; nb];
    for i in 0..x.len() {
        if x[i] > l || x[i] < 0.0 {
            continue;
        }
        let b = ((x[i] / bin) as usize).min(nb - 1);
        let v = y[i] + half[i];
        if !(top[b] >= v) {
            top[b] = v;
        }
    }
    (0..nb).map(|b| ((b as f64 + 0.5) * bin, top[b])).collect()
}

/// Surface angle [deg]: least-squares line through the profile points with x in
/// [`from`, `to`]·L (the inclined part: away from the wall corner and the thin toe).
pub fn slope_deg(profile: &[(f64, f64)], l: f64, from: f64, to: f64) -> f64 {
    let pts: Vec<(f64, f64)> = profile
        .iter()
        .cloned()
        .filter(|&(x, y)| y.is_finite() && x >= from * l && x <= to * l)
        .collect();
    if pts.len() < 2 {
        return f64::NAN;
    }
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let cov: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let var: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    (-cov / var).atan().to_degrees()
}

/// Packing fraction under the free surface (D09 global): solid area of the bodies left of
/// `l` over the area under the profile.
pub fn envelope_packing(profile: &[(f64, f64)], bin: f64, solid_area: f64) -> f64 {
    let area: f64 = profile.iter().filter(|p| p.1.is_finite()).map(|p| p.1 * bin).sum();
    if area > 0.0 { solid_area / area } else { f64::NAN }
}

/// Height of the profile at `x` (linear interpolation between bin centres, 0 beyond `l`).
pub fn surface_at(profile: &[(f64, f64)], x: f64, l: f64) -> f64 {
    if x > l || x < 0.0 {
        return 0.0;
    }
    let pts: Vec<(f64, f64)> = profile.iter().cloned().filter(|p| p.1.is_finite()).collect();
    if pts.is_empty() {
        return 0.0;
    }
    let ts: Vec<f64> = pts.iter().map(|p| p.0).collect();
    let vs: Vec<f64> = pts.iter().map(|p| p.1).collect();
    interp(&ts, &vs, x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn excitation_carries_exactly_e0() {
        let y = [0.1, 0.5, 0.9, 1.3];
        let m = [1.0, 2.0, 0.5, 1.5];
        for p in [Profile::Gradient, Profile::Uniform] {
            let v = excitation(p, &y, &m, 1.5, 7.0);
            assert!((kinetic(&m, &v) - 7.0).abs() < 1e-12);
        }
        // gradient: the top-most body is slowest, the profile is linear in y
        let v = excitation(Profile::Gradient, &y, &m, 1.5, 7.0);
        assert!(v[0] > v[1] && v[1] > v[2] && v[2] > v[3]);
        assert!(((v[0] - v[1]) / 0.4 - (v[2] - v[3]) / 0.4).abs() < 1e-12);
    }

    #[test]
    fn decay_time_is_the_half_life() {
        // E_kx = exp(−ln2 t'/τ) after t_1 with τ = 10 √(d/g): summarise must find τ = 10.
        let g = 9.81;
        let tu = (D_NORM / g).sqrt();
        let samples: Vec<Sample> = (0..2000)
            .map(|k| {
                let t = 0.05 * k as f64;
                let e = if t < T1_UNITS {
                    1.0
                } else {
                    (-(2f64.ln()) * (t - T1_UNITS) / 10.0).exp()
                };
                Sample {
                    t: t * tu,
                    l: D_NORM * (10.0 + t.min(40.0)),
                    h: 0.0,
                    ek: e,
                    ekx: e,
                    eky: 0.0,
                    erot: 0.0,
                }
            })
            .collect();
        let s = summarise(&samples, 10.0 * D_NORM, 1.0, 1.0, 1.0, true, g);
        assert!((s.tau - 10.0).abs() < 1e-3, "τ = {}", s.tau);
        assert!((s.ekx0 - 1.0).abs() < 1e-12);
        assert!((s.tf - 39.5).abs() < 0.06, "t_f = {}", s.tf);
        assert!((s.dl - 4.0).abs() < 1e-9);
    }

    #[test]
    fn slope_of_a_right_triangle() {
        // grains of radius 0 on the line y = 0.25 (1 − x)
        let x: Vec<f64> = (0..100).map(|i| i as f64 * 0.01).collect();
        let y: Vec<f64> = x.iter().map(|x| 0.25 * (1.0 - x)).collect();
        let h = vec![0.0; 100];
        let p = surface_profile(&x, &y, &h, 1.0, 0.05);
        let a = slope_deg(&p, 1.0, 0.2, 0.8);
        assert!((a - 0.25f64.atan().to_degrees()).abs() < 0.8, "slope {a}");
    }
}

/// One sample of a grain state (DEM or CD pile, both on `dem::State`): D01 front and height
/// with the given link, translational kinetic energy by component and the rotational one.
pub fn grain_sample(t: f64, st: &crate::dem::state::State, link: crate::analysis::front::Link) -> Sample {
    use crate::analysis::front::{Body, front};
    let f = front(
        &Body {
            x: &st.x,
            y: &st.y,
            half: &st.r,
            mass: &st.m,
        },
        link,
    );
    let ekx = kinetic(&st.m, &st.vx);
    let eky = kinetic(&st.m, &st.vy);
    let erot: f64 = (0..st.len()).map(|i| 0.5 * st.inertia[i] * st.w[i] * st.w[i]).sum();
    Sample {
        t,
        l: f.length,
        h: f.height,
        ek: ekx + eky,
        ekx,
        eky,
        erot,
    }
}

/// A finished pile run (any method).
#[derive(Debug, Clone)]
pub struct PileRun {
    /// Time series.
    pub samples: Vec<Sample>,
    /// L_0 of the run's own measure [m].
    pub l0: f64,
    /// Input energy [J/m].
    pub e0: f64,
    /// Σ ½ m v_x² at t = 0 / E_0.
    pub e0_check: f64,
    /// Whether the stopping rule ended the run.
    pub stopped: bool,
    /// Steps taken.
    pub steps: u64,
    /// Final body positions and half-sizes (x, y, half) for snapshots.
    pub final_bodies: (Vec<f64>, Vec<f64>, Vec<f64>),
    /// Frames at the requested instants (empty unless asked for).
    pub frames: Vec<Frame>,
}

// ---------------------------------------------------------------------------------------
// Snapshots of a pile run (figs 4.24, 4.31, 4.32, 4.42, 4.43): taken only when a stage asks.

/// The bodies of a pile run at one instant (DEM/CD grains or MPM points), SI.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Frame {
    /// Time since the excitation [s].
    pub t: f64,
    /// Centres x [m].
    pub x: Vec<f64>,
    /// Centres y [m].
    pub y: Vec<f64>,
    /// Radius (grains) or domain half-width (points) [m].
    pub half: Vec<f64>,
    /// Velocity x [m/s].
    pub vx: Vec<f64>,
    /// Velocity y [m/s].
    pub vy: Vec<f64>,
    /// Vertical stress σ_yy [Pa] (MPM points; empty for grains).
    pub sigma_yy: Vec<f64>,
}

/// When to take frames: times [s], ascending. `due(k, t)` tells whether frame `k` is due
/// at the sample instant `t` (snapshot times are multiples of the sampling interval, so
/// frames are taken at sample instants and the trajectory is the one without frames).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameTimes {
    /// Instants [s].
    pub times: Vec<f64>,
    /// End the run once every frame is taken (a frames-only run: its summary is partial).
    pub end_after_last: bool,
}

impl FrameTimes {
    /// Next frame index still to take, if due at `t` (half a sampling interval `dts` of slack).
    pub fn due(&self, taken: usize, t: f64, dts: f64) -> bool {
        self.times.get(taken).is_some_and(|&tk| t >= tk - 0.5 * dts)
    }
    /// Whether every frame has been taken.
    pub fn all_taken(&self, taken: usize) -> bool {
        taken >= self.times.len()
    }
    /// Whether a frames-only run may end now.
    pub fn ends(&self, taken: usize) -> bool {
        self.end_after_last && !self.times.is_empty() && self.all_taken(taken)
    }
}

/// A pile run's samples and frames, and whether it met the stopping rule.
pub struct Sampled {
    /// One sample every `stop.sample_every`, from t = 0.
    pub samples: Vec<Sample>,
    /// The frames taken.
    pub frames: Vec<Frame>,
    /// Whether the rule stopped it (false: t_max, or a frames-only run's last frame).
    pub stopped: bool,
}

/// The sampling loop every pile run shares, whatever the solver (DEM, CD, MPM): record at
/// t = 0, then `advance` to each next sample instant and record, take the frames that are
/// due, stop by the rule once every frame is taken — or at t_max, or after the last frame
/// of a frames-only run.
#[allow(clippy::too_many_arguments)]
pub fn sample_run<S, E>(
    s: &mut S,
    stop: &StopRule,
    frames: &FrameTimes,
    e0: f64,
    g: f64,
    time: impl Fn(&S) -> f64,
    rec: impl Fn(&S) -> Sample,
    frame: impl Fn(&S) -> Frame,
    mut advance: impl FnMut(&mut S) -> Result<(), E>,
) -> Result<Sampled, E> {
    let dts = stop.dt_sample(g);
    let mut samples = vec![rec(s)];
    let mut shots = Vec::new();
    if frames.due(0, time(s), dts) {
        shots.push(frame(s));
    }
    let mut stopped = false;
    loop {
        advance(s)?;
        samples.push(rec(s));
        if frames.due(shots.len(), time(s), dts) {
            shots.push(frame(s));
        }
        if stop.done(&samples, e0, g) && frames.all_taken(shots.len()) {
            stopped = true;
            break;
        }
        if frames.ends(shots.len()) || stop.expired(time(s), g) {
            break;
        }
    }
    Ok(Sampled {
        samples,
        frames: shots,
        stopped,
    })
}

/// Cavity behind the mass next to the left wall (figs 4.31, 4.42; docs/definitions.md
/// fig4-31: "empty cells of the pile envelope next to x = 0"), as an area [m²]: with the
/// free-surface profile top(x) (highest body edge per bin of width `bin`, 0 for empty bins)
/// over x ∈ [0, l], the envelope E(x) = max_{x' ≥ x} top(x') is the surface seen from the
/// right; the cavity is Σ (E − top)·bin over the bins left of the highest point. A pile
/// falling away from the wall (monotone surface) has none; a mass pushed away from the wall
/// leaves one. Only bodies touching another body or the base count (a grain in flight,
/// ahead of or above the mass, would otherwise raise the envelope over empty air); `extra`
/// [m] widens "touching" (MPM: points sharing grid nodes are one continuum).
pub fn cavity_area(x: &[f64], y: &[f64], half: &[f64], l: f64, bin: f64, extra: f64) -> f64 {
    let keep = touching(x, y, half, extra);
    let pick = |v: &[f64]| -> Vec<f64> { v.iter().zip(&keep).filter(|(_, k)| **k).map(|(a, _)| *a).collect() };
    let prof = surface_profile(&pick(x), &pick(y), &pick(half), l, bin);
    let top: Vec<f64> = prof.iter().map(|p| if p.1.is_finite() { p.1 } else { 0.0 }).collect();
    let Some(peak) = (0..top.len()).max_by(|&a, &b| top[a].total_cmp(&top[b]).then(b.cmp(&a))) else {
        return 0.0;
    };
    let mut env = 0.0f64;
    let mut area = 0.0;
    for b in (0..peak).rev() {
        env = env.max(top[b + 1]);
        area += (env - top[b]).max(0.0) * bin;
    }
    area
}

/// Whether each body touches the base (y − half within 5 % of half) or another body (centre
/// distance within 1.1 × the sum of the halves + `extra`: contacts of soft and rigid
/// grains, and the adjoining domains of material points).
pub fn touching(x: &[f64], y: &[f64], half: &[f64], extra: f64) -> Vec<bool> {
    let n = x.len();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| x[a].total_cmp(&x[b]).then(a.cmp(&b)));
    let hmax = half.iter().cloned().fold(0.0, f64::max);
    let mut out: Vec<bool> = (0..n).map(|i| y[i] - half[i] <= 0.05 * half[i]).collect();
    for (k, &i) in order.iter().enumerate() {
        if out[i] {
            continue;
        }
        let reach = 1.1 * (half[i] + hmax) + extra;
        let near = |j: usize| j != i && (x[j] - x[i]).hypot(y[j] - y[i]) <= 1.1 * (half[i] + half[j]) + extra;
        let fwd = order[k + 1..]
            .iter()
            .take_while(|&&j| x[j] - x[i] <= reach)
            .any(|&j| near(j));
        let back = order[..k]
            .iter()
            .rev()
            .take_while(|&&j| x[i] - x[j] <= reach)
            .any(|&j| near(j));
        out[i] = fwd || back;
    }
    out
}

/// Smallest gap between a body and the left wall x = 0, min(x − half) [m] (figs 4.31:
/// "the granular heap remains in contact with the left wall irrespective of the input energy").
pub fn wall_gap(x: &[f64], half: &[f64]) -> f64 {
    x.iter().zip(half).map(|(x, h)| x - h).fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod frame_tests {
    use super::*;

    #[test]
    fn cavity_of_a_monotone_pile_is_zero_and_of_a_dent_its_area() {
        // right-triangle pile against the wall: no cavity
        let mut x = Vec::new();
        let mut y = Vec::new();
        for i in 0..50 {
            for j in 0..(50 - i) {
                x.push(0.5 + i as f64);
                y.push(0.5 + j as f64 * 0.5);
            }
        }
        let h = vec![0.5; x.len()];
        assert_eq!(cavity_area(&x, &y, &h, 50.0, 1.0, 0.0), 0.0);
        // keep only the two bottom bodies (y = 0.5, 1.0: top 1.5) of the first 10 columns:
        // a dent 10 bins wide up to column 10's top 25.5 − 0.5·10 = 20.5
        let keep: Vec<usize> = (0..x.len()).filter(|&k| x[k] > 10.0 || y[k] <= 1.0).collect();
        let (x2, y2, h2): (Vec<f64>, Vec<f64>, Vec<f64>) = (
            keep.iter().map(|&k| x[k]).collect(),
            keep.iter().map(|&k| y[k]).collect(),
            keep.iter().map(|&k| h[k]).collect(),
        );
        let a = cavity_area(&x2, &y2, &h2, 50.0, 1.0, 0.0);
        assert!((a - 10.0 * (20.5 - 1.5)).abs() < 1e-9, "cavity {a}");
        assert!((wall_gap(&x2, &h2) - 0.0).abs() < 1e-12);
        // a grain in flight far above the wall corner does not make a cavity
        let (mut x3, mut y3, mut h3) = (x.clone(), y.clone(), h.clone());
        x3.push(30.5);
        y3.push(80.0);
        h3.push(0.5);
        assert_eq!(cavity_area(&x3, &y3, &h3, 50.0, 1.0, 0.0), 0.0);
        assert_eq!(touching(&x3, &y3, &h3, 0.0).iter().filter(|t| !**t).count(), 1);
    }

    #[test]
    fn frames_are_due_at_their_sample_instants_only() {
        let ft = FrameTimes {
            times: vec![0.0, 2.5],
            end_after_last: true,
        };
        assert!(ft.due(0, 0.0, 0.25));
        assert!(!ft.due(1, 2.25, 0.25));
        assert!(ft.due(1, 2.5, 0.25));
        assert!(ft.all_taken(2) && !ft.all_taken(1) && ft.ends(2) && !ft.ends(1));
        assert!(!FrameTimes::default().ends(0));
    }

    #[test]
    fn uniform_excitation_gives_every_body_the_same_v0() {
        let y = [0.1, 0.5, 0.9];
        let m = [1.0, 2.0, 3.0];
        let v = excitation(Profile::Uniform, &y, &m, 1.0, 3.0);
        // V_0 = √(2E_0/M) = √(6/6) = 1
        for vv in &v {
            assert!((vv - 1.0).abs() < 1e-15);
        }
    }
}

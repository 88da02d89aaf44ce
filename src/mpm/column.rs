//! Granular column collapse with MPM (docs/definitions.md SC-COL, COL-MPM-MC/-MUI; fig4-04).
//!
//! Geometry: the DEM column size (I11): area A = 3.9e-3 m², L_0 = √(A/a), H_0 = a L_0; L_0 is
//! snapped to whole cells (the gate must be a grid line) and H_0 = a L_0 to whole point
//! spacings (a = 1: 62.4 → 62.0 mm; a = 0.4: 98.7 × 39.5 → 98.0 × 39.0 mm). The actual values
//! are returned and must be used for normalisation. Left wall at x = 0 and base at
//! y = 0, both Coulomb with `wall_friction`; the gate is a frictionless roller at x = L_0 during
//! the geostatic stage, removed instantaneously at t = 0.
//! Background grid: from x = 0 to L_0 (1 + 3 ΔL_est) + 8h where ΔL_est = 1.67a (a ≤ 2.7) or
//! 2.7a^{2/3} (eq 4.6), and from y = 0 to 1.25 H_0 + 4h, plus ghost cells ("the extent of the
//! background mesh in MPM is much larger than the initial column").
//!
//! Front (D01): `run.front_rule` (the gathered length, or the right edge of the main mass
//! by the links of [`super::column_front`]); H = max(y + l_p) of the main mass.

use super::boundary;
pub use super::column_front::{front_linked, front_of, front_of_dilated, mass_quantile_x};
use super::energy::{Energies, energies};
use super::error::MpmError;
use super::geostatic::{self, GeostaticReport};
use super::grid::Grid;
use super::params::MpmParams;
use super::particles::{self, Point};
use super::solver::{PhaseTimes, Solver};
use super::state::State;
use super::watchdog::EnergyWatch;
use crate::analysis::cloud::Cloud;
use crate::analysis::front::{Front, Link, front, lengths_for_gaps};
use crate::analysis::gathered_front::{FrontRule, gathered_d};
use crate::analysis::inertial::{Grain, coarse_grained};
use crate::analysis::stop::{StopRule, Verdict};
use crate::analysis::thick_front::ThickRule;
use crate::math::Real;

pub use super::column_spec::{ColumnSpec, DEM_COLUMN_AREA};

/// A column ready to run: solver (walls + gate), state at rest and stress free.
#[derive(Debug, Clone)]
pub struct Column {
    /// Geometry actually discretised (snapped to whole point spacings).
    pub spec: ColumnSpec,
    /// Solver with walls and gate.
    pub solver: Solver,
    /// Points.
    pub state: State,
}

/// Discretise a column: √PPC × √PPC points per cell on the spacing lattice.
pub fn build(params: &MpmParams, spec: ColumnSpec) -> Result<Column, MpmError> {
    let mut c = crate::validate::Checker::new("column");
    c.positive("l0", spec.l0);
    c.positive("h0", spec.h0);
    if !c.issues.is_empty() {
        return Err(MpmError::InvalidParams(c.issues));
    }
    let s = params.spacing();
    let h = params.cell_size;
    // L_0 snapped to whole cells so that the gate lies on a grid line (a gate between node
    // lines lets the last partial cell bulge and spoils the geostatic field); H_0 keeps the
    // aspect ratio, snapped to whole point spacings.
    let cells = (spec.l0 / h).round().max(1.0) as usize;
    let nx = cells * params.ppc_1d() as usize;
    let ny = ((spec.aspect() * cells as Real * h) / s).round().max(1.0) as usize;
    let actual = ColumnSpec {
        l0: nx as Real * s,
        h0: ny as Real * s,
    };
    let pts = particles::rectangle(0.0, 0.0, nx, ny, s, params.material.density, 0);
    let x1 = actual.l0 * (1.0 + 3.0 * actual.runout_estimate()) + 8.0 * h;
    let y1 = 1.25 * actual.h0 + 4.0 * h;
    let grid = Grid::covering(0.0, 0.0, x1, y1, h);
    let mut walls = boundary::column_walls(params.wall_friction);
    walls.push(boundary::gate(actual.l0));
    let solver = Solver::new(params, grid, walls)?;
    Ok(Column {
        spec: actual,
        solver,
        state: State::new(pts),
    })
}

/// The geostatic a = 1 column of fig4-04.
#[derive(Debug, Clone)]
pub struct GeostaticColumn {
    /// Geometry.
    pub spec: ColumnSpec,
    /// Point x [m].
    pub x: Vec<Real>,
    /// Point y [m].
    pub y: Vec<Real>,
    /// σ_yy [Pa] (tension positive: negative in the column).
    pub sigma_yy: Vec<Real>,
    /// σ_xx [Pa].
    pub sigma_xx: Vec<Real>,
    /// Cell size [m] (grid lines at multiples of h from x = 0, y = 0).
    pub cell_size: Real,
    /// GIMP half-width l_p [m].
    pub half_width: Real,
    /// Mean σ_yy of the bottom row of points in the middle half of the base [Pa].
    pub base_sigma_yy: Real,
    /// The analytic value −ρ g (H_0 − y_row) at that row [Pa].
    pub base_sigma_yy_analytic: Real,
    /// |base − analytic| / |analytic| [-] (fig4-04 check: ≤ 2 %).
    pub base_error: Real,
    /// Geostatic stage report.
    pub report: GeostaticReport,
}

/// Build the column and load it geostatically (gate in place). Returns the column ready for
/// release (gate still present in `solver.walls`; call [`release`]).
pub fn geostatic_column(params: &MpmParams, spec: ColumnSpec) -> Result<(Column, GeostaticReport), MpmError> {
    let mut col = build(params, spec)?;
    let rep = geostatic::run(&mut col.solver, &mut col.state, col.spec.h0)?;
    Ok((col, rep))
}

/// Remove the gate (instantaneous release).
pub fn release(col: &mut Column) {
    let l0 = col.spec.l0;
    col.solver
        .walls
        .retain(|w| !(w.axis == super::params::Axis::X && w.at == l0 && !w.material_on_plus_side));
}

/// fig4-04: the a = 1 column (default size, table 4.3 parameters) after the geostatic stage.
pub fn fig4_04(params: &MpmParams) -> Result<GeostaticColumn, MpmError> {
    let (col, report) = geostatic_column(params, ColumnSpec::from_aspect(1.0))?;
    let pts = &col.state.points;
    let s = params.spacing();
    let rho_g = params.material.density * params.gravity;
    let (mut sum, mut n, mut y_row) = (0.0, 0usize, 0.0);
    for p in pts {
        if p.x.y < s && p.x.x > 0.25 * col.spec.l0 && p.x.x < 0.75 * col.spec.l0 {
            sum += p.stress.yy;
            y_row += p.x.y;
            n += 1;
        }
    }
    let base = sum / n.max(1) as Real;
    let y_row = y_row / n.max(1) as Real;
    let analytic = -rho_g * (col.spec.h0 - y_row);
    Ok(GeostaticColumn {
        spec: col.spec,
        x: pts.iter().map(|p| p.x.x).collect(),
        y: pts.iter().map(|p| p.x.y).collect(),
        sigma_yy: pts.iter().map(|p| p.stress.yy).collect(),
        sigma_xx: pts.iter().map(|p| p.stress.xx).collect(),
        cell_size: params.cell_size,
        half_width: params.half_width(),
        base_sigma_yy: base,
        base_sigma_yy_analytic: analytic,
        base_error: ((base - analytic) / analytic).abs(),
        report,
    })
}

/// When to stop a collapse run and what to record.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CollapseOptions {
    /// Sampling interval of the time series, in units of τ_c [-]. 0.02.
    pub sample_every_tau: Real,
    /// Stop when E_k,grid < `stop_ke_ratio` × E_p(0) (after `min_time_tau`) [-]. 1e-5.
    /// E_k,grid (`Energies::kinetic_grid`) ignores the FLIP point-velocity noise.
    pub stop_ke_ratio: Real,
    /// Also stop when the front is still: L and H moved less than `still_tol` over the last
    /// `still_tau` τ_c while E_k,grid < `still_ke_ratio` × E_p(0). Defaults: 1 τ_c,
    /// 0.5 d̄ = 0.575 mm (docs/definitions.md D10), 1e-3.
    pub still_tau: Real,
    /// See `still_tau` [m].
    pub still_tol: Real,
    /// See `still_tau` [-].
    pub still_ke_ratio: Real,
    /// Never stop before this time [τ_c]. 1.
    pub min_time_tau: Real,
    /// Hard end [τ_c]. 12.
    pub max_time_tau: Real,
    /// Snapshot times [τ_c] (taken at the first step at or after each).
    pub snapshot_tau: Vec<Real>,
    /// Skip the geostatic stage (start stress free; for tests).
    pub skip_geostatic: bool,
    /// Speed at which the gate is lifted, from the base up [m/s]; 0 (default): removed at
    /// once (docs/definitions.md SC-COL). An option, not the chapter's described method
    /// (issue 25, docs/mpm-start.md): while lifted, the gate holds the nodes at and right of
    /// x = L_0 above its lower edge v_g t, and is removed when that edge passes the grid top.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub gate_lift_speed: Real,
    /// The stated stop rule shared with the DEM (`crate::analysis::stop`). When set it
    /// replaces the rule above (`stop_ke_ratio` OR a still front, kept for the
    /// work-precision runs); its kinetic energy is the grid's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stop: Option<StopRule>,
    /// The thick-deposit front (`analysis::thick_front`, issue 25), an additional
    /// measurement only: reported as `runout_thick_norm` and the table
    /// `runout_by_threshold`; L(t), H(t), the run-out and the stop rule keep the links below.
    #[serde(skip_serializing_if = "ThickRule::is_default")]
    pub front: ThickRule,
    /// D01 rule of L(t), the run-out and the stop front: `links` (the main mass by the links
    /// below) or `gathered` (the gathered length over every point, bins and layer of one
    /// d̄: `analysis::gathered_front`, issue 25). H(t) and the main-mass fraction keep the
    /// links.
    #[serde(default, skip_serializing_if = "FrontRule::is_links")]
    pub front_rule: FrontRule,
    /// D01 linking gap [d̄ = material.grain_diameter]: points, as bodies of half-size l_p,
    /// are linked when their edges are within the gap (the DEM rule). None: the older
    /// 1.5 × initial spacing centre distance.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub link_gap: Option<Real>,
    /// D01 main mass through the grid: points linked when they share a background-grid
    /// node (uGIMP support h + l_p; `analysis::front::Link::SharedNode`) — the MPM's
    /// interaction, as contact is the DEM's. Replaces `link_gap` for L(t), H(t); the gap
    /// sensitivity table is still recorded. Fixes the detached-toe jumps of a film whose
    /// points drift apart by more than 2 l_p + gap inside their cells.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub link_grid: bool,
    /// Extra linking gaps [d̄] whose L(t) is recorded beside the main one.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub link_gap_sensitivity: Vec<Real>,
    /// Coarse-graining cell of the method-agnostic inertial-number statistics [d̄] (D08).
    #[serde(skip_serializing_if = "crate::analysis::inertial::is_default_cell")]
    pub inertial_cell: Real,
}

impl Default for CollapseOptions {
    fn default() -> Self {
        Self {
            sample_every_tau: 0.02,
            stop_ke_ratio: 1e-5,
            still_tau: 1.0,
            still_tol: 0.5 * 1.15e-3,
            still_ke_ratio: 1e-3,
            min_time_tau: 1.0,
            max_time_tau: 12.0,
            snapshot_tau: Vec::new(),
            skip_geostatic: false,
            gate_lift_speed: 0.0,
            stop: None,
            front: ThickRule::default(),
            front_rule: FrontRule::Links,
            link_gap: None,
            link_grid: false,
            link_gap_sensitivity: Vec::new(),
            inertial_cell: 3.0,
        }
    }
}

/// One row of the collapse time series.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Sample {
    /// Time since release [s].
    pub t: Real,
    /// Front L(t) [m] by `run.front_rule`.
    pub l: Real,
    /// The gathered length over every point (D01, `analysis::gathered_front`) [m].
    pub l_gathered: Real,
    /// Height H(t) [m].
    pub h: Real,
    /// Farthest right edge over all points, detached ones included [m] (diagnostic: the
    /// main-mass L depends on the linking distance of D01).
    pub l_all: Real,
    /// Mass fraction of the main mass [-].
    pub main_fraction: Real,
    /// L of the main mass with dilation-following links ([`front_of_dilated`]) [m].
    pub l_dilated: Real,
    /// x below which 99 % of the mass lies, plus l_p [m] (a front insensitive to linking).
    pub l_q99: Real,
    /// Energies [J/m].
    pub e: Energies,
    /// Inertial-number statistics (computed for every model as a diagnostic).
    pub inertial: InertialStats,
    /// Coarse-grained, lithostatic-pressure I statistics: the DEM's own measure (D08).
    pub inertial_cg: crate::analysis::inertial::Stats,
}

/// Inertial number I = γ̇ d̄/√(p/ρ_s) over the points at one time (docs/definitions.md D08,
/// fig4-15): γ̇ from the point's last velocity gradient, p = −tr σ/3, capped at
/// `material.i_max`. "Flowing" = γ̇ > 1e-3 √(g/d̄) and p > 0 (points at the Mohr–Coulomb
/// apex, stress free, have no defined I and are counted in `stress_free_fraction` instead).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct InertialStats {
    /// Mass-weighted mean of I over flowing points [-] (0 if none).
    pub mean_flowing: Real,
    /// 95th percentile of I over flowing points [-].
    pub p95_flowing: Real,
    /// Maximum of I over all points [-].
    pub max: Real,
    /// Mass fraction of flowing points [-].
    pub flowing_fraction: Real,
    /// Mass fraction of points with p ≤ 0 (stress free) [-].
    pub stress_free_fraction: Real,
    /// Mass-weighted median of I over flowing points [-].
    pub median_flowing: Real,
    /// Mass-weighted mean of I over flowing points with p ≥ ρ_s g d̄ (at least about one
    /// grain of overburden: the surface layer, where p → 0 and I → i_max, left out) [-].
    pub mean_flowing_deep: Real,
}

/// Inertial number of every point (diagnostic; the μ(I) models compute the same inside the
/// step) [-].
pub fn inertial_numbers(state: &State, m: &super::params::Material) -> Vec<Real> {
    state
        .points
        .iter()
        .map(|p| {
            super::material::inertial_number(
                super::material::shear_rate(&p.grad_v),
                p.stress.pressure(),
                m.grain_diameter,
                m.grain_density,
                m.i_max,
            )
        })
        .collect()
}

/// Statistics of I (see [`InertialStats`]).
pub fn inertial_stats(state: &State, m: &super::params::Material, g: Real) -> InertialStats {
    let thr = 1e-3 * (g / m.grain_diameter).sqrt();
    let p_deep = m.grain_density * g * m.grain_diameter;
    let (mut mdeep, mut sdeep) = (0.0, 0.0);
    let mut flowing: Vec<(Real, Real)> = Vec::new();
    let (mut mass, mut mflow, mut sum, mut max, mut mfree) = (0.0, 0.0, 0.0, 0.0f64, 0.0);
    for p in &state.points {
        let gd = super::material::shear_rate(&p.grad_v);
        let pr = p.stress.pressure();
        mass += p.mass;
        if pr <= 0.0 {
            mfree += p.mass;
            continue;
        }
        let i = super::material::inertial_number(gd, pr, m.grain_diameter, m.grain_density, m.i_max);
        max = max.max(i);
        if gd > thr {
            mflow += p.mass;
            sum += p.mass * i;
            flowing.push((i, p.mass));
            if pr >= p_deep {
                mdeep += p.mass;
                sdeep += p.mass * i;
            }
        }
    }
    if flowing.is_empty() {
        return InertialStats {
            max,
            stress_free_fraction: mfree / mass.max(1e-300),
            ..Default::default()
        };
    }
    flowing.sort_by(|a, b| a.0.total_cmp(&b.0));
    let k = ((flowing.len() as Real * 0.95).ceil() as usize).clamp(1, flowing.len()) - 1;
    let median = crate::analysis::inertial::weighted_stats(flowing.clone(), 0.0).median;
    InertialStats {
        mean_flowing: sum / mflow,
        p95_flowing: flowing[k].0,
        max,
        flowing_fraction: mflow / mass,
        stress_free_fraction: mfree / mass,
        median_flowing: median,
        mean_flowing_deep: if mdeep > 0.0 { sdeep / mdeep } else { 0.0 },
    }
}

/// Point fields at one time.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Snapshot {
    /// Time [s].
    pub t: Real,
    /// Point ids.
    pub id: Vec<u32>,
    /// x [m].
    pub x: Vec<Real>,
    /// y [m].
    pub y: Vec<Real>,
    /// v_x [m/s].
    pub vx: Vec<Real>,
    /// v_y [m/s].
    pub vy: Vec<Real>,
    /// σ_xx [Pa].
    pub sxx: Vec<Real>,
    /// σ_yy [Pa].
    pub syy: Vec<Real>,
    /// σ_xy [Pa].
    pub sxy: Vec<Real>,
    /// Equivalent plastic strain [-].
    pub eps_p: Vec<Real>,
    /// Inertial number [-] (D08; computed for every model in collapse runs).
    pub inertial: Vec<Real>,
    /// Mass [kg/m].
    pub mass: Vec<Real>,
}

impl Snapshot {
    /// The points as an analysis [`Cloud`] of half-size `lp`.
    pub fn cloud(&self, lp: Real) -> Cloud {
        Cloud {
            t: self.t,
            x: self.x.clone(),
            y: self.y.clone(),
            half: vec![lp; self.x.len()],
            mass: self.mass.clone(),
            vx: self.vx.clone(),
            vy: self.vy.clone(),
        }
    }
}

/// Snapshot of a state (`inertial` is left as the μ(I) models store it; use
/// [`snapshot_with`] to have it computed for every model).
pub fn snapshot(state: &State) -> Snapshot {
    let p = &state.points;
    Snapshot {
        t: state.t,
        id: p.iter().map(|p| p.id.0).collect(),
        x: p.iter().map(|p| p.x.x).collect(),
        y: p.iter().map(|p| p.x.y).collect(),
        vx: p.iter().map(|p| p.v.x).collect(),
        vy: p.iter().map(|p| p.v.y).collect(),
        sxx: p.iter().map(|p| p.stress.xx).collect(),
        syy: p.iter().map(|p| p.stress.yy).collect(),
        sxy: p.iter().map(|p| p.stress.xy).collect(),
        eps_p: p.iter().map(|p| p.eps_p).collect(),
        inertial: p.iter().map(|p| p.inertial).collect(),
        mass: p.iter().map(|p| p.mass).collect(),
    }
}

/// Snapshot with the inertial number computed for every model.
pub fn snapshot_with(state: &State, m: &super::params::Material) -> Snapshot {
    let mut s = snapshot(state);
    s.inertial = inertial_numbers(state, m);
    s
}

/// Result of a collapse run.
#[derive(Debug, Clone)]
pub struct CollapseResult {
    /// Geometry actually discretised.
    pub spec: ColumnSpec,
    /// Number of points.
    pub points: usize,
    /// Update scheme name.
    pub scheme: &'static str,
    /// Geostatic stage (None if skipped).
    pub geostatic: Option<GeostaticReport>,
    /// Time series.
    pub series: Vec<Sample>,
    /// Snapshots at the requested times.
    pub snapshots: Vec<Snapshot>,
    /// Final front by the links (its height is H_f).
    pub final_front: Front,
    /// L_f [m] by `run.front_rule`.
    pub final_length: Real,
    /// ΔL = (L_f − L_0)/L_0 [-] by `run.front_rule`.
    pub runout: Real,
    /// ΔL of the main mass with dilation-following links ([`front_of_dilated`]) [-]: less
    /// sensitive to gaps opening in a thin deposit at coarse resolution.
    pub runout_dilated: Real,
    /// ΔL from the 99 % mass quantile of x (+ l_p) [-]: insensitive to gaps and stray points.
    pub runout_q99: Real,
    /// Whether the stop criterion was met (false: stopped at max_time).
    pub stopped: bool,
    /// Steps of the collapse stage.
    pub steps: u64,
    /// Wall-clock time of the collapse stage [s].
    pub wall_s: Real,
    /// Per-phase times (geostatic + collapse).
    pub times: PhaseTimes,
    /// L(t) [m] for each gap of `link_gap_sensitivity`, one row per sample.
    pub gap_lengths: Vec<Vec<Real>>,
    /// The points at release and at the end.
    pub initial: Snapshot,
    /// See `initial`.
    pub final_state: Snapshot,
}

/// Expected largest speed of a column collapse, √(2 g H_0) (docs/definitions.md c.3) [m/s].
pub fn expected_v_max(spec: &ColumnSpec, g: Real) -> Real {
    (2.0 * g * spec.h0).sqrt()
}

/// Geostatic stage, release, collapse until rest. Refuses (before any work) a fixed step
/// above the CFL limit for v_max = √(2 g H_0) (`preflight`).
pub fn collapse(params: &MpmParams, spec: ColumnSpec, opts: &CollapseOptions) -> Result<CollapseResult, MpmError> {
    collapse_with_progress(params, spec, opts, &mut |_, _| {})
}

/// [`collapse`] calling `progress(sample, t_max)` after every recorded sample (for progress
/// bars: simulated time `sample.t` out of at most `t_max` seconds).
pub fn collapse_with_progress(
    params: &MpmParams,
    spec: ColumnSpec,
    opts: &CollapseOptions,
    progress: &mut dyn FnMut(&Sample, Real),
) -> Result<CollapseResult, MpmError> {
    let vmax = expected_v_max(&spec, params.gravity);
    super::preflight::preflight(params, super::preflight::planned_dt(params, vmax), vmax)?;
    let mut col = build(params, spec)?;
    let geo = if opts.skip_geostatic {
        None
    } else {
        Some(geostatic::run(&mut col.solver, &mut col.state, col.spec.h0)?)
    };
    if opts.gate_lift_speed <= 0.0 {
        release(&mut col);
    }
    run_collapse_with_progress(col, geo, params, opts, progress)
}

fn is_zero(v: &Real) -> bool {
    *v == 0.0
}

/// Run an already-built (and possibly loaded) column after release.
pub fn run_collapse(
    col: Column,
    geo: Option<GeostaticReport>,
    params: &MpmParams,
    opts: &CollapseOptions,
) -> Result<CollapseResult, MpmError> {
    run_collapse_with_progress(col, geo, params, opts, &mut |_, _| {})
}

/// [`run_collapse`] with a progress callback (see [`collapse_with_progress`]).
pub fn run_collapse_with_progress(
    mut col: Column,
    geo: Option<GeostaticReport>,
    params: &MpmParams,
    opts: &CollapseOptions,
    progress: &mut dyn FnMut(&Sample, Real),
) -> Result<CollapseResult, MpmError> {
    let g = params.gravity;
    let tau = col.spec.tau_c(g);
    let lp = params.half_width();
    let s = params.spacing();
    let el = *col.solver.elastic();
    let e0 = energies(&col.state, &el, g);
    let watch = EnergyWatch::new(&e0, params.energy_rise_tol);
    let mut series = Vec::new();
    let mut snapshots = Vec::new();
    let mut snap_times: Vec<Real> = opts.snapshot_tau.iter().map(|t| t * tau).collect();
    snap_times.sort_by(|a, b| a.total_cmp(b));
    let mut next_snap = 0usize;
    let mat = params.material.clone();
    let d = mat.grain_diameter;
    let link = match (opts.link_grid, opts.link_gap) {
        (true, _) => Link::SharedNode {
            h: params.cell_size,
            support: params.cell_size + lp,
        },
        (false, Some(k)) => Link::Contact { gap: k * d },
        (false, None) => Link::Distance(1.5 * s),
    };
    let gaps: Vec<Real> = opts.link_gap_sensitivity.iter().map(|k| k * d).collect();
    let grain = Grain {
        cell: opts.inertial_cell * d,
        d,
        rho_s: mat.grain_density,
        g,
    };
    let mut gap_lengths: Vec<Vec<Real>> = Vec::new();
    let initial = snapshot_with(&col.state, &params.material);
    let mut record = |state: &State, series: &mut Vec<Sample>| -> Energies {
        let e = energies(state, &el, g);
        // one set of bodies per sample for every front rule (the points, half-size l_p)
        let cloud = snapshot(state).cloud(lp);
        let body = cloud.body();
        let f = front(&body, link);
        gap_lengths.push(lengths_for_gaps(&body, &gaps));
        let l_gathered = gathered_d(&body, d);
        let inertial_cg = coarse_grained(&cloud, grain);
        let l_all = state.points.iter().map(|p| p.x.x + lp).fold(0.0, Real::max);
        series.push(Sample {
            t: state.t,
            l: match opts.front_rule {
                FrontRule::Links => f.length,
                FrontRule::Gathered => l_gathered,
            },
            l_gathered,
            h: f.height,
            l_all,
            main_fraction: f.mass_fraction,
            l_dilated: front_of_dilated(state, lp, s).length,
            l_q99: mass_quantile_x(state, 0.99) + lp,
            e,
            inertial: inertial_stats(state, &mat, g),
            inertial_cg,
        });
        e
    };
    record(&col.state, &mut series);
    let clock = std::time::Instant::now();
    let sample_dt = opts.sample_every_tau * tau;
    let mut next_sample = sample_dt;
    let mut stopped = false;
    let mut gate_lifting = opts.gate_lift_speed > 0.0;
    loop {
        while next_snap < snap_times.len() && col.state.t >= snap_times[next_snap] {
            snapshots.push(snapshot_with(&col.state, &params.material));
            next_snap += 1;
        }
        let dt = col.solver.dt(&col.state);
        if gate_lifting {
            // the gate's lower edge during this step; the gate is removed once it clears the grid
            let edge = opts.gate_lift_speed * col.state.t;
            if edge > col.solver.grid.origin.y + col.solver.grid.ny as Real * col.solver.grid.h {
                release(&mut col);
                col.solver.gate_open_below = Real::NEG_INFINITY;
                gate_lifting = false;
            } else {
                col.solver.gate_open_below = edge;
            }
        }
        col.solver.step(&mut col.state, dt)?;
        if col.state.t >= next_sample {
            next_sample += sample_dt;
            let e = record(&col.state, &mut series);
            if let Some(last) = series.last() {
                progress(last, opts.max_time_tau * tau);
            }
            watch.check(&e, &col.state.points, col.state.step, col.state.t)?;
            if let Some(rule) = opts.stop {
                let t: Vec<Real> = series.iter().map(|v| v.t).collect();
                let l: Vec<Real> = series.iter().map(|v| v.l).collect();
                let h: Vec<Real> = series.iter().map(|v| v.h).collect();
                match rule.verdict(&t, &l, &h, e.kinetic_grid / e0.potential, tau, d) {
                    Verdict::AtRest => {
                        stopped = true;
                        break;
                    }
                    Verdict::TimeLimit => break,
                    Verdict::Running => {}
                }
            } else if col.state.t >= opts.min_time_tau * tau
                && (e.kinetic_grid < opts.stop_ke_ratio * e0.potential
                    || front_still(&series, opts, tau, e.kinetic_grid / e0.potential))
            {
                stopped = true;
                break;
            }
        }
        if opts.stop.is_none() && col.state.t >= opts.max_time_tau * tau {
            record(&col.state, &mut series);
            break;
        }
    }
    while next_snap < snap_times.len() {
        snapshots.push(snapshot_with(&col.state, &params.material));
        next_snap += 1;
    }
    let wall_s = clock.elapsed().as_secs_f64();
    drop(record);
    let final_front = front_linked(&col.state, lp, link);
    let final_length = match opts.front_rule {
        FrontRule::Links => final_front.length,
        FrontRule::Gathered => gathered_d(&snapshot(&col.state).cloud(lp).body(), d),
    };
    Ok(CollapseResult {
        spec: col.spec,
        points: col.state.points.len(),
        scheme: col.solver.scheme(),
        geostatic: geo,
        series,
        snapshots,
        runout: (final_length - col.spec.l0) / col.spec.l0,
        final_length,
        runout_dilated: (front_of_dilated(&col.state, lp, s).length - col.spec.l0) / col.spec.l0,
        runout_q99: (mass_quantile_x(&col.state, 0.99) + lp - col.spec.l0) / col.spec.l0,
        final_front,
        stopped,
        steps: col.state.step,
        wall_s,
        times: col.solver.times,
        gap_lengths,
        initial,
        final_state: snapshot_with(&col.state, &params.material),
    })
}

fn front_still(series: &[Sample], opts: &CollapseOptions, tau: Real, ke_ratio: Real) -> bool {
    let Some(last) = series.last() else { return false };
    if ke_ratio >= opts.still_ke_ratio || last.t < opts.still_tau * tau {
        return false;
    }
    let t0 = last.t - opts.still_tau * tau;
    series
        .iter()
        .rev()
        .take_while(|s| s.t >= t0)
        .all(|s| (s.l - last.l).abs() < opts.still_tol && (s.h - last.h).abs() < opts.still_tol)
}

/// Points of a state as plain slices (for VTK output by the caller).
pub fn positions(points: &[Point]) -> (Vec<Real>, Vec<Real>) {
    (
        points.iter().map(|p| p.x.x).collect(),
        points.iter().map(|p| p.x.y).collect(),
    )
}

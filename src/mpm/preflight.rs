//! Stability pre-flight (docs/definitions.md c.3): every time scale of an MPM run against
//! the step.
//!
//! - CFL: Δt ≤ h/(c_p + |v|_max) with c_p = √(M/ρ), M = E(1−ν)/((1+ν)(1−2ν)) the plane-strain
//!   P-wave modulus (2.2605e6 Pa → 34.27 m/s for table 4.3). This is the hard limit (refused
//!   above it).
//! - Point-spacing CFL (h/√PPC instead of h): the conservative reading; reported only.
//! - μ(I): the friction is updated explicitly inside the plastic return mapping; it adds no
//!   viscous stress and so no time scale (reported as such).
//! - Geostatic stage: always runs at `geostatic.courant` × CFL (reported).

use super::error::MpmError;
use super::params::{Model, MpmParams, StepRule};
use crate::math::Real;
use std::fmt;

/// One time scale.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// What it is.
    pub name: String,
    /// Stable limit [s] (None: no limit).
    pub limit: Option<Real>,
    /// Whether exceeding it refuses the run.
    pub hard: bool,
}

/// Pre-flight table.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    /// Step checked [s].
    pub dt: Real,
    /// Expected maximum speed [m/s].
    pub v_max: Real,
    /// P-wave modulus M [Pa].
    pub p_modulus: Real,
    /// c_p [m/s].
    pub c_p: Real,
    /// Courant number Δt (c_p + v_max)/h.
    pub courant: Real,
    /// Time scales.
    pub rows: Vec<Row>,
}

/// The step a run will use for a given expected max speed (fixed, or the CFL rule at v_max).
pub fn planned_dt(params: &MpmParams, v_max: Real) -> Real {
    let c = params.material.p_wave_speed();
    match params.step {
        StepRule::Fixed { dt } => dt,
        StepRule::Cfl { courant, dt_max } => (courant * params.cell_size / (c + v_max)).min(dt_max),
    }
}

/// Check `dt` against the stable limits for an expected max speed `v_max` (e.g. √(2 g H_0)).
pub fn preflight(params: &MpmParams, dt: Real, v_max: Real) -> Result<Report, MpmError> {
    let issues = params.validate();
    if !issues.is_empty() {
        return Err(MpmError::InvalidParams(issues));
    }
    let m = &params.material;
    let c_p = m.p_wave_speed();
    let h = params.cell_size;
    let cfl = h / (c_p + v_max);
    let mut rows = vec![
        Row {
            name: "CFL, cell size: h/(c_p + v_max)".into(),
            limit: Some(cfl),
            hard: true,
        },
        Row {
            name: "CFL, point spacing: (h/sqrt(PPC))/(c_p + v_max)".into(),
            limit: Some(params.spacing() / (c_p + v_max)),
            hard: false,
        },
    ];
    let mu_row = match m.model {
        Model::MuILinear { .. } | Model::MuIJop { .. } => {
            "mu(I): friction updated explicitly in the return map, no viscous time scale"
        }
        _ => "mu(I): not used",
    };
    rows.push(Row {
        name: mu_row.into(),
        limit: None,
        hard: false,
    });
    rows.push(Row {
        name: format!(
            "geostatic stage: runs at Courant {} of the CFL step",
            params.geostatic.courant
        ),
        limit: None,
        hard: false,
    });
    let report = Report {
        dt,
        v_max,
        p_modulus: m.p_wave_modulus(),
        c_p,
        courant: dt * (c_p + v_max) / h,
        rows,
    };
    if dt.is_nan() || dt <= 0.0 || dt > cfl {
        return Err(MpmError::StepTooLarge {
            dt,
            limit: cfl,
            reason: format!("CFL with c_p = {c_p:.2} m/s, v_max = {v_max:.2} m/s, h = {h:.3e} m"),
        });
    }
    Ok(report)
}

impl fmt::Display for Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "MPM stability pre-flight: dt = {:.3e} s, v_max = {:.2} m/s",
            self.dt, self.v_max
        )?;
        writeln!(
            f,
            "  P-wave modulus M = {:.4e} Pa, c_p = {:.2} m/s, Courant number = {:.4}",
            self.p_modulus, self.c_p, self.courant
        )?;
        writeln!(
            f,
            "  {:<78} {:>12} {:>10} {:>6}",
            "time scale", "limit [s]", "dt/limit", "status"
        )?;
        for r in &self.rows {
            match r.limit {
                Some(l) => {
                    let ratio = self.dt / l;
                    let status = if ratio <= 1.0 {
                        "ok"
                    } else if r.hard {
                        "FAIL"
                    } else {
                        "warn"
                    };
                    writeln!(f, "  {:<78} {:>12.3e} {:>10.4} {:>6}", r.name, l, ratio, status)?;
                }
                None => writeln!(f, "  {:<78} {:>12} {:>10} {:>6}", r.name, "-", "-", "ok")?,
            }
        }
        Ok(())
    }
}

/// Validation-time containment check of a column collapse: the grid of
/// [`crate::mpm::column::build`] reaches x₁ = L_0(1 + 3·eq 4.6) + 8h. Base friction μ_w
/// dissipates at least μ_w M g per unit travel of the mass centre, which releases at most
/// ΔE_p ≤ M g H_0/2, so the centre travels at most H_0/(2μ_w); a front beyond x₁ is
/// then impossible only if L_0 + H_0/(2μ_w) ≤ x₁ is not violated by the spreading itself —
/// we refuse when even the centre's bound leaves the grid (μ_w = 0: no bound at all).
pub fn containment(params: &MpmParams, spec: crate::mpm::column_spec::ColumnSpec) -> Result<(), String> {
    let h = params.cell_size;
    let x1 = spec.l0 * (1.0 + 3.0 * spec.runout_estimate()) + 8.0 * h;
    let mu = params.wall_friction;
    let reach = if mu > 0.0 {
        spec.l0 + spec.h0 / (2.0 * mu)
    } else {
        Real::INFINITY
    };
    if reach <= x1 {
        return Ok(());
    }
    let mu_min = spec.h0 / (2.0 * (x1 - spec.l0));
    Err(format!(
        "points would leave the grid: with base friction wall_friction = {mu} nothing bounds the slide within the grid (mass-centre travel bound L_0 + H_0/(2 mu_w) = {reach:.3e} m > grid end x1 = {x1:.3e} m, sized to 1 + 3x the eq 4.6 run-out); limit: wall_friction >= {mu_min:.3} for this column; fix: raise wall_friction (table 4.3: 0.466) or shorten the column"
    ))
}

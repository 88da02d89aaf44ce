//! Pre-flight stability audit (docs/definitions.md c.1, c.2): every time scale of the scene
//! against the step, the explicit limit of each, and a refusal naming the binding one.
//!
//! Explicit limit of a damped oscillator under velocity Verlet:
//! Δt_crit = (2/ω₀)(√(1+ξ²) − ξ) (docs/definitions.md c.1). Multi-contact estimates use
//! z = 4 contacts on the smallest grain (docs/definitions.md c.1). With the implicit
//! rolling dashpot the dashpot itself has no limit and the rolling spring's limit follows
//! [`implicit_rolling_limit`] (2/ω_r without damping, none for the over-damped table 4.2
//! values).

use crate::dem::error::DemError;
use crate::dem::params::{DemParams, RollingDamping};
use crate::math::{PI, Real};
use serde::{Deserialize, Serialize};
use std::fmt;

pub use crate::dem::time_scale::TimeScale;

/// Contacts per grain assumed by the multi-contact estimates (dense random disks).
pub const Z_MULTI: Real = 4.0;
/// Fewer steps than this per collision time gets a warning (ε accuracy; docs/definitions.md
/// c.1).
pub const MIN_STEPS_PER_COLLISION: Real = 20.0;

/// Sizes the audit needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SizeClasses {
    /// Smallest radius [m].
    pub r_min: Real,
    /// Mean radius [m].
    pub r_mean: Real,
    /// Largest radius [m].
    pub r_max: Real,
}

/// The audit table for `--explain`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Preflight {
    /// The step audited [s].
    pub dt: Real,
    /// All rows.
    pub rows: Vec<TimeScale>,
}

impl Preflight {
    /// Rows whose step is unstable.
    pub fn violations(&self) -> impl Iterator<Item = &TimeScale> {
        self.rows.iter().filter(|r| r.ratio >= 1.0)
    }
    /// Largest stable step over all rows [s].
    pub fn limit(&self) -> Real {
        self.rows.iter().map(|r| r.limit).fold(Real::INFINITY, Real::min)
    }
}

impl fmt::Display for Preflight {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "DEM pre-flight, dt = {:.3e} s (stable limit {:.3e} s)",
            self.dt,
            self.limit()
        )?;
        writeln!(
            f,
            "{:<52} {:>11} {:>11} {:>8} {:>9}  status",
            "time scale", "value [s]", "limit [s]", "dt/lim", "steps"
        )?;
        for r in &self.rows {
            let status = if r.ratio >= 1.0 {
                "UNSTABLE"
            } else if !r.note.is_empty() {
                "warn"
            } else {
                "ok"
            };
            let lim = if r.limit.is_finite() {
                format!("{:.3e}", r.limit)
            } else {
                "none".into()
            };
            writeln!(
                f,
                "{:<52} {:>11.3e} {:>11} {:>8.3} {:>9.1}  {}{}{}",
                r.name,
                r.value,
                lim,
                r.ratio,
                r.steps,
                status,
                if r.note.is_empty() { "" } else { ": " },
                r.note
            )?;
        }
        Ok(())
    }
}

fn damped_limit(omega: Real, xi: Real) -> Real {
    (2.0 / omega) * ((1.0 + xi * xi).sqrt() - xi)
}

/// Largest stable step of the rolling spring (explicit) with the backward-Euler dashpot
/// of `dem::integrate`: per step the relative rate is damped by r = (1 + Δt c_r/(2I_eff))⁻²
/// and the leapfrog map is stable iff Δt² k_r/I_eff < 2(1+r)/r (Jury). Scanned in Δt;
/// ∞ if stable everywhere up to 1 s (the case for any ξ = c_r/(2√(k_r I_eff)) > 1/√2,
/// e.g. table 4.2 with ξ ≈ 50–170).
pub fn implicit_rolling_limit(kr: Real, cr: Real, ie: Real) -> Real {
    let stable = |dt: Real| {
        let r = (1.0 + dt * cr / (2.0 * ie)).powi(-2);
        dt * dt * kr / ie < 2.0 * (1.0 + r) / r
    };
    let mut dt = 1e-12;
    while dt < 1.0 {
        if !stable(dt) {
            // refine between dt/1.05 and dt
            let (mut lo, mut hi) = (dt / 1.05, dt);
            for _ in 0..50 {
                let mid = 0.5 * (lo + hi);
                if stable(mid) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            return lo;
        }
        dt *= 1.05;
    }
    Real::INFINITY
}

/// Every time scale of a scene with these parameters and sizes (walls optional).
pub fn time_scales(p: &DemParams, s: SizeClasses, walls: bool, dt: Real) -> Vec<TimeScale> {
    let mass = |r: Real| p.density * PI * r * r;
    let inertia = |r: Real| 0.5 * mass(r) * r * r;
    let mut rows = Vec::new();
    let mut push = |name: String, value: Real, limit: Real, fix: String, steps_warn: bool| {
        let steps = value / dt;
        let note = if steps_warn && steps < MIN_STEPS_PER_COLLISION {
            format!("only {steps:.1} steps per collision (< {MIN_STEPS_PER_COLLISION}); ε is under-resolved")
        } else {
            String::new()
        };
        rows.push(TimeScale {
            name,
            value,
            limit,
            ratio: dt / limit,
            steps,
            fix,
            note,
        });
    };
    let fix_dt = |lim: Real| format!("use dt <= {:.2e} s (or soften k by (dt_lim/dt)^2)", 0.9 * lim);
    // --- translational collisions ---
    let gg = p.grain.damping_ratio();
    for (label, r) in [("d_min", s.r_min), ("d_mean", s.r_mean), ("d_max", s.r_max)] {
        let m_eff = 0.5 * mass(r);
        let w0 = (p.grain.kn / m_eff).sqrt();
        let tc = PI / (w0 * (1.0 - gg * gg).sqrt());
        let lim = damped_limit(w0, gg);
        push(
            format!("collision grain-grain ({label} pair) t_c"),
            tc,
            lim,
            fix_dt(lim),
            true,
        );
    }
    let m_min = mass(s.r_min);
    let i_min = inertia(s.r_min);
    if walls {
        let gw = p.wall.damping_ratio();
        let w0 = (p.wall.kn / m_min).sqrt();
        let tc = PI / (w0 * (1.0 - gw * gw).sqrt());
        let lim = damped_limit(w0, gw);
        push("collision grain-wall (d_min) t_c".into(), tc, lim, fix_dt(lim), true);
        let wt = (3.0 * p.wall.kt / m_min).sqrt();
        push(
            "tangential grain-wall (d_min, with spin) 2pi/w".into(),
            2.0 * PI / wt,
            2.0 / wt,
            fix_dt(2.0 / wt),
            false,
        );
    }
    let wz = (2.0 * Z_MULTI * p.grain.kn / m_min).sqrt();
    push(
        format!("multi-contact normal (z={Z_MULTI}, d_min) 2pi/w"),
        2.0 * PI / wz,
        2.0 / wz,
        fix_dt(2.0 / wz),
        false,
    );
    let wt = (6.0 * p.grain.kt / m_min).sqrt();
    push(
        "tangential pair (d_min, with spin) 2pi/w".into(),
        2.0 * PI / wt,
        2.0 / wt,
        fix_dt(2.0 / wt),
        false,
    );
    let wtz = (4.0 * Z_MULTI * p.grain.kt / m_min).sqrt();
    push(
        format!("multi-contact tangential (z={Z_MULTI}, d_min) 2pi/w"),
        2.0 * PI / wtz,
        2.0 / wtz,
        fix_dt(2.0 / wtz),
        false,
    );
    // --- rolling ---
    if p.rolling.enabled {
        let (kr, cr) = (p.rolling.kr, p.rolling.cr);
        let cases: Vec<(&str, Real)> = if walls {
            vec![("d_min pair", 0.5 * i_min), ("d_min on wall", i_min)]
        } else {
            vec![("d_min pair", 0.5 * i_min)]
        };
        for (label, ie) in cases {
            let wr = (kr / ie).sqrt();
            match p.rolling.damping {
                RollingDamping::Explicit => {
                    let xi = cr / (2.0 * (kr * ie).sqrt());
                    let lim = damped_limit(wr, xi);
                    push(
                        format!("rolling spring+dashpot ({label}), explicit"),
                        2.0 * PI / wr,
                        lim,
                        format!("set rolling.damping: implicit, or dt <= {:.2e} s", 0.9 * lim),
                        false,
                    );
                    let lim_d = 2.0 * ie / cr.max(1e-300);
                    push(
                        format!("rolling dashpot relaxation I_eff/c_r ({label}), explicit"),
                        ie / cr.max(1e-300),
                        lim_d,
                        format!(
                            "set rolling.damping: implicit (explicit needs dt <= {:.2e} s)",
                            0.9 * lim_d
                        ),
                        false,
                    );
                }
                RollingDamping::Implicit => {
                    let lim = implicit_rolling_limit(kr, cr, ie);
                    push(
                        format!("rolling spring with implicit dashpot ({label})"),
                        2.0 * PI / wr,
                        lim,
                        fix_dt(lim),
                        false,
                    );
                    push(
                        format!("rolling dashpot relaxation I_eff/c_r ({label}), implicit"),
                        ie / cr.max(1e-300),
                        Real::INFINITY,
                        String::new(),
                        false,
                    );
                }
            }
        }
        let wz = (2.0 * Z_MULTI * kr / i_min).sqrt();
        if p.rolling.damping == RollingDamping::Explicit || cr == 0.0 {
            push(
                format!("multi-contact rolling spring (z={Z_MULTI}, d_min)"),
                2.0 * PI / wz,
                2.0 / wz,
                fix_dt(2.0 / wz),
                false,
            );
        } else {
            // z springs and z backward-Euler dashpots on a d_min grain: the pair map with
            // z k_r and z c_r on I_min/2 (the sequential sweep damps at least as much as z c_r)
            let lim = implicit_rolling_limit(Z_MULTI * kr, Z_MULTI * cr, 0.5 * i_min);
            push(
                format!("multi-contact rolling spring, implicit dashpot (z={Z_MULTI}, d_min)"),
                2.0 * PI / wz,
                lim,
                fix_dt(lim),
                false,
            );
        }
    }
    rows
}

/// Audit `dt`; refuse with the most violated time scale.
pub fn preflight(p: &DemParams, s: SizeClasses, walls: bool, dt: Real) -> Result<Preflight, DemError> {
    let rows = time_scales(p, s, walls, dt);
    let worst = rows
        .iter()
        .filter(|r| r.ratio >= 1.0)
        .max_by(|a, b| a.ratio.partial_cmp(&b.ratio).unwrap());
    if let Some(w) = worst {
        return Err(DemError::StepTooLarge {
            dt,
            limit: w.limit,
            scale: w.clone(),
        });
    }
    Ok(Preflight { dt, rows })
}

//! Pre-flight of every step: no grain may move more than half the alert distance in one
//! step, so no pair can close from beyond the alert distance unseen. Checked on the
//! start-of-step speeds before the step (refuse), and after it on the actual motion, which
//! must stay within the alert distance itself.

use crate::cd::body::Body;
use crate::cd::error::CdError;
use crate::math::Real;

/// Fastest body (translation) among `bodies`: (index, speed).
pub fn fastest(bodies: &[Body]) -> (usize, Real) {
    let mut best = (0usize, 0.0);
    for (i, b) in bodies.iter().enumerate() {
        let s2 = b.v[0] * b.v[0] + b.v[1] * b.v[1];
        if s2 > best.1 {
            best = (i, s2);
        }
    }
    (best.0, best.1.sqrt())
}

/// Refuse `speed·h > alert/2` with the limit and both fixes (`alert` is the budget: pass
/// twice the alert distance for the after-step check).
pub fn check_motion(
    step: u64,
    t: Real,
    body: usize,
    speed: Real,
    h: Real,
    alert: Real,
    d_min: Real,
) -> Result<(), CdError> {
    let disp = speed * h;
    if disp > 0.5 * alert {
        return Err(CdError::StepTooLarge {
            step,
            t,
            grain: body as u32,
            speed,
            displacement: disp,
            alert,
            dt_limit: 0.5 * alert / speed,
            alert_fraction_needed: 2.0 * disp / d_min,
        });
    }
    Ok(())
}

/// The docs/definitions.md c.5 step rule h ≤ 0.02 d_min / v_max, for a stage to state its
/// choice.
pub fn recommended_dt(d_min: Real, v_max: Real) -> Real {
    0.02 * d_min / v_max
}

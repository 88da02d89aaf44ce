//! The one contact law, used for grain–grain and grain–wall contacts alike (a wall is a
//! body of infinite mass with zero spin and zero lever arm).
//!
//! Normal: linear spring-dashpot without attraction (chapter 3 eq "nf"; C_n from eqs
//! 4.4–4.5). Tangential: linear spring with history, optional dashpot, Coulomb cap that
//! rescales the stored spring so spring + dashpot sits on the cone (chapter 3 eq "tf").
//! Rolling: Iwashita & Oda elastic-plastic spring-dashpot (see [`RollingParams`]).
//!
//! Which terms exist is chosen at compile time by [`Law`]'s const parameters, picked once
//! per run outside the pair loop.
//!
//! [`RollingParams`]: crate::dem::params::RollingParams

use crate::dem::params::ContactParams;
use crate::dem::state::ContactState;
use crate::math::{Real, Vec2};

/// Law coefficients of one contact family, derived once from [`ContactParams`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LawCoeffs {
    /// k_n [N/m].
    pub kn: Real,
    /// k_t [N/m].
    pub kt: Real,
    /// μ [-].
    pub mu: Real,
    /// Tangential dashpot / C_n [-].
    pub gt_ratio: Real,
    /// k_r [N·m/rad].
    pub kr: Real,
    /// c_r [N·m·s/rad].
    pub cr: Real,
    /// μ_r [-].
    pub mu_r: Real,
    /// The cap holds spring + dashpot together (LAMMPS `rolling sds`), not the spring alone.
    pub cap_dashpot: bool,
}

impl LawCoeffs {
    /// Coefficients from the parameter blocks (rolling terms zero when absent).
    pub fn new(c: &ContactParams, r: &crate::dem::params::RollingParams) -> Self {
        let on = r.enabled;
        Self {
            kn: c.kn,
            kt: c.kt,
            mu: c.friction,
            gt_ratio: c.tangential_damping_ratio,
            kr: if on { r.kr } else { 0.0 },
            cr: if on { r.cr } else { 0.0 },
            mu_r: if on { r.mu_r } else { 0.0 },
            cap_dashpot: r.model == crate::dem::params::RollingModel::Capped,
        }
    }
}

/// Geometry and kinematics of one contact, seen from body i.
#[derive(Debug, Clone, Copy)]
pub struct PairIn {
    /// Unit normal from j to i (wall: the wall's inward normal).
    pub n: Vec2,
    /// Overlap δ = r_i + r_j − |x_i − x_j| > 0 [m].
    pub overlap: Real,
    /// v_i − v_j [m/s].
    pub v_rel: Vec2,
    /// Spin of i [rad/s].
    pub w_i: Real,
    /// Spin of j (0 for a wall) [rad/s].
    pub w_j: Real,
    /// Lever arm of i (r_i) [m].
    pub arm_i: Real,
    /// Lever arm of j (r_j; 0 for a wall) [m].
    pub arm_j: Real,
    /// Rolling radius r_eff = r_i r_j/(r_i+r_j) (r_i at a wall) [m].
    pub r_roll: Real,
    /// Normal dashpot C_n = 2γ√(m_ij k_n) [N·s/m].
    pub cn: Real,
}

/// Energy booked by one contact during one step [J/m].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PairWork {
    /// Normal dashpot (collisional) dissipation.
    pub normal: Real,
    /// Tangential (sliding + dashpot) dissipation.
    pub tangential: Real,
    /// Rolling (plastic slip + explicit dashpot) dissipation.
    pub rolling: Real,
}

/// Implicit rolling dashpot of one contact, applied by the integrator as a pairwise
/// backward-Euler impulse (see `dem::integrate`). `c = 0`: no dashpot this step.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RollDashpot {
    /// Dashpot coefficient c_r [N·m·s].
    pub c: Real,
    /// Spring moment on body i [N·m/m] (the cap applies to spring + dashpot).
    pub m_spring: Real,
    /// Cap on |spring + dashpot| [N·m/m]; infinite for the EPSD model (dashpot uncapped).
    pub m_max: Real,
}

/// Result on body i (body j gets −f and its own torque).
#[derive(Debug, Clone, Copy, Default)]
pub struct PairOut {
    /// Force on i [N/m].
    pub f: Vec2,
    /// Torque on i [N·m/m].
    pub t_i: Real,
    /// Torque on j [N·m/m].
    pub t_j: Real,
    /// Implicit rolling dashpot active at this contact (`c = 0` if none).
    pub roll: RollDashpot,
    /// Dissipation booked this step (only filled with the ledger on).
    pub work: PairWork,
}

/// The contact law. `ROLLING`: rolling resistance present; `IMPLICIT`: the rolling dashpot
/// is left to the integrator (pairwise backward Euler), else applied explicitly here;
/// `LEDGER`: dissipation is booked.
#[derive(Debug, Clone, Copy, Default)]
pub struct Law<const ROLLING: bool, const IMPLICIT: bool, const LEDGER: bool>;

impl<const ROLLING: bool, const IMPLICIT: bool, const LEDGER: bool> Law<ROLLING, IMPLICIT, LEDGER> {
    /// Evaluate one contact over a step `dt` and update its history.
    #[inline(always)]
    pub fn eval(c: &LawCoeffs, p: &PairIn, h: &mut ContactState, dt: Real) -> PairOut {
        let mut out = PairOut::default();
        // --- relative velocity: normal and tangential split (t = perp(n)) ---
        let n = p.n;
        let t = Vec2::new(-n.y, n.x);
        let vn = p.v_rel.dot(&n); // > 0: separating
        let vt = p.v_rel.dot(&t) - (p.arm_i * p.w_i + p.arm_j * p.w_j);

        // --- normal force: spring + dashpot, no attraction ---
        let f_el = c.kn * p.overlap;
        let fn_ = (f_el - p.cn * vn).max(0.0);

        // --- tangential history and Coulomb cap ---
        let xi_old = h.tangential;
        let ft_old = h.ft;
        let mut xi = xi_old + vt * dt;
        let gt = c.gt_ratio * p.cn;
        let mut ft = -c.kt * xi - gt * vt;
        let ft_max = c.mu * fn_;
        if ft.abs() > ft_max {
            ft = ft_max.copysign(ft);
            // rescale the stored spring so spring + dashpot sits on the cone
            xi = -(ft + gt * vt) / c.kt;
        }
        h.tangential = xi;
        h.ft = ft;

        // --- force and torque on both bodies ---
        out.f = n * fn_ + t * ft;
        out.t_i = -p.arm_i * ft;
        out.t_j = -p.arm_j * ft;

        // --- rolling resistance (elastic-plastic spring, dashpot below the cap) ---
        let mut roll_work = 0.0;
        if ROLLING {
            let wr = p.w_i - p.w_j;
            let th_old = h.rolling;
            let m_old = h.mr;
            let mut th = th_old + wr * dt;
            let mut m = -c.kr * th;
            let m_max = c.mu_r * p.r_roll * fn_;
            let plastic = m.abs() >= m_max;
            if plastic {
                // full mobilisation: the spring sits on the cap, no dashpot
                m = m_max.copysign(m);
                th = -m / c.kr;
            } else if IMPLICIT {
                let cap = if c.cap_dashpot { m_max } else { Real::INFINITY };
                out.roll = RollDashpot { c: c.cr, m_spring: m, m_max: cap };
            } else {
                m -= c.cr * wr;
                if c.cap_dashpot && m.abs() > m_max {
                    // spring + dashpot on the cap (LAMMPS `rolling sds`): rescale the spring
                    m = m_max.copysign(m);
                    th = -(m + c.cr * wr) / c.kr;
                }
            }
            h.rolling = th;
            h.mr = m;
            out.t_i += m;
            out.t_j -= m;
            if LEDGER {
                // energy taken from the grains by the moment (trapezoid) minus what the
                // spring stored
                roll_work = -0.5 * (m_old + m) * wr * dt - 0.5 * c.kr * (th * th - th_old * th_old);
            }
        }

        if LEDGER {
            out.work.normal = -(fn_ - f_el) * vn * dt;
            out.work.tangential = -0.5 * (ft_old + ft) * vt * dt - 0.5 * c.kt * (xi * xi - xi_old * xi_old);
            out.work.rolling = roll_work;
        }
        out
    }

    /// Stored energy of the springs of a contact that separates (booked as dissipated).
    #[inline(always)]
    pub fn released(c: &LawCoeffs, h: &ContactState) -> (Real, Real) {
        (0.5 * c.kt * h.tangential * h.tangential, if ROLLING { 0.5 * c.kr * h.rolling * h.rolling } else { 0.0 })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::params::{ContactParams, RollingParams};

    fn coeffs() -> LawCoeffs { LawCoeffs::new(&ContactParams::grain(), &RollingParams::default()) }

    fn pin(overlap: Real, v_rel: Vec2) -> PairIn {
        PairIn { n: Vec2::new(0.0, 1.0), overlap, v_rel, w_i: 0.0, w_j: 0.0, arm_i: 5e-4, arm_j: 5e-4, r_roll: 2.5e-4, cn: 80.0 }
    }

    #[test]
    fn no_attraction_when_separating_fast() {
        let mut h = ContactState::default();
        let o = Law::<false, true, true>::eval(&coeffs(), &pin(1e-9, Vec2::new(0.0, 10.0)), &mut h, 1e-7);
        assert_eq!(o.f.y, 0.0);
        assert!(o.work.normal > 0.0);
    }

    #[test]
    fn coulomb_cap_rescales_spring() {
        let c = coeffs();
        let mut h = ContactState { tangential: 1e-3, ..Default::default() };
        let p = pin(1e-7, Vec2::new(0.0, 0.0));
        let o = Law::<false, true, false>::eval(&c, &p, &mut h, 1e-7);
        let fn_ = c.kn * 1e-7;
        assert!((o.f.x.abs() - c.mu * fn_).abs() < 1e-9 * fn_);
        assert!((c.kt * h.tangential.abs() - c.mu * fn_).abs() < 1e-9 * fn_);
        // the tangential force opposes the stored elongation (+x along t = (-1, 0))
        assert!(o.f.x > 0.0);
    }

    #[test]
    fn pure_stick_books_no_tangential_or_rolling_dissipation() {
        // A sticking contact loads its tangential and rolling springs: the work done on
        // them is stored, not dissipated. Booking end-of-step force × displacement (the old
        // rule) books ½kΔξ² each step; the trapezoid of the stored previous force is exact.
        let c = coeffs();
        let mut h = ContactState::default();
        let mut p = pin(1e-6, Vec2::new(1e-4, 0.0));
        p.w_i = 1e-3;
        let dt = 1e-7;
        let (mut wt, mut wr) = (0.0, 0.0);
        for _ in 0..100 {
            let o = Law::<true, true, true>::eval(&c, &p, &mut h, dt);
            wt += o.work.tangential;
            wr += o.work.rolling;
        }
        let stored_t = 0.5 * c.kt * h.tangential * h.tangential;
        let stored_r = 0.5 * c.kr * h.rolling * h.rolling;
        assert!(stored_t > 0.0 && h.ft.abs() < c.mu * c.kn * 1e-6, "still sticking");
        assert!(wt.abs() <= 1e-9 * stored_t, "tangential dissipation {wt:e} booked during pure stick (stored {stored_t:e})");
        assert!(wr.abs() <= 1e-9 * stored_r, "rolling dissipation {wr:e} booked during pure stick (stored {stored_r:e})");
    }

    #[test]
    fn rolling_cap_and_equal_opposite_moments() {
        let c = coeffs();
        let mut h = ContactState { rolling: 1.0, ..Default::default() };
        let p = pin(1e-7, Vec2::zeros());
        let o = Law::<true, true, false>::eval(&c, &p, &mut h, 1e-7);
        let m_max = c.mu_r * 2.5e-4 * c.kn * 1e-7;
        assert!((o.t_i + m_max).abs() < 1e-12);
        assert!((o.t_i + o.t_j).abs() < 1e-15);
        assert_eq!(o.roll.c, 0.0, "no dashpot at full mobilisation");
    }
}

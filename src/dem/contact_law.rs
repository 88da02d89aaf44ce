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
use crate::math::{Real, Vec2, select};

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
        // Both outcomes of the cone test are computed and one is selected, without a
        // branch: whether a contact slides follows no pattern along the pair list, and as
        // a branch it was mispredicted contact after contact.
        let xi_stick = xi_old + vt * dt;
        let gt = c.gt_ratio * p.cn;
        let ft_stick = -c.kt * xi_stick - gt * vt;
        let ft_max = c.mu * fn_;
        let slide = ft_stick.abs() > ft_max;
        let ft_slide = ft_max.copysign(ft_stick);
        // rescale the stored spring so spring + dashpot sits on the cone
        let xi_slide = -(ft_slide + gt * vt) / c.kt;
        let ft = select(slide, ft_slide, ft_stick);
        let xi = select(slide, xi_slide, xi_stick);
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
            let th_el = th_old + wr * dt;
            let m_el = -c.kr * th_el;
            let m_max = c.mu_r * p.r_roll * fn_;
            // branch-free as the cone test above
            let plastic = m_el.abs() >= m_max;
            // full mobilisation: the spring sits on the cap, no dashpot
            let m_pl = m_max.copysign(m_el);
            let th_pl = -m_pl / c.kr;
            let mut m = select(plastic, m_pl, m_el);
            let mut th = select(plastic, th_pl, th_el);
            if IMPLICIT {
                let cap = if c.cap_dashpot { m_max } else { Real::INFINITY };
                out.roll = RollDashpot {
                    c: select(plastic, 0.0, c.cr),
                    m_spring: m,
                    m_max: cap,
                };
            } else if !plastic {
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
        (
            0.5 * c.kt * h.tangential * h.tangential,
            if ROLLING {
                0.5 * c.kr * h.rolling * h.rolling
            } else {
                0.0
            },
        )
    }
}

/// Contacts per batch of [`eval_pairs`] (its scratch stays in L1).
pub(crate) const BATCH: usize = 64;

/// Inputs of a batch of grain pairs, lane by lane (structure of arrays): the separation
/// (dx, dy) = x_i − x_j, its square, r_i + r_j, the relative velocity, spins, radii, the
/// pair's rolling radius and normal dashpot, and the history (ξ_t, θ_r, F_t, M_r) in,
/// updated in place.
#[derive(Clone)]
pub(crate) struct PairBatch {
    pub dx: [Real; BATCH],
    pub dy: [Real; BATCH],
    pub rsq: [Real; BATCH],
    pub radsum: [Real; BATCH],
    pub dvx: [Real; BATCH],
    pub dvy: [Real; BATCH],
    pub w_i: [Real; BATCH],
    pub w_j: [Real; BATCH],
    pub r_i: [Real; BATCH],
    pub r_j: [Real; BATCH],
    pub r_roll: [Real; BATCH],
    pub cn: [Real; BATCH],
    pub h: [[Real; BATCH]; 4],
}

/// Results of a batch, lane by lane: overlap, force on i, torques, rolling dashpot
/// (c, M_spring, M_max), work (normal, tangential, rolling).
#[derive(Clone)]
pub(crate) struct PairBatchOut {
    pub overlap: [Real; BATCH],
    pub fx: [Real; BATCH],
    pub fy: [Real; BATCH],
    pub t_i: [Real; BATCH],
    pub t_j: [Real; BATCH],
    pub roll: [[Real; BATCH]; 3],
    pub work: [[Real; BATCH]; 3],
}

impl Default for PairBatch {
    fn default() -> Self {
        let z = [0.0; BATCH];
        PairBatch {
            dx: z,
            dy: z,
            rsq: z,
            radsum: z,
            dvx: z,
            dvy: z,
            w_i: z,
            w_j: z,
            r_i: z,
            r_j: z,
            r_roll: z,
            cn: z,
            h: [z; 4],
        }
    }
}

impl Default for PairBatchOut {
    fn default() -> Self {
        let z = [0.0; BATCH];
        PairBatchOut {
            overlap: z,
            fx: z,
            fy: z,
            t_i: z,
            t_j: z,
            roll: [z; 3],
            work: [z; 3],
        }
    }
}

impl<const ROLLING: bool, const IMPLICIT: bool, const LEDGER: bool> Law<ROLLING, IMPLICIT, LEDGER> {
    /// [`Law::eval`] of the first `nb` lanes of a batch of touching grain pairs, with the
    /// pair geometry (d = √rsq, n = (dx, dy)/d, δ = r_i + r_j − d) — lane by lane the very
    /// same arithmetic as one call per pair, so the results are bit-identical to it. The
    /// lanes are independent and the law has no branch on a lane's data, so the loop runs
    /// several contacts at once (SIMD), where one contact after another was bound by the
    /// latency of its chain √ → ÷ → cone test → ÷.
    ///
    /// Inlined into its caller, which is built for the widest vector unit the CPU has
    /// (`passes::PairPass::chunk` dispatches to AVX-512, AVX2, else the baseline's SSE2):
    /// IEEE add, multiply, divide and square root are exactly rounded at any width, and
    /// no multiply–add is fused, so every width gives the same bits.
    #[inline(always)]
    pub(crate) fn eval_pairs(c: &LawCoeffs, b: &mut PairBatch, o: &mut PairBatchOut, nb: usize, dt: Real) {
        let nb = nb.min(BATCH);
        for l in 0..nb {
            let d = b.rsq[l].sqrt();
            let inv = 1.0 / d;
            let overlap = b.radsum[l] - d;
            let pin = PairIn {
                n: Vec2::new(b.dx[l] * inv, b.dy[l] * inv),
                overlap,
                v_rel: Vec2::new(b.dvx[l], b.dvy[l]),
                w_i: b.w_i[l],
                w_j: b.w_j[l],
                arm_i: b.r_i[l],
                arm_j: b.r_j[l],
                r_roll: b.r_roll[l],
                cn: b.cn[l],
            };
            let mut h = ContactState {
                tangential: b.h[0][l],
                rolling: b.h[1][l],
                ft: b.h[2][l],
                mr: b.h[3][l],
            };
            let r = Self::eval(c, &pin, &mut h, dt);
            b.h[0][l] = h.tangential;
            b.h[1][l] = h.rolling;
            b.h[2][l] = h.ft;
            b.h[3][l] = h.mr;
            o.overlap[l] = overlap;
            o.fx[l] = r.f.x;
            o.fy[l] = r.f.y;
            o.t_i[l] = r.t_i;
            o.t_j[l] = r.t_j;
            o.roll[0][l] = r.roll.c;
            o.roll[1][l] = r.roll.m_spring;
            o.roll[2][l] = r.roll.m_max;
            o.work[0][l] = r.work.normal;
            o.work[1][l] = r.work.tangential;
            o.work[2][l] = r.work.rolling;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::params::{ContactParams, RollingParams};

    fn coeffs() -> LawCoeffs {
        LawCoeffs::new(&ContactParams::grain(), &RollingParams::default())
    }

    fn pin(overlap: Real, v_rel: Vec2) -> PairIn {
        PairIn {
            n: Vec2::new(0.0, 1.0),
            overlap,
            v_rel,
            w_i: 0.0,
            w_j: 0.0,
            arm_i: 5e-4,
            arm_j: 5e-4,
            r_roll: 2.5e-4,
            cn: 80.0,
        }
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
        let mut h = ContactState {
            tangential: 1e-3,
            ..Default::default()
        };
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
        assert!(
            wt.abs() <= 1e-9 * stored_t,
            "tangential dissipation {wt:e} booked during pure stick (stored {stored_t:e})"
        );
        assert!(
            wr.abs() <= 1e-9 * stored_r,
            "rolling dissipation {wr:e} booked during pure stick (stored {stored_r:e})"
        );
    }

    #[test]
    fn rolling_cap_and_equal_opposite_moments() {
        let c = coeffs();
        let mut h = ContactState {
            rolling: 1.0,
            ..Default::default()
        };
        let p = pin(1e-7, Vec2::zeros());
        let o = Law::<true, true, false>::eval(&c, &p, &mut h, 1e-7);
        let m_max = c.mu_r * 2.5e-4 * c.kn * 1e-7;
        assert!((o.t_i + m_max).abs() < 1e-12);
        assert!((o.t_i + o.t_j).abs() < 1e-15);
        assert_eq!(o.roll.c, 0.0, "no dashpot at full mobilisation");
    }

    type EvalPairs = unsafe fn(&LawCoeffs, &mut PairBatch, &mut PairBatchOut, usize, Real);

    fn eval_base<const R: bool, const I: bool, const L: bool>(
        c: &LawCoeffs,
        b: &mut PairBatch,
        o: &mut PairBatchOut,
        nb: usize,
        dt: Real,
    ) {
        Law::<R, I, L>::eval_pairs(c, b, o, nb, dt)
    }

    /// The batched law built for AVX2.
    ///
    /// # Safety
    /// The CPU has AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn eval_avx2<const R: bool, const I: bool, const L: bool>(
        c: &LawCoeffs,
        b: &mut PairBatch,
        o: &mut PairBatchOut,
        nb: usize,
        dt: Real,
    ) {
        Law::<R, I, L>::eval_pairs(c, b, o, nb, dt)
    }

    /// The batched law built for AVX-512.
    ///
    /// # Safety
    /// The CPU has AVX-512F.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn eval_avx512<const R: bool, const I: bool, const L: bool>(
        c: &LawCoeffs,
        b: &mut PairBatch,
        o: &mut PairBatchOut,
        nb: usize,
        dt: Real,
    ) {
        Law::<R, I, L>::eval_pairs(c, b, o, nb, dt)
    }

    /// The batched law built for each vector width this CPU has (the pair pass runs the
    /// widest) gives the same bits as one scalar call per contact, over sticking, sliding,
    /// rolling-plastic, separating and capped contacts.
    fn batch_matches_scalar<const R: bool, const I: bool, const L: bool>(cap_dashpot: bool) {
        let mut widths: Vec<(&str, EvalPairs)> = vec![("baseline", eval_base::<R, I, L>)];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                widths.push(("avx2", eval_avx2::<R, I, L>));
            }
            if std::arch::is_x86_feature_detected!("avx512f") {
                widths.push(("avx512f", eval_avx512::<R, I, L>));
            }
        }
        for (name, eval) in widths {
            eprintln!("lanes built for {name}");
            batch_matches_scalar_with::<R, I, L>(cap_dashpot, eval);
        }
    }

    fn batch_matches_scalar_with<const R: bool, const I: bool, const L: bool>(cap_dashpot: bool, eval: EvalPairs) {
        let mut c = coeffs();
        c.cap_dashpot = cap_dashpot;
        let mut rng = crate::sample::rng::SplitMix64(7);
        let mut u = |a: Real, b: Real| a + (b - a) * rng.next_f64();
        let mut b = PairBatch::default();
        let mut o = PairBatchOut::default();
        let nb = BATCH - 3;
        let mut want = Vec::new();
        for l in 0..nb {
            let (ri, rj) = (u(4e-4, 7e-4), u(4e-4, 7e-4));
            let d = (ri + rj) * u(0.995, 1.0005);
            let ang = u(0.0, 6.3);
            let (dx, dy) = (d * ang.cos(), d * ang.sin());
            b.dx[l] = dx;
            b.dy[l] = dy;
            b.rsq[l] = dx * dx + dy * dy;
            b.radsum[l] = ri + rj;
            b.dvx[l] = u(-0.3, 0.3);
            b.dvy[l] = u(-0.3, 0.3);
            b.w_i[l] = u(-300.0, 300.0);
            b.w_j[l] = u(-300.0, 300.0);
            b.r_i[l] = ri;
            b.r_j[l] = rj;
            b.r_roll[l] = ri * rj / (ri + rj);
            b.cn[l] = u(10.0, 100.0);
            // springs loaded up to twice their caps: both sides of the cone tests
            let f_scale = c.kn * (ri + rj - d).max(1e-9);
            let h = ContactState {
                tangential: u(-2.0, 2.0) * c.mu * f_scale / c.kt,
                rolling: u(-2.0, 2.0) * c.mu_r * (ri * rj / (ri + rj)) * f_scale / c.kr,
                ft: u(-1.0, 1.0) * c.mu * f_scale,
                mr: u(-1e-4, 1e-4),
            };
            b.h[0][l] = h.tangential;
            b.h[1][l] = h.rolling;
            b.h[2][l] = h.ft;
            b.h[3][l] = h.mr;
            let dd = b.rsq[l].sqrt();
            let inv = 1.0 / dd;
            let p = PairIn {
                n: Vec2::new(dx * inv, dy * inv),
                overlap: ri + rj - dd,
                v_rel: Vec2::new(b.dvx[l], b.dvy[l]),
                w_i: b.w_i[l],
                w_j: b.w_j[l],
                arm_i: ri,
                arm_j: rj,
                r_roll: b.r_roll[l],
                cn: b.cn[l],
            };
            let mut hh = h;
            let r = Law::<R, I, L>::eval(&c, &p, &mut hh, 1e-6);
            want.push((hh, r, p.overlap));
        }
        // SAFETY: `eval` is built for a feature this CPU has
        unsafe { eval(&c, &mut b, &mut o, nb, 1e-6) };
        let bits = |v: &[Real]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let (mut touching, mut sliding, mut plastic) = (0, 0, 0);
        for (l, (h, r, ov)) in want.iter().enumerate() {
            if *ov <= 0.0 {
                continue;
            }
            touching += 1;
            // on the Coulomb cone: |F_t| = μ F_n (sliding lane)
            let fnn = r.f.dot(&Vec2::new(b.dx[l], b.dy[l])) / b.rsq[l].sqrt();
            sliding += usize::from((h.ft.abs() - c.mu * fnn).abs() <= 1e-12 * fnn.abs());
            plastic += usize::from(R && I && r.roll.c == 0.0);
            assert_eq!(
                bits(&[b.h[0][l], b.h[1][l], b.h[2][l], b.h[3][l]]),
                bits(&[h.tangential, h.rolling, h.ft, h.mr]),
                "history, lane {l}"
            );
            assert_eq!(
                bits(&[o.overlap[l], o.fx[l], o.fy[l], o.t_i[l], o.t_j[l]]),
                bits(&[*ov, r.f.x, r.f.y, r.t_i, r.t_j]),
                "forces, lane {l}"
            );
            assert_eq!(
                bits(&[o.roll[0][l], o.work[0][l], o.work[1][l], o.work[2][l]]),
                bits(&[r.roll.c, r.work.normal, r.work.tangential, r.work.rolling]),
                "dashpot/work, lane {l}"
            );
            if r.roll.c > 0.0 {
                assert_eq!(
                    bits(&[o.roll[1][l], o.roll[2][l]]),
                    bits(&[r.roll.m_spring, r.roll.m_max]),
                    "dashpot, lane {l}"
                );
            }
        }
        assert!(touching > 10 && touching < nb, "touching lanes: {touching} of {nb}");
        assert!(
            sliding > 0 && sliding < touching,
            "sliding lanes: {sliding} of {touching}"
        );
        if R && I {
            assert!(
                plastic > 0 && plastic < touching,
                "rolling-plastic lanes: {plastic} of {touching}"
            );
        }
    }

    #[test]
    fn batched_law_is_bit_identical_to_the_scalar_law() {
        batch_matches_scalar::<true, true, true>(true);
        batch_matches_scalar::<true, true, true>(false);
        batch_matches_scalar::<true, false, true>(true);
        batch_matches_scalar::<true, true, false>(true);
        batch_matches_scalar::<false, false, true>(true);
        batch_matches_scalar::<false, false, false>(true);
    }
}

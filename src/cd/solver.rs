//! The `gauss_seidel` phase: nonlinear Gauss–Seidel (NLGS) over the active contacts in
//! their fixed (key) order, each contact solved exactly as a 2×2 Signorini–Coulomb problem
//! with its Delassus block while the others are frozen (Jean 1999; Moreau 1993).
//!
//! Local problem of contact c (q = u⁺ + bias, Moreau's formal velocity times (1+ε)):
//!   q = W P + q_free,   0 ≤ q_n ⊥ P_n ≥ 0,   |P_t| ≤ μ P_n,
//!   |P_t| < μ P_n ⇒ q_t = 0,   |P_t| = μ P_n ⇒ q_t = −λ P_t, λ ≥ 0.
//! Solved by enumeration: separation, sticking (W P = −q_free), sliding in either
//! direction; the first consistent case is the solution (unique when W_nt = 0, i.e. for
//! every contact between grains with isotropic mass).
//!
//! Convergence (both stated, both reported): (1) the quadratic-mean relative impulse change
//! of one sweep η = ‖ΔP‖₂/‖P‖₂ ≤ `tolerance` (LMGC90 "Quad"-like); once it passes, (2) the
//! natural-map residual r = ‖P − proj_K(P − ρ q̂)‖₂/‖(P, ρq)‖₂, ρ = 1/W_nn, q̂ = (q_n + μ|q_t|, q_t)
//! (De Saxcé), ≤ `residual_tolerance`. `max_iterations` caps the sweeps; a capped step is
//! reported unconverged. Sequential sweeps in key order: the result does not depend on
//! threads. (`CdParams::coloured_sweeps` picks the colour-class sweep of `cd::colour`
//! instead, which shares this file's per-contact update.)

use crate::cd::body::Body;
use crate::cd::contacts::Row;
use crate::math::Real;

/// Outcome of one contact solve.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SolveInfo {
    /// Sweeps done.
    pub iterations: u32,
    /// η of the last sweep.
    pub change: Real,
    /// Natural-map residual at exit (computed when η passed, or at the cap).
    pub residual: Real,
    /// Both tests passed before the cap.
    pub converged: bool,
}

/// Exact solution of the local 2D Signorini–Coulomb problem q = W P + q0 (W = (W_nn,
/// W_nt, W_tt), symmetric positive semi-definite). Returns (P_n, P_t).
#[inline(always)]
pub fn local_solve(w: [Real; 3], mu: Real, q0: [Real; 2]) -> [Real; 2] {
    let [wnn, wnt, wtt] = w;
    // separation: no impulse leaves q_n ≥ 0
    if q0[0] >= 0.0 {
        return [0.0, 0.0];
    }
    // sticking: q = 0
    let det = wnn * wtt - wnt * wnt;
    let mut pt_stick = 0.0;
    if det > 1e-14 * (wnn * wtt).max(Real::MIN_POSITIVE) {
        let pn = (-q0[0] * wtt + q0[1] * wnt) / det;
        let pt = (-q0[1] * wnn + q0[0] * wnt) / det;
        if pn >= 0.0 && pt.abs() <= mu * pn {
            return [pn, pt];
        }
        pt_stick = pt;
    }
    // sliding with q_t of sign s and P_t = −s μ P_n; try the direction the sticking
    // impulse points against first
    let s0 = if pt_stick > 0.0 {
        -1.0
    } else if pt_stick < 0.0 {
        1.0
    } else if q0[1] >= 0.0 {
        1.0
    } else {
        -1.0
    };
    for s in [s0, -s0] {
        let den = wnn - s * mu * wnt;
        if den <= 0.0 {
            continue;
        }
        let pn = -q0[0] / den;
        let qt = (wnt - s * mu * wtt) * pn + q0[1];
        if s * qt >= 0.0 {
            return [pn, -s * mu * pn];
        }
    }
    // degenerate W (should not happen for a free body): frictionless normal solve
    if wnn > 0.0 { [-q0[0] / wnn, 0.0] } else { [0.0, 0.0] }
}

/// Local relative velocity (u_n, u_t) of a row from the body velocities.
#[inline(always)]
pub fn relative_velocity(r: &Row, va: &[Real; 3], vb: &[Real; 3]) -> [Real; 2] {
    let (n, t) = (r.n, [-r.n[1], r.n[0]]);
    let dv = [vb[0] - va[0], vb[1] - va[1]];
    [
        dv[0] * n[0] + dv[1] * n[1],
        dv[0] * t[0] + dv[1] * t[1] - va[2] * r.ra - vb[2] * r.rb,
    ]
}

/// Where a sweep reads and writes the body velocities: the body slice (a sequential
/// sweep) or a shared view whose rows do not collide (a colour class, [`crate::cd::colour`]).
pub(crate) trait BodyStore {
    /// Body `i`.
    fn body(&self, i: u32) -> Body;
    /// Store body `i`'s new velocity.
    fn put_v(&mut self, i: u32, v: [Real; 3]);
}

impl BodyStore for [Body] {
    #[inline(always)]
    fn body(&self, i: u32) -> Body {
        self[i as usize]
    }
    #[inline(always)]
    fn put_v(&mut self, i: u32, v: [Real; 3]) {
        self[i as usize].v = v;
    }
}

/// Apply impulse increment (dP_n, dP_t) of a row to its two bodies.
#[inline(always)]
pub fn apply(r: &Row, bodies: &mut [Body], dp: [Real; 2]) {
    apply_to(r, bodies, dp)
}

#[inline(always)]
pub(crate) fn apply_to<S: BodyStore + ?Sized>(r: &Row, bodies: &mut S, dp: [Real; 2]) {
    let (n, t) = (r.n, [-r.n[1], r.n[0]]);
    let px = dp[0] * n[0] + dp[1] * t[0];
    let py = dp[0] * n[1] + dp[1] * t[1];
    let mut b = bodies.body(r.b);
    b.v[0] += b.inv[0] * px;
    b.v[1] += b.inv[1] * py;
    b.v[2] -= b.inv[2] * r.rb * dp[1];
    bodies.put_v(r.b, b.v);
    let mut a = bodies.body(r.a);
    a.v[0] -= a.inv[0] * px;
    a.v[1] -= a.inv[1] * py;
    a.v[2] -= a.inv[2] * r.ra * dp[1];
    bodies.put_v(r.a, a.v);
}

/// Solver settings (from [`CdParams`](crate::cd::CdParams)).
#[derive(Debug, Clone, Copy)]
pub struct Settings {
    /// η tolerance.
    pub tolerance: Real,
    /// Natural-map residual tolerance.
    pub residual_tolerance: Real,
    /// Sweep cap.
    pub max_iterations: u32,
    /// Under-relaxation ω.
    pub relaxation: Real,
}

/// Natural-map residual ‖P − proj_K(P − ρ q̂)‖₂ / ‖(P, ρq)‖₂ of the current state (no
/// update; the ρq term only matters where no contact carries an impulse).
pub fn residual(rows: &[Row], bodies: &[Body]) -> Real {
    let (mut num, mut den) = (0.0, 0.0);
    for r in rows {
        let u = relative_velocity(r, &bodies[r.a as usize].v, &bodies[r.b as usize].v);
        let q = [u[0] + r.bias[0], u[1] + r.bias[1]];
        let rho = if r.w[0] > 0.0 {
            1.0 / r.w[0]
        } else {
            1.0 / r.w[2].max(Real::MIN_POSITIVE)
        };
        let z = [r.p[0] - rho * (q[0] + r.mu * q[1].abs()), r.p[1] - rho * q[1]];
        let pr = project_cone(z, r.mu);
        let d = [r.p[0] - pr[0], r.p[1] - pr[1]];
        num += d[0] * d[0] + d[1] * d[1];
        den += r.p[0] * r.p[0] + r.p[1] * r.p[1] + rho * rho * (q[0] * q[0] + q[1] * q[1]);
    }
    if den > 0.0 { (num / den).sqrt() } else { 0.0 }
}

/// Projection of (z_n, z_t) on the Coulomb cone |z_t| ≤ μ z_n.
#[inline(always)]
pub fn project_cone(z: [Real; 2], mu: Real) -> [Real; 2] {
    let at = z[1].abs();
    if at <= mu * z[0] {
        return z;
    }
    if mu * at <= -z[0] {
        return [0.0, 0.0];
    }
    let pn = (z[0] + mu * at) / (1.0 + mu * mu);
    [pn, mu * pn * z[1].signum()]
}

/// Apply a rolling moment impulse increment dM (+dM on b, −dM on a).
#[inline(always)]
pub fn apply_rolling(r: &Row, bodies: &mut [Body], dm: Real) {
    apply_rolling_to(r, bodies, dm)
}

#[inline(always)]
fn apply_rolling_to<S: BodyStore + ?Sized>(r: &Row, bodies: &mut S, dm: Real) {
    let mut b = bodies.body(r.b);
    b.v[2] += b.inv[2] * dm;
    bodies.put_v(r.b, b.v);
    let mut a = bodies.body(r.a);
    a.v[2] -= a.inv[2] * dm;
    bodies.put_v(r.a, a.v);
}

/// Run NLGS sweeps. On entry the bodies hold the free velocities plus the warm-start
/// impulses of `rows` (already applied). With rolling resistance (`roll` = Some((M_r,
/// r_eff, μ_r))), each contact solves its (P_n, P_t) block, then its rolling moment with
/// P_n fixed, M_r = clamp(−(ω_rel − W_rr M_r)/W_rr, ±μ_r r_eff P_n), W_rr = 1/I_a + 1/I_b
/// (block Gauss–Seidel within the contact; same fixed point).
pub fn gauss_seidel(
    rows: &mut [Row],
    bodies: &mut [Body],
    s: &Settings,
    roll: Option<(&mut [Real], &[Real], Real)>,
) -> SolveInfo {
    solve(rows, bodies, s, roll, sweeps::<false>, sweeps::<true>)
}

/// A sweep loop (rows, bodies, settings, rolling moments, rolling radii, μ_r): the key
/// order of this file or the colour classes of `cd::colour`.
pub(crate) type Sweeps = fn(&mut [Row], &mut [Body], &Settings, &mut [Real], &[Real], Real) -> SolveInfo;

/// The `gauss_seidel` phase with the sweep loops `plain` (no rolling resistance) and
/// `rolling`: nothing to do without contacts.
pub(crate) fn solve(
    rows: &mut [Row],
    bodies: &mut [Body],
    s: &Settings,
    roll: Option<(&mut [Real], &[Real], Real)>,
    plain: Sweeps,
    rolling: Sweeps,
) -> SolveInfo {
    if rows.is_empty() {
        return SolveInfo {
            converged: true,
            ..SolveInfo::default()
        };
    }
    match roll {
        None => plain(rows, bodies, s, &mut [], &[], 0.0),
        Some((mr, re, mu_r)) => rolling(rows, bodies, s, mr, re, mu_r),
    }
}

/// One contact's update in a sweep: its (P_n, P_t) block, then (with `ROLL`) its rolling
/// moment with P_n fixed, adding this contact's |ΔP|² and |P|² to the sweep's `sums` (in
/// the order the sequential sweep always added them).
#[inline(always)]
pub(crate) fn update_row<const ROLL: bool, S: BodyStore + ?Sized>(
    r: &mut Row,
    mr: &mut Real,
    re: Real,
    mu_r: Real,
    omega: Real,
    bodies: &mut S,
    sums: &mut (Real, Real),
) {
    let va = bodies.body(r.a).v;
    let vb = bodies.body(r.b).v;
    let u = relative_velocity(r, &va, &vb);
    // velocity this contact would see without its own impulse, plus the bias
    let q0 = [
        u[0] - (r.w[0] * r.p[0] + r.w[1] * r.p[1]) + r.bias[0],
        u[1] - (r.w[1] * r.p[0] + r.w[2] * r.p[1]) + r.bias[1],
    ];
    let mut p = local_solve(r.w, r.mu, q0);
    if omega != 1.0 {
        p = [
            omega * p[0] + (1.0 - omega) * r.p[0],
            omega * p[1] + (1.0 - omega) * r.p[1],
        ];
    }
    let dp = [p[0] - r.p[0], p[1] - r.p[1]];
    if dp[0] != 0.0 || dp[1] != 0.0 {
        apply_to(r, bodies, dp);
        r.p = p;
    }
    sums.0 += dp[0] * dp[0] + dp[1] * dp[1];
    sums.1 += p[0] * p[0] + p[1] * p[1];
    if ROLL {
        let (ba, bb) = (bodies.body(r.a), bodies.body(r.b));
        let wrr = ba.inv[2] + bb.inv[2];
        if wrr > 0.0 {
            let lim = mu_r * re * r.p[0];
            let m = (*mr - (bb.v[2] - ba.v[2]) / wrr).clamp(-lim, lim);
            let dm = m - *mr;
            if dm != 0.0 {
                apply_rolling_to(r, bodies, dm);
                *mr = m;
            }
            let (dmr, mrr) = (dm / re, m / re);
            sums.0 += dmr * dmr;
            sums.1 += mrr * mrr;
        }
    }
}

/// η of a sweep from its sums.
pub(crate) fn change(dsum: Real, psum: Real) -> Real {
    if psum > 0.0 {
        (dsum / psum).sqrt()
    } else if dsum > 0.0 {
        Real::INFINITY
    } else {
        0.0
    }
}

fn sweeps<const ROLL: bool>(
    rows: &mut [Row],
    bodies: &mut [Body],
    s: &Settings,
    mr: &mut [Real],
    re: &[Real],
    mu_r: Real,
) -> SolveInfo {
    let mut info = SolveInfo::default();
    let omega = s.relaxation;
    for it in 1..=s.max_iterations {
        let mut sums = (0.0, 0.0);
        for (k, r) in rows.iter_mut().enumerate() {
            if ROLL {
                update_row::<true, _>(r, &mut mr[k], re[k], mu_r, omega, bodies, &mut sums);
            } else {
                update_row::<false, _>(r, &mut 0.0, 1.0, 0.0, omega, bodies, &mut sums);
            }
        }
        info.iterations = it;
        info.change = change(sums.0, sums.1);
        if info.change <= s.tolerance {
            info.residual = residual(rows, bodies);
            if info.residual <= s.residual_tolerance {
                info.converged = true;
                return info;
            }
        }
    }
    info.residual = residual(rows, bodies);
    info
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(w: [Real; 3], mu: Real, q0: [Real; 2]) {
        let p = local_solve(w, mu, q0);
        let q = [w[0] * p[0] + w[1] * p[1] + q0[0], w[1] * p[0] + w[2] * p[1] + q0[1]];
        let tol = 1e-12 * (1.0 + q0[0].abs() + q0[1].abs());
        assert!(
            p[0] >= 0.0 && q[0] >= -tol && (p[0] * q[0]).abs() <= tol * (1.0 + p[0]),
            "Signorini {p:?} {q:?}"
        );
        assert!(p[1].abs() <= mu * p[0] + tol, "cone {p:?}");
        if p[1].abs() < mu * p[0] - tol {
            assert!(q[1].abs() <= tol, "stick {p:?} {q:?}");
        } else if p[0] > 0.0 {
            assert!(p[1] * q[1] <= tol, "sliding opposes {p:?} {q:?}");
        }
    }

    #[test]
    fn local_solve_satisfies_signorini_coulomb() {
        let mut seed = 1u64;
        let mut rnd = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as Real / (1u64 << 53) as Real * 2.0 - 1.0
        };
        for _ in 0..20000 {
            let (a, b, c) = (rnd().abs() + 0.1, rnd() * 0.3, rnd().abs() + 0.1);
            let w = [a, b * (a * c).sqrt(), c];
            check(w, rnd().abs(), [rnd(), rnd()]);
            check([a, 0.0, c], 0.4, [rnd(), rnd()]);
        }
    }

    #[test]
    fn residual_is_zero_at_the_solution() {
        let z = project_cone([1.0, 2.0], 0.5);
        assert!((z[1] - 0.5 * z[0]).abs() < 1e-15);
        assert_eq!(project_cone([-1.0, 0.1], 0.5), [0.0, 0.0]);
    }
}

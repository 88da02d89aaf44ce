//! Velocity Verlet (kick–drift–kick) for disks, with the semi-implicit rolling dashpot.
//!
//! Translation: v ← v + (h/m) F, h = Δt/2; x ← x + Δt v. Rotation, explicit:
//! ω ← ω + (h/I) M. Rotation with the implicit rolling dashpot (params
//! [`RollingDamping::Implicit`](crate::dem::params::RollingDamping)), split after the
//! explicit moments ω* = ω + (h/I) M:
//! 1. wall partners (spin 0): ω** = ω* / (1 + h C_w / I) (backward Euler);
//! 2. grain partners: ω⁺ = ω** + β (ω̄ − ω**), ω̄ = Σ c_r ω_j / Σ c_r (spins of the force
//!    evaluation), β = x/(1+2x), x = h C_g/I.
//! For an isolated equal pair this is exactly backward Euler of the relative rolling rate,
//! u⁺ = u/(1 + 2x), with angular momentum conserved; in a network ω⁺ is a convex
//! combination with weight ≤ ½ on the partners, so even the alternating (checkerboard)
//! mode decays monotonically: unconditionally stable, no overshoot, no exp() per grain.
//! The dashpot work is booked as the change ½I(ω*² − ω⁺²) it causes.
//! Prescribed grains (1/m = 0) keep their velocity; the work their drivers do is booked
//! as external work.

use crate::dem::world::{GRAIN_CHUNK, Partial, Ptr, World, chunked};
use crate::math::Real;

impl World {
    /// First half kick and drift, fused in one pass over the grains; returns whether the
    /// neighbour list must be rebuilt.
    pub(crate) fn integrate_first_half<const IMP: bool, const L: bool>(&mut self) -> bool {
        let dt = self.params.dt;
        for wall in self.walls.iter_mut() {
            wall.origin += wall.velocity * dt;
        }
        let force_rebuild = self.nl.x0.len() != self.state.len();
        let moved = self.kick_pass::<IMP, L, true>();
        moved || force_rebuild
    }

    /// Second half kick.
    pub(crate) fn integrate_second_half<const IMP: bool, const L: bool>(&mut self) { self.kick_pass::<IMP, L, false>(); }

    /// Half kick of every grain, then (if `DRIFT`) x ← x + Δt v, θ ← θ + Δt ω and the skin
    /// check. Returns whether a grain moved more than skin/2 since the last build.
    fn kick_pass<const IMP: bool, const L: bool, const DRIFT: bool>(&mut self) -> bool {
        let dt = self.params.dt;
        let h = 0.5 * dt;
        let s = &mut self.state;
        let n = s.len();
        let (vx, vy, w) = (Ptr(s.vx.as_mut_ptr()), Ptr(s.vy.as_mut_ptr()), Ptr(s.w.as_mut_ptr()));
        let (x, y, th) = (Ptr(s.x.as_mut_ptr()), Ptr(s.y.as_mut_ptr()), Ptr(s.theta.as_mut_ptr()));
        let (inv_m, inv_i) = (&s.inv_m[..], &s.inv_i[..]);
        let (fx, fy, tq, cr, sr, cw) = (&self.fx[..], &self.fy[..], &self.tq[..], &self.c_roll[..], &self.s_roll[..], &self.c_wall[..]);
        let lim = 0.25 * self.nl.skin * self.nl.skin;
        let have_x0 = self.nl.x0.len() == n;
        let (x0, y0) = (&self.nl.x0[..], &self.nl.y0[..]);
        chunked(n, GRAIN_CHUNK, &mut self.partials, |lo, hi| {
            let mut part = Partial::default();
            for a in lo..hi {
                unsafe {
                    let im = inv_m[a];
                    let ii = inv_i[a];
                    let (vxa, vya, wa) = (vx.get(a), vy.get(a), w.get(a));
                    if L && im == 0.0 {
                        // driver keeps the prescribed velocity against contacts and gravity
                        part.ledger.external_work -= h * (fx[a] * vxa + fy[a] * vya + tq[a] * wa);
                    }
                    let vxn = vxa + h * im * fx[a];
                    let vyn = vya + h * im * fy[a];
                    vx.set(a, vxn);
                    vy.set(a, vyn);
                    let ws = wa + h * ii * tq[a]; // explicit moments (springs, friction)
                    let wn = if IMP && ii > 0.0 {
                        // walls (spin 0): backward Euler of I ω̇ = −C_w ω
                        let mut wn = ws / (1.0 + h * ii * cw[a]);
                        // grains: relax toward the c-weighted mean spin of the partners
                        // with β = x/(1+2x), x = h C_g / I — backward Euler of the
                        // relative rate of an equal pair, β ≤ ½ so no mode overshoots
                        if cr[a] > 0.0 {
                            let x = h * ii * cr[a];
                            let beta = x / (1.0 + 2.0 * x);
                            wn += beta * (sr[a] / cr[a] - wn);
                        }
                        if L {
                            // work of the dashpot step = change of ½Iω² it caused
                            part.ledger.rolling += 0.5 * (ws * ws - wn * wn) / ii;
                        }
                        wn
                    } else {
                        ws
                    };
                    w.set(a, wn);
                    if DRIFT {
                        let xa = x.get(a) + dt * vxn;
                        let ya = y.get(a) + dt * vyn;
                        x.set(a, xa);
                        y.set(a, ya);
                        th.set(a, th.get(a) + dt * wn);
                        if have_x0 {
                            let (dx, dy) = (xa - x0[a], ya - y0[a]);
                            part.moved |= dx * dx + dy * dy > lim;
                        }
                    }
                }
            }
            part
        });
        let mut tot = Partial::default();
        for p in &self.partials {
            tot.merge(p);
        }
        if L {
            self.ledger += tot.ledger;
        }
        tot.moved
    }
}

/// Kinetic energy per grain (helper for the watchdog) [J/m].
pub(crate) fn grain_ke(s: &crate::dem::state::State, i: usize) -> Real {
    0.5 * s.m[i] * (s.vx[i] * s.vx[i] + s.vy[i] * s.vy[i]) + 0.5 * s.inertia[i] * s.w[i] * s.w[i]
}

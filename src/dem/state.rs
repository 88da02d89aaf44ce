//! Grain state as struct-of-arrays, plus the handles that outlive a neighbour rebuild.

use crate::math::{PI, Real};
use serde::{Deserialize, Serialize};

/// Index of a grain; stable for the life of a [`State`] (grains are only removed by
/// building a new state, e.g. when trimming a deposit).
#[repr(transparent)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct GrainId(pub u32);

impl GrainId {
    /// A sentinel that names no grain.
    pub fn invalid() -> Self {
        GrainId(u32::MAX)
    }
}

/// Key of a grain–grain contact, `i < j` (LAMMPS `FixNeighHistory` keys by the pair).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ContactKey {
    /// Smaller grain index.
    pub i: u32,
    /// Larger grain index.
    pub j: u32,
}

impl ContactKey {
    /// Key of the unordered pair {a, b}.
    pub fn new(a: u32, b: u32) -> Self {
        if a < b {
            Self { i: a, j: b }
        } else {
            Self { i: b, j: a }
        }
    }
}

/// Per-contact history. In 2D the tangent space of a contact is one-dimensional, so the
/// tangential spring is a scalar along t = perp(n): that *is* the projection of the stored
/// spring into the current tangent plane, with its magnitude kept (LAMMPS rotates and
/// rescales a 3-vector to get the same effect).
///
/// The force and moment of the last evaluation are kept so that the work of a step is
/// booked by the trapezoid rule, ½(F_old + F_new)·Δu: exact for a spring in pure stick,
/// where end-of-step force × displacement books a spurious ½kΔξ² every step.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ContactState {
    /// Tangential spring elongation ξ_t along t [m].
    pub tangential: Real,
    /// Rolling spring rotation θ_r [rad].
    pub rolling: Real,
    /// Tangential force of the last evaluation, along t [N/m].
    pub ft: Real,
    /// Rolling moment on body i of the last evaluation (spring, plus the dashpot when it is
    /// explicit) [N·m/m].
    pub mr: Real,
}

impl ContactState {
    /// The history of a contact whose grains are renamed to `a` and `b`, keyed (i < j) again:
    /// when the names swap the pair's i and j, its normal and tangent turn over, so ξ_t and
    /// F_t (along t) keep their values and the rolling rotation ω_i − ω_j and the moment on
    /// i change sign. Used by the memory sort and the benchmark's shuffle.
    pub fn renamed(self, a: u32, b: u32) -> (u32, u32, ContactState) {
        if a > b {
            let turned = ContactState {
                rolling: -self.rolling,
                mr: -self.mr,
                ..self
            };
            (b, a, turned)
        } else {
            (a, b, self)
        }
    }
}

/// How a grain moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Motion {
    /// Integrated from forces.
    Free,
    /// Velocity prescribed from outside (fixed or driven layer grains): infinite mass in
    /// the integrator, real mass in the contact law (eq 4.5 m_ij).
    Prescribed,
}

/// Struct-of-arrays grain state (SI, per metre of thickness).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct State {
    /// Centre x [m].
    pub x: Vec<Real>,
    /// Centre y [m].
    pub y: Vec<Real>,
    /// Velocity x [m/s].
    pub vx: Vec<Real>,
    /// Velocity y [m/s].
    pub vy: Vec<Real>,
    /// Angular velocity (counter-clockwise) [rad/s].
    pub w: Vec<Real>,
    /// Accumulated rotation [rad].
    pub theta: Vec<Real>,
    /// Radius [m].
    pub r: Vec<Real>,
    /// Mass m = ρπr² [kg/m].
    pub m: Vec<Real>,
    /// 1/m for free grains, 0 for prescribed ones [1/kg].
    pub inv_m: Vec<Real>,
    /// Moment of inertia I = ½mr² [kg·m].
    pub inertia: Vec<Real>,
    /// 1/I for free grains, 0 for prescribed ones.
    pub inv_i: Vec<Real>,
}

impl State {
    /// An empty state.
    pub fn new() -> Self {
        Self::default()
    }
    /// Empty state with room for `n` grains.
    pub fn with_capacity(n: usize) -> Self {
        let v = || Vec::with_capacity(n);
        Self {
            x: v(),
            y: v(),
            vx: v(),
            vy: v(),
            w: v(),
            theta: v(),
            r: v(),
            m: v(),
            inv_m: v(),
            inertia: v(),
            inv_i: v(),
        }
    }
    /// Number of grains.
    pub fn len(&self) -> usize {
        self.x.len()
    }
    /// No grains.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }
    /// Add a grain at rest at (x, y) with radius r and density ρ; returns its id.
    pub fn insert(&mut self, x: Real, y: Real, r: Real, density: Real) -> GrainId {
        let m = density * PI * r * r;
        let inertia = 0.5 * m * r * r;
        self.x.push(x);
        self.y.push(y);
        self.vx.push(0.0);
        self.vy.push(0.0);
        self.w.push(0.0);
        self.theta.push(0.0);
        self.r.push(r);
        self.m.push(m);
        self.inv_m.push(1.0 / m);
        self.inertia.push(inertia);
        self.inv_i.push(1.0 / inertia);
        GrainId(self.x.len() as u32 - 1)
    }
    /// Set how grain `i` moves.
    pub fn set_motion(&mut self, i: usize, motion: Motion) {
        match motion {
            Motion::Free => {
                self.inv_m[i] = 1.0 / self.m[i];
                self.inv_i[i] = 1.0 / self.inertia[i];
            }
            Motion::Prescribed => {
                self.inv_m[i] = 0.0;
                self.inv_i[i] = 0.0;
            }
        }
    }
    /// Whether grain `i` is integrated.
    pub fn is_free(&self, i: usize) -> bool {
        self.inv_m[i] > 0.0
    }
    /// Keep only the grains for which `keep(i)` is true (order preserved).
    pub fn retain(&self, keep: impl Fn(usize) -> bool) -> State {
        let idx: Vec<usize> = (0..self.len()).filter(|&i| keep(i)).collect();
        self.gather(&idx)
    }
    /// The grains in the order `order` (grain `order[p]` of `self` becomes grain `p`;
    /// `order` is a permutation of `0..len`).
    pub fn permuted(&self, order: &[usize]) -> State {
        assert_eq!(order.len(), self.len(), "a permutation of every grain");
        self.gather(order)
    }
    /// Grain `idx[p]` of `self` as grain `p`, every per-grain array alike.
    fn gather(&self, idx: &[usize]) -> State {
        let pick = |v: &Vec<Real>| idx.iter().map(|&i| v[i]).collect::<Vec<_>>();
        State {
            x: pick(&self.x),
            y: pick(&self.y),
            vx: pick(&self.vx),
            vy: pick(&self.vy),
            w: pick(&self.w),
            theta: pick(&self.theta),
            r: pick(&self.r),
            m: pick(&self.m),
            inv_m: pick(&self.inv_m),
            inertia: pick(&self.inertia),
            inv_i: pick(&self.inv_i),
        }
    }
    /// Total mass [kg/m].
    pub fn total_mass(&self) -> Real {
        self.m.iter().sum()
    }
    /// Total solid area Σπr² [m²].
    pub fn solid_area(&self) -> Real {
        self.r.iter().map(|r| PI * r * r).sum()
    }
    /// Smallest, number-mean and largest radius [m].
    pub fn radius_stats(&self) -> (Real, Real, Real) {
        let mut lo = Real::INFINITY;
        let mut hi: Real = 0.0;
        let mut s = 0.0;
        for &r in &self.r {
            lo = lo.min(r);
            hi = hi.max(r);
            s += r;
        }
        (lo, s / self.r.len().max(1) as Real, hi)
    }
    /// Volume (area) mean diameter Σd·πr²/Σπr² = 2Σr³/Σr² [m] — the chapter's d̄ (1.15 mm
    /// for PSD-COL), used by D01's link gap and D10's tolerance.
    pub fn volume_mean_diameter(&self) -> Real {
        let (mut s3, mut s2) = (0.0, 0.0);
        for &r in &self.r {
            s3 += r * r * r;
            s2 += r * r;
        }
        if s2 > 0.0 { 2.0 * s3 / s2 } else { 0.0 }
    }
    /// Set all velocities and spins to zero.
    pub fn stop(&mut self) {
        self.vx.iter_mut().for_each(|v| *v = 0.0);
        self.vy.iter_mut().for_each(|v| *v = 0.0);
        self.w.iter_mut().for_each(|v| *v = 0.0);
    }
}

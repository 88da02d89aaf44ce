//! The D01 fronts of a set of material points (docs/definitions.md D01): points as bodies
//! of half-size l_p, linked by centre distance, edge gap or shared grid node; the mass
//! quantile. Split from `column.rs`, which runs the collapse and samples these.

use super::particles::Point;
use super::state::State;
use crate::analysis::front::{Body, Front, Link, front, main_mass};
use crate::math::Real;

/// Material points as front bodies: squares of half-size `lp` at the points' positions,
/// with their masses (the one construction every rule below reads).
pub struct PointBodies {
    x: Vec<Real>,
    y: Vec<Real>,
    half: Vec<Real>,
    mass: Vec<Real>,
}

impl PointBodies {
    /// The bodies of `points`, half-size `lp` [m].
    pub fn new(points: &[Point], lp: Real) -> Self {
        PointBodies {
            x: points.iter().map(|p| p.x.x).collect(),
            y: points.iter().map(|p| p.x.y).collect(),
            half: vec![lp; points.len()],
            mass: points.iter().map(|p| p.mass).collect(),
        }
    }
    /// As a front [`Body`].
    pub fn body(&self) -> Body<'_> {
        Body {
            x: &self.x,
            y: &self.y,
            half: &self.half,
            mass: &self.mass,
        }
    }
}

/// Front of a state (D01).
pub fn front_of(state: &State, lp: Real, spacing: Real) -> Front {
    front(
        &PointBodies::new(&state.points, lp).body(),
        Link::Distance(1.5 * spacing),
    )
}

/// Front of a state with an explicit linking rule, points as bodies of half-size `lp`.
pub fn front_linked(state: &State, lp: Real, link: Link) -> Front {
    front(&PointBodies::new(&state.points, lp).body(), link)
}

/// Front with links that follow the points' dilation: points i and j are linked when
/// |x_i − x_j| ≤ 0.75 s (√J_i + √J_j) (= 1.5 s, the D01 rule, for undeformed points). A thin
/// deposit whose points have spread apart (J ≫ 1 at the toe) stays one mass as long as the
/// point volumes still tile it. L and H are still max(x + l_p), max(y + l_p).
pub fn front_of_dilated(state: &State, lp: Real, spacing: Real) -> Front {
    let n = state.points.len();
    let (mut x, mut y, mut m, mut r) = (
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    );
    for p in &state.points {
        x.push(p.x.x);
        y.push(p.x.y);
        m.push(p.mass);
        r.push(0.75 * spacing * p.j.max(1.0).sqrt());
    }
    let idx = main_mass(
        &Body {
            x: &x,
            y: &y,
            half: &r,
            mass: &m,
        },
        Link::Contact { gap: 0.0 },
    );
    let total: Real = m.iter().sum();
    let (mut length, mut height, mut mm) = (0.0 as Real, 0.0 as Real, 0.0);
    for &i in &idx {
        length = length.max(x[i] + lp);
        height = height.max(y[i] + lp);
        mm += m[i];
    }
    Front {
        length,
        height,
        n_main: idx.len(),
        mass_fraction: if total > 0.0 { mm / total } else { 0.0 },
    }
}

/// x below which the fraction `q` of the points' mass lies [m].
pub fn mass_quantile_x(state: &State, q: Real) -> Real {
    let mut xm: Vec<(Real, Real)> = state.points.iter().map(|p| (p.x.x, p.mass)).collect();
    xm.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: Real = xm.iter().map(|v| v.1).sum();
    let mut acc = 0.0;
    for (x, m) in &xm {
        acc += m;
        if acc >= q * total {
            return *x;
        }
    }
    xm.last().map(|v| v.0).unwrap_or(0.0)
}

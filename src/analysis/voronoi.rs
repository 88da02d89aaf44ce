//! Local packing fraction by Voronoi cells (docs/definitions.md D09), for grains.
//!
//! Plain (not radical) Voronoi cells of the grain centres, each clipped to the reach of its
//! grain: the cell of grain i is the square of half-side R_i = r_i + `reach` around its
//! centre, cut by the wall (x ≥ 0) and the base (y ≥ 0) and by the perpendicular bisector
//! of every neighbour closer than 2R_i (Sutherland–Hodgman clipping of a convex polygon by
//! half-planes). A cell is *interior* when every vertex lies within r_i + `reach` of its
//! centre: then no side of the square survives and the cell is the exact Voronoi cell;
//! free-surface grains, grains beside large voids and a dilute front fail the test and are
//! left out, so φ measures the mass, not the air around it. The stages use reach = 0.4 d̄:
//! a regular hexagonal cell reaches r + 0.08 d, a square-lattice one r + 0.21 d, while
//! a grain on a flat free face of a crystal reaches r + 0.5 d and is left out. Local φ_i = π r_i² / A_i; a
//! region's packing fraction is Σ π r_i² / Σ A_i over its interior cells.
//!
//! (The `voronoice` crate was tried first: it panics on a hexagonal lattice — cocircular
//! sites put Voronoi vertices on its bounding box — which is one of our packings.)

/// Voronoi cells of one configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct Cells {
    /// Cell area of each grain, clipped as in the module docs [m²].
    pub area: Vec<f64>,
    /// Whether the cell is interior (see the module docs).
    pub interior: Vec<bool>,
}

/// Keep the part of convex polygon `poly` with (p − m)·n ≤ 0.
fn clip(poly: &[(f64, f64)], m: (f64, f64), n: (f64, f64)) -> Vec<(f64, f64)> {
    let side = |p: (f64, f64)| (p.0 - m.0) * n.0 + (p.1 - m.1) * n.1;
    let mut out = Vec::with_capacity(poly.len() + 1);
    for k in 0..poly.len() {
        let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
        let (sa, sb) = (side(a), side(b));
        if sa <= 0.0 {
            out.push(a);
        }
        if (sa < 0.0 && sb > 0.0) || (sa > 0.0 && sb < 0.0) {
            let t = sa / (sa - sb);
            out.push((a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1)));
        }
    }
    out
}

fn area(poly: &[(f64, f64)]) -> f64 {
    let mut a = 0.0;
    for k in 0..poly.len() {
        let (p, q) = (poly[k], poly[(k + 1) % poly.len()]);
        a += p.0 * q.1 - q.0 * p.1;
    }
    0.5 * a.abs()
}

/// Voronoi cells of grains at (x, y) with radii r; `reach` [m] as in the module docs.
pub fn cells(x: &[f64], y: &[f64], r: &[f64], reach: f64) -> Cells {
    let n = x.len();
    let mut out = Cells {
        area: vec![f64::NAN; n],
        interior: vec![false; n],
    };
    if n == 0 {
        return out;
    }
    let rmax = r.iter().cloned().fold(0.0, f64::max);
    let h = 2.0 * (rmax + reach) * (1.0 + 1e-9);
    let x0 = x.iter().cloned().fold(f64::INFINITY, f64::min);
    let y0 = y.iter().cloned().fold(f64::INFINITY, f64::min);
    let nx = (((x.iter().cloned().fold(f64::NEG_INFINITY, f64::max) - x0) / h).floor() as usize + 1).min(1 << 14);
    let ny = (((y.iter().cloned().fold(f64::NEG_INFINITY, f64::max) - y0) / h).floor() as usize + 1).min(1 << 14);
    let cell = |i: usize| {
        (
            (((x[i] - x0) / h) as usize).min(nx - 1),
            (((y[i] - y0) / h) as usize).min(ny - 1),
        )
    };
    let mut bucket: Vec<Vec<u32>> = vec![Vec::new(); nx * ny];
    for i in 0..n {
        let (cx, cy) = cell(i);
        bucket[cy * nx + cx].push(i as u32);
    }
    for i in 0..n {
        let lim = r[i] + reach;
        let big = lim * (1.0 + 1e-9);
        let (xi, yi) = (x[i], y[i]);
        let mut poly = vec![
            (xi - big, yi - big),
            (xi + big, yi - big),
            (xi + big, yi + big),
            (xi - big, yi + big),
        ];
        poly = clip(&poly, (0.0, 0.0), (-1.0, 0.0)); // wall: x ≥ 0
        poly = clip(&poly, (0.0, 0.0), (0.0, -1.0)); // base: y ≥ 0
        let (cx, cy) = cell(i);
        for ccy in cy.saturating_sub(1)..=(cy + 1).min(ny - 1) {
            for ccx in cx.saturating_sub(1)..=(cx + 1).min(nx - 1) {
                for &j in &bucket[ccy * nx + ccx] {
                    let j = j as usize;
                    if j == i {
                        continue;
                    }
                    let (dx, dy) = (x[j] - xi, y[j] - yi);
                    if dx * dx + dy * dy >= 4.0 * big * big || (dx == 0.0 && dy == 0.0) {
                        continue;
                    }
                    poly = clip(&poly, (xi + 0.5 * dx, yi + 0.5 * dy), (dx, dy));
                    if poly.is_empty() {
                        break;
                    }
                }
            }
        }
        if poly.len() >= 3 {
            out.area[i] = area(&poly);
            out.interior[i] = poly.iter().all(|p| (p.0 - xi).hypot(p.1 - yi) <= lim);
        }
    }
    out
}

/// Packing fraction Σ π r_i² / Σ A_i over the interior cells selected by `keep`, and
/// their number (NaN, 0 when there are none).
pub fn packing_fraction(c: &Cells, r: &[f64], keep: impl Fn(usize) -> bool) -> (f64, usize) {
    let (mut solid, mut total, mut k) = (0.0, 0.0, 0usize);
    for i in 0..r.len() {
        if c.interior[i] && c.area[i].is_finite() && keep(i) {
            solid += std::f64::consts::PI * r[i] * r[i];
            total += c.area[i];
            k += 1;
        }
    }
    if k == 0 { (f64::NAN, 0) } else { (solid / total, k) }
}

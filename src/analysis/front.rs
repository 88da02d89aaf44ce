//! Flow front and height of the main mass (docs/definitions.md D01, D03), for any set of round
//! bodies: DEM grains (half-size = radius) or MPM material points (half-size = GIMP
//! half-width l_p).
//!
//! Main mass = the connected component of largest mass; two bodies are linked when
//! [`Link`] says so. Walls and the base never link bodies. L = max over the main mass of
//! (x + half), H = max of (y + half), both measured from the left wall / base at 0.
//!
//! The neighbour search is a uniform cell grid (O(N)), components come from a union–find
//! with path halving; the result does not depend on the input order beyond ties in mass.

/// Bodies as struct-of-arrays slices, all of the same length.
#[derive(Debug, Clone, Copy)]
pub struct Body<'a> {
    /// Centre x [m].
    pub x: &'a [f64],
    /// Centre y [m].
    pub y: &'a [f64],
    /// Half-size [m]: grain radius, or GIMP half-width of a material point.
    pub half: &'a [f64],
    /// Mass [kg per m of thickness].
    pub mass: &'a [f64],
}

/// When two bodies belong to the same mass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Link {
    /// Grains touch or nearly touch: centre distance ≤ r_i + r_j + `gap` [m]
    /// (D01 proposes gap δ_c = 0.01 d̄).
    Contact {
        /// Largest gap still counted as a contact [m].
        gap: f64,
    },
    /// Centres closer than a fixed distance [m] (MPM: 1.5 × initial point spacing).
    Distance(f64),
    /// MPM points interact only through the background grid: two are linked when some
    /// node (node lines at integer multiples of `h` from the wall x = 0 and the base
    /// y = 0) lies strictly within `support` of both, in x and in y — uGIMP support
    /// h + l_p. This is the DEM's rule (bodies that interact are one mass) for material
    /// points: a stretched film whose points drift farther apart than 2 l_p + gap still
    /// shares nodes, while points separated by an empty cell do not.
    SharedNode {
        /// Grid spacing [m].
        h: f64,
        /// Half-width of a point's node support [m] (uGIMP: h + l_p).
        support: f64,
    },
}

/// Node-index range (inclusive) of the nodes strictly within `support` of `c` on a
/// lattice of spacing `h` through 0.
fn node_range(c: f64, h: f64, support: f64) -> (i64, i64) {
    (
        ((c - support) / h).floor() as i64 + 1,
        ((c + support) / h).ceil() as i64 - 1,
    )
}

/// Do two points share a node of the grid (see [`Link::SharedNode`])?
fn share_node(xi: f64, yi: f64, xj: f64, yj: f64, h: f64, support: f64) -> bool {
    let overlap = |a: (i64, i64), b: (i64, i64)| a.0.max(b.0) <= a.1.min(b.1);
    overlap(node_range(xi, h, support), node_range(xj, h, support))
        && overlap(node_range(yi, h, support), node_range(yj, h, support))
}

/// Front measurements of one configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Front {
    /// L: farthest right edge of the main mass [m].
    pub length: f64,
    /// H: highest top edge of the main mass [m].
    pub height: f64,
    /// Number of bodies in the main mass.
    pub n_main: usize,
    /// Mass fraction of all bodies in the main mass.
    pub mass_fraction: f64,
}

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let p = parent[parent[i as usize] as usize];
        parent[i as usize] = p;
        i = p;
    }
    i
}

/// Component label (root index) of every body.
pub fn components(body: &Body, link: Link) -> Vec<u32> {
    let n = body.x.len();
    assert!(
        body.y.len() == n && body.half.len() == n && body.mass.len() == n,
        "Body slices differ in length"
    );
    let mut parent: Vec<u32> = (0..n as u32).collect();
    if n == 0 {
        return parent;
    }
    let max_half = body.half.iter().cloned().fold(0.0, f64::max);
    let reach = match link {
        Link::Contact { gap } => 2.0 * max_half + gap,
        Link::Distance(d) => d,
        Link::SharedNode { support, .. } => 2.0 * support,
    }
    .max(1e-12);
    let (mut x0, mut y0) = (f64::INFINITY, f64::INFINITY);
    let (mut x1, mut y1) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    for i in 0..n {
        x0 = x0.min(body.x[i]);
        y0 = y0.min(body.y[i]);
        x1 = x1.max(body.x[i]);
        y1 = y1.max(body.y[i]);
    }
    let nx = (((x1 - x0) / reach).floor() as usize + 1).min(1 << 15);
    let ny = (((y1 - y0) / reach).floor() as usize + 1).min(1 << 15);
    let cell = |x: f64, y: f64| -> (usize, usize) {
        (
            (((x - x0) / reach) as usize).min(nx - 1),
            (((y - y0) / reach) as usize).min(ny - 1),
        )
    };
    // Counting sort of bodies into cells.
    let mut start = vec![0u32; nx * ny + 1];
    for i in 0..n {
        let (cx, cy) = cell(body.x[i], body.y[i]);
        start[cy * nx + cx + 1] += 1;
    }
    for c in 0..nx * ny {
        start[c + 1] += start[c];
    }
    let mut fill = start.clone();
    let mut order = vec![0u32; n];
    for i in 0..n {
        let (cx, cy) = cell(body.x[i], body.y[i]);
        let c = cy * nx + cx;
        order[fill[c] as usize] = i as u32;
        fill[c] += 1;
    }
    for i in 0..n {
        let (cx, cy) = cell(body.x[i], body.y[i]);
        for dy in 0..3usize {
            let Some(ccy) = (cy + dy).checked_sub(1) else { continue };
            if ccy >= ny {
                continue;
            }
            for dx in 0..3usize {
                let Some(ccx) = (cx + dx).checked_sub(1) else { continue };
                if ccx >= nx {
                    continue;
                }
                let c = ccy * nx + ccx;
                for &j in &order[start[c] as usize..start[c + 1] as usize] {
                    let j = j as usize;
                    if j <= i {
                        continue;
                    }
                    let ddx = body.x[j] - body.x[i];
                    let ddy = body.y[j] - body.y[i];
                    let linked = match link {
                        Link::Contact { gap } => {
                            let lim = body.half[i] + body.half[j] + gap;
                            ddx * ddx + ddy * ddy <= lim * lim
                        }
                        Link::Distance(d) => ddx * ddx + ddy * ddy <= d * d,
                        Link::SharedNode { h, support } => {
                            share_node(body.x[i], body.y[i], body.x[j], body.y[j], h, support)
                        }
                    };
                    if linked {
                        let (a, b) = (find(&mut parent, i as u32), find(&mut parent, j as u32));
                        if a != b {
                            let (lo, hi) = if a < b { (a, b) } else { (b, a) };
                            parent[hi as usize] = lo;
                        }
                    }
                }
            }
        }
    }
    for i in 0..n as u32 {
        let r = find(&mut parent, i);
        parent[i as usize] = r;
    }
    parent
}

/// Indices of the main mass (largest total mass; ties go to the lowest root index).
pub fn main_mass(body: &Body, link: Link) -> Vec<usize> {
    let labels = components(body, link);
    let n = labels.len();
    let mut mass = vec![0.0f64; n];
    for i in 0..n {
        mass[labels[i] as usize] += body.mass[i];
    }
    let mut best = 0usize;
    for r in 0..n {
        if mass[r] > mass[best] {
            best = r;
        }
    }
    (0..n).filter(|&i| labels[i] as usize == best).collect()
}

/// L, H and the size of the main mass (D01, D03).
pub fn front(body: &Body, link: Link) -> Front {
    let idx = main_mass(body, link);
    let total: f64 = body.mass.iter().sum();
    let mut length = 0.0f64;
    let mut height = 0.0f64;
    let mut m = 0.0;
    for &i in &idx {
        length = length.max(body.x[i] + body.half[i]);
        height = height.max(body.y[i] + body.half[i]);
        m += body.mass[i];
    }
    Front {
        length,
        height,
        n_main: idx.len(),
        mass_fraction: if total > 0.0 { m / total } else { 0.0 },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detached_grain_is_not_the_front() {
        // A chain of 5 touching grains and one grain far to the right.
        let x = [0.5, 1.5, 2.5, 3.5, 4.5, 10.0];
        let y = [0.5; 6];
        let r = [0.5; 6];
        let m = [1.0; 6];
        let b = Body {
            x: &x,
            y: &y,
            half: &r,
            mass: &m,
        };
        let f = front(&b, Link::Contact { gap: 0.01 });
        assert_eq!(f.n_main, 5);
        assert!((f.length - 5.0).abs() < 1e-12);
        assert!((f.height - 1.0).abs() < 1e-12);
        assert!((f.mass_fraction - 5.0 / 6.0).abs() < 1e-12);
        // With a large linking distance everything is one mass.
        let f = front(&b, Link::Distance(6.0));
        assert_eq!(f.n_main, 6);
        assert!((f.length - 10.5).abs() < 1e-12);
    }

    #[test]
    fn stretched_mpm_film_is_one_mass_through_its_grid_nodes() {
        // A spreading MPM toe: points (l_p = 0.25 mm) drifted 1.5 mm apart along the base
        // inside 2 mm cells. The edge-gap rule (0.5 d̄ = 0.575 mm) cuts it into single
        // points and the run-out jumps back to the column; the points still share grid
        // nodes, so through the grid they are one continuum.
        let (h, lp) = (2e-3, 0.25e-3);
        let x: Vec<f64> = (0..12).map(|k| 1e-3 + 1.5e-3 * k as f64).collect();
        let y = vec![0.3e-3; 12];
        let half = vec![lp; 12];
        let mut m = vec![1.0; 12];
        m[0] = 5.0; // the column end, heaviest
        let b = Body {
            x: &x,
            y: &y,
            half: &half,
            mass: &m,
        };
        let old = front(&b, Link::Contact { gap: 0.575e-3 });
        assert_eq!(old.n_main, 1, "the old rule splits the film");
        let new = front(&b, Link::SharedNode { h, support: h + lp });
        assert_eq!(new.n_main, 12);
        assert!((new.length - (x[11] + lp)).abs() < 1e-15);
    }

    #[test]
    fn points_across_an_empty_cell_do_not_share_a_node() {
        // Nodes at 0, 2, 4, 6, 8 mm; support 2.25 mm. A point at 1.0 mm reaches nodes 0, 2;
        // one at 5.5 mm reaches nodes 4, 6: nothing shared, two masses. At 4.0 mm it
        // reaches node 2 (|4 − 2| < 2.25): one mass.
        let (h, lp) = (2e-3, 0.25e-3);
        let link = Link::SharedNode { h, support: h + lp };
        let (y, half, m) = ([1e-3; 2], [lp; 2], [2.0, 1.0]);
        let apart = front(
            &Body {
                x: &[1e-3, 5.5e-3],
                y: &y,
                half: &half,
                mass: &m,
            },
            link,
        );
        assert_eq!(apart.n_main, 1);
        let near = front(
            &Body {
                x: &[1e-3, 4.0e-3],
                y: &y,
                half: &half,
                mass: &m,
            },
            link,
        );
        assert_eq!(near.n_main, 2);
        // Vertical separation counts too: same x, 5 mm apart in y.
        let above = front(
            &Body {
                x: &[1e-3, 1e-3],
                y: &[1e-3, 6e-3],
                half: &half,
                mass: &m,
            },
            link,
        );
        assert_eq!(above.n_main, 1);
    }

    #[test]
    fn heaviest_component_wins() {
        let x = [0.0, 1.0, 5.0];
        let y = [0.0; 3];
        let r = [0.5; 3];
        let m = [1.0, 1.0, 3.0];
        let b = Body {
            x: &x,
            y: &y,
            half: &r,
            mass: &m,
        };
        assert_eq!(main_mass(&b, Link::Contact { gap: 0.0 }), vec![2]);
    }
}

/// Run-out duration t_f (docs/definitions.md D10): the first time after which the front stays
/// within `tol` of its final value, t_f = min{t : L(t') ≥ L_f − tol for all t' ≥ t}.
/// `t` and `l` are the sampled times and front positions (same length, time order).
pub fn stop_time(t: &[f64], l: &[f64], tol: f64) -> f64 {
    assert_eq!(t.len(), l.len(), "stop_time: t and l differ in length");
    let Some(&lf) = l.last() else { return f64::NAN };
    let mut tf = t[t.len() - 1];
    for k in (0..l.len()).rev() {
        if l[k] >= lf - tol {
            tf = t[k];
        } else {
            break;
        }
    }
    tf
}

#[cfg(test)]
mod stop_tests {
    #[test]
    fn stop_time_is_when_the_front_settles() {
        let t = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0];
        let l = [0.0, 0.5, 0.9, 0.99, 1.0, 1.0];
        assert_eq!(super::stop_time(&t, &l, 0.05), 3.0);
        assert_eq!(super::stop_time(&t, &l, 0.2), 2.0);
    }
}

/// L(t) of the main mass for each linking gap of `gaps` [m] (the gap-sensitivity table
/// of D01): bodies linked when their edges are within the gap.
pub fn lengths_for_gaps(body: &Body, gaps: &[f64]) -> Vec<f64> {
    gaps.iter()
        .map(|&g| front(body, Link::Contact { gap: g }).length)
        .collect()
}

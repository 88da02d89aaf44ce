//! Regular background grid. Nodes are stored column by column (index = i·ny + j), so a band
//! of node columns is one contiguous slice: the deterministic parallel P2G hands disjoint
//! bands to threads (see `solver.rs`).

use crate::math::{Real, Vec2};

/// Nodal quantities of one step. `repr(C)`: the vectorised transfers (transfer.rs) read
/// p, f and v, Δv as runs of four f64.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[repr(C)]
pub struct Node {
    /// Mass [kg/m].
    pub m: Real,
    /// Momentum [kg/s] (per m of thickness).
    pub p: Vec2,
    /// Total force (internal + gravity) [N/m].
    pub f: Vec2,
    /// Updated velocity v^{n+1} after boundary conditions [m/s].
    pub v: Vec2,
    /// Velocity increment v^{n+1} − v^n (FLIP) [m/s].
    pub dv: Vec2,
}

/// A rectangular grid of `nx × ny` nodes, spacing `h`, node (0, 0) at `origin`.
#[derive(Debug, Clone)]
pub struct Grid {
    /// Position of node (0, 0) [m].
    pub origin: Vec2,
    /// Cell size [m].
    pub h: Real,
    /// Nodes in x.
    pub nx: usize,
    /// Nodes in y.
    pub ny: usize,
    /// Nodes, column-major.
    pub nodes: Vec<Node>,
}

impl Grid {
    /// A grid covering [x0, x1] × [y0, y1] with two ghost cells outside every side (GIMP
    /// points within l_p of a boundary line touch nodes one cell beyond it). `x0`, `y0` are
    /// snapped so that they are node lines.
    pub fn covering(x0: Real, y0: Real, x1: Real, y1: Real, h: Real) -> Self {
        let ghost = 2usize;
        let nxc = ((x1 - x0) / h).ceil() as usize;
        let nyc = ((y1 - y0) / h).ceil() as usize;
        let nx = nxc + 1 + 2 * ghost;
        let ny = nyc + 1 + 2 * ghost;
        let origin = Vec2::new(x0 - ghost as Real * h, y0 - ghost as Real * h);
        Self {
            origin,
            h,
            nx,
            ny,
            nodes: vec![Node::default(); nx * ny],
        }
    }
    /// Flat index of node (i, j).
    #[inline(always)]
    pub fn idx(&self, i: usize, j: usize) -> usize {
        i * self.ny + j
    }
    /// Position of node (i, j) [m].
    #[inline(always)]
    pub fn pos(&self, i: usize, j: usize) -> Vec2 {
        Vec2::new(self.origin.x + i as Real * self.h, self.origin.y + j as Real * self.h)
    }
    /// Upper corner of the grid [m].
    pub fn upper(&self) -> Vec2 {
        self.pos(self.nx - 1, self.ny - 1)
    }
    /// Zero every node (phase `reset_grid`).
    pub fn reset(&mut self) {
        self.nodes.fill(Node::default());
    }
    /// Whether a point at `x` with half-width `lp` has its whole 3 × 3 stencil inside the
    /// grid (one cell of margin on every side).
    #[inline(always)]
    pub fn contains(&self, x: Vec2, lp: Real) -> bool {
        let u = (x - self.origin) / self.h;
        let l = lp / self.h;
        u.x - l >= 0.0 && u.y - l >= 0.0 && u.x + l < (self.nx - 2) as Real && u.y + l < (self.ny - 2) as Real
    }
}

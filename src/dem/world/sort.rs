//! The world's memory order: grains renamed along a Hilbert curve at a neighbour rebuild
//! ([`crate::dem::order`]), everything that names a grain renamed with them.
//!
//! A sort happens in `World::refresh_neighbors`, just before the rebuild it precedes, at
//! the first rebuild at or after every `DemParams::sort_every` steps. That point is the
//! same whether or not steps are joined on a thread team, so results stay independent of
//! the thread count. What a sort changes is the order of the floating-point sums and of
//! the implicit dashpot's Gauss–Seidel sweep, which follow the grain indices (the pairs
//! by (i, j), each grain's force gather): a sorted run is the same physics as an unsorted
//! one, not the same bits (`tests/` and the unit tests below measure how far apart).
//!
//! Renamed here: the state, the last evaluation's forces and torques (the joined step's
//! pending spin work reads the torques), the grain–wall histories, live bytes and
//! dashpots, the dashpot lists of the last evaluation (names only: the pending sweep
//! visits the same grains in the same order as it would have), the listed pairs and
//! their histories (for the rebuild's merge), and [`World::grain_ids`]. Everything else
//! that names grains (pair outputs, near-wall lists, chunk dependencies, live bits) is
//! made again by the rebuild that follows.

use super::data::World;
use crate::dem::order::{inverse, permute_blocks, spatial_order};
use crate::math::Real;

impl World {
    /// Rename the grains in Hilbert order over bins of half the neighbour cell. Not done
    /// below `sort_min_grains` grains (the step's data fit in cache: nothing to win), nor
    /// when a grain is prescribed (1/m = 0: the drivers of prescribed grains — the shear
    /// cells' rough layers — name them by index between runs).
    pub(crate) fn sort_grains(&mut self) {
        let n = self.state.len();
        self.next_sort = self.steps + self.params.sort_every;
        if n < 2.max(self.sort_min_grains) || self.nl.x0.len() != n || self.state.inv_m.contains(&0.0) {
            return;
        }
        if self.grain_ids.len() != n {
            self.grain_ids = (0..n as u32).collect();
        }
        let r_max = self.state.r.iter().cloned().fold(0.0, Real::max);
        let skin = self.params.skin_fraction * 2.0 * r_max;
        let order = spatial_order(&self.state.x, &self.state.y, r_max + 0.5 * skin);
        if order.iter().enumerate().all(|(p, &a)| a as usize == p) {
            return;
        }
        let new_of = inverse(&order);
        let mut tmp: Vec<Real> = Vec::with_capacity(n);
        let s = &mut self.state;
        for v in [
            &mut s.x, &mut s.y, &mut s.vx, &mut s.vy, &mut s.w, &mut s.theta, &mut s.r, &mut s.m, &mut s.inv_m,
            &mut s.inertia, &mut s.inv_i, &mut self.fx, &mut self.fy, &mut self.tq, &mut self.wall_cn,
        ] {
            permute_blocks(v, &order, &mut tmp);
        }
        permute_blocks(&mut self.wall_hist, &order, &mut Vec::new());
        permute_blocks(&mut self.wlive, &order, &mut Vec::new());
        permute_blocks(&mut self.grain_ids, &order, &mut Vec::new());
        let rename = |g: &mut u32| {
            if (*g as usize) < n {
                *g = new_of[*g as usize];
            }
        };
        for it in self.roll.items.iter_mut().chain(self.roll.witems.iter_mut()) {
            rename(&mut it.i);
            rename(&mut it.j);
        }
        self.nl.relabel(&new_of);
        self.sorts += 1;
    }

    /// Sort the grains now and rebuild the list (between runs; `bench scaling --sorted`
    /// times a shuffled scene after this).
    pub fn sort_now(&mut self) {
        let every = self.next_sort;
        self.sort_grains();
        self.next_sort = every;
        self.rebuild();
        self.forces_valid = false;
    }

    /// Number of sorts so far.
    pub fn sorts(&self) -> u64 {
        self.sorts
    }

    /// The grains in the order of their original indices ([`World::grain_ids`]): what a
    /// driver publishes per grain (snapshots, frames), so that row `i` of every table is
    /// the same grain whether or not the world sorted. The state itself when unsorted.
    pub fn state_by_id(&self) -> crate::dem::state::State {
        let n = self.state.len();
        if self.grain_ids.len() != n || self.grain_ids.iter().enumerate().all(|(p, &g)| g as usize == p) {
            return self.state.clone();
        }
        let mut at = vec![0usize; n];
        for (p, &g) in self.grain_ids.iter().enumerate() {
            at[g as usize] = p;
        }
        self.state.permuted(&at)
    }
}

#[cfg(test)]
#[path = "sort_tests.rs"]
mod tests;

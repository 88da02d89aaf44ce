//! A [`World`]'s scratch (sized to its grains) and its contact histories: listed, saved
//! for a restart and restored on the same grains.

use super::data::{SavedHistories, World};
use crate::dem::params::normal_damping;
use crate::dem::scratch::{GRAIN_CHUNK, MAX_WALLS, RollItem};
use crate::dem::state::ContactState;

impl World {
    /// Call after appending grains or changing masses (histories of existing grains are
    /// kept; after removing grains build a new `World` instead).
    pub fn resize_scratch(&mut self) {
        let n = self.state.len();
        // appended grains take the next original indices; after a removal the names
        // start over
        let known = self.grain_ids.len();
        if known > n {
            self.grain_ids = (0..n as u32).collect();
        } else {
            self.grain_ids.extend(known as u32..n as u32);
        }
        for v in [&mut self.fx, &mut self.fy, &mut self.tq] {
            v.clear();
            v.resize(n, 0.0);
        }
        self.roll.witems.clear();
        self.roll.witems.resize(MAX_WALLS * n, RollItem::default());
        self.roll.wcount.clear();
        self.roll.wcount.resize(MAX_WALLS * n.div_ceil(GRAIN_CHUNK), 0);
        // keep wall histories of grains that still exist (grains appended at the end)
        let old_n = self.wall_hist.len() / MAX_WALLS;
        let mut wh = vec![ContactState::default(); MAX_WALLS * n];
        for wi in 0..MAX_WALLS {
            for a in 0..old_n.min(n) {
                wh[wi * n + a] = self.wall_hist[wi * old_n + a];
            }
        }
        self.wall_hist = wh;
        self.wlive.clear();
        self.wlive.resize(MAX_WALLS * n, 1);
        self.near.invalidate();
        let (z, kn) = (self.params.wall.damping_ratio(), self.params.wall.kn);
        self.wall_cn = self.state.m.iter().map(|&m| normal_damping(z, m, kn)).collect();
        // the list is rebuilt (positions changed); pair histories are kept by key
        self.nl.x0.clear();
        self.forces_valid = false;
    }

    /// All listed grain pairs with their history (zero for pairs not in contact).
    pub fn contact_histories(&self) -> impl Iterator<Item = (crate::dem::state::ContactKey, ContactState)> + '_ {
        (0..self.nl.len()).map(|k| {
            (
                crate::dem::state::ContactKey {
                    i: self.nl.pi[k],
                    j: self.nl.pj[k],
                },
                self.nl.hist[k],
            )
        })
    }

    /// Contact history between grains a and b, if listed.
    pub fn contact_history(&self, a: u32, b: u32) -> Option<ContactState> {
        self.nl.history(a, b)
    }

    /// Contact histories worth keeping across a restart: grain pairs and grain–wall
    /// contacts whose springs hold something.
    pub fn saved_histories(&self) -> SavedHistories {
        let n = self.state.len();
        let pairs = (0..self.nl.len())
            .filter(|&k| self.nl.hist[k] != ContactState::default())
            .map(|k| (self.nl.pi[k], self.nl.pj[k], self.nl.hist[k]))
            .collect();
        let walls = (0..self.walls.len())
            .flat_map(|wi| (0..n).map(move |a| (wi, a)))
            .filter(|&(wi, a)| self.wall_hist[wi * n + a] != ContactState::default())
            .map(|(wi, a)| (wi as u32, a as u32, self.wall_hist[wi * n + a]))
            .collect();
        SavedHistories { pairs, walls }
    }

    /// Restore contact histories saved by [`World::saved_histories`] on the same grains
    /// (a restarted column keeps its settled tangential and rolling springs). Pairs that
    /// are not listed now (moved apart) and walls that do not exist are skipped; returns
    /// how many histories were restored.
    pub fn restore_histories(&mut self, h: &SavedHistories) -> usize {
        let n = self.state.len();
        let mut restored = 0;
        for &(a, b, st) in &h.pairs {
            let key = crate::dem::state::ContactKey::new(a, b);
            let (Some(&lo), Some(&hi)) = (
                self.nl.istart.get(key.i as usize),
                self.nl.istart.get(key.i as usize + 1),
            ) else {
                continue;
            };
            if let Some(k) = (lo as usize..hi as usize).find(|&k| self.nl.pj[k] == key.j) {
                self.nl.hist[k] = st;
                restored += 1;
            }
        }
        for &(wi, a, st) in &h.walls {
            let (wi, a) = (wi as usize, a as usize);
            if wi < self.walls.len() && a < n {
                self.wall_hist[wi * n + a] = st;
                restored += 1;
            }
        }
        self.all_pairs_live();
        self.wlive.fill(1);
        self.near.invalidate();
        self.forces_valid = false;
        restored
    }
}

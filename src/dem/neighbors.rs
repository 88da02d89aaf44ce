//! Verlet neighbour list built with linked cells, with contact history carried across
//! rebuilds, and the per-grain gather table used for the deterministic force reduction.
//!
//! A pair (i < j) is listed when |x_i − x_j| < r_i + r_j + skin. The list is rebuilt when
//! some grain moved more than skin/2 since the last build (then no pair can have come
//! into contact unlisted). Pairs are sorted by (i, j); the old history is merged into the
//! new list by a sorted merge on [`ContactKey`], so it is deterministic and allocation-free
//! once the buffers have grown.
//!
//! Periodicity along x (period `lx`): grains are wrapped into [0, lx) at each rebuild and
//! each pair stores the image shift of j (−1, 0, +1) × lx.

use crate::dem::state::{ContactKey, ContactState, State};
use crate::math::Real;

/// Pair list, aligned history and gather table.
#[derive(Debug, Clone, Default)]
pub struct NeighborList {
    /// First grain of each pair.
    pub pi: Vec<u32>,
    /// Second grain of each pair (pi < pj).
    pub pj: Vec<u32>,
    /// Image shift of j along x, in periods.
    pub shift: Vec<Real>,
    /// Contact history of each pair.
    pub hist: Vec<ContactState>,
    /// Normal dashpot C_n of each pair (eq 4.4 with m_ij).
    pub cn: Vec<Real>,
    /// Rolling radius r_i r_j/(r_i + r_j).
    pub r_roll: Vec<Real>,
    /// Gather table, i side: grain g is the `i` of pairs `istart[g]..istart[g+1]` (the
    /// list is sorted by i, so this is a contiguous range read sequentially).
    pub istart: Vec<u32>,
    /// Gather table, j side: grain g is the `j` of pairs `jlist[jstart[g]..jstart[g+1]]`
    /// (increasing pair index). A grain sums its i-side pairs, then its j-side pairs:
    /// a fixed order, and no branch per entry.
    pub jstart: Vec<u32>,
    /// See `jstart`.
    pub jlist: Vec<u32>,
    /// Positions at the last build.
    pub x0: Vec<Real>,
    /// See `x0`.
    pub y0: Vec<Real>,
    /// Skin [m].
    pub skin: Real,
    /// Number of builds so far.
    pub builds: u64,
    // scratch
    cell_start: Vec<u32>,
    cell_items: Vec<u32>,
    old_pi: Vec<u32>,
    old_pj: Vec<u32>,
    old_hist: Vec<ContactState>,
    fill: Vec<u32>,
    row: Vec<(u32, Real)>,
}

impl NeighborList {
    /// Number of listed pairs.
    pub fn len(&self) -> usize {
        self.pi.len()
    }
    /// No pairs listed.
    pub fn is_empty(&self) -> bool {
        self.pi.is_empty()
    }

    /// Whether some grain moved more than skin/2 since the last build.
    pub fn needs_rebuild(&self, s: &State) -> bool {
        if self.x0.len() != s.len() {
            return true;
        }
        let lim = 0.25 * self.skin * self.skin;
        (0..s.len()).any(|i| {
            let dx = s.x[i] - self.x0[i];
            let dy = s.y[i] - self.y0[i];
            dx * dx + dy * dy > lim
        })
    }

    /// Rebuild the list (wrapping x into [0, lx) when periodic) and carry history over.
    /// `cn_of(i, j)` gives the pair dashpot.
    pub fn build(
        &mut self,
        s: &mut State,
        skin: Real,
        periodic_lx: Option<Real>,
        cn_of: impl Fn(usize, usize) -> Real,
    ) {
        let n = s.len();
        self.skin = skin;
        self.builds += 1;
        if let Some(lx) = periodic_lx {
            for x in s.x.iter_mut() {
                *x = x.rem_euclid(lx);
                if *x >= lx {
                    *x -= lx;
                }
            }
        }
        // keep old pairs for the history merge
        std::mem::swap(&mut self.old_pi, &mut self.pi);
        std::mem::swap(&mut self.old_pj, &mut self.pj);
        std::mem::swap(&mut self.old_hist, &mut self.hist);
        self.pi.clear();
        self.pj.clear();
        self.shift.clear();
        self.hist.clear();
        self.cn.clear();
        self.r_roll.clear();
        self.x0.clear();
        self.x0.extend_from_slice(&s.x);
        self.y0.clear();
        self.y0.extend_from_slice(&s.y);
        if n == 0 {
            self.istart.clear();
            self.istart.push(0);
            self.jstart.clear();
            self.jstart.push(0);
            self.jlist.clear();
            return;
        }
        let r_max = s.r.iter().cloned().fold(0.0, Real::max);
        let mut cell = 2.0 * r_max + skin;
        let (mut x_lo, mut y_lo, mut x_hi, mut y_hi) =
            (Real::INFINITY, Real::INFINITY, Real::NEG_INFINITY, Real::NEG_INFINITY);
        for i in 0..n {
            x_lo = x_lo.min(s.x[i]);
            x_hi = x_hi.max(s.x[i]);
            y_lo = y_lo.min(s.y[i]);
            y_hi = y_hi.max(s.y[i]);
        }
        // a few escaped grains must not blow the grid up: at most ~4 cells per grain
        let cap = 4.0 * n as Real + 64.0;
        if periodic_lx.is_none() {
            let area = ((x_hi - x_lo) / cell + 1.0) * ((y_hi - y_lo) / cell + 1.0);
            if area > cap {
                cell *= (area / cap).sqrt();
            }
        } else {
            let rows = (y_hi - y_lo) / cell + 1.0;
            if rows > cap {
                cell *= rows / cap;
            }
        }
        let (nx, x_lo, cw) = match periodic_lx {
            Some(lx) => {
                let nx = ((lx / cell).floor() as usize).max(1);
                assert!(
                    nx >= 3,
                    "periodic cell too narrow: period {lx} m < 3 neighbour cells of {cell} m"
                );
                (nx, 0.0, lx / nx as Real)
            }
            None => ((((x_hi - x_lo) / cell).floor() as usize + 1).min(1 << 14), x_lo, cell),
        };
        let ny = (((y_hi - y_lo) / cell).floor() as usize + 1).min(1 << 14);
        let cell_of = |x: Real, y: Real| -> (usize, usize) {
            (
                (((x - x_lo) / cw).max(0.0) as usize).min(nx - 1),
                (((y - y_lo) / cell).max(0.0) as usize).min(ny - 1),
            )
        };
        // counting sort into cells
        self.cell_start.clear();
        self.cell_start.resize(nx * ny + 1, 0);
        for i in 0..n {
            let (cx, cy) = cell_of(s.x[i], s.y[i]);
            self.cell_start[cy * nx + cx + 1] += 1;
        }
        for c in 0..nx * ny {
            self.cell_start[c + 1] += self.cell_start[c];
        }
        self.cell_items.clear();
        self.cell_items.resize(n, 0);
        self.fill.clear();
        self.fill.extend_from_slice(&self.cell_start[..nx * ny]);
        for i in 0..n {
            let (cx, cy) = cell_of(s.x[i], s.y[i]);
            let c = cy * nx + cx;
            self.cell_items[self.fill[c] as usize] = i as u32;
            self.fill[c] += 1;
        }
        // enumerate pairs i < j, grain by grain so the list comes out sorted by i
        let mut row = std::mem::take(&mut self.row);
        for i in 0..n {
            let (cx, cy) = cell_of(s.x[i], s.y[i]);
            row.clear();
            for dy in 0..3usize {
                let Some(ccy) = (cy + dy).checked_sub(1) else { continue };
                if ccy >= ny {
                    continue;
                }
                for dxo in 0..3isize {
                    let raw = cx as isize + dxo - 1;
                    let (ccx, sh) = match periodic_lx {
                        Some(_) => {
                            if raw < 0 {
                                ((raw + nx as isize) as usize, -1.0)
                            } else if raw >= nx as isize {
                                ((raw - nx as isize) as usize, 1.0)
                            } else {
                                (raw as usize, 0.0)
                            }
                        }
                        None => {
                            if raw < 0 || raw >= nx as isize {
                                continue;
                            }
                            (raw as usize, 0.0)
                        }
                    };
                    let c = ccy * nx + ccx;
                    for &j in &self.cell_items[self.cell_start[c] as usize..self.cell_start[c + 1] as usize] {
                        if (j as usize) <= i {
                            continue;
                        }
                        let lx = periodic_lx.unwrap_or(0.0);
                        let dx = s.x[j as usize] + sh * lx - s.x[i];
                        let dy = s.y[j as usize] - s.y[i];
                        let cut = s.r[i] + s.r[j as usize] + skin;
                        if dx * dx + dy * dy < cut * cut {
                            row.push((j, sh));
                        }
                    }
                }
            }
            row.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.partial_cmp(&b.1).unwrap()));
            for &(j, sh) in &row {
                self.pi.push(i as u32);
                self.pj.push(j);
                self.shift.push(sh);
                self.cn.push(cn_of(i, j as usize));
                let (ri, rj) = (s.r[i], s.r[j as usize]);
                self.r_roll.push(ri * rj / (ri + rj));
            }
        }
        self.row = row;
        // carry history over by a sorted merge on ContactKey
        self.hist.resize(self.pi.len(), ContactState::default());
        let (mut a, mut b) = (0usize, 0usize);
        while a < self.old_pi.len() && b < self.pi.len() {
            let ka = ContactKey {
                i: self.old_pi[a],
                j: self.old_pj[a],
            };
            let kb = ContactKey {
                i: self.pi[b],
                j: self.pj[b],
            };
            match ka.cmp(&kb) {
                std::cmp::Ordering::Less => a += 1,
                std::cmp::Ordering::Greater => b += 1,
                std::cmp::Ordering::Equal => {
                    self.hist[b] = self.old_hist[a];
                    a += 1;
                    b += 1;
                }
            }
        }
        // gather tables (CSR), entries in increasing pair order per grain
        self.istart.clear();
        self.istart.resize(n + 1, 0);
        self.jstart.clear();
        self.jstart.resize(n + 1, 0);
        for k in 0..self.pi.len() {
            self.istart[self.pi[k] as usize + 1] += 1;
            self.jstart[self.pj[k] as usize + 1] += 1;
        }
        for g in 0..n {
            self.istart[g + 1] += self.istart[g];
            self.jstart[g + 1] += self.jstart[g];
        }
        self.jlist.clear();
        self.jlist.resize(self.pi.len(), 0);
        self.fill.clear();
        self.fill.extend_from_slice(&self.jstart[..n]);
        for k in 0..self.pi.len() {
            let j = self.pj[k] as usize;
            self.jlist[self.fill[j] as usize] = k as u32;
            self.fill[j] += 1;
        }
    }

    /// Rename the grains of the listed pairs (`new_of[old]`) ahead of a rebuild: the pairs
    /// and their histories are kept, keyed again by (i < j) and sorted, for the rebuild's
    /// history merge (a pair whose i and j swap turns over: [`ContactState::renamed`]).
    /// Everything else of the list is stale
    /// until [`NeighborList::build`] runs (`x0` is cleared so that it must).
    pub fn relabel(&mut self, new_of: &[u32]) {
        let mut pairs: Vec<(u32, u32, ContactState)> = (0..self.pi.len())
            .map(|k| self.hist[k].renamed(new_of[self.pi[k] as usize], new_of[self.pj[k] as usize]))
            .collect();
        pairs.sort_by_key(|p| (p.0, p.1));
        self.pi.clear();
        self.pj.clear();
        self.hist.clear();
        for (a, b, h) in pairs {
            self.pi.push(a);
            self.pj.push(b);
            self.hist.push(h);
        }
        self.x0.clear();
        self.y0.clear();
    }

    /// History of the contact between a and b, if they are listed.
    pub fn history(&self, a: u32, b: u32) -> Option<ContactState> {
        let k = ContactKey::new(a, b);
        let lo = self.istart.get(k.i as usize).copied()? as usize;
        let hi = self.istart.get(k.i as usize + 1).copied()? as usize;
        (lo..hi).find(|&p| self.pj[p] == k.j).map(|p| self.hist[p])
    }
}

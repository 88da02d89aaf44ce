//! Memory order that follows space: grains sorted along a Hilbert curve over square bins
//! (LAMMPS `atom_modify sort`), so that grains near in space are near in memory and the
//! pair and grain passes read their neighbours from cache instead of from DRAM.
//!
//! The world sorts its grains at a neighbour rebuild every `DemParams::sort_every` steps
//! (`World::sort_grains`); this file holds the curve and the permutation helpers, free of
//! the world. A sort renames grains: [`crate::dem::World::grain_ids`] keeps each grain's
//! original index.

use crate::math::Real;

/// Below this many grains a world is not sorted: its step's data (≈ 0.4 kB per grain,
/// 1.6 MB at 4,096) sit in the last-level cache, so memory order costs little (`bench
/// scaling`: no gain measured at 3,000 grains; docs/performance.md).
pub const SORT_MIN_GRAINS: usize = 4096;

/// Most bits per axis of the bin grid (2^16 bins a side; wider scenes get wider bins).
pub const MAX_BITS: u32 = 16;

/// Index of bin (x, y) along the Hilbert curve of a 2^bits × 2^bits grid (x, y < 2^bits).
pub fn hilbert_key(bits: u32, mut x: u32, mut y: u32) -> u64 {
    let n: u32 = 1 << bits;
    let mut d: u64 = 0;
    let mut s = n >> 1;
    while s > 0 {
        let rx = (x & s != 0) as u32;
        let ry = (y & s != 0) as u32;
        d += (s as u64) * (s as u64) * ((3 * rx) ^ ry) as u64;
        // rotate the quadrant so that the curve's lower levels run the same way
        if ry == 0 {
            if rx == 1 {
                x = n - 1 - x;
                y = n - 1 - y;
            }
            std::mem::swap(&mut x, &mut y);
        }
        s >>= 1;
    }
    d
}

/// The grains in Hilbert order over square bins of side `bin` [m] spanning their bounding
/// box: grain `order[p]` goes to place `p`. Ties (one bin) keep their current order, so
/// the result depends on the positions and the current order only.
pub fn spatial_order(x: &[Real], y: &[Real], bin: Real) -> Vec<u32> {
    let n = x.len();
    if n == 0 {
        return Vec::new();
    }
    let (mut x_lo, mut y_lo, mut x_hi, mut y_hi) = (x[0], y[0], x[0], y[0]);
    for i in 1..n {
        x_lo = x_lo.min(x[i]);
        x_hi = x_hi.max(x[i]);
        y_lo = y_lo.min(y[i]);
        y_hi = y_hi.max(y[i]);
    }
    let span = (x_hi - x_lo).max(y_hi - y_lo);
    let side = (1u64 << MAX_BITS) as Real;
    let bin = if bin > 0.0 && span / bin < side {
        bin
    } else {
        (span / side).max(Real::MIN_POSITIVE)
    };
    let cells = ((span / bin) as u64 + 1).max(1);
    let bits = (64 - (cells - 1).leading_zeros()).clamp(1, MAX_BITS);
    let top = (1u32 << bits) - 1;
    let coord = |v: Real, lo: Real| (((v - lo) / bin).max(0.0) as u64).min(top as u64) as u32;
    let mut keyed: Vec<(u64, u32)> = (0..n)
        .map(|i| (hilbert_key(bits, coord(x[i], x_lo), coord(y[i], y_lo)), i as u32))
        .collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// The inverse of a permutation: `new_of[order[p]] = p`.
pub fn inverse(order: &[u32]) -> Vec<u32> {
    let mut inv = vec![0u32; order.len()];
    for (p, &a) in order.iter().enumerate() {
        inv[a as usize] = p as u32;
    }
    inv
}

/// `v[p] ← v[order[p]]` for each block of `order.len()` items of `v` (one block: a
/// per-grain array; several: per-wall slots `wall * n + grain`), through `tmp`.
pub fn permute_blocks<T: Copy>(v: &mut Vec<T>, order: &[u32], tmp: &mut Vec<T>) {
    let n = order.len();
    if n == 0 || v.is_empty() {
        return;
    }
    debug_assert!(v.len().is_multiple_of(n));
    tmp.clear();
    for block in v.chunks(n) {
        tmp.extend(order.iter().map(|&a| block[a as usize]));
    }
    std::mem::swap(v, tmp);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hilbert_key_visits_every_bin_once_by_steps_to_a_neighbour() {
        for bits in 1..=5u32 {
            let n = 1u32 << bits;
            let mut at = vec![(0u32, 0u32); (n * n) as usize];
            for x in 0..n {
                for y in 0..n {
                    at[hilbert_key(bits, x, y) as usize] = (x, y);
                }
            }
            // a bijection onto 0..n² whose consecutive bins share a side
            for k in 1..at.len() {
                let (a, b) = (at[k - 1], at[k]);
                assert_eq!(a.0.abs_diff(b.0) + a.1.abs_diff(b.1), 1, "bits {bits}, step {k}");
            }
            assert_eq!(at[0], (0, 0));
        }
    }

    #[test]
    fn spatial_order_is_a_permutation_that_brings_neighbours_together() {
        // a 64 x 64 lattice listed in a scrambled order
        let side = 64usize;
        let n = side * side;
        let scramble: Vec<usize> = (0..n).map(|k| (k * 2_654_435_761usize) % n).collect();
        let (mut x, mut y) = (vec![0.0; n], vec![0.0; n]);
        for (k, &c) in scramble.iter().enumerate() {
            x[k] = (c % side) as Real;
            y[k] = (c / side) as Real;
        }
        let order = spatial_order(&x, &y, 1.0);
        let mut seen = order.clone();
        seen.sort_unstable();
        assert!(seen.iter().enumerate().all(|(p, &a)| a as usize == p));
        // consecutive places are lattice neighbours (the curve's property), where the
        // scrambled order jumps across the lattice
        let step = |a: usize, b: usize| (x[a] - x[b]).abs() + (y[a] - y[b]).abs();
        let sorted: Real = order.windows(2).map(|w| step(w[0] as usize, w[1] as usize)).sum();
        let before: Real = (1..n).map(|k| step(k - 1, k)).sum();
        assert_eq!(sorted, (n - 1) as Real);
        assert!(before > 20.0 * sorted, "{before} vs {sorted}");
        assert_eq!(inverse(&order)[order[17] as usize], 17);
    }

    #[test]
    fn permute_blocks_moves_each_block_alike() {
        let order = [2u32, 0, 1];
        let mut v = vec![10, 11, 12, 20, 21, 22];
        let mut tmp = Vec::new();
        permute_blocks(&mut v, &order, &mut tmp);
        assert_eq!(v, vec![12, 10, 11, 22, 20, 21]);
    }
}

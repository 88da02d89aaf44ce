//! Tests of the pair filter and the pair/grain passes against brute force (and, with the
//! `checked` feature, a corrupt neighbour index stopped by the shared views).

use super::*;
use crate::dem::params::DemParams;
use crate::dem::prep::{box_walls, hex_lattice};
use crate::sample::rng::SplitMix64;

/// The filter lists, chunk by chunk and in pair order, exactly the pairs that touch
/// or are live — on a packing shaken so that some contacts open and others close,
/// with random live bits and a short last chunk.
#[test]
fn filter_lists_exactly_the_touching_and_live_pairs() {
    let p = DemParams::default();
    let d = 1.15e-3;
    let s = hex_lattice(0.04, 0.03, d, p.density);
    let mut w = World::new(p, s, box_walls(0.04), None).unwrap();
    let np = w.nl.len();
    assert!(
        np > 3 * PAIR_CHUNK && np % PAIR_CHUNK != 0 && np % 64 != 0,
        "{np} pairs"
    );
    let mut rng = SplitMix64(3);
    for trial in 0..4 {
        for a in 0..w.state.len() {
            w.state.x[a] += 0.02 * d * (rng.next_f64() - 0.5);
            w.state.y[a] += 0.02 * d * (rng.next_f64() - 0.5);
        }
        for (q, v) in w.plive.iter_mut().enumerate() {
            let bits = (rng.next_f64() * u32::MAX as f64) as u64 | ((rng.next_f64() * u32::MAX as f64) as u64) << 32;
            let tail = np - (q * 64).min(np);
            *v = if tail >= 64 { bits } else { bits & ((1u64 << tail) - 1) };
        }
        let f = PairFilter::new(&mut w);
        let (s, nl) = (&w.state, &w.nl);
        let mut touching = 0;
        for lo in (0..np).step_by(PAIR_CHUNK) {
            let hi = (lo + PAIR_CHUNK).min(np);
            let mut got = vec![0u16; PAIR_CHUNK];
            // SAFETY: one chunk of the list the filter was made for, nothing else running
            let k = unsafe { f.run_to(lo, hi, got.as_mut_ptr()) };
            let want: Vec<u16> = (lo..hi)
                .filter(|&k| {
                    let (i, j) = (nl.pi[k] as usize, nl.pj[k] as usize);
                    let (dx, dy) = (s.x[i] - s.x[j], s.y[i] - s.y[j]);
                    let t = (dx * dx + dy * dy).sqrt() < s.r[i] + s.r[j];
                    touching += usize::from(t);
                    t || w.plive[k / 64] >> (k % 64) & 1 == 1
                })
                .map(|k| (k - lo) as u16)
                .collect();
            assert_eq!(&got[..k], &want[..], "trial {trial}, chunk at {lo}");
        }
        assert!(touching > np / 10, "too few contacts: {touching} of {np}");
    }
}

/// With `checked`, a neighbour list whose pair names a grain past the end is stopped by
/// the pair kernel's first read of it (`SharedRef`'s bounds assertion), where the
/// unchecked build would read past the position arrays.
#[cfg(feature = "checked")]
#[test]
#[should_panic(expected = "SharedRef: index")]
fn checked_pair_pass_stops_a_corrupt_neighbour_index() {
    let p = DemParams::default();
    let s = hex_lattice(0.01, 0.01, 1.15e-3, p.density);
    let mut w = World::new(p, s, box_walls(0.01), None).unwrap();
    let (n, np) = (w.state.len(), w.nl.len());
    assert!(np > 0 && np <= PAIR_CHUNK, "{np} pairs");
    w.nl.pi[np - 1] = n as u32;
    w.plive.fill(0);
    let pass = PairPass::<true, true, true>::new(&mut w, 0.0);
    // SAFETY: broken on purpose (one corrupt index, module doc); nothing else runs
    unsafe { pass.chunk(0, np, None) };
}

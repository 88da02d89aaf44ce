//! Contract: CD results are bit-identical at 1 and 2 rayon threads (the NLGS sweep is
//! sequential in a fixed contact order; nothing reads the thread count).

use granrepro::cd::pile::{DropSpec, drop};
use granrepro::cd::CdParams;

fn fingerprint(threads: usize) -> Vec<u64> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| {
        let spec = DropSpec { ncol: 10, nrow: 6, scale: 1e-3, seed: 4 };
        let r = drop(&spec, &CdParams { dt: 4e-5, ..CdParams::default() }, 1500).unwrap();
        let s = &r.state;
        let mut bits: Vec<u64> = Vec::new();
        for v in [&s.x, &s.y, &s.vx, &s.vy, &s.w, &s.theta] {
            bits.extend(v.iter().map(|x| x.to_bits()));
        }
        bits.push(r.stats.iterations);
        bits
    })
}

#[test]
fn same_state_at_one_and_two_threads() {
    assert_eq!(fingerprint(1), fingerprint(2));
}

//! Contract: CD results are bit-identical at 1 and 2 rayon threads (the NLGS sweep is
//! sequential in a fixed contact order; nothing reads the thread count).

use granrepro::cd::CdParams;
use granrepro::cd::pile::{DropSpec, drop};

fn fingerprint(threads: usize) -> Vec<u64> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| {
        let spec = DropSpec {
            ncol: 10,
            nrow: 6,
            scale: 1e-3,
            seed: 4,
        };
        let r = drop(
            &spec,
            &CdParams {
                dt: 4e-5,
                ..CdParams::default()
            },
            1500,
        )
        .unwrap();
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

/// The shear driver runs its inertial numbers in parallel (each point sequential): the
/// table must not depend on the pool size.
fn shear_table(threads: usize) -> Vec<u64> {
    use granrepro::cd::shear::{ShearCdParams, shear_test};
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| {
        let radii: Vec<f64> = (0..40)
            .map(|k| 1.0e-3 + 0.4e-3 * ((k * 7919) % 13) as f64 / 12.0)
            .collect();
        let sp = ShearCdParams {
            inertial_numbers: vec![1e-2, 0.1],
            strain: 0.2,
            width: 8.0,
            ..ShearCdParams::default()
        };
        let r = shear_test(&radii, &CdParams::default(), &sp).unwrap();
        r.points
            .iter()
            .flat_map(|q| [q.mu, q.inertial_number, q.sigma_n, q.packing_fraction])
            .chain([r.mu_min, r.b])
            .map(f64::to_bits)
            .collect()
    })
}

#[test]
fn same_shear_table_at_one_and_two_threads() {
    assert_eq!(shear_table(1), shear_table(2));
}

//! Contract: results are bit-identical for 1 and 2 rayon threads (forces per contact in
//! parallel, gathered per grain in a fixed order, partial sums in fixed chunk order).

use granrepro::dem::prep::{box_walls, hex_lattice};
use granrepro::dem::{DemParams, State, World};
use granrepro::sample::rng::SplitMix64;

/// A hexagonal column of ≈ 4900 touching grains — above `TEAM_MIN_GRAINS`, so a 2-thread
/// pool steps it with a thread team (pair and grain chunks shared out) — with random spins so that rolling and tangential
/// histories are exercised.
fn packed() -> State {
    let mut s = hex_lattice(0.08, 0.07, 1.15e-3, 2500.0);
    assert!(
        s.len() >= granrepro::dem::team::TEAM_MIN_GRAINS,
        "{} grains: too few to run in parallel",
        s.len()
    );
    let mut rng = SplitMix64(7);
    for i in 0..s.len() {
        s.w[i] = 200.0 * (rng.next_f64() - 0.5);
    }
    s
}

fn fingerprint(s: &State, threads: usize) -> (Vec<u64>, Vec<u64>) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| run_scene(s, false))
}

/// `probe`: let `World::run` choose between team and one thread by timing (default);
/// else the team steps every step.
fn run_scene(s: &State, probe: bool) -> (Vec<u64>, Vec<u64>) {
    {
        let p = DemParams {
            dt: 2e-7,
            ..DemParams::default()
        };
        let mut w = World::new(p, s.clone(), box_walls(0.08), None).unwrap();
        w.team_probe = probe;
        w.run(1000).unwrap();
        w.walls[2].active = false; // open the gate
        w.run(2000).unwrap();
        let nc = w.contact_count();
        eprintln!("contacts at the end: {nc}, rebuilds {}", w.rebuilds());
        assert!(nc > 4000, "scene must have contacts");
        let s = &w.state;
        let mut bits = Vec::new();
        for v in [&s.x, &s.y, &s.vx, &s.vy, &s.w, &s.theta] {
            bits.extend(v.iter().map(|x| x.to_bits()));
        }
        let l = w.ledger;
        let led = [
            l.normal_damping, l.tangential, l.rolling, l.wall_normal, l.wall_tangential, l.external_work,
        ]
        .iter()
        .map(|x| x.to_bits())
        .collect();
        (bits, led)
    }
}

#[test]
fn bit_identical_at_1_and_2_threads() {
    let s = packed();
    let a = fingerprint(&s, 1);
    let b = fingerprint(&s, 2);
    assert!(a.0 == b.0, "state differs between 1 and 2 threads");
    assert!(a.1 == b.1, "ledger differs between 1 and 2 threads");
}

/// Two worlds stepped side by side on one 2-thread pool (as a stage runs ensemble members):
/// each world's team helper can only start when the other world's thread is free, or
/// never; the runs must finish (no thread waits for a helper to start) with the same
/// bits as alone on one thread.
#[test]
fn side_by_side_worlds_on_a_shared_pool_match_one_thread() {
    let s = packed();
    let a = fingerprint(&s, 1);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let (b, c) = pool.install(|| rayon::join(|| run_scene(&s, false), || run_scene(&s, true)));
    assert!(
        a == b && a == c,
        "a world run beside another differs from the one-thread run"
    );
}

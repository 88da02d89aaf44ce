//! The colouring is a proper colouring, and the coloured sweep solves the same contact
//! problem as the key-order sweep, at any thread count with the same bits.

use super::*;
use crate::cd::bench::{dense_scene, deposit_width, run_scene, siconos_params};
use crate::cd::params::CdParams;
use crate::cd::world::World;

/// A settled 12 × 10 deposit kicked with the pile's gradient excitation (13 M g d̄).
fn scene() -> (crate::dem::state::State, Vec<crate::dem::walls::Wall>) {
    dense_scene(12, 10, 2.0, 13.0).unwrap()
}

#[test]
fn no_class_holds_two_contacts_of_one_moving_body() {
    let (st, walls) = scene();
    let mut w = World::new(siconos_params(), st, walls, None).unwrap();
    for _ in 0..20 {
        w.step().unwrap();
    }
    let (rows, bodies) = (&w.contacts.rows, &w.bodies);
    assert!(rows.len() > 100, "{} contacts", rows.len());
    let col = colour(rows, bodies);
    assert_eq!(col, colour(rows, bodies), "deterministic");
    let mut seen = vec![false; rows.len()];
    for c in 0..col.start.len() - 1 {
        let idx = &col.order[col.start[c] as usize..col.start[c + 1] as usize];
        let mut owner = vec![false; bodies.len()];
        for &k in idx {
            assert!(!seen[k as usize], "row {k} in two classes");
            seen[k as usize] = true;
            let r = &rows[k as usize];
            for b in [r.a as usize, r.b as usize] {
                if bodies[b].inv != [0.0; 3] {
                    assert!(!owner[b], "class {c}: body {b} in two contacts");
                    owner[b] = true;
                }
            }
        }
        // key order within a class
        assert!(idx.windows(2).all(|p| p[0] < p[1]));
    }
    assert!(seen.iter().all(|&s| s));
    // disks: a handful of classes, the walls shared by all
    assert!((3..=12).contains(&col.classes()), "{} classes", col.classes());
}

/// Run `steps` steps of the kicked scene, coloured or not, in a pool of `threads`.
fn run(coloured: bool, threads: usize, steps: usize) -> World {
    let (st, walls) = scene();
    let params = CdParams {
        coloured_sweeps: coloured,
        ..siconos_params()
    };
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| {
            let mut w = World::new(params, st, walls, None).unwrap();
            for _ in 0..steps {
                w.step().unwrap();
            }
            w
        })
}

#[test]
fn the_coloured_sweep_does_not_depend_on_the_thread_count() {
    let (a, b) = (run(true, 1, 40), run(true, 2, 40));
    assert_eq!(a.state, b.state);
    assert_eq!(a.stats.iterations, b.stats.iterations);
    assert_eq!(a.ledger.dissipated().to_bits(), b.ledger.dissipated().to_bits());
}

#[test]
fn the_coloured_sweep_solves_the_same_contact_problem() {
    // each step converges to the tolerances of the key-order sweep, and a step from the
    // same state gives the same impulses to the solver's tolerance
    let base = run(false, 1, 30);
    let (mut a, mut b) = (base.clone(), base.clone());
    b.params.coloured_sweeps = true;
    let (ia, ib) = (a.step().unwrap(), b.step().unwrap());
    assert!(ia.converged && ib.converged, "{ia:?} {ib:?}");
    let pn = |w: &World| w.contacts.rows.iter().map(|r| r.p[0]).sum::<Real>();
    let (pa, pb) = (pn(&a), pn(&b));
    assert!(pa > 0.0 && (pa - pb).abs() <= 1e-3 * pa, "sum of P_n {pa} vs {pb}");
    let gap = (0..a.state.len())
        .map(|i| {
            (a.state.vx[i] - b.state.vx[i])
                .abs()
                .max((a.state.vy[i] - b.state.vy[i]).abs())
        })
        .fold(0.0, Real::max);
    let vmax = a
        .state
        .vx
        .iter()
        .chain(&a.state.vy)
        .fold(0.0 as Real, |m, v| m.max(v.abs()));
    assert!(gap <= 1e-2 * vmax, "largest velocity gap {gap} against {vmax}");
    // and over a run the energy books balance as well either way
    let c = run(true, 1, 60);
    let bal = c.balance();
    assert!(bal.residual.abs() <= 1e-9 * bal.e0.abs().max(1e-30), "{bal:?}");
    let _ = (deposit_width(12), run_scene);
}

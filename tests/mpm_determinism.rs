//! Bit-identical results at 1, 2, 3 and 5 threads (deterministic band-ordered P2G, one range
//! of bands per thread with deferred boundary bands; fixed-order reductions), for USL and
//! MUSL, Mohr–Coulomb and μ(I). 3 and 5 threads exercise several range boundaries and the
//! cut-off when there are fewer bands than ranges need.

use granrepro::mpm::{Model, MpmParams, Scheme, column};

fn fingerprint(scheme: Scheme, model: Model, threads: usize) -> Vec<u64> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| {
        let mut p = MpmParams::quick();
        p.scheme = scheme;
        p.material.model = model;
        let mut col = column::build(&p, column::ColumnSpec::from_area(0.5, 1.0e-3)).unwrap();
        column::release(&mut col);
        for _ in 0..400 {
            let dt = col.solver.dt(&col.state);
            col.solver.step(&mut col.state, dt).unwrap();
        }
        let mut out = Vec::new();
        for q in &col.state.points {
            for v in [
                q.x.x, q.x.y, q.v.x, q.v.y, q.stress.xx, q.stress.yy, q.stress.xy, q.stress.zz, q.vol, q.eps_p,
                q.work_p,
            ] {
                out.push(v.to_bits());
            }
        }
        out.push(col.state.t.to_bits());
        out.push(col.state.ledger.wall_friction.to_bits());
        out
    })
}

#[test]
fn one_and_two_threads_are_bit_identical() {
    for (scheme, model) in [(Scheme::Usl, Model::MohrCoulomb), (Scheme::Musl, Model::mu_i_default())] {
        let a = fingerprint(scheme, model, 1);
        for threads in [2, 3, 5] {
            let b = fingerprint(scheme, model, threads);
            assert_eq!(a.len(), b.len());
            let first_diff = a.iter().zip(&b).position(|(x, y)| x != y);
            assert!(
                first_diff.is_none(),
                "{scheme:?}, {threads} threads: first difference at word {first_diff:?}"
            );
        }
    }
}

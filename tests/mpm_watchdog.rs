//! Watchdog: a run stops with an error naming step, time and point.

use granrepro::math::Vec2;
use granrepro::mpm::column::{self, ColumnSpec};
use granrepro::mpm::watchdog::EnergyWatch;
use granrepro::mpm::{MpmError, MpmParams, PointId, energies};

fn small() -> column::Column {
    let p = MpmParams::quick();
    let mut c = column::build(&p, ColumnSpec::from_area(0.5, 1e-3)).unwrap();
    column::release(&mut c);
    c
}

#[test]
fn nan_stress_is_reported_with_its_point() {
    let mut c = small();
    c.state.points[17].stress.xy = f64::NAN;
    let dt = c.solver.dt(&c.state);
    let err = c.solver.step(&mut c.state, dt).unwrap_err();
    match err {
        MpmError::NonFinite { step, point, .. } => {
            assert!(step <= 1);
            // The NaN spreads through the grid within the step; the first bad point is named.
            assert!(point.0 <= 17, "{point:?}");
        }
        e => panic!("unexpected {e}"),
    }
}

#[test]
fn point_leaving_the_grid_is_reported() {
    let mut c = small();
    // The top-right point is shot upwards; the grid ends 4 cells above the column.
    let top = c
        .state
        .points
        .iter()
        .enumerate()
        .max_by(|a, b| (a.1.x.x + a.1.x.y).total_cmp(&(b.1.x.x + b.1.x.y)))
        .unwrap()
        .0;
    c.state.points[top].v = Vec2::new(0.0, 300.0);
    let mut res = Ok(());
    for _ in 0..500 {
        res = c.solver.step(&mut c.state, 2e-5);
        if res.is_err() {
            break;
        }
    }
    let e = res.unwrap_err();
    eprintln!("{e}");
    assert!(
        matches!(
            e,
            MpmError::LeftGrid { .. } | MpmError::NonFinite { .. } | MpmError::JacobianNonPositive { .. }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("step"));
}

#[test]
fn energy_rise_is_reported() {
    let mut c = small();
    let el = *c.solver.elastic();
    let e0 = energies(&c.state, &el, 9.81);
    let w = EnergyWatch::new(&e0, 0.05);
    c.state.points[3].v = Vec2::new(5.0, 0.0);
    let e1 = energies(&c.state, &el, 9.81);
    match w.check(&e1, &c.state.points, 0, 0.0) {
        Err(MpmError::EnergyRise { point, .. }) => assert_eq!(point, PointId(3)),
        r => panic!("expected EnergyRise, got {r:?}"),
    }
}

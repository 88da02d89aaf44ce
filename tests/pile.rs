//! The pile study (issue 11): bad input refused at validation (exit 2, naming key, value
//! and what is allowed), and the physics the stages rest on (the excitation carries E_0
//! exactly; the decay analysis finds a known half-life; a settled pile stays at rest).

mod common;
use common::TempProject;

use granrepro::analysis::pile::{Profile, StopRule, excitation, kinetic};
use granrepro::dem::DemParams;

const PREP: &str = "  - id: psd\n    kind: psd\n    params: { n: 60, d_min_mm: 1.964, d_max_mm: 2.946 }\n  - id: pile\n    kind: dem-pile-prep\n    params: { PREP_PARAMS }\n    inputs: { psd: psd }\n";

fn project(run_params: &str, prep_params: &str) -> TempProject {
    let y = format!(
        "version: 1\nstages:\n{}  - id: run\n    kind: pile-run\n    params: {{ {run_params} }}\n    inputs: {{ pile: pile }}\n",
        PREP.replace("PREP_PARAMS", prep_params)
    );
    TempProject::new(&y)
}

fn refused(run_params: &str, prep_params: &str, needles: &[&str]) {
    let t = project(run_params, prep_params);
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "expected exit 2 for `{run_params}` / `{prep_params}`: {err}");
    for n in needles {
        assert!(err.contains(n), "missing `{n}` in: {err}");
    }
}

#[test]
fn negative_energy_is_refused_naming_key_value_and_range() {
    refused(
        "energies_mgd: [5.0, -3.0]",
        "dem: { density: 2600.0 }",
        &["energies_mgd[1]", "-3", "E_0 > 0"],
    );
}

#[test]
fn non_finite_and_empty_energy_lists_are_refused() {
    refused(
        "energies_mgd: [.nan]",
        "dem: { density: 2600.0 }",
        &["energies_mgd", "finite"],
    );
    refused(
        "energies_mgd: [.inf]",
        "dem: { density: 2600.0 }",
        &["energies_mgd", "finite"],
    );
    refused(
        "energies_mgd: []",
        "dem: { density: 2600.0 }",
        &["energies_mgd", "non-empty"],
    );
}

#[test]
fn unknown_profile_is_refused_with_the_allowed_ones() {
    refused(
        "energies_mgd: [5.0], profile: sinusoidal",
        "dem: { density: 2600.0 }",
        &["profile", "sinusoidal", "gradient", "uniform"],
    );
}

#[test]
fn a_pile_not_at_rest_is_refused() {
    // A rest criterion looser than "every grain at rest" would hand the excitation a moving pile.
    refused(
        "energies_mgd: [5.0]",
        "pile: { settle_ratio: 0.01 }",
        &["pile.settle_ratio", "0.01", "1e-4"],
    );
    refused(
        "energies_mgd: [5.0]",
        "pile: { settle_speed: 0.5 }",
        &["pile.settle_speed", "0.5"],
    );
}

#[test]
fn ppc_and_cell_size_the_pile_cannot_hold_are_refused() {
    refused(
        "method: mpm, energies_mgd: [5.0], mpm: { ppc: 20 }",
        "dem: { density: 2600.0 }",
        &["mpm.ppc", "20", "perfect square"],
    );
    refused(
        "method: mpm, energies_mgd: [5.0], mpm: { cell_size: 0.2, ppc: 4 }",
        "dem: { density: 2600.0 }",
        &["mpm.cell_size", "0.2", "spacing"],
    );
    refused(
        "method: mpm, energies_mgd: [5.0], mpm: { ppc: 144, cell_size: 0.03 }",
        "dem: { density: 2600.0 }",
        &["mpm.ppc", "144"],
    );
}

#[test]
fn excitation_carries_e0_exactly_for_both_profiles() {
    let y: Vec<f64> = (0..50)
        .map(|i| 0.001 * (i as f64 * 0.37).sin().abs() + 0.002 * i as f64)
        .collect();
    let m: Vec<f64> = (0..50).map(|i| 0.01 + 0.001 * (i % 7) as f64).collect();
    let top = y.iter().cloned().fold(0.0, f64::max) + 0.001;
    for p in [Profile::Gradient, Profile::Uniform] {
        for e0 in [1e-3, 0.37, 50.0] {
            let v = excitation(p, &y, &m, top, e0);
            assert!((kinetic(&m, &v) / e0 - 1.0).abs() < 1e-12, "{p:?} {e0}");
        }
    }
    // Gradient: v_x = k (y_max − y) vanishes at the top edge and is largest at the base.
    let v = excitation(Profile::Gradient, &[0.0, 1.0], &[1.0, 1.0], 1.0, 1.0);
    assert!(v[1].abs() < 1e-15 && v[0] > 0.0);
}

#[test]
fn a_settled_pile_does_not_run_out_without_excitation() {
    // 40 grains poured and relaxed, then "excited" with a vanishing energy: the front must
    // not move (a pile that creeps would fail the chapter's preparation criterion).
    let (pile, p) = small_pile();
    assert!(pile.settled, "not settled: E_k/E_p = {}", pile.ke_over_ep);
    let stop = StopRule {
        t_min: 10.0,
        t_max: 20.0,
        ..Default::default()
    };
    let r = granrepro::dem::pile::run_pile(&pile.state, &p, Profile::Gradient, 1e-12, &stop).unwrap();
    let lf = r.samples.last().unwrap().l;
    assert!((lf - r.l0).abs() < 0.05 * 2.455e-3, "front moved {} m", lf - r.l0);
}

// ---- part B: snapshots, uniform excitation, comparisons --------------------------------

#[test]
fn snapshot_requests_the_run_cannot_honour_are_refused() {
    // the photographed run must be one of the swept energies
    refused(
        "energies_mgd: [5.0], snapshots: { e0_mgd: 61.0, times: [0.0] }",
        "dem: { density: 2600.0 }",
        &["snapshots.e0_mgd", "61", "one of energies_mgd"],
    );
    // frames are taken at sample instants: 0.3 is not a multiple of sample_every 0.25
    refused(
        "energies_mgd: [5.0], snapshots: { e0_mgd: 5.0, times: [0.0, 0.3] }",
        "dem: { density: 2600.0 }",
        &["snapshots.times[1]", "0.3", "multiples of stop.sample_every"],
    );
    refused(
        "energies_mgd: [5.0], snapshots: { e0_mgd: 5.0, times: [5.0, 2.5] }",
        "dem: { density: 2600.0 }",
        &["snapshots.times[1]", "ascending"],
    );
    refused(
        "energies_mgd: [5.0], snapshots: { e0_mgd: 5.0, times: [] }",
        "dem: { density: 2600.0 }",
        &["snapshots.times", "non-empty"],
    );
    refused(
        "energies_mgd: [5.0], snapshots: { e0_mgd: 5.0, times: [0.0], every: 2 }",
        "dem: { density: 2600.0 }",
        &["snapshots.every"],
    );
}

#[test]
fn an_unknown_comparison_is_refused_with_the_allowed_ones() {
    let y = "version: 1\nstages:\n  - id: c\n    kind: pile-compare\n    params: { what: sideways }\n    inputs: { runs: [] }\n";
    let t = TempProject::new(y);
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "{err}");
    for n in ["what", "sideways", "profiles", "restitution", "cavity", "front"] {
        assert!(err.contains(n), "missing `{n}` in: {err}");
    }
}

/// A small pile (40 grains poured and relaxed) and its contact law.
fn small_pile() -> (granrepro::dem::pile::Pile, DemParams) {
    let radii: Vec<f64> = granrepro::dem::prep::diameters_uniform_by_area(40, 1.964e-3, 2.946e-3, 3)
        .iter()
        .map(|d| 0.5 * d)
        .collect();
    let mut p = DemParams::default();
    p.density = 2600.0;
    p.grain.kn = 1e6;
    p.grain.kt = 1e6;
    p.wall.kn = 1e6;
    p.wall.kt = 1e6;
    p.grain.friction = 0.4;
    p.wall.friction = 0.4;
    p.rolling.kr = 1.5;
    p.rolling.cr = 7.5e-4;
    p.rolling.mu_r = 0.15;
    p.dt = 9.5e-6;
    p.ledger = false;
    let mut pp = granrepro::dem::pile::PileParams::default();
    pp.deposition.width = 0.012;
    pp.deposition.drop_height = 1.0;
    pp.deposition.rows_per_layer = 1000;
    pp.deposition.softening = 1.0;
    pp.deposition.settle_ratio = 1e-4;
    pp.max_time = 2.0;
    (granrepro::dem::pile::prepare_pile(&radii, &p, &pp).unwrap(), p)
}

#[test]
fn frames_do_not_change_the_run_and_carry_the_input_energy() {
    use granrepro::analysis::pile::FrameTimes;
    let (pile, p) = small_pile();
    let s = pile.state;
    let stop = StopRule {
        t_min: 10.0,
        t_max: 12.0,
        ..Default::default()
    };
    let g = p.gravity;
    let tu = (2.455e-3 / g).sqrt();
    let e0 = 1e-3;
    for profile in [Profile::Gradient, Profile::Uniform] {
        let plain = granrepro::dem::pile::run_pile(&s, &p, profile, e0, &stop).unwrap();
        let ft = FrameTimes {
            times: vec![0.0, 2.5 * tu, 5.0 * tu],
            end_after_last: false,
        };
        let shot = granrepro::dem::pile::run_pile_frames(&s, &p, profile, e0, &stop, &ft).unwrap();
        // leave-out: frames are read at sample instants, the trajectory is the same
        assert_eq!(plain.samples, shot.samples, "{profile:?}: frames changed the run");
        assert!(plain.frames.is_empty());
        assert_eq!(shot.frames.len(), 3);
        // the t = 0 frame is the excited pile: Σ½m v_x² = E_0, v_y = 0; uniform: one V_0
        let f0 = &shot.frames[0];
        let m: Vec<f64> = s.m.clone();
        assert!((kinetic(&m, &f0.vx) / e0 - 1.0).abs() < 1e-12);
        assert!(f0.vy.iter().all(|v| *v == 0.0));
        if profile == Profile::Uniform {
            let v0 = (2.0 * e0 / m.iter().sum::<f64>()).sqrt();
            assert!(f0.vx.iter().all(|v| (v - v0).abs() < 1e-12 * v0));
        }
        assert!((shot.frames[1].t / tu - 2.5).abs() < 0.05 && (shot.frames[2].t / tu - 5.0).abs() < 0.05);
        // a frames-only run ends at its last frame
        let short = granrepro::dem::pile::run_pile_frames(
            &s,
            &p,
            profile,
            e0,
            &stop,
            &FrameTimes {
                end_after_last: true,
                ..ft.clone()
            },
        )
        .unwrap();
        assert!(short.samples.last().unwrap().t < 5.5 * tu && !short.stopped);
        assert_eq!(short.samples[..], plain.samples[..short.samples.len()]);
    }
}

/// The pile's pour is one layer of the rows its grains fill. 95 equal grains (r = 1 mm,
/// pitch 2.1 mm) in a 21.2 mm box fill rows of 10 and 9 alternately: 10 rows. The
/// deposition waits for the fall of its layer's top row, computed from `rows_per_layer`:
/// the pile stage asks for one layer with `rows_per_layer: 100000`, which the old code
/// passed through, so the paper pile waited 10.3 s of simulated time (a 100,000-row fall)
/// instead of 0.5 s. A cap below the rows filled is kept (several layers).
#[test]
fn a_pile_pour_is_one_layer_of_the_rows_its_grains_fill() {
    use granrepro::dem::pour::pour;
    use granrepro::dem::prep::DepositionParams;
    let radii = vec![1e-3; 95];
    let dep = DepositionParams {
        width: 0.0212,
        rows_per_layer: 100_000,
        spacing: 1.05,
        ..DepositionParams::default()
    };
    assert_eq!(pour(&radii, &dep).rows_per_layer, 10);
    assert_eq!(pour(&radii[..86], &dep).rows_per_layer, 9);
    let capped = DepositionParams {
        rows_per_layer: 5,
        ..dep.clone()
    };
    assert_eq!(pour(&radii, &capped).rows_per_layer, 5);
    assert_eq!(pour(&radii, &capped), capped);
}

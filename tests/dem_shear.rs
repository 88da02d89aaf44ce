//! Periodic shear calibration (SC-SHEAR-DEM) at test size: the driver reaches a steady
//! state whose σ_n matches the applied pressure and whose friction is in the range of
//! sheared frictional disks with rolling resistance.

use granrepro::dem::DemParams;
use granrepro::dem::prep::diameters_uniform_by_area;
use granrepro::dem::shear::{ShearParams, shear_test};

#[test]
fn small_periodic_shear_reaches_steady_friction() {
    let radii: Vec<f64> = diameters_uniform_by_area(200, 0.92e-3, 1.38e-3, 21)
        .iter()
        .map(|d| 0.5 * d)
        .collect();
    // quick: k/100, Δt × 10; pressures chosen so grains stay rigid, κ = k_n/P ≥ 8000
    // (the chapter's k_n at 1–20 kPa gives κ = 8e3–1.6e5)
    let p = DemParams::default().softened(1e-2);
    let sp = ShearParams {
        pressures: vec![100.0, 200.0],
        inertial_number: 1e-2,
        strain: 0.4,
        width: 10.0,
        ..ShearParams::default()
    };
    let r = shear_test(&radii, &p, &sp).unwrap();
    for q in &r.points {
        eprintln!(
            "P {:.0} Pa: σn {:.0} τ {:.0} μ {:.3} I {:.2e} v {:.3e} ({} samples, {:.1} s)",
            q.pressure,
            q.sigma_n,
            q.tau,
            q.mu,
            q.inertial_number,
            q.velocity,
            q.series.len(),
            q.wall_s
        );
        assert!((q.sigma_n - q.pressure).abs() < 0.05 * q.pressure);
        assert!(q.mu > 0.15 && q.mu < 0.8);
    }
    eprintln!(
        "φ_cs = {:.2}° (free fit {:.2}°, c = {:.1} Pa)",
        r.friction_angle_deg, r.friction_angle_free_deg, r.cohesion_free
    );
}

/// `n` radii of the shear cell's PSD (`psd-shear`: β(4, 4) by volume on [0.92, 1.38] mm,
/// the stage's seed).
fn quick_psd_radii(n: usize) -> Vec<f64> {
    let g = granrepro::sample::psd::BetaGrading {
        d_min: 0.92e-3,
        d_max: 1.38e-3,
        a: 4.0,
        b: 4.0,
    };
    g.sample(n, 20150403).iter().map(|d| 0.5 * d).collect()
}

/// μ* = τ/σ_n of the quick shear cell (the `psd-shear` grains of the quick profile: 400
/// disks, β(4, 4) on [0.92, 1.38] mm, width 12 d̄, contacts ×0.01, I = 1e-3) at 250 Pa and
/// 1 kPa, without rolling resistance, sheared to γ and averaged over its second half.
fn quick_cell_mu_star(strain: f64) -> (f64, f64) {
    let radii = quick_psd_radii(400);
    let mut p = DemParams::default().softened(1e-2);
    p.rolling.enabled = false;
    let sp = ShearParams {
        pressures: vec![250.0, 1000.0],
        inertial_number: 1e-3,
        strain,
        average_from: 0.5,
        width: 12.0,
        seed: 5,
        ..ShearParams::default()
    };
    let r = shear_test(&radii, &p, &sp).unwrap();
    eprintln!(
        "γ = {strain}: μ*(250 Pa) = {:.4}, μ*(1 kPa) = {:.4}, φ = {:.2}°",
        r.points[0].mu, r.points[1].mu, r.friction_angle_deg
    );
    (r.points[0].mu, r.points[1].mu)
}

/// Issue 24 item 1: a critical state does not depend on the pressure. Without rolling
/// resistance the quick cell sheared to γ = 2 gives the same μ* at 250 Pa and 1 kPa
/// within ±0.01, in the published range of frictional disks (μ* ≈ 0.25–0.30). Today's
/// quick calibration grid shears to γ = 0.6 only, which is not yet the critical state at
/// 250 Pa: there the same cell reads μ* 0.05 apart (docs/calibration.md), and this check
/// fails — asserted below, so that the check is seen to fail on that protocol.
#[test]
fn critical_state_mu_star_is_pressure_independent_without_rolling_resistance() {
    let (lo, hi) = quick_cell_mu_star(2.0);
    assert!(
        (lo - hi).abs() <= 0.01,
        "γ = 2: μ* {lo:.4} at 250 Pa vs {hi:.4} at 1 kPa"
    );
    for m in [lo, hi] {
        assert!(
            (0.22..=0.32).contains(&m),
            "μ* = {m:.4} outside frictional disks' 0.25–0.30 (± 0.03)"
        );
    }
    let (lo6, hi6) = quick_cell_mu_star(0.6);
    assert!(
        (lo6 - hi6).abs() > 0.01,
        "γ = 0.6 was expected to miss the critical state at 250 Pa: μ* {lo6:.4} vs {hi6:.4}"
    );
}

/// The critical-state protocol (src/dem/critical_state.rs) on a cell of `n` grains of the
/// quick PSD (β(4, 4) on [0.92, 1.38] mm), κ = k_n/P = 1600 at each pressure, I = 1e-3, the
/// dense (frictionless) compaction, sheared to γ and averaged over its second half.
fn protocol_cell(
    p: &DemParams,
    n: usize,
    width: f64,
    pressures: &[f64],
    strain: f64,
) -> granrepro::dem::critical_state::CsResult {
    use granrepro::dem::critical_state::{CriticalStateParams, Preparation, critical_state_test};
    let radii = quick_psd_radii(n);
    let sp = CriticalStateParams {
        pressures: pressures.to_vec(),
        strain,
        steady_from: 0.5 * strain,
        kappa: Some(1600.0),
        width,
        bulk_margin: if n < 300 { 2.0 } else { 4.0 },
        preparations: vec![Preparation::default()],
        ..CriticalStateParams::default()
    };
    let r = critical_state_test(&radii, p, &sp).unwrap();
    for q in &r.points {
        eprintln!(
            "P {:.0} Pa: μ* bulk {:.6} ± {:.4} wall {:.6}, drift {:+.4}, packing {:.4}, I bulk {:.2e} (band {:.2e}), rate ratio {:.2} ({:.0} s)",
            q.pressure,
            q.mu,
            q.mu_se,
            q.mu_wall,
            q.drift,
            q.packing,
            q.inertial_bulk,
            q.inertial_local_max,
            q.shear_rate_ratio,
            q.wall_s
        );
    }
    r
}

/// Issue 24 item 1, the protocol itself. At a fixed κ = k_n/P and I, a cell without
/// rolling resistance is the same problem at every pressure on a clock running as √P:
/// from 250 Pa to 1 kPa, k_n × 4, the step ÷ 2, the wall speed × 2, the damping × 2 (all
/// exact in floating point), so μ* is not only pressure-independent but bit-identical. The
/// quick cell (400 grains, γ = 2): μ* equal at both pressures; the bulk stress (the force
/// through planes in the bulk) equals the force on the moving wall within 0.01 in μ
/// (momentum balance: no body force, steady state); σ_n carries P; μ* in the range of
/// frictional disks. Fails if k_n, the step or the compaction clock did not scale with P
/// (the former protocol's fixed k_n read 0.2635 and 0.2574), or if the planes summed the
/// wrong side's forces.
#[test]
fn critical_state_protocol_is_pressure_independent_without_rolling_resistance() {
    let mut p = DemParams::default();
    p.rolling.enabled = false;
    let r = protocol_cell(&p, 400, 12.0, &[250.0, 1000.0], 2.0);
    let (lo, hi) = (r.points[0].mu, r.points[1].mu);
    assert!(lo == hi, "μ* {lo:.6} at 250 Pa vs {hi:.6} at 1 kPa");
    for q in &r.points {
        assert!(
            (q.mu - q.mu_wall).abs() <= 0.01,
            "bulk μ {:.4} vs wall μ {:.4}",
            q.mu,
            q.mu_wall
        );
        assert!(
            (q.sigma_bulk - q.pressure).abs() <= 0.05 * q.pressure,
            "σ_n {:.1} at P {:.0}",
            q.sigma_bulk,
            q.pressure
        );
        assert!(
            (0.22..=0.32).contains(&q.mu),
            "μ* = {:.4} outside frictional disks' 0.25–0.30 (± 0.03)",
            q.mu
        );
    }
}

/// Issue 24 item 1, the chosen model's pressure dependence and its cause. With rolling
/// resistance (the quick choice: EPSD, μ_r = 0.1, table 4.2's c_r = 0.1 N·m·s/rad) the
/// similarity above holds for every term but the rolling dashpot: k_r scales with k_n, the
/// cap μ_r r F_n with P, but c_r θ̇ grows only as √P. Asserted: with c_r fixed μ* moves
/// with the pressure; with c_r × 2 at 4P (the dashpot scaled like the rest) μ* is
/// bit-identical again — so the dependence is the dashpot's, and nothing else's.
#[test]
fn critical_state_protocol_pressure_dependence_is_the_rolling_dashpots() {
    let mut p = DemParams::default();
    p.rolling.mu_r = 0.1;
    p.rolling.model = granrepro::dem::RollingModel::Epsd;
    let (n, w, g) = (200, 10.0, 0.6);
    let fixed = protocol_cell(&p, n, w, &[250.0, 1000.0], g);
    let mut p4 = p.clone();
    p4.rolling.cr *= 2.0;
    let scaled = protocol_cell(&p4, n, w, &[1000.0], g);
    let (m250, m1k, m1k_scaled) = (fixed.points[0].mu, fixed.points[1].mu, scaled.points[0].mu);
    eprintln!("μ* 250 Pa {m250:.6}; 1 kPa, c_r fixed {m1k:.6}; 1 kPa, c_r × 2 {m1k_scaled:.6}");
    assert!(
        m250 != m1k,
        "c_r fixed: μ* was expected to move with P ({m250:.6} both)"
    );
    assert!(
        m250 == m1k_scaled,
        "c_r scaled with √P: μ* {m250:.6} vs {m1k_scaled:.6}"
    );
}

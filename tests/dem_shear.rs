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

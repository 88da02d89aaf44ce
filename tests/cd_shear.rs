//! CD periodic shear on a small cell: the plate carries the imposed pressure, the measured
//! inertial number follows the imposed one, and μ* is a dense-flow value that grows with I.
//! (σ_n within 15 %: over γ = 1 at I = 0.2 the plate still lags the sample's dilation.)

use granrepro::cd::CdParams;
use granrepro::cd::shear::{ShearCdParams, shear_test};
use granrepro::sample::rng::SplitMix64;

#[test]
fn small_cell_gives_pressure_inertial_number_and_rising_friction() {
    // PSD-PILE-like radii, uniform by volume in [1.964, 2.946] mm (number pdf ∝ d⁻²)
    let mut rng = SplitMix64(11);
    let (a, b) = (1.964e-3, 2.946e-3);
    let radii: Vec<f64> = (0..90)
        .map(|_| 0.5 / (1.0 / a - rng.next_f64() * (1.0 / a - 1.0 / b)))
        .collect();
    let sp = ShearCdParams {
        inertial_numbers: vec![5e-3, 0.2],
        strain: 1.0,
        width: 10.0,
        ..ShearCdParams::default()
    };
    let r = shear_test(&radii, &CdParams::default(), &sp).unwrap();
    for q in &r.points {
        eprintln!(
            "I* = {:.2e}: I = {:.3e}, μ* = {:.3} ± {:.3}, σ_n = {:.1} Pa, φ = {:.3}, h = {:.2e} s, {} steps, {:.0} sweeps/step, {} unconverged, pen {:.4} d, {:.1} s",
            q.target,
            q.inertial_number,
            q.mu,
            q.mu_se,
            q.sigma_n,
            q.packing_fraction,
            q.dt,
            q.steps,
            q.mean_iterations,
            q.unconverged,
            q.max_penetration,
            q.wall_s
        );
    }
    eprintln!(
        "compaction φ = {:.3}; fit μ_min = {:.3}, b = {:.3}",
        r.compaction_packing, r.mu_min, r.b
    );
    for q in &r.points {
        assert!(
            (q.sigma_n - sp.pressure).abs() < 0.15 * sp.pressure,
            "σ_n = {}",
            q.sigma_n
        );
        assert!(
            (q.inertial_number / q.target - 1.0).abs() < 0.3,
            "I = {} for target {}",
            q.inertial_number,
            q.target
        );
        assert!(q.mu > 0.1 && q.mu < 0.8, "μ* = {}", q.mu);
    }
    assert!(r.points[1].mu > r.points[0].mu, "μ* grows with I");
}

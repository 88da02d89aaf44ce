//! uGIMP shape functions: partition of unity, gradients summing to zero, continuity, support.

use granrepro::mpm::shape::{Stencil, gimp_1d};

fn lcg(seed: &mut u64) -> f64 {
    *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    (*seed >> 11) as f64 / (1u64 << 53) as f64
}

#[test]
fn partition_of_unity_and_zero_gradient_sum() {
    let mut seed = 7u64;
    for &(h, lp) in &[(2e-3, 0.25e-3), (2e-3, 0.5e-3), (4e-3, 1e-3), (1.0, 0.5), (1.0, 0.1)] {
        for _ in 0..2000 {
            let x = 10.0 * h * (0.2 + 0.6 * lcg(&mut seed));
            let y = 10.0 * h * (0.2 + 0.6 * lcg(&mut seed));
            let s = Stencil::new(x, y, 0.0, 0.0, h, lp);
            let (mut sum, mut gx, mut gy) = (0.0, 0.0, 0.0);
            let (mut mx, mut my) = (0.0, 0.0);
            for a in 0..3 {
                for b in 0..3 {
                    let w = s.wx[a] * s.wy[b];
                    assert!(w >= 0.0);
                    sum += w;
                    gx += s.dx[a] * s.wy[b];
                    gy += s.wx[a] * s.dy[b];
                    mx += w * (s.i0 + a) as f64 * h;
                    my += w * (s.j0 + b) as f64 * h;
                }
            }
            assert!((sum - 1.0).abs() < 1e-12, "partition of unity: {sum}");
            assert!(gx.abs() < 1e-9 / h && gy.abs() < 1e-9 / h, "gradient sum ({gx}, {gy})");
            // Linear completeness: Σ w x_i = x.
            assert!((mx - x).abs() < 1e-12 * 10.0 * h && (my - y).abs() < 1e-12 * 10.0 * h);
        }
    }
}

#[test]
fn weight_is_continuous_and_derivative_matches() {
    let (h, lp) = (2e-3, 0.25e-3);
    let n = 20000;
    let dr = 2.0 * (h + lp) / n as f64;
    for k in 0..n {
        let r = -(h + lp) + k as f64 * dr;
        let (w0, d0) = gimp_1d(r, h, lp);
        let (w1, d1) = gimp_1d(r + dr, h, lp);
        assert!((w1 - w0).abs() < 2.0 * dr / h, "jump at r = {r}");
        // Centred finite difference vs analytic derivative (d/dx_p of φ(x_p − x_i)).
        let fd = (w1 - w0) / dr;
        assert!(
            (fd - 0.5 * (d0 + d1)).abs() <= dr / (h * lp),
            "derivative at r = {r}: {fd} vs {d0}"
        );
    }
    assert_eq!(gimp_1d(h + lp, h, lp), (0.0, 0.0));
    assert!((gimp_1d(0.0, h, lp).0 - (1.0 - lp / (2.0 * h))).abs() < 1e-15);
}

#[test]
fn stencil_matches_piecewise_definition() {
    let mut seed = 11u64;
    for &(h, lp) in &[(2e-3, 0.25e-3), (2e-3, 1e-3), (4e-3, 0.5e-3)] {
        for _ in 0..2000 {
            let (ox, oy) = (-2.0 * h, -2.0 * h);
            let x = 10.0 * h * (0.2 + 0.6 * lcg(&mut seed));
            let y = 10.0 * h * (0.2 + 0.6 * lcg(&mut seed));
            let s = Stencil::new(x, y, ox, oy, h, lp);
            for k in 0..3 {
                let (w, d) = gimp_1d(x - (ox + (s.i0 + k) as f64 * h), h, lp);
                assert!(
                    (w - s.wx[k]).abs() < 1e-12 && (d - s.dx[k]).abs() < 1e-9 / h,
                    "x node {k}"
                );
                let (w, d) = gimp_1d(y - (oy + (s.j0 + k) as f64 * h), h, lp);
                assert!(
                    (w - s.wy[k]).abs() < 1e-12 && (d - s.dy[k]).abs() < 1e-9 / h,
                    "y node {k}"
                );
            }
            // No node outside the stencil carries weight.
            for k in [-1isize, 3] {
                let xi = ox + (s.i0 as isize + k) as f64 * h;
                assert_eq!(gimp_1d(x - xi, h, lp).0, 0.0);
            }
        }
    }
}

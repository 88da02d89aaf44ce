//! CD parameters. The chapter gives only the method and its three contact parameters
//! (μ, ε_n, ε_t; chapter4.txt line 309); every other value is chosen here with its reason.
//!
//! All quantities SI, 2D disks of unit (1 m) thickness: masses in kg per metre.

use crate::math::{G, Real};
use crate::validate::{Checker, Issue};
use serde::{Deserialize, Serialize};

/// Contact Dynamics solver parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CdParams {
    /// Time step h [s]. UNSPEC; docs/definitions.md c.5 rule: h ≤ 0.02 d_min / v_max, which
    /// also bounds the one-step interpenetration of an impact by h v_max / 2 ≤ 1 % d_min.
    /// Default 1e-4 s: v_max ≈ 0.39 m/s for the pile grains (d_min = 1.964 mm).
    pub dt: Real,
    /// θ of the Moreau–Jean scheme, x⁺ = x⁻ + h((1−θ)v⁻ + θv⁺), in [0.5, 1]. Default 0.5:
    /// the midpoint rule makes the discrete energy balance exact (ΔE_k + ΔE_p = Σ P·ū, no
    /// numerical dissipation; θ > 0.5 adds a damping h(½−θ)F·Δv that the ledger books),
    /// free flight is integrated exactly, and it is what Siconos' reference script runs
    /// (θ = 0.50001) and LMGC90's default.
    pub theta: Real,
    /// Grain density ρ [kg/m³]. Chapter §4.3 pile grains: 2600.
    pub density: Real,
    /// Gravity [m/s²] (0 in the periodic shear cell).
    pub gravity: Real,
    /// Grain–grain Coulomb friction μ. Chapter: "internal friction coefficient of 0.4 between
    /// grains" (pile DEM, docs/definitions.md b.4 takes the same for CD).
    pub friction: Real,
    /// Grain–wall Coulomb friction. UNSPEC: the grain value.
    pub wall_friction: Real,
    /// Normal restitution ε_n (Newton, Moreau's form). Baseline 0 (docs/definitions.md b.4;
    /// the chapter states its CD pile results do not depend on restitution).
    pub restitution_n: Real,
    /// Tangential restitution ε_t. Baseline 0 (same reason).
    pub restitution_t: Real,
    /// Rolling resistance μ_r (dimensionless): the rolling moment impulse of a contact obeys
    /// |M_r| ≤ μ_r r_eff P_n, r_eff = r_a r_b/(r_a + r_b) (the grain radius against a
    /// wall). 0 = off (default; none stated for the pile): the sweep then runs the plain
    /// two-unknown loop, so the option costs nothing when off.
    pub rolling_friction: Real,
    /// Alert distance as a fraction of the smallest grain diameter. Pairs closer than this
    /// are detected at the start of a step; the step is refused if a grain would move more
    /// than half of it (so no pair can close unseen). Default 0.1 d_min: with the c.5 step
    /// rule a grain moves at most 0.02 d_min per step, so 0.1 leaves a factor 2.5 margin for
    /// accelerations within the step.
    pub alert_fraction: Real,
    /// NLGS convergence tolerance on the quadratic-mean relative impulse change of one
    /// sweep, ‖ΔP‖₂/‖P‖₂ (LMGC90's "Quad"-like norm). docs/definitions.md c.5: "mean force
    /// change < 1e-4".
    pub tolerance: Real,
    /// Second convergence test, checked once the first passes: the natural-map residual of
    /// the local Signorini–Coulomb problems (De Saxcé's modified velocity, Siconos-like),
    /// ‖P − proj_K(P − ρ q̂)‖₂/‖(P, ρq)‖₂ with ρ = 1/W_nn. 1e-3: Gauss–Seidel's last sweep
    /// underestimates the distance to the solution on long force chains by about 10×.
    pub residual_tolerance: Real,
    /// Iteration cap per step. Steps that reach it are counted as unconverged and reported.
    /// 4000: in dense quasi-static shear the sweep count is heavy-tailed (mean ≈ 1000 at
    /// tolerance 1e-4); a cap of 1000 left 45 % of the steps unconverged and lowered μ* by
    /// ≈ 0.03, a cap of 4000 converges all but ≈ 0.2 % for +20 % sweeps.
    pub max_iterations: u32,
    /// Under-relaxation ω ∈ (0, 1] of the local solution (1: plain NLGS).
    pub relaxation: Real,
    /// Sweep the contacts colour class by colour class, each class shared out on the
    /// thread pool (`src/cd/colour.rs`), instead of in key order on one thread. The same
    /// solver and tests in another order of updates: not the same bits as the key order,
    /// the same at any thread count. Default false.
    pub coloured_sweeps: bool,
    /// Verlet skin of the pair list as a multiple of the alert distance (≥ 2). 4: rebuild
    /// once a grain moved 1.5 alert distances.
    pub skin_factor: Real,
    /// Watchdog: stop if an interpenetration exceeds this fraction of the smaller diameter.
    /// 0.05 d: five times the c.5 one-impact bound.
    pub max_penetration: Real,
    /// Watchdog: stop if E_k + E_p exceeds E_0 + W_in by this fraction of max(E_0, E_k) —
    /// rigid, inelastic contacts can only take energy out.
    pub energy_rise: Real,
}

impl Default for CdParams {
    fn default() -> Self {
        CdParams {
            dt: 1e-4,
            theta: 0.5,
            density: 2600.0,
            gravity: G,
            friction: 0.4,
            wall_friction: 0.4,
            restitution_n: 0.0,
            restitution_t: 0.0,
            rolling_friction: 0.0,
            alert_fraction: 0.1,
            tolerance: 1e-4,
            residual_tolerance: 1e-3,
            max_iterations: 4000,
            relaxation: 1.0,
            coloured_sweeps: false,
            skin_factor: 4.0,
            max_penetration: 0.05,
            energy_rise: 1e-3,
        }
    }
}

impl CdParams {
    /// Validation-time pre-flight of step `dt` for grains of smallest diameter `d_min`
    /// moving at most at `v_max` (a stage's stated speed, e.g. the excitation v0): a grain
    /// may move at most half the alert distance per step (the same bound [`World::step`]
    /// enforces on the actual speeds), else a pair can close — and, once the travel
    /// exceeds d_min, pass through one another — between two detections. The binding time
    /// scale is the alert-crossing time alert/(2 v_max).
    ///
    /// [`World::step`]: crate::cd::World::step
    pub fn step_preflight(&self, dt: Real, d_min: Real, v_max: Real) -> Result<(), String> {
        let alert = self.alert_fraction * d_min;
        let limit = 0.5 * alert / v_max;
        if dt <= limit {
            return Ok(());
        }
        let travel = dt * v_max;
        let through = if travel >= d_min {
            " — more than d_min: grains pass through one another unseen"
        } else {
            ""
        };
        Err(format!(
            "CD step {dt:.3e} s moves a grain at v_max = {v_max:.3} m/s by {travel:.3e} m = {:.2} d_min per step{through}; binding time scale: alert-distance crossing time alert/(2 v_max) = {limit:.3e} s (alert = {} d_min = {alert:.3e} m); limit dt <= {limit:.3e} s; fix: dt <= {:.3e} s (docs/definitions.md c.5: 0.02 d_min/v_max = {:.3e} s) or alert_fraction >= {:.3}",
            travel / d_min,
            self.alert_fraction,
            0.9 * limit,
            crate::cd::preflight::recommended_dt(d_min, v_max),
            2.0 * travel / d_min
        ))
    }

    /// All range problems at once (empty when valid).
    pub fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        c.positive("dt", self.dt);
        c.in_closed("theta", self.theta, 0.5, 1.0);
        c.positive("density", self.density);
        c.non_negative("gravity", self.gravity);
        c.non_negative("friction", self.friction);
        c.non_negative("wall_friction", self.wall_friction);
        c.in_closed("restitution_n", self.restitution_n, 0.0, 1.0);
        c.in_closed("restitution_t", self.restitution_t, 0.0, 1.0);
        c.non_negative("rolling_friction", self.rolling_friction);
        c.in_open_closed("alert_fraction", self.alert_fraction, 0.0, 1.0);
        c.in_open("tolerance", self.tolerance, 0.0, 1.0);
        c.in_open("residual_tolerance", self.residual_tolerance, 0.0, 1.0);
        c.check(self.max_iterations >= 1, "max_iterations", self.max_iterations, "≥ 1");
        c.in_open_closed("relaxation", self.relaxation, 0.0, 1.0);
        c.in_closed("skin_factor", self.skin_factor, 2.0, 100.0);
        c.in_open_closed("max_penetration", self.max_penetration, 0.0, 1.0);
        c.positive("energy_rise", self.energy_rise);
        c.issues
    }
}

//! Parameters of the MPM solver (docs/definitions.md b.2, chapter 4 table 4.3).
//!
//! `Default` is table 4.3: E = 1.98e6 Pa, ν = 0.22, φ = 22.2°, ψ = 0, ρ = 1925 kg/m³,
//! wall/base friction 0.466, cell 2 mm, 16 PPC, Δt = 1e-6 s. Friction angle and modulus are
//! plain fields so the pipeline can inject the values measured by the DEM calibration stages
//! (C1 shear test → `material.friction_deg`, C2 confined compression → `material.young_pa`).

use crate::math::Real;
use crate::validate::{Checker, Issue};
use serde::{Deserialize, Serialize};

/// Explicit update scheme (a strategy: the two differ only in where the stress update takes
/// its nodal velocities from; see `solver.rs`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Scheme {
    /// Update Stress Last (chapter 3 §"Integration scheme": the thesis' choice). The strain
    /// increment uses the updated nodal velocities of the same step.
    Usl,
    /// Modified USL (Sulsky et al. 1995): particle momenta are mapped back to the grid after
    /// the particle update and the strain increment uses those re-mapped velocities. More
    /// robust for nodes with tiny mass (free surface).
    Musl,
}

impl Scheme {
    /// Name for logs and reports.
    pub fn name(self) -> &'static str {
        match self {
            Scheme::Usl => "USL",
            Scheme::Musl => "MUSL",
        }
    }
}

/// Shape functions of the background grid as seen by a material point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Shape {
    /// uGIMP (the thesis' choice): the linear hat convolved with the point's characteristic
    /// function of half-width l_p = h/(2√PPC).
    #[default]
    Gimp,
    /// Standard MPM: the linear hat itself (GIMP with l_p → 0); a point's weights jump
    /// when it crosses a cell boundary (cell-crossing noise).
    Linear,
}

impl Shape {
    /// Whether this is the default (GIMP): then the field is left out of the canonical
    /// params, so stages that never set it keep their cache keys.
    pub fn is_gimp(&self) -> bool {
        *self == Shape::Gimp
    }
}

/// Constitutive model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Model {
    /// Linear isotropic elasticity (verification only).
    Elastic,
    /// Mohr–Coulomb, perfectly plastic, φ = `material.friction_deg`, ψ = `material.dilation_deg`.
    MohrCoulomb,
    /// Mohr–Coulomb whose friction is updated per point each step from μ = μ_min + b·I
    /// (chapter 4 §4.2.4, Da Cruz et al. 2005; docs/definitions.md D08, I6).
    MuILinear {
        /// μ_min [-]. Default tan 22.2° = 0.408 (docs/definitions.md I6); the literal
        /// "0.22" of the chapter is available by setting it.
        mu_min: Real,
        /// b [-]. Chapter: 1.
        b: Real,
    },
    /// Jop, Forterre & Pouliquen (2006): μ = μ_s + (μ_2 − μ_s)/(I_0/I + 1).
    MuIJop {
        /// μ_s [-]. Default tan 22.2°.
        mu_s: Real,
        /// μ_2 [-]. Default μ_s + 0.2616 (the Jop glass-bead spread tan 32.76° − tan 20.9°).
        mu_2: Real,
        /// I_0 [-]. Jop et al.: 0.279.
        i0: Real,
    },
}

impl Model {
    /// μ(I) with the chapter's values and μ_min = tan 22.2° (docs/definitions.md I6).
    pub fn mu_i_default() -> Self {
        Model::MuILinear {
            mu_min: (22.2 as Real).to_radians().tan(),
            b: 1.0,
        }
    }
    /// Jop et al. form with μ_s = tan 22.2°.
    pub fn jop_default() -> Self {
        let mu_s = (22.2 as Real).to_radians().tan();
        Model::MuIJop {
            mu_s,
            mu_2: mu_s + 0.2616,
            i0: 0.279,
        }
    }
}

/// Material constants.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Material {
    /// Constitutive model. Default Mohr–Coulomb.
    pub model: Model,
    /// Young's modulus E [Pa]. Table 4.3: 1.98e6 (see docs/definitions.md I12 on whether it
    /// is M).
    pub young_pa: Real,
    /// Poisson's ratio ν [-]. Table 4.3: 0.22 to 0.24; 0.22 used.
    pub poisson: Real,
    /// Bulk density ρ [kg/m³]. Table 4.3: 1925.
    pub density: Real,
    /// Friction angle φ [deg]. Table 4.3: 22.2 (critical state, DEM shear test C1).
    pub friction_deg: Real,
    /// Dilation angle ψ [deg]. Table 4.3: 0.
    pub dilation_deg: Real,
    /// Cohesion c [Pa]. UNSPEC; 0 (dry sand). No regularisation is needed by the return map.
    pub cohesion_pa: Real,
    /// Tension cut-off: largest principal stress allowed [Pa] (tension positive). With c = 0
    /// Mohr–Coulomb already caps it at 0; it matters only with c > 0. Default 0.
    pub tension_cutoff_pa: Real,
    /// Mean grain diameter d̄ in I = γ̇ d̄/√(p/ρ_s) [m]. 1.15 mm (PSD-COL volume mean).
    pub grain_diameter: Real,
    /// Grain (solid) density ρ_s in I [kg/m³]. UNSPEC; 2500 chosen (docs/definitions.md
    /// D08: the chapter's ρ = 1925 = 2500 × 0.77 is a bulk density, Da Cruz et al. use the
    /// grain one).
    pub grain_density: Real,
    /// Cap on I [-] where p → 0 (free surface): μ(I) is evaluated at min(I, i_max). 1.0.
    pub i_max: Real,
}

impl Default for Material {
    fn default() -> Self {
        Self {
            model: Model::MohrCoulomb,
            young_pa: 1.98e6,
            poisson: 0.22,
            density: 1925.0,
            friction_deg: 22.2,
            dilation_deg: 0.0,
            cohesion_pa: 0.0,
            tension_cutoff_pa: 0.0,
            grain_diameter: 1.15e-3,
            grain_density: 2500.0,
            i_max: 1.0,
        }
    }
}

impl Material {
    /// Shear modulus G = E/(2(1+ν)) [Pa].
    pub fn shear_modulus(&self) -> Real {
        self.young_pa / (2.0 * (1.0 + self.poisson))
    }
    /// Lamé λ = Eν/((1+ν)(1−2ν)) [Pa].
    pub fn lame(&self) -> Real {
        self.young_pa * self.poisson / ((1.0 + self.poisson) * (1.0 - 2.0 * self.poisson))
    }
    /// Plane-strain P-wave (constrained) modulus M = λ + 2G [Pa] (docs/definitions.md c.3:
    /// 2.2605e6).
    pub fn p_wave_modulus(&self) -> Real {
        self.lame() + 2.0 * self.shear_modulus()
    }
    /// P-wave speed c_p = √(M/ρ) [m/s] (docs/definitions.md c.3: 34.27 m/s).
    pub fn p_wave_speed(&self) -> Real {
        (self.p_wave_modulus() / self.density).sqrt()
    }
}

/// Time-step rule.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StepRule {
    /// Fixed Δt [s]. Table 4.3: 1e-6 s.
    Fixed {
        /// Δt [s].
        dt: Real,
    },
    /// Δt = courant · h / (c_p + max |v_p|), re-evaluated every step, capped by `dt_max`.
    Cfl {
        /// Courant number (0, 1]. 0.5 is a safe default for GIMP + FLIP.
        courant: Real,
        /// Upper bound on Δt [s].
        dt_max: Real,
    },
}

/// A straight frictional boundary on a grid line (chapter 3 alg. "friction boundary",
/// Bandara 2013): a unilateral Coulomb constraint on the nodal velocities of every node on or
/// beyond the line.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Wall {
    /// Which coordinate is constrained: `x` (vertical wall) or `y` (horizontal floor/lid).
    pub axis: Axis,
    /// Position of the line [m].
    pub at: Real,
    /// True if the material lies on the + side of the line (left wall, floor); false for a
    /// right wall / gate / lid.
    pub material_on_plus_side: bool,
    /// Coulomb friction coefficient [-] (table 4.3: 0.466).
    pub friction: Real,
    /// Bilateral (no separation: roller/fixed) instead of unilateral contact.
    pub bilateral: bool,
}

/// Coordinate axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Axis {
    /// Horizontal coordinate.
    X,
    /// Vertical coordinate.
    Y,
}

/// Geostatic stage (gravity loading with local damping until stationary).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Geostatic {
    /// Cundall local (non-viscous) damping coefficient α on nodal forces [-]. 0.7.
    pub damping: Real,
    /// Stationary when E_k < tol × M g H (kinetic energy relative to the column's weight
    /// times its height) [-]. 1e-9.
    pub ke_tol: Real,
    /// Minimum duration [s] (a few P-wave transits). 0.02 s.
    pub min_time: Real,
    /// Maximum duration [s]; reaching it is an error. 1.0 s.
    pub max_time: Real,
    /// Courant number used during the geostatic stage (its path is irrelevant, only its
    /// end state is used). 0.25: at 0.5 a Mohr–Coulomb column with 16 PPC in 4 mm cells
    /// (E = 4e4 Pa, φ = 17.5°) cycled at E_k/(M g H) ≈ 4–9e-8 and never came to rest
    /// (tests/mpm_geostatic.rs).
    pub courant: Real,
}

impl Default for Geostatic {
    fn default() -> Self {
        Self {
            damping: 0.7,
            ke_tol: 1e-9,
            min_time: 0.02,
            max_time: 1.0,
            courant: 0.25,
        }
    }
}

/// All parameters of one MPM run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MpmParams {
    /// Material.
    pub material: Material,
    /// Background cell size h [m]. Table 4.3: 2e-3.
    pub cell_size: Real,
    /// Material points per cell, a perfect square n² (n per direction). Table 4.3: 16.
    pub ppc: u32,
    /// Update scheme. Default USL (the thesis' choice).
    pub scheme: Scheme,
    /// Shape functions: `gimp` (default, the thesis) or `linear` (standard MPM).
    #[serde(skip_serializing_if = "Shape::is_gimp")]
    pub shape: Shape,
    /// FLIP fraction of the particle velocity update [0, 1] (1 = pure FLIP, 0 = PIC).
    /// UNSPEC; 1.0 (the Uintah-lineage GIMP codes the thesis built on use FLIP).
    pub flip: Real,
    /// Time-step rule. Table 4.3: fixed 1e-6 s.
    pub step: StepRule,
    /// Gravity magnitude [m/s²] (acts along −y).
    pub gravity: Real,
    /// Friction of the left wall and the base [-]. Table 4.3: 0.466.
    pub wall_friction: Real,
    /// Geostatic stage.
    pub geostatic: Geostatic,
    /// Watchdog: stop if E_k + E_p + E_el + dissipated work exceeds its initial value by more
    /// than this fraction of E_p(0) [-]. 0.05.
    pub energy_rise_tol: Real,
}

impl Default for MpmParams {
    fn default() -> Self {
        Self {
            material: Material::default(),
            cell_size: 2e-3,
            ppc: 16,
            scheme: Scheme::Usl,
            shape: Shape::Gimp,
            flip: 1.0,
            step: StepRule::Fixed { dt: 1e-6 },
            gravity: crate::math::G,
            wall_friction: 0.466,
            geostatic: Geostatic::default(),
            energy_rise_tol: 0.05,
        }
    }
}

impl MpmParams {
    /// A quick profile: 4 mm cells, 4 PPC, CFL step (Courant 0.5). Used by tests and the
    /// `quick` pipeline profile.
    pub fn quick() -> Self {
        Self {
            cell_size: 4e-3,
            ppc: 4,
            step: StepRule::Cfl {
                courant: 0.5,
                dt_max: 1e-3,
            },
            ..Self::default()
        }
    }
    /// Points per cell per direction (√PPC).
    pub fn ppc_1d(&self) -> u32 {
        (self.ppc as f64).sqrt().round() as u32
    }
    /// Initial point spacing h/√PPC [m] (table 4.3: 0.5 mm).
    pub fn spacing(&self) -> Real {
        self.cell_size / self.ppc_1d() as Real
    }
    /// GIMP half-width l_p = h/(2√PPC) [m] (docs/definitions.md D01: 0.25 mm).
    pub fn half_width(&self) -> Real {
        0.5 * self.spacing()
    }
    /// Half-width of the shape functions' particle domain: l_p for GIMP, 0 for the linear
    /// hat (standard MPM). [`half_width`](Self::half_width) stays the point's half-size
    /// h/(2√PPC), the body size the run-out and height measurements use
    /// (docs/definitions.md D01) whatever the shape functions.
    pub fn shape_half_width(&self) -> Real {
        match self.shape {
            Shape::Gimp => self.half_width(),
            Shape::Linear => 0.0,
        }
    }

    /// Every invalid value, all at once.
    pub fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        let m = &self.material;
        c.plausible("material.young_pa", m.young_pa, 1e3, 1e12, "Young's modulus [Pa]");
        c.in_open("material.poisson", m.poisson, -1.0, 0.5);
        c.plausible("material.density", m.density, 100.0, 2.5e4, "bulk density [kg/m³]");
        c.in_open("material.friction_deg", m.friction_deg, 0.0, 90.0);
        c.check(
            m.dilation_deg.is_finite() && m.dilation_deg >= 0.0 && m.dilation_deg <= m.friction_deg,
            "material.dilation_deg",
            m.dilation_deg,
            "in [0, friction_deg]",
        );
        c.plausible("material.cohesion_pa", m.cohesion_pa, 0.0, 1e9, "cohesion [Pa]");
        c.plausible(
            "material.tension_cutoff_pa", m.tension_cutoff_pa, 0.0, 1e9, "tension cut-off [Pa]",
        );
        c.plausible(
            "material.grain_diameter", m.grain_diameter, 1e-6, 1.0, "grain diameter [m]",
        );
        c.plausible(
            "material.grain_density", m.grain_density, 100.0, 2.5e4, "grain density [kg/m³]",
        );
        c.positive("material.i_max", m.i_max);
        match m.model {
            Model::MuILinear { mu_min, b } => {
                c.positive("material.model.mu_min", mu_min);
                c.non_negative("material.model.b", b);
            }
            Model::MuIJop { mu_s, mu_2, i0 } => {
                c.positive("material.model.mu_s", mu_s);
                c.check(mu_2.is_finite() && mu_2 >= mu_s, "material.model.mu_2", mu_2, ">= mu_s");
                c.positive("material.model.i0", i0);
            }
            _ => {}
        }
        c.plausible("cell_size", self.cell_size, 1e-5, 10.0, "cell size [m]");
        let n = self.ppc_1d();
        c.check(
            self.ppc >= 1 && n * n == self.ppc,
            "ppc",
            self.ppc,
            "a perfect square >= 1 (1, 4, 9, 16, 25, ...)",
        );
        c.in_closed("flip", self.flip, 0.0, 1.0);
        match self.step {
            StepRule::Fixed { dt } => c.positive("step.fixed.dt", dt),
            StepRule::Cfl { courant, dt_max } => {
                c.in_open_closed("step.cfl.courant", courant, 0.0, 1.0);
                c.positive("step.cfl.dt_max", dt_max);
            }
        }
        c.plausible("gravity", self.gravity, 0.0, 100.0, "gravity [m/s²]");
        c.plausible("wall_friction", self.wall_friction, 0.0, 10.0, "Coulomb coefficient");
        let g = &self.geostatic;
        c.in_closed("geostatic.damping", g.damping, 0.0, 1.0);
        c.positive("geostatic.ke_tol", g.ke_tol);
        c.non_negative("geostatic.min_time", g.min_time);
        c.check(
            g.max_time.is_finite() && g.max_time > g.min_time,
            "geostatic.max_time",
            g.max_time,
            "> geostatic.min_time",
        );
        c.in_open_closed("geostatic.courant", g.courant, 0.0, 1.0);
        c.positive("energy_rise_tol", self.energy_rise_tol);
        c.issues
    }
}

//! DEM parameters. `Default` = the chapter's table 4.2 (column DEM, §4.2.1), with every
//! UNSPEC value chosen here and justified in its field doc (docs/definitions.md b.1, c.1–c.6).
//!
//! All quantities are SI, 2D disks of unit (1 m) thickness: masses in kg per metre,
//! stiffnesses in N/m per metre of thickness (docs/definitions.md b.0).

use crate::math::Real;
use crate::validate::{Checker, Issue};
use serde::{Deserialize, Serialize};

/// Damping coefficient ratio γ of eq 4.5: γ = −ln ε / √(π² + ln² ε).
pub fn gamma_from_restitution(e: Real) -> Real {
    let l = e.ln();
    -l / (std::f64::consts::PI * std::f64::consts::PI + l * l).sqrt()
}

/// Restitution of the linear spring-dashpot with damping ratio ζ when the normal force is
/// clipped at zero (no attraction): the contact ends when k δ = C δ̇, i.e. at
/// ω t* = π − atan(2ζω/(1 − 2ζ²)) (ω₀ = 1, ω = √(1−ζ²)), and
/// ε = e^{−ζ t*} (cos ωt* − (ζ/ω) sin ωt*). Larger than eq 4.5's e^{−πζ/ω} because the
/// attractive tail that eq 4.5 assumes is cut off.
pub fn restitution_no_attraction(zeta: Real) -> Real {
    let w = (1.0 - zeta * zeta).sqrt();
    let wt = std::f64::consts::PI - (2.0 * zeta * w).atan2(1.0 - 2.0 * zeta * zeta);
    let t = wt / w;
    (-zeta * t).exp() * (wt.cos() - zeta / w * wt.sin()).abs()
}

/// How the damping ratio is derived from the restitution coefficient.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DampingModel {
    /// Chapter eq 4.5 literally, γ = −ln ε/√(π² + ln² ε). With the no-attraction clip the
    /// measured ε is then 0.7605 for ε = 0.75 (+1.4 %).
    Eq45,
    /// γ solved so that the clipped (no-attraction) contact returns exactly ε
    /// ([`restitution_no_attraction`]); γ = 0.0983 for ε = 0.75. Default: the chapter asks
    /// for ε = 0.75, eq 4.5 is only the means.
    NoAttractionExact,
}

/// Damping ratio ζ (the γ of eq 4.4) for restitution `e` under `model`.
pub fn damping_ratio(e: Real, model: DampingModel) -> Real {
    match model {
        DampingModel::Eq45 => gamma_from_restitution(e),
        DampingModel::NoAttractionExact => {
            if e >= 1.0 {
                return 0.0;
            }
            // ε(ζ) decreases monotonically on (0, 1/√2): bisection on a bracket just inside
            // it (the literal is the bracket the results were computed with, not √½).
            #[allow(clippy::approx_constant)]
            let (mut lo, mut hi) = (0.0, 0.7071);
            for _ in 0..80 {
                let mid = 0.5 * (lo + hi);
                if restitution_no_attraction(mid) > e {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            0.5 * (lo + hi)
        }
    }
}

/// Normal dashpot C_n = 2ζ√(m_ij k_n) (eq 4.4) for effective mass `m_eff` [kg].
pub fn normal_damping(zeta: Real, m_eff: Real, kn: Real) -> Real {
    2.0 * zeta * (m_eff * kn).sqrt()
}

/// Contact parameters of one contact family (grain–grain or grain–wall).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ContactParams {
    /// Normal spring stiffness k_n [N/m]. Table 4.2: 1.6e8 grain–grain, 4e8 wall.
    pub kn: Real,
    /// Tangential spring stiffness k_s [N/m]. Table 4.2: "normal and shear stiffness" equal.
    pub kt: Real,
    /// Coulomb friction coefficient μ [-]. Table 4.2: 0.53 grains, 0.466 wall.
    pub friction: Real,
    /// Normal coefficient of restitution ε [-] (eqs 4.4–4.5). Table 4.2: 0.75. For walls
    /// UNSPEC: the grain value is reused.
    pub restitution: Real,
    /// Tangential dashpot as a fraction of C_n [-]. UNSPEC in the chapter; 0 (pure
    /// elastic-Coulomb spring, as eq "tf" of chapter 3 with γ_t = 0).
    pub tangential_damping_ratio: Real,
    /// How C_n follows from ε; see [`DampingModel`]. Default `no_attraction_exact`.
    pub damping_model: DampingModel,
}

impl ContactParams {
    /// Table 4.2 grain–grain values.
    pub fn grain() -> Self {
        Self {
            kn: 1.6e8,
            kt: 1.6e8,
            friction: 0.53,
            restitution: 0.75,
            tangential_damping_ratio: 0.0,
            damping_model: DampingModel::NoAttractionExact,
        }
    }
    /// Table 4.2 grain–wall values.
    pub fn wall() -> Self {
        Self {
            kn: 4e8,
            kt: 4e8,
            friction: 0.466,
            restitution: 0.75,
            tangential_damping_ratio: 0.0,
            damping_model: DampingModel::NoAttractionExact,
        }
    }
    /// Damping ratio ζ of this family.
    pub fn damping_ratio(&self) -> Real {
        damping_ratio(self.restitution, self.damping_model)
    }
    fn check(&self, c: &mut Checker) {
        c.plausible("kn", self.kn, 1.0, 1e12, "contact stiffness [N/m per metre]");
        c.plausible("kt", self.kt, 1.0, 1e12, "contact stiffness [N/m per metre]");
        c.plausible("friction", self.friction, 0.0, 10.0, "Coulomb coefficient");
        c.in_open_closed("restitution", self.restitution, 0.0, 1.0);
        c.plausible(
            "tangential_damping_ratio", self.tangential_damping_ratio, 0.0, 10.0, "fraction of C_n",
        );
    }
}

impl Default for ContactParams {
    fn default() -> Self {
        Self::grain()
    }
}

/// How the rolling dashpot is integrated (docs/definitions.md c.2: I/c_r ≈ 1e-9 s).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RollingDamping {
    /// Naive explicit dashpot M = −c_r θ̇_r. Stable only for Δt < 2 I_eff / c_r (≈ 2–20 ns
    /// with table 4.2): kept so the pre-flight can refuse it with numbers.
    Explicit,
    /// Pairwise backward-Euler impulses in the spin update (see `dem::integrate`): for each
    /// contact in a fixed order, the relative rolling rate u = ω_i − ω_j relaxes as
    /// u⁺ = u/(1 + h c_r/I_eff), I_eff = I_iI_j/(I_i+I_j), by an equal and opposite
    /// impulse. Conserves ΣIω exactly, never raises E_rot, unconditionally stable; for
    /// c_r h/I → 0 it reduces to the explicit dashpot.
    Implicit,
}

/// Which moments the rolling cap μ_r r_eff F_n limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RollingModel {
    /// Iwashita & Oda (1998) as used by Ai et al. (2011), "type C" EPSD: the spring is
    /// capped; the dashpot acts (uncapped) while the spring is below the cap. With table
    /// 4.2's c_r = 0.1 (c_r Δt/I ≈ 10²–10³) it locks relative rolling below the cap.
    Epsd,
    /// Spring and dashpot capped together, |M_k + M_d| ≤ μ_r r_eff F_n, as the tangential
    /// force and as LAMMPS `pair granular … rolling sds`.
    Capped,
}

/// Rolling resistance, elastic-plastic spring-dashpot after Iwashita & Oda (1998) in the
/// "EPSD" form of Ai et al. (2011): M_r = −k_r θ_r − c_r θ̇_r with θ̇_r = ω_i − ω_j; the
/// spring moment is capped at μ_r r_eff F_n (stored rotation rescaled, like Coulomb), and
/// the dashpot acts only while the spring is below the cap (full mobilisation = plastic).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RollingParams {
    /// Whether rolling resistance is present at all (absent ⇒ costs nothing).
    pub enabled: bool,
    /// Rolling spring k_r [N·m/rad]. Table 4.2: 1.0e3.
    pub kr: Real,
    /// Rolling dashpot c_r [N·m·s/rad]. Table 4.2: 0.1.
    pub cr: Real,
    /// Rolling friction coefficient μ_r [-]: |M_r| ≤ μ_r r_eff F_n, r_eff = r_i r_j/(r_i+r_j)
    /// (r_i at a wall; LAMMPS's R_eff). UNSPEC in the chapter. Calibrated with the periodic
    /// shear test (C1, 1078 grains, I = 1e-3, k/100): μ_r = 0.1 → φ_cs = 18.4° (μ = 0.33, three
    /// pressures), 0.3 → 21.7°, 0.35 → 21.3° (plateau); the chapter's 22.2° needs μ_r ≳ 0.3,
    /// so 0.3. A single disk then stays on slopes up to atan(0.3) = 16.7° (wall contact).
    pub mu_r: Real,
    /// Integration of the dashpot; see [`RollingDamping`]. Default implicit.
    pub damping: RollingDamping,
    /// What the cap limits; see [`RollingModel`].
    pub model: RollingModel,
}

impl Default for RollingParams {
    fn default() -> Self {
        Self {
            enabled: true,
            kr: 1.0e3,
            cr: 0.1,
            mu_r: 0.3,
            damping: RollingDamping::Implicit,
            model: RollingModel::Epsd,
        }
    }
}

/// Watchdog thresholds (checked every `every` steps).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WatchdogParams {
    /// Check interval [steps]; 0 disables the watchdog.
    pub every: u64,
    /// Largest allowed overlap as a fraction of the smaller diameter of the pair [-].
    /// 0.05: ten times the chapter's 0.1–1 % target (I13); beyond it the linear law is
    /// meaningless and usually Δt or k_n is wrong.
    pub max_overlap_fraction: Real,
    /// Allowed rise of E_k + E_p + E_rot above (E_0 + external work) as a fraction of E_0.
    pub energy_rise_fraction: Real,
}

impl Default for WatchdogParams {
    fn default() -> Self {
        Self {
            every: 200,
            max_overlap_fraction: 0.05,
            energy_rise_fraction: 0.05,
        }
    }
}

/// All DEM solver parameters of one scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DemParams {
    /// Grain density ρ_s [kg/m³]; m = ρπr² per metre, I = ½mr². UNSPEC (docs/definitions.md
    /// b.0): 2500, glass.
    pub density: Real,
    /// Gravity magnitude g [m/s²], acting along −y. UNSPEC: 9.81.
    pub gravity: Real,
    /// Time step [s]. UNSPEC; 1.5e-7 s = t_c(min pair)/48 (docs/definitions.md c.1),
    /// which resolves ε = 0.75 to < 1 % and is below every explicit limit of
    /// docs/definitions.md c.1–c.2.
    pub dt: Real,
    /// Grain–grain contact law.
    pub grain: ContactParams,
    /// Grain–wall contact law ("its own stiffness"; k_wall alone, not in series: UNSPEC,
    /// table 4.2 lists it as the wall's normal and shear stiffness).
    pub wall: ContactParams,
    /// Rolling resistance (grain–grain and grain–wall alike).
    pub rolling: RollingParams,
    /// Verlet skin as a fraction of the largest diameter [-]; lists are rebuilt when a grain
    /// moved more than skin/2. 0.2 (LAMMPS bench: 0.25 mm ≈ 0.18 d_max).
    pub skin_fraction: Real,
    /// Keep the energy ledger (D06/D07 split). Off ⇒ zero cost in the pair loop.
    pub ledger: bool,
    /// Watchdog thresholds.
    pub watchdog: WatchdogParams,
    /// Sort the grains along a Hilbert curve at the first neighbour rebuild after every
    /// this many steps (0: never), so that grains near in space are near in memory
    /// (LAMMPS `atom_modify sort`, every 1000 steps by default). Same physics, not the
    /// same bits: the order of the force sums and of the implicit dashpot's sweep follows
    /// the grain indices (`crate::dem::world` sort module). Off unless a scene asks.
    pub sort_every: u64,
}

impl Default for DemParams {
    fn default() -> Self {
        Self {
            density: 2500.0,
            gravity: crate::math::G,
            dt: 1.5e-7,
            grain: ContactParams::grain(),
            wall: ContactParams::wall(),
            rolling: RollingParams::default(),
            skin_fraction: 0.2,
            ledger: true,
            watchdog: WatchdogParams::default(),
            sort_every: 0,
        }
    }
}

impl DemParams {
    /// Steps per simulated second with the contact stiffnesses softened by
    /// `stiffness_factor` (the stable step scales as 1/√k): the rate the cost models of
    /// `plan --estimate` scale by.
    pub fn steps_per_second(&self, stiffness_factor: Real) -> Real {
        stiffness_factor.sqrt() / self.dt
    }

    /// "Quick" profile: k_n, k_t, k_r softened by `factor` (< 1) and Δt divided by
    /// √factor, so every time scale of docs/definitions.md c.1–c.2 keeps the same
    /// steps-per-period ratio. k_r is scaled with k_n to keep the rolling/translational
    /// period ratio of the chapter.
    pub fn softened(&self, factor: Real) -> Self {
        let mut p = self.clone();
        p.grain.kn *= factor;
        p.grain.kt *= factor;
        p.wall.kn *= factor;
        p.wall.kt *= factor;
        p.rolling.kr *= factor;
        p.dt /= factor.sqrt();
        p
    }

    /// All invalid values at once (keys relative to the DEM params block).
    pub fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        c.plausible("density", self.density, 100.0, 2.5e4, "grain density [kg/m³]");
        c.plausible("gravity", self.gravity, 0.0, 100.0, "gravity [m/s²]");
        c.plausible("dt", self.dt, 1e-15, 1.0, "time step [s]");
        let mut g = Checker::new("grain");
        self.grain.check(&mut g);
        c.extend(g);
        let mut w = Checker::new("wall");
        self.wall.check(&mut w);
        c.extend(w);
        if self.rolling.enabled {
            c.plausible("rolling.kr", self.rolling.kr, 1e-15, 1e9, "rolling stiffness [N·m/rad]");
            c.plausible("rolling.cr", self.rolling.cr, 0.0, 1e6, "rolling dashpot [N·m·s/rad]");
            c.plausible(
                "rolling.mu_r", self.rolling.mu_r, 0.0, 10.0, "rolling friction coefficient",
            );
        }
        c.in_open("skin_fraction", self.skin_fraction, 0.0, 2.0);
        c.in_open(
            "watchdog.max_overlap_fraction", self.watchdog.max_overlap_fraction, 0.0, 1.0,
        );
        c.plausible(
            "watchdog.energy_rise_fraction", self.watchdog.energy_rise_fraction, 0.0, 1e3, "fraction of E_0",
        );
        c.issues
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_table_4_2_and_valid() {
        let p = DemParams::default();
        assert!(p.validate().is_empty());
        assert_eq!(
            (p.grain.kn, p.wall.kn, p.grain.friction, p.wall.friction),
            (1.6e8, 4e8, 0.53, 0.466)
        );
        assert_eq!((p.rolling.kr, p.rolling.cr), (1.0e3, 0.1));
        // eq 4.5: γ = 0.09119 for ε = 0.75 (docs/definitions.md c.1)
        assert!((gamma_from_restitution(0.75) - 0.09119).abs() < 1e-5);
        // the exact no-attraction ratio reproduces ε
        let z = damping_ratio(0.75, DampingModel::NoAttractionExact);
        assert!((restitution_no_attraction(z) - 0.75).abs() < 1e-12);
        assert!(z > 0.0912);
    }

    #[test]
    fn yaml_partial_override_and_unknown_key() {
        let p: DemParams = serde_yaml::from_str("dt: 1.0e-7\nrolling: {damping: explicit, mu_r: 0.05}\n").unwrap();
        assert_eq!(p.rolling.damping, RollingDamping::Explicit);
        assert_eq!(p.rolling.kr, 1.0e3);
        assert_eq!(p.grain.kn, 1.6e8);
        assert!(serde_yaml::from_str::<DemParams>("grain: {stiffness: 1}\n").is_err());
    }

    #[test]
    fn validate_reports_every_issue() {
        let mut p = DemParams::default();
        p.grain.restitution = 1.5;
        p.wall.kn = -1.0;
        p.dt = 0.0;
        let keys: Vec<String> = p.validate().into_iter().map(|i| i.key).collect();
        assert_eq!(keys, vec!["dt", "grain.restitution", "wall.kn"]);
    }
}

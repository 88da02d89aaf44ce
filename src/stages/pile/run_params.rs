//! The schema of the `pile-run` kind ([`super::run`]): one method, one excitation
//! profile, a list of input energies, and that method's own block. The canonical params
//! hold the stage's method's keys only ([`params`]).

use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::common::check_dem_pile;
use crate::analysis::pile::{D_NORM, Profile, StopRule};
use crate::cd::CdParams;
use crate::dem::DemParams;
use crate::engines::Method;
use crate::mpm::params::MpmParams;
use crate::mpm::pile::MpmPileSpec;
use crate::stages::Validate;
use crate::stages::kind::{ParamProblem, typed};
use crate::validate::{Checker, Issue};

/// Parameters of a `pile-run` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RunParams {
    /// Solver.
    pub method: Method,
    /// Initial velocity profile (D19).
    pub profile: Profile,
    /// Input energies E_0 [m g d per grain] (D21).
    pub energies_mgd: Vec<f64>,
    /// DEM parameters (method `dem`).
    pub dem: DemParams,
    /// DEM softening (must match the prep's: the pile was settled with it).
    pub stiffness_factor: f64,
    /// CD parameters (method `cd`); `cd.dt` is the largest step of the adaptive rule.
    pub cd: CdParams,
    /// MPM parameters (method `mpm`). Friction angle and base friction come from the CD
    /// shear test's μ_min (input `shear`) unless `mpm_friction` is set.
    pub mpm: MpmParams,
    /// MPM pile geometry and geostatic stage.
    pub mpm_pile: MpmPileSpec,
    /// Override of the MPM friction coefficient (material tan φ and base/wall) [-].
    pub mpm_friction: Option<f64>,
    /// Base (and left-wall) friction alone, the material's φ unchanged (fig 4.41's μ_s) [-].
    /// Left out of the canonical params when absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mpm_base_friction: Option<f64>,
    /// MPM bulk density = grain density × the DEM pile's packing fraction (true), else
    /// `mpm.material.density`.
    pub mpm_density_from_packing: bool,
    /// Grain density of the DEM pile [kg/m³] (for the MPM bulk density).
    pub grain_density: f64,
    /// MPM front (D01): points of one mass are closer than this many cells (0: D01's
    /// 1.5 × the initial point spacing).
    pub mpm_link_cells: f64,
    /// Stopping rule.
    pub stop: StopRule,
    /// Snapshots of one run (figs 4.24, 4.31, 4.32, 4.42, 4.43), taken only when asked.
    pub snapshots: Option<SnapSpec>,
}

/// Which run to photograph and when (leave-out: no frames are taken without this).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SnapSpec {
    /// The run's input energy [mgd per grain]: one of `energies_mgd`.
    pub e0_mgd: f64,
    /// Instants [√(d/g)], ascending multiples of `stop.sample_every`; the run does not stop
    /// before the last.
    pub times: Vec<f64>,
    /// End that run at the last frame (a frames-only run: its summary row is partial and
    /// marked `stopped` = 0; the stopping-rule check skips it). Default: run to rest.
    #[serde(default)]
    pub end_after_last: bool,
}

impl Default for RunParams {
    fn default() -> Self {
        RunParams {
            method: Method::Dem,
            profile: Profile::Gradient,
            energies_mgd: vec![],
            dem: DemParams::default(),
            stiffness_factor: 1.0,
            cd: CdParams::default(),
            mpm: MpmParams::default(),
            mpm_pile: MpmPileSpec::default(),
            mpm_friction: None,
            mpm_base_friction: None,
            mpm_density_from_packing: true,
            grain_density: 2600.0,
            mpm_link_cells: 2.0,
            stop: StopRule::default(),
            snapshots: None,
        }
    }
}

impl Validate for RunParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        if self.energies_mgd.is_empty() {
            c.fail(
                "energies_mgd",
                "[]",
                "a non-empty list of input energies E_0 > 0 [m g d per grain]",
            );
        }
        for (i, e) in self.energies_mgd.iter().enumerate() {
            c.check(
                e.is_finite() && *e > 0.0,
                &format!("energies_mgd[{i}]"),
                e,
                "a finite input energy E_0 > 0 [m g d per grain]",
            );
        }
        let s = &self.stop;
        c.positive("stop.sample_every", s.sample_every);
        c.non_negative("stop.t_min", s.t_min);
        c.check(
            s.t_max.is_finite() && s.t_max > s.t_min.max(crate::analysis::pile::T1_UNITS),
            "stop.t_max",
            s.t_max,
            "> stop.t_min and > t_1 = 7.5 √(d/g)",
        );
        c.positive("stop.ek_ratio", s.ek_ratio);
        c.non_negative("stop.still_time", s.still_time);
        c.positive("stop.still_tol", s.still_tol);
        if let Some(sn) = &self.snapshots {
            c.check(
                self.energies_mgd
                    .iter()
                    .any(|e| (e - sn.e0_mgd).abs() <= 1e-9 * e.abs()),
                "snapshots.e0_mgd",
                sn.e0_mgd,
                "one of energies_mgd (the run whose frames are taken)",
            );
            c.check(
                !sn.times.is_empty(),
                "snapshots.times",
                "[]",
                "a non-empty list of instants [√(d/g)]",
            );
            for (i, t) in sn.times.iter().enumerate() {
                let q = t / s.sample_every;
                let ok = t.is_finite()
                    && *t >= 0.0
                    && *t <= s.t_max
                    && (q - q.round()).abs() < 1e-9
                    && (i == 0 || *t > sn.times[i - 1]);
                c.check(ok, &format!("snapshots.times[{i}]"), t, "ascending instants in [0, stop.t_max] √(d/g), multiples of stop.sample_every (frames are taken at sample instants)");
            }
        }
        match self.method {
            Method::Dem => check_dem_pile(&self.dem, self.stiffness_factor, &mut c),
            Method::Cd => {
                for i in self.cd.validate() {
                    c.fail(&format!("cd.{}", i.key), i.value, &i.allowed);
                }
            }
            Method::Mpm => {
                for i in self.mpm.validate() {
                    c.fail(&format!("mpm.{}", i.key), i.value, &i.allowed);
                }
                if c.issues.is_empty() {
                    // "the material point spacing is adopted to be the same as the mean
                    // grain diameter": a spacing far from d̄ cannot represent the pile.
                    let sp = self.mpm.spacing();
                    c.check(
                        (0.2 * D_NORM..=3.0 * D_NORM).contains(&sp),
                        "mpm.cell_size",
                        format!("{} m with ppc {} (point spacing {:.2} mm)", self.mpm.cell_size, self.mpm.ppc, sp * 1e3),
                        "a point spacing h/√PPC in [0.2, 3] d̄ = [0.49, 7.4] mm (chapter: spacing ≈ d̄; its PPC study reaches 6.25 mm = 2.55 d̄ at h = 0.0125 m, PPC 4)",
                    );
                    c.check(
                        self.mpm.ppc <= 100,
                        "mpm.ppc",
                        self.mpm.ppc,
                        "a perfect square in 1..=100 (the chapter's study: 4–100)",
                    );
                }
                if let Some(mu) = self.mpm_friction {
                    c.check(
                        mu.is_finite() && mu > 0.0 && mu < 2.0,
                        "mpm_friction",
                        mu,
                        "a friction coefficient in (0, 2)",
                    );
                }
                if let Some(mu) = self.mpm_base_friction {
                    c.check(
                        mu.is_finite() && mu > 0.0 && mu <= 1.0,
                        "mpm_base_friction",
                        mu,
                        "a base friction coefficient in (0, 1] (the chapter's sweep: 0.1–0.4)",
                    );
                }
                c.check(
                    self.mpm_pile.domain_length_l0 > 1.0,
                    "mpm_pile.domain_length_l0",
                    self.mpm_pile.domain_length_l0,
                    "> 1 (the grid must hold the run-out)",
                );
                c.check(
                    p_ok(self.mpm_link_cells),
                    "mpm_link_cells",
                    self.mpm_link_cells,
                    "0 (D01: 1.5 × point spacing) or a distance in cells in (0, 4]",
                );
                c.in_open(
                    "mpm_pile.geostatic_friction_deg", self.mpm_pile.geostatic_friction_deg, 0.0, 90.0,
                );
            }
        }
        c.issues
    }
}

fn p_ok(v: f64) -> bool {
    v.is_finite() && (0.0..=4.0).contains(&v)
}

/// The keys that belong to one method. A stage may not set another method's keys, and the
/// canonical params (the cache key) leave them out: a change to the MPM's defaults does not
/// re-run the DEM's piles.
const METHOD_KEYS: &[(Method, &[&str])] = &[
    (Method::Dem, &["dem", "stiffness_factor"]),
    (Method::Cd, &["cd"]),
    (
        Method::Mpm,
        &[
            "mpm", "mpm_pile", "mpm_friction", "mpm_base_friction", "mpm_density_from_packing", "grain_density",
            "mpm_link_cells",
        ],
    ),
];

/// Schema: [`RunParams`], then only the keys of the stage's method.
pub(super) fn params(v: &Value) -> Result<Value, Vec<ParamProblem>> {
    let mut canonical = typed::<RunParams>(v)?;
    let method: Method = serde_json::from_value(canonical["method"].clone()).map_err(|e| {
        vec![ParamProblem {
            key: "method".into(),
            message: e.to_string(),
            allowed: "dem | cd | mpm".into(),
        }]
    })?;
    let own = METHOD_KEYS
        .iter()
        .find(|(m, _)| *m == method)
        .map(|(_, k)| *k)
        .unwrap_or(&[]);
    let mut problems = Vec::new();
    for (m, keys) in METHOD_KEYS.iter().filter(|(m, _)| *m != method) {
        for k in *keys {
            if v.get(*k).is_some() {
                problems.push(ParamProblem {
                    key: (*k).into(),
                    message: format!(
                        "a parameter of method {}, not of this stage's method {}",
                        m.key(),
                        method.key()
                    ),
                    allowed: format!("the keys of method {}: {}", method.key(), own.join(", ")),
                });
            }
            if let Some(map) = canonical.as_object_mut() {
                map.remove(*k);
            }
        }
    }
    if problems.is_empty() {
        Ok(canonical)
    } else {
        Err(problems)
    }
}

#[cfg(test)]
mod tests {
    use super::params;
    use serde_json::json;

    /// The cache key of a DEM pile holds no other method's block: before, every default of
    /// the CD and MPM solvers was part of it, so changing one re-ran the DEM piles.
    #[test]
    fn canonical_params_hold_only_the_stage_method_keys() {
        let c = params(&json!({ "method": "dem", "energies_mgd": [10.0] })).unwrap();
        for k in ["cd", "mpm", "mpm_pile", "grain_density", "mpm_link_cells"] {
            assert!(c.get(k).is_none(), "{k} in the canonical params of a DEM pile");
        }
        assert!(c.get("dem").is_some() && c.get("stiffness_factor").is_some());
        let c = params(&json!({ "method": "mpm", "energies_mgd": [10.0] })).unwrap();
        assert!(c.get("dem").is_none() && c.get("cd").is_none() && c.get("mpm").is_some());
    }
}

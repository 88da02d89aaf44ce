//! Kind `material-table`: tables 4.1–4.3 rendered from the parameter files the scenes
//! actually use (`stages/*-material.yaml`), with the derived checks docs/definitions.md
//! tab4-01 … tab4-03 ask for printed beside them. Nothing is copied text: change a material
//! file and the table (and every scene reading that file) changes with it.

use polars::prelude::*;
use serde::{Deserialize, Serialize};

use crate::math::PI;
use crate::pipeline::context::{Claim, Output, StageCtx};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// Literature constants of the glass ballotini (table 4.1, Lajeunesse et al. 2004).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LiteratureMaterial {
    /// Mean grain diameter [mm].
    pub mean_diameter_mm: f64,
    /// Repose angle [°] and its ± [°].
    pub repose_angle_deg: [f64; 2],
    /// Avalanche angle [°] and its ± [°].
    pub avalanche_angle_deg: [f64; 2],
    /// Wall friction angle [°] and its ± [°].
    pub wall_friction_angle_deg: [f64; 2],
    /// Young's modulus of a glass bead [Pa] (table 4.2; sets k_n = 4ER, eq 4.3).
    pub glass_youngs_modulus_pa: f64,
    /// Poisson's ratio of glass (table 4.2: 0.22–0.24; unused by the linear law).
    pub glass_poisson_ratio: f64,
}

impl Default for LiteratureMaterial {
    fn default() -> Self {
        LiteratureMaterial {
            mean_diameter_mm: 1.15,
            repose_angle_deg: [22.0, 0.5],
            avalanche_angle_deg: [27.4, 0.5],
            wall_friction_angle_deg: [24.8, 0.2],
            glass_youngs_modulus_pa: 70e9,
            glass_poisson_ratio: 0.22,
        }
    }
}

/// Which table to render.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq, Default)]
pub enum Which {
    /// Table 4.1.
    #[serde(rename = "tab4-01")]
    #[default]
    Tab401,
    /// Table 4.2.
    #[serde(rename = "tab4-02")]
    Tab402,
    /// Table 4.3.
    #[serde(rename = "tab4-03")]
    Tab403,
}

/// Parameters of a `material-table` stage: which table, and the material files it renders.
#[derive(Debug, Clone, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct TableParams {
    /// Which table.
    pub table: Which,
    /// Literature constants (tab4-01).
    pub literature: LiteratureMaterial,
    /// DEM scene parameters (tab4-02, wall-friction check of tab4-01): the solver's own
    /// schema, from stages/dem-column.yaml.
    pub dem: crate::dem::DemParams,
    /// MPM scene parameters (tab4-03): the solver's own schema, from stages/mpm-column.yaml.
    pub mpm: crate::mpm::MpmParams,
}

impl Validate for TableParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        for i in self.dem.validate() {
            c.issues.push(Issue {
                key: format!("dem.{}", i.key),
                ..i
            });
        }
        c.positive(
            "literature.glass_youngs_modulus_pa", self.literature.glass_youngs_modulus_pa,
        );
        for i in self.mpm.validate() {
            c.issues.push(Issue {
                key: format!("mpm.{}", i.key),
                ..i
            });
        }
        c.issues
    }
}

struct Rows {
    param: Vec<String>,
    value: Vec<String>,
    unit: Vec<String>,
    source: Vec<String>,
}

impl Rows {
    fn new() -> Rows {
        Rows {
            param: vec![],
            value: vec![],
            unit: vec![],
            source: vec![],
        }
    }
    fn add(&mut self, p: &str, v: String, u: &str, s: &str) {
        self.param.push(p.into());
        self.value.push(v);
        self.unit.push(u.into());
        self.source.push(s.into());
    }
    fn frame(&self) -> anyhow::Result<DataFrame> {
        Ok(DataFrame::new_infer_height(vec![
            Column::new("parameter".into(), self.param.clone()),
            Column::new("value".into(), self.value.clone()),
            Column::new("unit".into(), self.unit.clone()),
            Column::new("source".into(), self.source.clone()),
        ])?)
    }
    fn markdown(&self, caption: &str) -> String {
        let mut s = format!("{caption}\n\n| Parameter | Value | Unit | Source |\n|---|---|---|---|\n");
        for i in 0..self.param.len() {
            s.push_str(&format!(
                "| {} | {} | {} | {} |\n",
                self.param[i], self.value[i], self.unit[i], self.source[i]
            ));
        }
        s
    }
}

fn g(v: f64) -> String {
    if v != 0.0 && (v.abs() >= 1e4 || v.abs() < 1e-2) {
        format!("{v:.3e}")
    } else {
        format!("{v}")
    }
}

fn run_table(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: TableParams = decode(ctx)?;
    let mut out = Output::default();
    let mut rows = Rows::new();
    let caption = ctx.caption.clone().unwrap_or_default();
    // Optional inputs: the PSD the scenes sample from; DEM calibration results.
    let psd = ctx
        .input_opt("psd")
        .map(|i| serde_json::from_value::<super::psd::PsdParams>(i.params.clone()))
        .transpose()?;
    match p.table {
        Which::Tab401 => {
            let l = &p.literature;
            rows.add(
                "Mean grain diameter",
                g(l.mean_diameter_mm),
                "mm",
                "Lajeunesse et al. (2004)",
            );
            rows.add(
                "Repose angle",
                format!("{} ± {}", l.repose_angle_deg[0], l.repose_angle_deg[1]),
                "°",
                "Lajeunesse et al. (2004)",
            );
            rows.add(
                "Avalanche angle",
                format!("{} ± {}", l.avalanche_angle_deg[0], l.avalanche_angle_deg[1]),
                "°",
                "Lajeunesse et al. (2004)",
            );
            rows.add(
                "Wall friction angle",
                format!("{} ± {}", l.wall_friction_angle_deg[0], l.wall_friction_angle_deg[1]),
                "°",
                "Lajeunesse et al. (2004)",
            );
            let wall_deg = p.dem.wall.friction.atan().to_degrees();
            rows.add(
                "check: atan(DEM wall friction)",
                format!("{wall_deg:.2}"),
                "°",
                "stages/dem-column.yaml",
            );
            out.scalar("dem_wall_friction_angle_deg", wall_deg);
            out.checks.push(Claim::abs(
                "wall-friction-angle",
                "DEM wall friction 0.466 ↔ wall friction angle 24.8 ± 0.2° (atan 0.466 = 24.99°)",
                l.wall_friction_angle_deg[0],
                wall_deg,
                l.wall_friction_angle_deg[1],
            ));
            if let Some(psd) = &psd {
                let mean = 0.5 * (psd.d_min_mm + psd.d_max_mm);
                rows.add(
                    "check: PSD volume-mean diameter",
                    format!("{mean:.3}"),
                    "mm",
                    "stages/psd-col.yaml",
                );
                out.checks.push(Claim::rel(
                    "mean-diameter",
                    "mean grain diameter 1.15 mm = midpoint of the uniform-by-volume PSD",
                    l.mean_diameter_mm,
                    mean,
                    0.005,
                ));
            }
            if let Some(shear) = ctx.input_opt("shear") {
                let phi = shear.scalar("friction_angle_deg")?;
                rows.add(
                    "check: DEM critical-state friction angle",
                    format!("{phi:.2}"),
                    "°",
                    "periodic shear test (stage shear-dem)",
                );
                out.checks.push(Claim::abs(
                    "repose-vs-critical-state",
                    "repose angle 22 ± 0.5° ↔ critical-state friction angle 22.2° (C1)",
                    l.repose_angle_deg[0],
                    phi,
                    1.0,
                ));
            }
        }
        Which::Tab402 => {
            let m = &p.dem;
            let l = &p.literature;
            rows.add(
                "Young's modulus of glass bead",
                g(l.glass_youngs_modulus_pa),
                "N/m²",
                "table 4.2 (enters through k_n = 4ER)",
            );
            rows.add(
                "Poisson's ratio",
                g(l.glass_poisson_ratio),
                "–",
                "table 4.2 (0.22–0.24; unused by the linear law)",
            );
            if let Some(psd) = &psd {
                rows.add(
                    "Diameter of glass beads",
                    format!("{} to {}", psd.d_min_mm, psd.d_max_mm),
                    "mm",
                    "stages/psd-col.yaml",
                );
            }
            rows.add("Normal stiffness of grains k_n", g(m.grain.kn), "N/m", "table 4.2");
            rows.add("Shear stiffness of grains k_t", g(m.grain.kt), "N/m", "table 4.2");
            rows.add("Normal stiffness of wall", g(m.wall.kn), "N/m", "table 4.2");
            rows.add("Shear stiffness of wall", g(m.wall.kt), "N/m", "table 4.2");
            rows.add(
                "Inter-particle friction coefficient μ",
                g(m.grain.friction),
                "–",
                "table 4.2",
            );
            rows.add("Wall friction coefficient", g(m.wall.friction), "–", "table 4.2");
            rows.add("Coefficient of restitution ε", g(m.grain.restitution), "–", "table 4.2");
            rows.add("Rolling spring constant", g(m.rolling.kr), "N·m/rad", "table 4.2");
            rows.add(
                "Coefficient of rolling damping",
                g(m.rolling.cr),
                "N·m·s/rad",
                "table 4.2 (integrated implicitly)",
            );
            rows.add(
                "Rolling friction μ_r (not in the chapter)",
                g(m.rolling.mu_r),
                "–",
                "granrepro choice (stages/dem-column.yaml)",
            );
            rows.add(
                "Grain density (not in the chapter)",
                g(m.density),
                "kg/m³",
                "granrepro choice: glass",
            );
            rows.add(
                "Time step (not in the chapter)",
                g(m.dt),
                "s",
                "granrepro choice (docs/definitions.md c.1: t_c/48)",
            );
            // Derived checks (docs/definitions.md tab4-02).
            let r_mean = psd
                .as_ref()
                .map(|p| 0.25 * (p.d_min_mm + p.d_max_mm) * 1e-3)
                .unwrap_or(0.575e-3);
            let kn_4er = 4.0 * l.glass_youngs_modulus_pa * r_mean;
            let lne = m.grain.restitution.ln();
            let gamma = -lne / (PI * PI + lne * lne).sqrt();
            let mass = m.density * PI * r_mean * r_mean; // per metre of thickness
            let cn = 2.0 * gamma * (0.5 * mass * m.grain.kn).sqrt();
            rows.add("derived: 4ER (eq 4.3, mean radius)", g(kn_4er), "N/m", "eq 4.3");
            rows.add(
                "derived: damping ratio γ (eq 4.5)",
                format!("{gamma:.5}"),
                "–",
                "eq 4.5",
            );
            rows.add(
                "derived: C_n mean–mean pair (eq 4.4)",
                format!("{cn:.1}"),
                "N·s/m",
                "eq 4.4, 2D masses",
            );
            rows.add(
                "used: damping ratio for exact ε without attraction",
                format!("{:.5}", m.grain.damping_ratio()),
                "–",
                "granrepro (see src/dem/params.rs)",
            );
            out.scalar("kn_4er_n_per_m", kn_4er)
                .scalar("damping_ratio_eq45", gamma)
                .scalar("damping_ratio_used", m.grain.damping_ratio())
                .scalar("cn_mean_pair_ns_per_m", cn);
            out.checks.push(Claim::rel(
                "kn-equals-4ER",
                "k_n = 4ER (eq 4.3) = 1.61e8 N/m at the mean radius",
                m.grain.kn,
                kn_4er,
                0.01,
            ));
            out.checks.push(Claim::rel(
                "damping-ratio",
                "γ = −ln ε/√(π²+ln²ε) = 0.09119 for ε = 0.75 (docs/definitions.md tab4-02)",
                0.09119,
                gamma,
                0.001,
            ));
        }
        Which::Tab403 => {
            let m = &p.mpm;
            let spacing = m.spacing();
            rows.add("Material point spacing", g(spacing * 1e3), "mm", "derived: h/√PPC");
            rows.add(
                "Number of material points per cell",
                m.ppc.to_string(),
                "–",
                "table 4.3",
            );
            rows.add("Mesh length", g(m.cell_size), "m", "table 4.3");
            let (e, e_src) = match ctx.input_opt("compression") {
                Some(c) => (c.scalar("youngs_modulus_pa")?, "measured: DEM confined compression"),
                None => (m.material.young_pa, "table 4.3"),
            };
            rows.add("Young's Modulus, E", g(e), "N/m²", e_src);
            rows.add(
                "Poisson's ratio, ν",
                g(m.material.poisson),
                "–",
                "table 4.3 (0.22 to 0.24)",
            );
            let (phi, phi_src) = match ctx.input_opt("shear") {
                Some(s) => (s.scalar("friction_angle_deg")?, "measured: DEM periodic shear"),
                None => (m.material.friction_deg, "table 4.3"),
            };
            rows.add("Friction angle, φ", format!("{phi:.2}"), "°", phi_src);
            rows.add("Dilatancy angle, Φ", g(m.material.dilation_deg), "°", "table 4.3");
            rows.add("Density, ρ", g(m.material.density), "kg/m³", "table 4.3");
            rows.add("Wall friction", g(m.wall_friction), "–", "table 4.3");
            match m.step {
                crate::mpm::StepRule::Fixed { dt } => rows.add("Time step increment", g(dt), "s", "table 4.3"),
                crate::mpm::StepRule::Cfl { courant, dt_max } => rows.add(
                    "Time step increment",
                    format!("CFL, Courant {courant} (≤ {})", g(dt_max)),
                    "s",
                    "profile choice (table 4.3: 1e-6 s)",
                ),
            }
            rows.add(
                "Cohesion (not in the chapter)",
                g(m.material.cohesion_pa),
                "Pa",
                "granrepro choice",
            );
            out.scalar("friction_angle_deg", phi)
                .scalar("youngs_modulus_pa", e)
                .scalar("point_spacing_m", spacing);
            if ctx.profile == "paper" {
                out.checks.push(Claim::abs(
                    "point-spacing",
                    "2 mm/√16 = 0.5 mm material point spacing",
                    0.5e-3,
                    spacing,
                    1e-9,
                ));
            } else {
                out.note(format!("Profile `{}` discretises coarser than table 4.3 (h = {} m, {} PPC): its run-out error is measured by wp-mpm-column.", ctx.profile, m.cell_size, m.ppc));
            }
            if ctx.input_opt("shear").is_some() {
                out.checks.push(Claim::abs("friction-angle", "φ fed to the MPM: the DEM shear test's φ_cs (restates fig4-03's claim, which rests on the calibrated μ_r)", 22.2, phi, 0.2));
            }
            if ctx.input_opt("compression").is_some() {
                out.checks.push(Claim::rel(
                    "youngs-modulus",
                    "E fed to the MPM: the DEM confined-compression modulus (restates compress-dem's claim)",
                    1.98e6,
                    e,
                    0.25,
                ));
            }
        }
    }
    out.table("table", rows.frame()?);
    out.files
        .push(("table.md".into(), rows.markdown(&caption).into_bytes()));
    Ok(out)
}

/// Kind `material-table`.
pub const KIND: Kind = Kind {
    name: "material-table",
    source: file!(),
    method: None,
    version: 3,
    about: "tables 4.1–4.3 rendered from the material files the scenes use, with derived checks",
    params: typed::<TableParams>,
    run: run_table,
    explain: None,
    roles: crate::stages::kind::Roles::Fixed(&[
        ("psd", crate::pipeline::context::Arity::OptionalOne),
        ("shear", crate::pipeline::context::Arity::OptionalOne),
        ("compression", crate::pipeline::context::Arity::OptionalOne),
    ]),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "cn_mean_pair_ns_per_m", "damping_ratio_eq45", "damping_ratio_used", "dem_wall_friction_angle_deg",
            "friction_angle_deg", "kn_4er_n_per_m", "point_spacing_m", "youngs_modulus_pa",
        ],
        tables: &[crate::stages::kind::TableDecl {
            name: "table",
            columns: &["parameter", "source", "unit", "value"],
        }],
        measurements: &[],
        texts: &[],
    },
    reads: None,
    cost: None,
    atlas: None,
};

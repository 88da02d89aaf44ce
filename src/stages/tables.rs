//! Kind `material-table`: tables 4.1–4.3 rendered from the parameter files the scenes
//! actually use (`stages/*-material.yaml`), with the derived checks figures.md §4 asks
//! for printed beside them. Nothing is copied text: change a material file and the table
//! (and every scene reading that file) changes with it.

use polars::prelude::*;
use serde::{Deserialize, Serialize};

use super::{Kind, Validate, decode, typed};
use crate::math::PI;
use crate::pipeline::context::{Claim, Output, StageCtx};
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
}

impl Default for LiteratureMaterial {
    fn default() -> Self {
        LiteratureMaterial { mean_diameter_mm: 1.15, repose_angle_deg: [22.0, 0.5], avalanche_angle_deg: [27.4, 0.5], wall_friction_angle_deg: [24.8, 0.2] }
    }
}

/// The DEM contact material of the column scenes (table 4.2). All stiffnesses are per
/// metre of out-of-plane thickness (figures.md §b.0).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct DemMaterial {
    /// Grain density [kg/m³] (UNSPEC in the chapter: glass, 2500).
    pub density_kg_m3: f64,
    /// Young's modulus of a glass bead [Pa] (sets k_n = 4ER, eq 4.3).
    pub youngs_modulus_pa: f64,
    /// Poisson's ratio (0.22–0.24; unused by the linear law).
    pub poisson_ratio: f64,
    /// Grain–grain normal stiffness k_n [N/m].
    pub kn_n_per_m: f64,
    /// Grain–grain tangential stiffness k_t [N/m].
    pub kt_n_per_m: f64,
    /// Grain–wall normal stiffness [N/m].
    pub kn_wall_n_per_m: f64,
    /// Grain–wall tangential stiffness [N/m].
    pub kt_wall_n_per_m: f64,
    /// Inter-particle friction coefficient μ.
    pub friction: f64,
    /// Wall friction coefficient.
    pub wall_friction: f64,
    /// Coefficient of restitution ε (eqs 4.4–4.5).
    pub restitution: f64,
    /// Rolling spring constant k_r [N·m/rad].
    pub rolling_stiffness_nm_per_rad: f64,
    /// Rolling damping c_r [N·m·s/rad].
    pub rolling_damping_nms_per_rad: f64,
    /// Rolling-friction coefficient μ_r (UNSPEC; caps |M_r| ≤ μ_r·r̄·f_n).
    pub rolling_friction: f64,
}

impl Default for DemMaterial {
    fn default() -> Self {
        DemMaterial {
            density_kg_m3: 2500.0,
            youngs_modulus_pa: 70e9,
            poisson_ratio: 0.22,
            kn_n_per_m: 1.6e8,
            kt_n_per_m: 1.6e8,
            kn_wall_n_per_m: 4e8,
            kt_wall_n_per_m: 4e8,
            friction: 0.53,
            wall_friction: 0.466,
            restitution: 0.75,
            rolling_stiffness_nm_per_rad: 1e3,
            rolling_damping_nms_per_rad: 0.1,
            rolling_friction: 0.1,
        }
    }
}

impl DemMaterial {
    /// Checks shared by every stage that reads this material.
    pub fn check(&self, c: &mut Checker) {
        c.positive("density_kg_m3", self.density_kg_m3);
        c.positive("youngs_modulus_pa", self.youngs_modulus_pa);
        c.in_open("poisson_ratio", self.poisson_ratio, -1.0, 0.5);
        c.positive("kn_n_per_m", self.kn_n_per_m);
        c.non_negative("kt_n_per_m", self.kt_n_per_m);
        c.positive("kn_wall_n_per_m", self.kn_wall_n_per_m);
        c.non_negative("kt_wall_n_per_m", self.kt_wall_n_per_m);
        c.in_closed("friction", self.friction, 0.0, 10.0);
        c.in_closed("wall_friction", self.wall_friction, 0.0, 10.0);
        c.in_open_closed("restitution", self.restitution, 0.0, 1.0);
        c.non_negative("rolling_stiffness_nm_per_rad", self.rolling_stiffness_nm_per_rad);
        c.non_negative("rolling_damping_nms_per_rad", self.rolling_damping_nms_per_rad);
        c.in_closed("rolling_friction", self.rolling_friction, 0.0, 10.0);
    }
    /// Damping ratio from restitution, eq 4.5: γ = −ln ε / √(π² + ln² ε).
    pub fn damping_ratio(&self) -> f64 {
        let l = self.restitution.ln();
        -l / (PI * PI + l * l).sqrt()
    }
}

/// The continuum material of the MPM column scenes (table 4.3).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct MpmMaterial {
    /// Background cell size h [m].
    pub cell_size_m: f64,
    /// Material points per cell (a perfect square).
    pub points_per_cell: usize,
    /// Young's modulus E [Pa].
    pub youngs_modulus_pa: f64,
    /// Poisson's ratio ν.
    pub poisson_ratio: f64,
    /// Friction angle φ [°] (table value; the pipeline injects the DEM-measured one).
    pub friction_angle_deg: f64,
    /// Dilatancy angle ψ [°].
    pub dilatancy_angle_deg: f64,
    /// Cohesion [Pa] (absent from table 4.3: 0).
    pub cohesion_pa: f64,
    /// Bulk density ρ [kg/m³].
    pub density_kg_m3: f64,
    /// Wall and base friction coefficient.
    pub wall_friction: f64,
    /// Time step [s] (table 4.3: 1e-6 s).
    pub time_step_s: f64,
}

impl Default for MpmMaterial {
    fn default() -> Self {
        MpmMaterial {
            cell_size_m: 2e-3,
            points_per_cell: 16,
            youngs_modulus_pa: 1.98e6,
            poisson_ratio: 0.22,
            friction_angle_deg: 22.2,
            dilatancy_angle_deg: 0.0,
            cohesion_pa: 0.0,
            density_kg_m3: 1925.0,
            wall_friction: 0.466,
            time_step_s: 1e-6,
        }
    }
}

impl MpmMaterial {
    /// Range checks.
    pub fn check(&self, c: &mut Checker) {
        c.positive("cell_size_m", self.cell_size_m);
        let r = (self.points_per_cell as f64).sqrt().round() as usize;
        c.check(self.points_per_cell >= 1 && r * r == self.points_per_cell, "points_per_cell", self.points_per_cell, "a perfect square (1, 4, 9, 16, 25, …)");
        c.positive("youngs_modulus_pa", self.youngs_modulus_pa);
        c.in_open("poisson_ratio", self.poisson_ratio, -1.0, 0.5);
        c.in_open("friction_angle_deg", self.friction_angle_deg, 0.0, 90.0);
        c.in_closed("dilatancy_angle_deg", self.dilatancy_angle_deg, 0.0, self.friction_angle_deg.max(0.0));
        c.non_negative("cohesion_pa", self.cohesion_pa);
        c.positive("density_kg_m3", self.density_kg_m3);
        c.in_closed("wall_friction", self.wall_friction, 0.0, 10.0);
        c.positive("time_step_s", self.time_step_s);
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
    /// DEM material (tab4-02, and the wall-friction check of tab4-01).
    pub dem: DemMaterial,
    /// MPM material (tab4-03).
    pub mpm: MpmMaterial,
}

impl Validate for TableParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("dem");
        self.dem.check(&mut c);
        let mut m = Checker::new("mpm");
        self.mpm.check(&mut m);
        c.extend(m);
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
        Rows { param: vec![], value: vec![], unit: vec![], source: vec![] }
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
            s.push_str(&format!("| {} | {} | {} | {} |\n", self.param[i], self.value[i], self.unit[i], self.source[i]));
        }
        s
    }
}

fn g(v: f64) -> String {
    if v != 0.0 && (v.abs() >= 1e4 || v.abs() < 1e-2) { format!("{v:.3e}") } else { format!("{v}") }
}

fn run_table(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: TableParams = decode(ctx)?;
    let mut out = Output::default();
    let mut rows = Rows::new();
    let caption = ctx.caption.clone().unwrap_or_default();
    // Optional inputs: the PSD the scenes sample from; DEM calibration results.
    let psd = ctx.input_opt("psd").map(|i| serde_json::from_value::<super::psd::PsdParams>(i.params.clone())).transpose()?;
    match p.table {
        Which::Tab401 => {
            let l = &p.literature;
            rows.add("Mean grain diameter", g(l.mean_diameter_mm), "mm", "Lajeunesse et al. (2004)");
            rows.add("Repose angle", format!("{} ± {}", l.repose_angle_deg[0], l.repose_angle_deg[1]), "°", "Lajeunesse et al. (2004)");
            rows.add("Avalanche angle", format!("{} ± {}", l.avalanche_angle_deg[0], l.avalanche_angle_deg[1]), "°", "Lajeunesse et al. (2004)");
            rows.add("Wall friction angle", format!("{} ± {}", l.wall_friction_angle_deg[0], l.wall_friction_angle_deg[1]), "°", "Lajeunesse et al. (2004)");
            let wall_deg = p.dem.wall_friction.atan().to_degrees();
            rows.add("check: atan(DEM wall friction)", format!("{wall_deg:.2}"), "°", "stages/dem-material.yaml");
            out.scalar("dem_wall_friction_angle_deg", wall_deg);
            out.claims.push(Claim::abs("wall-friction-angle", "DEM wall friction 0.466 ↔ wall friction angle 24.8 ± 0.2° (atan 0.466 = 24.99°)", l.wall_friction_angle_deg[0], wall_deg, l.wall_friction_angle_deg[1]));
            if let Some(psd) = &psd {
                let mean = 0.5 * (psd.d_min_mm + psd.d_max_mm);
                rows.add("check: PSD volume-mean diameter", format!("{mean:.3}"), "mm", "stages/psd-col.yaml");
                out.claims.push(Claim::rel("mean-diameter", "mean grain diameter 1.15 mm = midpoint of the uniform-by-volume PSD", l.mean_diameter_mm, mean, 0.005));
            }
            if let Some(shear) = ctx.input_opt("shear") {
                let phi = shear.scalar("friction_angle_deg")?;
                rows.add("check: DEM critical-state friction angle", format!("{phi:.2}"), "°", "periodic shear test (stage shear-dem)");
                out.claims.push(Claim::abs("repose-vs-critical-state", "repose angle 22 ± 0.5° ↔ critical-state friction angle 22.2° (C1)", l.repose_angle_deg[0], phi, 1.0));
            }
        }
        Which::Tab402 => {
            let m = &p.dem;
            rows.add("Young's modulus of glass bead", g(m.youngs_modulus_pa), "N/m²", "table 4.2");
            rows.add("Poisson's ratio", g(m.poisson_ratio), "–", "table 4.2 (0.22–0.24; unused by the linear law)");
            if let Some(psd) = &psd {
                rows.add("Diameter of glass beads", format!("{} to {}", psd.d_min_mm, psd.d_max_mm), "mm", "stages/psd-col.yaml");
            }
            rows.add("Normal stiffness of grains k_n", g(m.kn_n_per_m), "N/m", "table 4.2");
            rows.add("Shear stiffness of grains k_t", g(m.kt_n_per_m), "N/m", "table 4.2");
            rows.add("Normal stiffness of wall", g(m.kn_wall_n_per_m), "N/m", "table 4.2");
            rows.add("Shear stiffness of wall", g(m.kt_wall_n_per_m), "N/m", "table 4.2");
            rows.add("Inter-particle friction coefficient μ", g(m.friction), "–", "table 4.2");
            rows.add("Wall friction coefficient", g(m.wall_friction), "–", "table 4.2");
            rows.add("Coefficient of restitution ε", g(m.restitution), "–", "table 4.2");
            rows.add("Rolling spring constant", g(m.rolling_stiffness_nm_per_rad), "N·m/rad", "table 4.2");
            rows.add("Coefficient of rolling damping", g(m.rolling_damping_nms_per_rad), "N·m·s/rad", "table 4.2");
            rows.add("Rolling friction μ_r (not in the chapter)", g(m.rolling_friction), "–", "granrepro choice (stages/dem-material.yaml)");
            rows.add("Grain density (not in the chapter)", g(m.density_kg_m3), "kg/m³", "granrepro choice: glass");
            // Derived checks (figures.md tab4-02).
            let r_mean = psd.as_ref().map(|p| 0.25 * (p.d_min_mm + p.d_max_mm) * 1e-3).unwrap_or(0.575e-3);
            let kn_4er = 4.0 * m.youngs_modulus_pa * r_mean;
            let gamma = m.damping_ratio();
            let mass = m.density_kg_m3 * PI * r_mean * r_mean; // per metre of thickness
            let cn = 2.0 * gamma * (0.5 * mass * m.kn_n_per_m).sqrt();
            rows.add("derived: 4ER (eq 4.3, mean radius)", g(kn_4er), "N/m", "eq 4.3");
            rows.add("derived: damping ratio γ (eq 4.5)", format!("{gamma:.5}"), "–", "eq 4.5");
            rows.add("derived: C_n mean–mean pair (eq 4.4)", format!("{cn:.1}"), "N·s/m", "eq 4.4, 2D masses");
            out.scalar("kn_4er_n_per_m", kn_4er).scalar("damping_ratio", gamma).scalar("cn_mean_pair_ns_per_m", cn);
            out.claims.push(Claim::rel("kn-equals-4ER", "k_n = 4ER (eq 4.3) = 1.61e8 N/m at the mean radius", m.kn_n_per_m, kn_4er, 0.01));
            out.claims.push(Claim::rel("damping-ratio", "γ = −ln ε/√(π²+ln²ε) = 0.09119 for ε = 0.75 (figures.md tab4-02)", 0.09119, gamma, 0.001));
        }
        Which::Tab403 => {
            let m = &p.mpm;
            let spacing = m.cell_size_m / (m.points_per_cell as f64).sqrt();
            rows.add("Material point spacing", g(spacing * 1e3), "mm", "derived: h/√PPC");
            rows.add("Number of material points per cell", m.points_per_cell.to_string(), "–", "table 4.3");
            rows.add("Mesh length", g(m.cell_size_m), "m", "table 4.3");
            let (e, e_src) = match ctx.input_opt("compression") {
                Some(c) => (c.scalar("youngs_modulus_pa")?, "measured: DEM confined compression"),
                None => (m.youngs_modulus_pa, "table 4.3"),
            };
            rows.add("Young's Modulus, E", g(e), "N/m²", e_src);
            rows.add("Poisson's ratio, ν", g(m.poisson_ratio), "–", "table 4.3 (0.22 to 0.24)");
            let (phi, phi_src) = match ctx.input_opt("shear") {
                Some(s) => (s.scalar("friction_angle_deg")?, "measured: DEM periodic shear"),
                None => (m.friction_angle_deg, "table 4.3"),
            };
            rows.add("Friction angle, φ", format!("{phi:.2}"), "°", phi_src);
            rows.add("Dilatancy angle, ψ", g(m.dilatancy_angle_deg), "°", "table 4.3");
            rows.add("Density, ρ", g(m.density_kg_m3), "kg/m³", "table 4.3");
            rows.add("Wall friction", g(m.wall_friction), "–", "table 4.3");
            rows.add("Time step increment", g(m.time_step_s), "s", "table 4.3");
            rows.add("Cohesion (not in the chapter)", g(m.cohesion_pa), "Pa", "granrepro choice");
            out.scalar("friction_angle_deg", phi).scalar("youngs_modulus_pa", e).scalar("point_spacing_m", spacing);
            out.claims.push(Claim::abs("point-spacing", "2 mm/√16 = 0.5 mm material point spacing", 0.5e-3, spacing, 1e-9));
            if ctx.input_opt("shear").is_some() {
                out.claims.push(Claim::abs("friction-angle", "\"A critical state friction angle of 22.2° was obtained\" (table 4.3: 22.2 ± 0.2°)", 22.2, phi, 0.2));
            }
            if ctx.input_opt("compression").is_some() {
                out.claims.push(Claim::rel("youngs-modulus", "E = 1.98e6 N/m² from laterally confined compression (figures.md I12)", 1.98e6, e, 0.25));
            }
        }
    }
    out.table("table", rows.frame()?);
    out.files.push(("table.md".into(), rows.markdown(&caption).into_bytes()));
    Ok(out)
}

/// Kind `material-table`.
pub const KIND: Kind = Kind {
    name: "material-table",
    version: 1,
    about: "tables 4.1–4.3 rendered from the material files the scenes use, with derived checks",
    params: typed::<TableParams>,
    run: run_table,
};

//! The MPM's adapter of the `pile-run` kind ([`super::run`]): the deposit's surface seeds
//! a continuum (geostatic stage first, docs/definitions.md I7 option ii); E_0 is given per
//! unit of the continuum's mass (D21), material in the wall's grid cell touches it, and
//! points are one mass while they share grid nodes.

use super::run::frame_times;
use super::run_params::RunParams;
use crate::analysis::pile::{D_NORM, Frame, Profile, summarise, surface_at};
use crate::engines::Preflight;
use crate::engines::pile::{Excited, PileEngine, PileScene};
use crate::pipeline::context::{Claim, Output, StageCtx};

/// `method: mpm`.
pub struct MpmPile<'a>(pub &'a RunParams);

impl Preflight for MpmPile<'_> {
    fn preflight(&self) -> String {
        crate::stages::column::mpm_common::preflight_mpm(&self.0.mpm)
    }
}

impl MpmPile<'_> {
    /// Link distance of the front and the cavity [m]: `mpm_link_cells` cells, else D01's
    /// 1.5 × the initial point spacing.
    fn link(&self) -> f64 {
        let p = self.0;
        if p.mpm_link_cells > 0.0 {
            p.mpm_link_cells * p.mpm.cell_size
        } else {
            1.5 * p.mpm.spacing()
        }
    }
}

impl PileEngine for MpmPile<'_> {
    /// Points fill the pile's area (∝ grains) at ppc per h²; the CFL step ∝ h.
    fn work(&self, grains: f64, time: f64) -> Vec<(&'static str, f64)> {
        let m = &self.0.mpm;
        let (h, ppc) = (m.cell_size, m.ppc as f64);
        let courant = match m.step {
            crate::mpm::params::StepRule::Cfl { courant, .. } => courant,
            _ => 1.0,
        };
        vec![("points", grains * ppc / (h * h)), ("steps", time / (courant * h))]
    }
    fn density(&self) -> f64 {
        self.0.grain_density
    }
    fn gravity(&self) -> f64 {
        self.0.mpm.gravity
    }
    fn excite(&self, ctx: &StageCtx, scene: &PileScene, out: &mut Output) -> anyhow::Result<Vec<Excited>> {
        let p = self.0;
        let g = self.gravity();
        let n = p.energies_mgd.len();
        let mut mp = p.mpm.clone();
        let (mu, source) = match (p.mpm_friction, ctx.input_opt("shear")) {
            (Some(m), _) => (m, "mpm_friction (stated)".to_string()),
            (None, Some(sh)) => (sh.scalar("mu_min")?, format!("μ_min of the CD shear test `{}`", sh.id)),
            (None, None) => {
                anyhow::bail!("MPM pile: no friction — give `inputs: {{ shear: shear-cd }}` or `mpm_friction`")
            }
        };
        mp.material.friction_deg = mu.atan().to_degrees();
        mp.wall_friction = p.mpm_base_friction.unwrap_or(mu);
        if p.mpm_density_from_packing {
            mp.material.density = p.grain_density * scene.packing;
        }
        let loaded = crate::mpm::pile::load_pile(&mp, &p.mpm_pile, &scene.profile, scene.l0)?;
        let cells_high = scene
            .profile
            .iter()
            .filter(|q| q.1.is_finite())
            .map(|q| q.1)
            .fold(0.0, f64::max)
            / mp.cell_size;
        anyhow::ensure!(
            cells_high >= 2.0,
            "the pile is only {cells_high:.1} cells of mpm.cell_size = {} m high: use smaller cells",
            mp.cell_size
        );
        let mass: f64 = loaded.state.points.iter().map(|q| q.mass).sum();
        let link = self.link();
        // D21 for MPM: E_0[mgd] = E_0 / (M_total g d).
        let unit = mass * g * D_NORM;
        let mut runs = Vec::with_capacity(n);
        for (k, &e) in p.energies_mgd.iter().enumerate() {
            let clock = std::time::Instant::now();
            let ft = frame_times(p, e, g);
            let r = crate::mpm::pile::run_pile_frames(&loaded, &mp, p.profile, e * unit, &p.stop, link, &ft)?;
            let summary = summarise(&r.samples, r.l0, r.e0, unit, r.e0_check, r.stopped, g);
            runs.push(Excited {
                summary,
                run: r,
                wall_s: clock.elapsed().as_secs_f64(),
            });
            ctx.set_progress((k + 1) as f64 / n as f64);
        }
        if let Some(b) = p.mpm_base_friction {
            out.scalar("mpm_base_friction", b);
        }
        if let Some(f0) = runs.iter().flat_map(|r| r.run.frames.first()).find(|f| f.t == 0.0) {
            // fig4-24b: σ_yy after the geostatic stage against the overburden −ρg(h_s(x) − y)
            // of the seeding surface, over the points deeper than 2 spacings.
            let (err, n_deep) =
                lithostatic_misfit(f0, &scene.profile, scene.l0, mp.material.density, g, 2.0 * mp.spacing());
            out.scalar("snap_sigma_yy_rel_err", err)
                .scalar("snap_sigma_yy_points", n_deep as f64);
            // Not exact: the frictional wall and base carry part of the weight (column
            // fig4-04: 2.5 % at the base) and the seeding surface is the grains' rough top.
            out.checks.push(Claim::at_most("sigma-yy-lithostatic", "fig4-24b: σ_yy after the geostatic stage ≈ −ρg(h_surface(x) − y) (relative L2 misfit over the points > 2 spacings deep; bound 0.2)", 0.2, err));
            // docs/definitions.md fig4-24: "Expected max v_x = kH ≈ 1.1 m/s at the base
            // next to the wall (triangle estimate)": E_0/(M g d) = (kH)²/(4 g d) for a
            // right triangle.
            if p.profile == Profile::Gradient {
                let e_mgd = runs
                    .iter()
                    .find(|r| r.run.frames.first().is_some_and(|f| f.t == 0.0))
                    .map(|r| r.summary.e0_mgd)
                    .unwrap_or(f64::NAN);
                let kh = (4.0 * g * D_NORM * e_mgd).sqrt();
                let vmax = f0.vx.iter().cloned().fold(0.0, f64::max);
                out.scalar("snap_vx_max_m_s", vmax).scalar("snap_vx_triangle_m_s", kh);
                out.checks.push(Claim::rel("vx-max-triangle", &format!("fig4-24c: largest v_x at t = 0 against the right-triangle estimate kH = √(4 g d E_0) = {kh:.3} m/s (the pile is not an exact triangle; 10 %)"), kh, vmax, 0.1));
            }
        }
        out.scalar("mpm_friction", mu)
            .scalar("mpm_friction_deg", mu.atan().to_degrees())
            .scalar("mpm_density", mp.material.density)
            .scalar("mpm_points", loaded.state.points.len() as f64)
            .scalar("mpm_geostatic_time_s", loaded.geostatic_time);
        out.note(format!(
            "MPM: Mohr–Coulomb φ = {:.2}° and base/wall friction {mu:.3} from {source}; ρ = {:.0} kg/m³ (grain density × the DEM pile's φ); {} points, cell {} m, PPC {}; geostatic stage at φ = {}° (docs/definitions.md I7 option ii).",
            mu.atan().to_degrees(), mp.material.density, loaded.state.points.len(), mp.cell_size, mp.ppc, p.mpm_pile.geostatic_friction_deg
        ));
        Ok(runs)
    }
    /// The wall is a node line: the continuum meets it in the wall's grid cell.
    fn wall_contact(&self) -> (f64, &'static str) {
        (self.0.mpm.cell_size / D_NORM, "one grid cell")
    }
    /// Points are one continuum while they share grid nodes (`mpm_link_cells`, as the front).
    fn cavity_link(&self, half: f64) -> f64 {
        (self.link() - 2.0 * half).max(0.0)
    }
}

/// Relative L2 misfit of σ_yy against −ρg(h_s(x) − y) over the points deeper than `depth`.
fn lithostatic_misfit(f: &Frame, profile: &[(f64, f64)], l0: f64, rho: f64, g: f64, depth: f64) -> (f64, usize) {
    let (mut num, mut den, mut n) = (0.0, 0.0, 0usize);
    for i in 0..f.x.len() {
        let z = surface_at(profile, f.x[i], l0) - f.y[i];
        if z > depth {
            let want = -rho * g * z;
            num += (f.sigma_yy[i] - want).powi(2);
            den += want * want;
            n += 1;
        }
    }
    (if den > 0.0 { (num / den).sqrt() } else { f64::NAN }, n)
}

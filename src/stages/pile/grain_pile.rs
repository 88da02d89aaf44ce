//! The grain methods' adapters of the `pile-run` kind ([`super::run`]): DEM and CD excite
//! the settled deposit grain by grain, so E_0 is given per grain (D21) and the wall is
//! touched by a grain within half a diameter.

use super::common::PILE_SIZES;
use super::run::frame_times;
use super::run_params::RunParams;
use crate::analysis::pile::{D_NORM, M_NORM, PileRun, summarise};
use crate::engines::pile::{Excited, PileEngine, PileScene};
use crate::engines::{Method, Preflight};
use crate::pipeline::context::{InputRef, Output, StageCtx};

/// `method: dem`.
pub struct DemPile<'a>(pub &'a RunParams);

/// `method: cd`.
pub struct CdPile<'a>(pub &'a RunParams);

impl Preflight for DemPile<'_> {
    fn preflight(&self) -> String {
        crate::stages::column::dem_common::preflight_dem(&self.0.dem, self.0.stiffness_factor, PILE_SIZES)
    }
}

impl Preflight for CdPile<'_> {
    fn preflight(&self) -> String {
        "CD: no stability limit on Δt (contact dynamics is implicit in the contact forces); \
         `cd.dt` is the largest step of the adaptive rule"
            .into()
    }
}

/// Every energy of `p`, side by side on the stage's pool (each small pile steps on one
/// thread), results in the order of `energies_mgd`; E_0 per grain (D21: E_0[mgd] =
/// E_0 / (N m g d), m = 0.0123 kg, d = 2.455 mm).
fn excite_grains(
    ctx: &StageCtx,
    p: &RunParams,
    scene: &PileScene,
    g: f64,
    solve: &(dyn Fn(f64, &crate::analysis::pile::FrameTimes) -> anyhow::Result<PileRun> + Sync),
) -> anyhow::Result<Vec<Excited>> {
    use rayon::prelude::*;
    let unit = scene.state.len() as f64 * M_NORM * g * D_NORM;
    let n = p.energies_mgd.len();
    let finished = std::sync::atomic::AtomicUsize::new(0);
    let results: Vec<anyhow::Result<Excited>> = p
        .energies_mgd
        .par_iter()
        .map(|&e| {
            let clock = std::time::Instant::now();
            let r = solve(e * unit, &frame_times(p, e, g))?;
            let summary = summarise(&r.samples, r.l0, r.e0, unit, r.e0_check, r.stopped, g);
            let k = finished.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            ctx.set_progress(k as f64 / n as f64);
            Ok(Excited {
                summary,
                run: r,
                wall_s: clock.elapsed().as_secs_f64(),
            })
        })
        .collect();
    results.into_iter().collect()
}

impl PileEngine for DemPile<'_> {
    fn work(&self, grains: f64, time: f64) -> Vec<(&'static str, f64)> {
        let p = self.0;
        vec![
            ("grains", grains),
            ("steps", p.dem.steps_per_second(p.stiffness_factor) * time),
        ]
    }
    fn density(&self) -> f64 {
        self.0.dem.density
    }
    fn gravity(&self) -> f64 {
        self.0.dem.gravity
    }
    fn accept(&self, input: &InputRef) -> anyhow::Result<()> {
        let f = input
            .params
            .get("stiffness_factor")
            .and_then(|v| v.as_f64())
            .unwrap_or(1.0);
        anyhow::ensure!(
            f == self.0.stiffness_factor,
            "stiffness_factor {} differs from the pile `{}`'s {f}: the pile was settled with its own contacts; use the same value",
            self.0.stiffness_factor,
            input.id
        );
        Ok(())
    }
    fn excite(&self, ctx: &StageCtx, scene: &PileScene, out: &mut Output) -> anyhow::Result<Vec<Excited>> {
        let p = self.0;
        let run = p.dem.softened(p.stiffness_factor);
        let runs = excite_grains(ctx, p, scene, self.gravity(), &|e0, ft| {
            Ok(crate::dem::pile::run_pile_frames(
                &scene.state, &run, p.profile, e0, &p.stop, ft,
            )?)
        })?;
        out.scalar("stiffness_factor", p.stiffness_factor)
            .scalar("dt_s", run.dt);
        Ok(runs)
    }
    fn wall_contact(&self) -> (f64, &'static str) {
        (0.5, "half a grain")
    }
}

impl PileEngine for CdPile<'_> {
    /// Adaptive step below cd.dt: cd.dt bounds the step count from below.
    fn work(&self, grains: f64, time: f64) -> Vec<(&'static str, f64)> {
        vec![("grains", grains), ("steps", time / self.0.cd.dt)]
    }
    fn density(&self) -> f64 {
        self.0.cd.density
    }
    fn gravity(&self) -> f64 {
        self.0.cd.gravity
    }
    fn excite(&self, ctx: &StageCtx, scene: &PileScene, out: &mut Output) -> anyhow::Result<Vec<Excited>> {
        let p = self.0;
        let runs = excite_grains(ctx, p, scene, self.gravity(), &|e0, ft| {
            Ok(crate::cd::pile::run_excited_pile_frames(
                &scene.state, &p.cd, p.profile, e0, &p.stop, ft,
            )?)
        })?;
        out.scalar("cd_dt_max_s", p.cd.dt);
        Ok(runs)
    }
    fn wall_contact(&self) -> (f64, &'static str) {
        (0.5, "half a grain")
    }
}

/// The stage's engine.
impl RunParams {
    /// The adapter of the stage's method.
    pub fn engine(&self) -> Box<dyn PileEngine + '_> {
        match self.method {
            Method::Dem => Box::new(DemPile(self)),
            Method::Cd => Box::new(CdPile(self)),
            Method::Mpm => Box::new(super::mpm_pile::MpmPile(self)),
        }
    }
}

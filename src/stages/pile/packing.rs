//! Kind `pile-packing` (fig 4.36): packing fraction of the main mass of a DEM pile against
//! time after the excitation, at one input energy (the chapter: E_0 = 152 mgd, gradient).
//!
//! One extra DEM run of the prepared pile (input `pile`, the DEM deposit of fig4-23, with
//! the contact law and softening it was settled with); φ(t) is measured every
//! `sample_every` √(d/g) only here (the pile-run series carry no packing: left out unless a
//! scene asks). φ (D09, global): the solid area of the main mass's grains (linked within
//! 0.01 d̄, walls excluded, D01) over the area under its free surface (highest grain edge
//! per 2 d bin from the wall to the front) — the prep's measure (fig4-23 `packing_fraction`).

use serde::{Deserialize, Serialize};

use crate::analysis::front::{Body, Link, main_mass};
use crate::analysis::pile::{D_NORM, M_NORM, Profile, envelope_packing, excitation, surface_profile};
use crate::dem::pile::pile_walls;
use crate::dem::world::World;
use crate::dem::{DemParams, State};
use crate::pipeline::context::{Claim, Output, StageCtx, col_f64, frame};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::{Checker, Issue};

/// Parameters of a `pile-packing` stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PackingParams {
    /// Contact law of the pile grains (the prep's).
    pub dem: DemParams,
    /// Softening (must equal the prep's).
    pub stiffness_factor: f64,
    /// Input energy [mgd per grain] (D21).
    pub e0_mgd: f64,
    /// Excitation profile (D19).
    pub profile: Profile,
    /// Sampling interval [√(d/g)].
    pub sample_every: f64,
    /// Run length [√(d/g)].
    pub t_max: f64,
}

impl Default for PackingParams {
    fn default() -> Self {
        PackingParams {
            dem: DemParams::default(),
            stiffness_factor: 1.0,
            e0_mgd: 152.0,
            profile: Profile::Gradient,
            sample_every: 1.0,
            t_max: 80.0,
        }
    }
}

impl Validate for PackingParams {
    fn validate(&self) -> Vec<Issue> {
        let mut c = Checker::new("");
        for i in self.dem.validate() {
            c.fail(&format!("dem.{}", i.key), i.value, &i.allowed);
        }
        c.in_open_closed("stiffness_factor", self.stiffness_factor, 0.0, 1.0);
        c.check(
            self.e0_mgd.is_finite() && self.e0_mgd > 0.0,
            "e0_mgd",
            self.e0_mgd,
            "a finite input energy E_0 > 0 [m g d per grain]",
        );
        c.check(
            self.sample_every.is_finite() && self.sample_every > 0.0,
            "sample_every",
            self.sample_every,
            "a finite interval > 0 [√(d/g)]",
        );
        c.check(
            self.t_max.is_finite() && self.t_max >= 10.0 * self.sample_every && self.t_max <= 1000.0,
            "t_max",
            self.t_max,
            "in [10 × sample_every, 1000] √(d/g)",
        );
        c.issues
    }
}

/// φ of the main mass: its solid area over the area under its surface (2 d bins).
pub fn main_mass_packing(s: &State, link: Link) -> f64 {
    let idx = main_mass(
        &Body {
            x: &s.x,
            y: &s.y,
            half: &s.r,
            mass: &s.m,
        },
        link,
    );
    let (x, y, r): (Vec<f64>, Vec<f64>, Vec<f64>) = (
        idx.iter().map(|&i| s.x[i]).collect(),
        idx.iter().map(|&i| s.y[i]).collect(),
        idx.iter().map(|&i| s.r[i]).collect(),
    );
    let l = x.iter().zip(&r).map(|(x, r)| x + r).fold(0.0, f64::max);
    let bin = 2.0 * D_NORM;
    let prof = surface_profile(&x, &y, &r, l, bin);
    let solid: f64 = r.iter().map(|r| std::f64::consts::PI * r * r).sum();
    envelope_packing(&prof, bin, solid)
}

/// Fig 4.36's "densifies after the initial dilation": the sample of lowest φ before the
/// end (the dilation's end), and φ(end) minus that lowest φ. The end is excluded from the
/// minimum, else a mass that only dilates would "densify" by 0 ≥ 0; with fewer than three
/// samples there is nothing to measure (NaN).
pub fn densification(phi: &[f64]) -> (usize, f64) {
    if phi.len() < 3 {
        return (0, f64::NAN);
    }
    let n = phi.len() - 1;
    let k = (1..n).min_by(|&a, &b| phi[a].total_cmp(&phi[b])).unwrap_or(1);
    (k, phi[n] - phi[k])
}

fn run(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: PackingParams = decode(ctx)?;
    let pin = ctx.input("pile")?;
    anyhow::ensure!(
        pin.scalar("settled")? == 1.0,
        "input pile `{}` did not come to rest before the excitation",
        pin.id
    );
    let f = pin
        .params
        .get("stiffness_factor")
        .and_then(|v| v.as_f64())
        .unwrap_or(1.0);
    anyhow::ensure!(
        f == p.stiffness_factor,
        "stiffness_factor {} differs from the pile `{}`'s {f}: use the same value",
        p.stiffness_factor,
        pin.id
    );
    let df = pin.table("table")?;
    let (x, y, r) = (col_f64(&df, "x_m")?, col_f64(&df, "y_m")?, col_f64(&df, "r_m")?);
    let mut s = State::new();
    for i in 0..x.len() {
        s.insert(x[i], y[i], r[i], p.dem.density);
    }
    let mut run = p.dem.softened(p.stiffness_factor);
    run.ledger = false;
    let g = run.gravity;
    let tu = (D_NORM / g).sqrt();
    // D21: E_0 [mgd per grain] = E_0 / (N m g d); D19: the excitation carries E_0 exactly.
    let e0 = p.e0_mgd * s.len() as f64 * M_NORM * g * D_NORM;
    let top = (0..s.len()).map(|i| s.y[i] + s.r[i]).fold(0.0, f64::max);
    s.vx = excitation(p.profile, &s.y, &s.m, top, e0);
    let link = Link::Contact {
        gap: 0.01 * 2.0 * s.radius_stats().1,
    };
    let mut w = World::new(run, s, pile_walls(), None)?;
    let (mut ts, mut phi) = (vec![0.0], vec![main_mass_packing(&w.state, link)]);
    while w.t < (p.t_max - 0.5 * p.sample_every) * tu {
        w.run_until(w.t + p.sample_every * tu)?;
        ts.push(w.t / tu);
        phi.push(main_mass_packing(&w.state, link));
    }
    let mut out = Output::default();
    out.table("table", frame(vec![("t", ts.clone()), ("phi", phi.clone())])?);
    let (k_min, densified) = densification(&phi);
    let (phi0, phi_min, t_min, phi_end) = (phi[0], phi[k_min], ts[k_min], *phi.last().unwrap());
    out.scalar("phi_initial", phi0)
        .scalar("phi_min", phi_min)
        .scalar("t_phi_min", t_min)
        .scalar("phi_end", phi_end)
        .scalar("densification", densified)
        .scalar("e0_mgd", p.e0_mgd)
        .scalar("grains", x.len() as f64);
    out.claims.push(Claim::abs("dilation-until-20", &format!("fig 4.36: \"The granular mass densifies as the flow progresses, after the initial dilation phase for t = 20√(d/g)\": time of the lowest φ of the main mass [√(d/g)] (tolerance ±10, UNSPEC; φ_min = {phi_min:.3})"), 20.0, t_min, 10.0));
    out.claims.push(Claim::at_least("densifies", &format!("fig 4.36: \"The granular mass densifies as the flow progresses\": φ at t = {} √(d/g) minus its lowest value (> 0; φ_end = {phi_end:.3})", p.t_max), 0.0, densified));
    let prep_phi = pin.scalar("packing_fraction")?;
    out.checks.push(Claim::abs("phi-initial", &format!("the excited pile is the prepared one: φ of the main mass at t = 0 against the prep `{}`'s packing_fraction (same measure; the chapter's ≃ 0.82 is fig4-23's claim)", pin.id), prep_phi, phi0, 0.01));
    out.note(format!("DEM pile of {} grains, {} excitation, E_0 = {} mgd per grain; φ of the main mass every {} √(d/g) to {} √(d/g).", x.len(), p.profile.name(), p.e0_mgd, p.sample_every, p.t_max));
    Ok(out)
}

/// Kind `pile-packing`.
pub const KIND: Kind = Kind {
    name: "pile-packing",
    source: file!(),
    method: None,
    version: 1,
    about: "fig 4.36: packing fraction of the main mass of a DEM pile against time after the excitation, at one E_0",
    params: typed::<PackingParams>,
    run,
    explain: None,
    roles: crate::stages::kind::Roles::Fixed(&[("pile", crate::pipeline::context::Arity::One)]),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "densification", "e0_mgd", "grains", "phi_end", "phi_initial", "phi_min", "t_phi_min",
        ],
        tables: &[crate::stages::kind::TableDecl {
            name: "table",
            columns: &["phi", "t"],
        }],
        measurements: &["densifies", "dilation-until-20"],
        texts: &[],
    },
    reads: None,
    cost: None,
    atlas: None,
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packing_of_a_square_lattice_is_pi_over_4() {
        // touching disks of diameter 2 d on a square lattice: φ = π/4 under the flat top
        let mut s = State::new();
        let r = D_NORM;
        for i in 0..20 {
            for j in 0..10 {
                s.insert(r + 2.0 * r * i as f64, r + 2.0 * r * j as f64, r, 2600.0);
            }
        }
        let phi = main_mass_packing(&s, Link::Contact { gap: 0.01 * r });
        assert!((phi - std::f64::consts::FRAC_PI_4).abs() < 1e-9, "φ = {phi}");
    }

    #[test]
    fn a_mass_that_only_dilates_does_not_densify() {
        // The old measure took the minimum over every sample, the last included: φ_end −
        // min φ ≥ 0 whatever the flow did, so "densifies" could not fail.
        let (_, d) = densification(&[0.80, 0.79, 0.78, 0.77]);
        assert!(d < 0.0, "{d}");
        let (k, d) = densification(&[0.80, 0.76, 0.78, 0.79]);
        assert_eq!(k, 1);
        assert!((d - 0.03).abs() < 1e-12, "{d}");
        assert!(densification(&[0.8, 0.7]).1.is_nan());
    }
}

//! Per-run analysis of a column collapse, the same for every method of the
//! `column-collapse` kind (issue 9, item 2): run-out sensitivity to the D01 linking gap,
//! τ_c nominal and measured (D05), phases of §4.2 (0.8 τ_c, 3 τ_c, 6 τ_c), run-out and stop
//! times (D10), inertial-number statistics (D08), failure angle at τ_c (D18) and μ_e by
//! the three estimators of D17. Every number comes from `crate::analysis` reading the
//! method's time series and a [`Cloud`] of its bodies; the claims are the chapter's, with
//! the tolerances stated here.

use crate::analysis::cloud::Cloud;
use crate::analysis::failure::{failure_line, mohr_coulomb_angle_deg};
use crate::analysis::inertial::Stats;
use crate::analysis::runout::{argmax, line_fit, mu_e_geometric, mu_e_staron_hinch_law, staron_hinch_work};
use crate::pipeline::context::{Claim, Output, frame};

/// What one run provides.
pub struct Run<'a> {
    /// "DEM" or "MPM".
    pub method: &'a str,
    /// L_0, H_0 [m].
    pub l0: f64,
    /// See `l0`.
    pub h0: f64,
    /// τ_c = √(H_0/g) [s].
    pub tau: f64,
    /// d̄ [m].
    pub d: f64,
    /// Sample times [s].
    pub t: &'a [f64],
    /// L(t), H(t) [m] with the stage's linking gap.
    pub l: &'a [f64],
    /// See `l`.
    pub h: &'a [f64],
    /// Translational kinetic energy (eq 4.11) [J/m].
    pub ek: &'a [f64],
    /// E_p [J/m].
    pub ep: &'a [f64],
    /// Coarse-grained I statistics per sample.
    pub inertial: &'a [Stats],
    /// Linking gaps of the sensitivity table [d̄], and L(t) for each (rows = samples).
    pub gaps: &'a [f64],
    /// See `gaps`.
    pub gap_lengths: &'a [Vec<f64>],
    /// Linking gap of `l` [d̄] (NaN: another rule, said in a note).
    pub link_gap: f64,
    /// The bodies at the sample closest to t = τ_c (D18), if any.
    pub at_tau: Option<&'a Cloud>,
    /// Horizontal positions at release and at the end, masses (same order) for D17.
    pub x_start: &'a [f64],
    /// See `x_start`.
    pub x_end: &'a [f64],
    /// See `x_start`.
    pub mass: &'a [f64],
    /// Friction angle φ from the shear-test artifact [°] (NaN if the stage has none).
    pub phi_deg: f64,
    /// Grain (DEM) friction coefficient for the Staron–Hinch law (NaN: not applicable).
    pub mu_grain: f64,
    /// Whether the stop rule was met (false: the upper bound ended the run).
    pub at_rest: bool,
    /// Gravity [m/s²].
    pub g: f64,
}

/// D18 slice height [d̄] and moving threshold [fraction of max|v|].
const FAILURE_BIN_D: f64 = 1.0;
const FAILURE_V_FRAC: f64 = 0.1;

pub(crate) fn value_at(t: &[f64], y: &[f64], at: f64) -> f64 {
    // Last sample at or before `at` (samples are every ≤ 0.02 τ_c).
    let mut v = f64::NAN;
    for (a, b) in t.iter().zip(y) {
        if *a <= at + 1e-12 {
            v = *b;
        } else {
            break;
        }
    }
    v
}

/// Add the tables, scalars, notes and measurements of the per-run analysis to `out`. Every
/// run measures the same things; the claims ledger (`stages/ledger.yaml`) judges them only
/// where the chapter states them (a = 0.4 and 6, random packing).
pub fn analyse(out: &mut Output, r: &Run) -> anyhow::Result<()> {
    analyse_all(out, r)
}

fn analyse_all(out: &mut Output, r: &Run) -> anyhow::Result<()> {
    let tau = r.tau;
    let tn: Vec<f64> = r.t.iter().map(|v| v / tau).collect();
    let end = tn.last().copied().unwrap_or(f64::NAN);
    // --- D01 linking-gap sensitivity --------------------------------------------------
    if !r.gaps.is_empty() {
        let mut gap_col = Vec::new();
        let mut cols: Vec<Vec<f64>> = vec![Vec::new(); 6];
        for (k, &gd) in r.gaps.iter().enumerate() {
            let lk: Vec<f64> = r.gap_lengths.iter().map(|row| row[k]).collect();
            let dl = |at: f64| (value_at(&tn, &lk, at) - r.l0) / r.l0;
            // Largest backward jump of L(t) (a chain losing contact), in L_0.
            let drop = crate::analysis::runout::max_drawdown(&lk);
            gap_col.push(gd);
            for (c, v) in cols.iter_mut().zip([
                dl(1.0),
                dl(2.0),
                dl(3.0),
                dl(f64::INFINITY),
                drop / r.l0,
                lk.len() as f64,
            ]) {
                c.push(v);
            }
        }
        out.table(
            "link_gap_sensitivity",
            frame(vec![
                ("gap_over_d", gap_col),
                ("runout_norm_1tau", cols[0].clone()),
                ("runout_norm_2tau", cols[1].clone()),
                ("runout_norm_3tau", cols[2].clone()),
                ("runout_norm_final", cols[3].clone()),
                ("largest_backward_jump_over_l0", cols[4].clone()),
            ])?,
        );
        let mut ts = vec![("t_over_tau_c", tn.clone())];
        let names: Vec<String> = r.gaps.iter().map(|g| format!("runout_norm_gap{g}")).collect();
        for (k, n) in names.iter().enumerate() {
            ts.push((
                n.as_str(),
                r.gap_lengths.iter().map(|row| (row[k] - r.l0) / r.l0).collect(),
            ));
        }
        out.table("runout_by_gap", frame(ts)?);
    }
    out.scalar("link_gap_over_d", r.link_gap);
    // --- D05, D10, phases ---------------------------------------------------------------
    let k_max = argmax(r.ek);
    let t_kemax = k_max.map(|k| tn[k]).unwrap_or(f64::NAN);
    let t_f = crate::analysis::front::stop_time(r.t, r.l, 0.5 * r.d) / tau;
    let (v_front, lin_r2, _) = line_fit(&tn, r.l, 0.8, 2.8);
    let back_jump = crate::analysis::runout::max_backward_jump(r.l, r.l0);
    out.scalar("t_kemax_s", t_kemax * tau)
        .scalar("t_kemax_over_tau_c", t_kemax)
        .scalar("t_stop_over_tau_c", end)
        .scalar("stop_rule_met", if r.at_rest { 1.0 } else { 0.0 })
        .scalar("front_speed_08_28_m_s", v_front / tau)
        .scalar("front_linearity_r2_08_28", lin_r2)
        .scalar("runout_norm_1tau", (value_at(&tn, r.l, 1.0) - r.l0) / r.l0)
        .scalar("runout_norm_3tau", (value_at(&tn, r.l, 3.0) - r.l0) / r.l0)
        .scalar("front_max_backward_jump_over_l0", back_jump);
    // E_p/E_0 and E_d/E_0 = 1 − (E_p + E_k)/E_0 at 3 τ_c (eqs 4.10, 4.12; fig 4.13's last time)
    let (ep3, ek3, e0) = (
        value_at(&tn, r.ep, 3.0),
        value_at(&tn, r.ek, 3.0),
        r.ep.first().map_or(f64::NAN, |e| *e),
    );
    out.scalar("ep_over_e0_3tau", ep3 / e0)
        .scalar("ed_over_e0_3tau", 1.0 - (ep3 + ek3) / e0);
    let m = r.method;
    out.claims.push(Claim::abs(
        "acceleration-phase",
        &format!("{m}: \"An initial transient acceleration phase is observed for a time 0.8τ_c\" — t_KEmax/τ_c, the end of the acceleration (D05 measured; tolerance 0.25)"),
        0.8, t_kemax, 0.25,
    ));
    out.claims.push(Claim::abs(
        "constant-spreading-velocity",
        &format!("{m}: \"a constant spreading velocity V for about 2τ_c\" — R² of a straight line through L(t) over [0.8, 2.8]τ_c (paper: 1, tolerance 0.05)"),
        1.0, lin_r2, 0.05,
    ));
    out.claims.push(Claim::abs(
        "spreading-ceases-3tau",
        &format!("{m}: \"The spreading of the granular column ceases after a time on the order of about 3τ_c\" — t_f/τ_c, front within 0.5 d̄ of L_f (D10; tolerance 1)"),
        3.0, t_f, 1.0,
    ));
    // --- D08 --------------------------------------------------------------------------
    let flowing: Vec<&Stats> = r.inertial.iter().filter(|s| s.flowing_fraction > 0.0).collect();
    let i_mean_max = flowing.iter().map(|s| s.mean).fold(0.0, f64::max);
    let i_p95_max = flowing.iter().map(|s| s.p95).fold(0.0, f64::max);
    let i_max = flowing.iter().map(|s| s.max).fold(0.0, f64::max);
    // The same mean with static cells counted as I = 0 (a whole-mass average).
    let i_all_max = r
        .inertial
        .iter()
        .map(|s| s.mean * s.flowing_fraction)
        .fold(0.0, f64::max);
    out.scalar("i_cg_mean_max", i_mean_max)
        .scalar("i_cg_p95_max", i_p95_max)
        .scalar("i_cg_max", i_max)
        .scalar("i_cg_mean_all_mass_max", i_all_max);
    out.claims.push(Claim::at_most(
        "inertial-number-dense",
        &format!("{m}: I in the dense regime, \"the short column attains a maximum inertial number of 0.012\" (fig 4.15) — max over time of the mass-weighted mean of the coarse-grained I over flowing cells (D08; paper bound 0.1, the dense-regime limit the text quotes)"),
        0.1, i_mean_max,
    ));
    // --- D18 --------------------------------------------------------------------------
    let mc = mohr_coulomb_angle_deg(r.phi_deg);
    out.scalar("failure_angle_mohr_coulomb_deg", mc)
        .scalar("friction_angle_shear_deg", r.phi_deg);
    match r
        .at_tau
        .and_then(|c| failure_line(c, r.l0, FAILURE_BIN_D * r.d, FAILURE_V_FRAC).map(|f| (c.t, f)))
    {
        Some((t, f)) => {
            out.scalar("failure_angle_deg", f.angle_deg)
                .scalar("failure_fit_r2", f.r2)
                .scalar("failure_fit_slices", f.n_slices as f64)
                .scalar("failure_time_over_tau_c", t / tau);
            out.note(format!(
                "{m} failure surface at t = {:.2} τ_c (D18: moving = |v| > 0.1 max|v|, slices of d̄, fit over 0.1–0.9 of its height): {:.1}° (R² {:.2}, {} slices), 45° + φ/2 = {:.1}° with φ = {:.2}° from the shear test.",
                t / tau, f.angle_deg, f.r2, f.n_slices, mc, r.phi_deg
            ));
            out.claims.push(Claim::abs("failure-angle", &format!("{m}: \"The angle of the failure surface is found to be about 55°\" at τ_c (D18; tolerance 5°, the text's own 50–55° spread)"), 55.0, f.angle_deg, 5.0));
        }
        None => {
            out.scalar("failure_angle_deg", f64::NAN);
            out.note(format!("{m}: no failure surface could be fitted at τ_c (fewer than three slices with static and moving bodies)."));
            out.claims.push(Claim::abs("failure-angle", &format!("{m}: \"The angle of the failure surface is found to be about 55°\" at τ_c (D18) — not measurable in this run"), 55.0, f64::NAN, 5.0));
        }
    }
    // --- D17 --------------------------------------------------------------------------
    let lf = r.l.last().copied().unwrap_or(f64::NAN);
    let mu1 = mu_e_geometric(r.h0, r.l0, lf);
    let de = r.ep.first().copied().unwrap_or(f64::NAN) - r.ep.last().copied().unwrap_or(f64::NAN);
    let w = staron_hinch_work(r.x_start, r.x_end, r.mass, r.g);
    let mu2 = de / w;
    let mu3 = mu_e_staron_hinch_law(r.mu_grain);
    out.scalar("mu_e_runout", mu1)
        .scalar("mu_e_runout_deg", mu1.atan().to_degrees())
        .scalar("delta_e_j", de)
        .scalar("staron_hinch_w_j", w)
        .scalar("mu_e_energy", mu2)
        .scalar("mu_e_energy_deg", mu2.atan().to_degrees())
        .scalar("mu_e_law", mu3)
        .scalar("mu_e_law_deg", mu3.atan().to_degrees());
    out.note(format!(
        "{m} μ_e (D17): H_0/(L_f − L_0) = {mu1:.3} ({:.1}°); δE/(g Σ m_p |x_end − x_0|) = {mu2:.3} ({:.1}°, one run; the chapter's estimator is the slope over the short columns, a fan-in); Staron–Hinch law 0.425 μ^0.2 = {}.",
        mu1.atan().to_degrees(), mu2.atan().to_degrees(),
        if mu3.is_finite() { format!("{mu3:.3} ({:.1}°, a formula of the grain friction μ = {}, not a measurement)", mu3.atan().to_degrees(), r.mu_grain) } else { "n/a (no grain friction)".into() }
    ));
    if r.h0 / r.l0 <= 2.7 {
        out.claims.push(Claim::abs("mu-e-runout", &format!("{m}: \"an effective friction angle μ_e of 21° is observed\" — atan(H_0/(L_f − L_0)) (eqs 4.8–4.9; tolerance 3°)"), 21.0, mu1.atan().to_degrees(), 3.0));
        out.claims.push(Claim::abs("mu-e-energy", &format!("{m}: \"an effective friction angle μ_e of 21° is observed\" — atan(δE/W), Staron & Hinch's energy estimator on this run (tolerance 3°)"), 21.0, mu2.atan().to_degrees(), 3.0));
    }
    Ok(())
}

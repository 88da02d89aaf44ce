//! What the DEM stage kinds share: the parameter check with its pre-flight (bad input before
//! anything runs), the `--explain` table, and a prepared column's tables written and read
//! back (grains and contact histories).

use crate::dem::prep::{Column, SettleReport};
use crate::dem::{ContactState, DemParams, SavedHistories, SizeClasses, State};
use crate::pipeline::context::{InputRef, col_f64, frame};
use crate::validate::Checker;

/// Size classes the validation-time pre-flight assumes: PSD-COL (0.92–1.38 mm). The
/// smallest grains bind, so larger PSDs are covered; each run repeats the audit with its
/// actual grains.
pub const PREFLIGHT_SIZES: crate::dem::SizeClasses = crate::dem::SizeClasses {
    r_min: 0.46e-3,
    r_mean: 0.575e-3,
    r_max: 0.69e-3,
};

pub(crate) fn check_dem(p: &DemParams, factor: f64, c: &mut Checker) {
    check_dem_at(
        p,
        factor,
        PREFLIGHT_SIZES,
        "a stable step",
        ". `granrepro run --explain` prints every time scale",
        c,
    );
}

/// A DEM block's own checks, then the pre-flight of its softened step on the grain sizes
/// `sizes` (an unstable step is bad input, exit 2); `what` opens the allowed phrase and
/// `hint` ends it.
pub(crate) fn check_dem_at(p: &DemParams, factor: f64, sizes: SizeClasses, what: &str, hint: &str, c: &mut Checker) {
    for i in p.validate() {
        c.fail(&format!("dem.{}", i.key), i.value, &i.allowed);
    }
    c.in_open_closed("stiffness_factor", factor, 0.0, 1.0);
    if !c.issues.is_empty() {
        return;
    }
    let run = p.softened(factor);
    if let Err(e) = crate::dem::preflight(&run, sizes, true, run.dt) {
        c.fail(
            "dem.dt",
            format!("{:.3e} s (with stiffness_factor {factor})", run.dt),
            &format!("{what} — {e}{hint}"),
        );
        // Without the rolling dashpot the rolling spring is integrated explicitly and its
        // scale binds: the fix may equally be `rolling.cr` (set in another file than `dt`).
        if e.to_string().contains("rolling spring") && !(p.rolling.cr > 0.0) {
            c.fail(
                "dem.rolling.cr",
                p.rolling.cr,
                &format!(
                    "> 0 (the implicit rolling dashpot) at dem.dt = {:.3e} s, or a smaller dem.dt — {e}",
                    run.dt
                ),
            );
        }
    }
}

/// `--explain`: the pre-flight table of a DEM stage's parameters.
pub(crate) fn explain_dem(v: &serde_json::Value) -> String {
    let dem: DemParams = v
        .get("dem")
        .cloned()
        .and_then(|d| serde_json::from_value(d).ok())
        .unwrap_or_default();
    let f = v.get("stiffness_factor").and_then(|x| x.as_f64()).unwrap_or(1.0);
    preflight_dem(&dem, f, PREFLIGHT_SIZES)
}

/// The DEM pre-flight table: every time scale of grains of `sizes` against the step of
/// `dem` softened by `factor`.
pub(crate) fn preflight_dem(dem: &DemParams, factor: f64, sizes: crate::dem::SizeClasses) -> String {
    let run = dem.softened(factor);
    let rows = crate::dem::time_scales(&run, sizes, true, run.dt);
    let pf = crate::dem::Preflight { dt: run.dt, rows };
    format!("{pf}")
}

/// Grains table of a state.
pub(crate) fn grains_table(s: &State) -> anyhow::Result<polars::prelude::DataFrame> {
    frame(vec![("x_m", s.x.clone()), ("y_m", s.y.clone()), ("r_m", s.r.clone())])
}

/// Contact-history table of a settled sample: `wall` = −1 for a grain pair (a, b),
/// else the wall index with grain a.
pub(crate) fn histories_table(h: &SavedHistories) -> anyhow::Result<polars::prelude::DataFrame> {
    let rows: Vec<(f64, u32, u32, ContactState)> = h
        .pairs
        .iter()
        .map(|&(a, b, c)| (-1.0, a, b, c))
        .chain(h.walls.iter().map(|&(w, a, c)| (w as f64, a, 0, c)))
        .collect();
    frame(vec![
        ("wall", rows.iter().map(|r| r.0).collect()),
        ("a", rows.iter().map(|r| r.1 as f64).collect()),
        ("b", rows.iter().map(|r| r.2 as f64).collect()),
        ("tangential_m", rows.iter().map(|r| r.3.tangential).collect()),
        ("rolling_rad", rows.iter().map(|r| r.3.rolling).collect()),
        ("ft_n", rows.iter().map(|r| r.3.ft).collect()),
        ("mr_nm", rows.iter().map(|r| r.3.mr).collect()),
    ])
}

/// The histories written by [`histories_table`].
fn histories_from(input: &InputRef) -> anyhow::Result<SavedHistories> {
    let df = input.table("contacts")?;
    let (w, a, b) = (col_f64(&df, "wall")?, col_f64(&df, "a")?, col_f64(&df, "b")?);
    let (t, r, ft, mr) = (
        col_f64(&df, "tangential_m")?,
        col_f64(&df, "rolling_rad")?,
        col_f64(&df, "ft_n")?,
        col_f64(&df, "mr_nm")?,
    );
    let mut h = SavedHistories::default();
    for k in 0..w.len() {
        let c = ContactState {
            tangential: t[k],
            rolling: r[k],
            ft: ft[k],
            mr: mr[k],
        };
        if w[k] < 0.0 {
            h.pairs.push((a[k] as u32, b[k] as u32, c));
        } else {
            h.walls.push((w[k] as u32, a[k] as u32, c));
        }
    }
    Ok(h)
}

/// Rebuild a prepared column from a prep stage's artifacts.
pub(crate) fn column_from(input: &InputRef, density: f64) -> anyhow::Result<Column> {
    let df = input.table("table")?;
    let (x, y, r) = (col_f64(&df, "x_m")?, col_f64(&df, "y_m")?, col_f64(&df, "r_m")?);
    let mut s = State::new();
    for i in 0..x.len() {
        s.insert(x[i], y[i], r[i], density);
    }
    let sc = input.scalars()?;
    let get = |k: &str| {
        sc.get(k)
            .copied()
            .ok_or_else(|| anyhow::anyhow!("input `{}` has no scalar `{k}`", input.id))
    };
    Ok(Column {
        state: s,
        l0: get("l0_m")?,
        h0: get("h0_m")?,
        packing_fraction: get("packing_fraction")?,
        packing_fraction_core: sc.get("packing_fraction_core").copied().unwrap_or(f64::NAN),
        settle: SettleReport {
            time: get("settle_time_s")?,
            ke_over_ep: get("settle_ke_over_ep")?,
            converged: true,
        },
        histories: histories_from(input)?,
    })
}

/// Gravity used by the DEM stages (for documentation of τ_c).
pub const GRAVITY: f64 = crate::math::G;

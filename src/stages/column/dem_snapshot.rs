//! Kind `dem-snapshot` (figs 4.1a, 4.2: a prepared DEM column drawn, optionally with its
//! contact network), and the column drawing the prep stage uses too.

use serde::{Deserialize, Serialize};

use super::dem_common::{column_from, grains_table};
use crate::dem::State;
use crate::pipeline::context::{Output, StageCtx};
use crate::report::plot::footer;
use crate::report::snapshot::{Field, Segment, Shape, Snapshot};
use crate::stages::{Kind, Validate, decode, typed};
use crate::validate::Issue;

/// Grain–grain contacts of a packing at rest: (i, j, overlap δ). With the linear contact
/// law at one k_n, F_n = k_n δ, so δ is the normal force up to that constant. Sweep over
/// grains sorted by x (a packing at rest has few neighbours within 2 r_max).
pub(crate) fn contacts_at_rest(s: &State) -> Vec<(usize, usize, f64)> {
    let n = s.x.len();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| s.x[a].total_cmp(&s.x[b]));
    let rmax = s.r.iter().copied().fold(0.0, f64::max);
    let mut out = Vec::new();
    for (k, &i) in order.iter().enumerate() {
        for &j in &order[k + 1..] {
            if s.x[j] - s.x[i] > s.r[i] + rmax {
                break;
            }
            let d = ((s.x[j] - s.x[i]).powi(2) + (s.y[j] - s.y[i]).powi(2)).sqrt();
            let delta = s.r[i] + s.r[j] - d;
            if delta > 0.0 {
                out.push((i.min(j), i.max(j), delta));
            }
        }
    }
    out.sort_by_key(|a| (a.0, a.1));
    out
}

pub(crate) fn column_snapshot(
    title: String,
    foot: String,
    s: &State,
    l0: f64,
    h0: f64,
    colour_by_size: bool,
    gate: bool,
) -> String {
    column_snapshot_with(title, foot, s, l0, h0, colour_by_size, gate, &[])
}

#[allow(clippy::too_many_arguments)]
pub(crate) fn column_snapshot_with(
    title: String,
    foot: String,
    s: &State,
    l0: f64,
    h0: f64,
    colour_by_size: bool,
    gate: bool,
    network: &[(usize, usize, f64)],
) -> String {
    let d: Vec<f64> = s.r.iter().map(|r| 2e3 * r).collect();
    let (dmin, dmax) = d
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
    let mut segs = vec![
        Segment {
            a: (0.0, 0.0),
            b: (0.0, 1.1 * h0),
            color: "black",
            width: 2.5,
            dashed: false,
        },
        Segment {
            a: (0.0, 0.0),
            b: (1.15 * l0, 0.0),
            color: "black",
            width: 2.5,
            dashed: false,
        },
    ];
    if gate {
        segs.push(Segment {
            a: (l0, 0.0),
            b: (l0, 1.1 * h0),
            color: "#555",
            width: 2.0,
            dashed: true,
        });
    }
    let fmax = network.iter().map(|c| c.2).fold(0.0, f64::max);
    for &(i, j, f) in network {
        segs.push(Segment {
            a: (s.x[i], s.y[i]),
            b: (s.x[j], s.y[j]),
            color: "#b2182b",
            width: 0.2 + 2.8 * f / fmax.max(1e-300),
            dashed: false,
        });
    }
    Snapshot {
        title,
        footer: foot,
        x: &s.x,
        y: &s.y,
        half: &s.r,
        shape: Shape::Disk,
        field: colour_by_size.then(|| Field {
            values: &d,
            label: "grain diameter [mm]".into(),
            range: (dmin, dmax.max(dmin + 1e-9)),
        }),
        black: None,
        fill: (!network.is_empty()).then_some("#c8c8c8"),
        segments: segs,
        view: None,
        width_px: 640.0,
    }
    .to_svg()
}

/// Parameters of a `dem-snapshot` stage (figures of a prepared column).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SnapshotParams {
    /// Colour grains by diameter (fig4-01a) or uniformly (fig4-02).
    pub colour_by_size: bool,
    /// Draw the gate at x = L_0.
    pub gate: bool,
    /// Grains grey with the contact-force network over them: one line per grain–grain
    /// contact between the centres, width ∝ normal force (fig4-01a as the original).
    pub force_network: bool,
}

impl Default for SnapshotParams {
    fn default() -> Self {
        SnapshotParams {
            colour_by_size: false,
            gate: true,
            force_network: false,
        }
    }
}

impl Validate for SnapshotParams {
    fn validate(&self) -> Vec<Issue> {
        vec![]
    }
}

fn run_snapshot(ctx: &StageCtx) -> anyhow::Result<Output> {
    let p: SnapshotParams = decode(ctx)?;
    let input = ctx.input("column")?;
    let col = column_from(input, 2500.0)?;
    let mut out = Output::default();
    out.scalar("n", col.state.len() as f64)
        .scalar("packing_fraction", col.packing_fraction)
        .scalar("l0_m", col.l0)
        .scalar("h0_m", col.h0)
        .scalar("a", col.h0 / col.l0);
    let network = if p.force_network {
        contacts_at_rest(&col.state)
    } else {
        Vec::new()
    };
    let mut foot = format!(
        "N = {}, φ = {:.3}, L_0 = {:.1} mm, H_0 = {:.1} mm, at rest (E_k/E_p = {:.1e})",
        col.state.len(),
        col.packing_fraction,
        col.l0 * 1e3,
        col.h0 * 1e3,
        col.settle.ke_over_ep
    );
    if p.force_network {
        let z = 2.0 * network.len() as f64 / col.state.len() as f64;
        out.scalar("grain_contacts", network.len() as f64)
            .scalar("coordination_number", z);
        foot.push_str(&format!(
            "; {} grain contacts (z = {z:.2}), line width ∝ F_n",
            network.len()
        ));
    }
    let svg = column_snapshot_with(
        ctx.caption.clone().unwrap_or_else(|| "DEM column".into()),
        footer(&ctx.profile, &foot),
        &col.state,
        col.l0,
        col.h0,
        p.colour_by_size,
        p.gate,
        &network,
    );
    out.figure("figure", svg);
    out.table("table", grains_table(&col.state)?);
    Ok(out)
}

/// Kind `dem-snapshot`.
pub const SNAPSHOT_KIND: Kind = Kind {
    name: "dem-snapshot",
    source: file!(),
    method: Some(crate::engines::Method::Dem),
    version: 2,
    about: "snapshot figure of a prepared DEM column (fig4-01a, fig4-02)",
    params: typed::<SnapshotParams>,
    run: run_snapshot,
    explain: None,
    roles: crate::stages::kind::Roles::Fixed(&[("column", crate::pipeline::context::Arity::One)]),
    outputs: crate::stages::kind::Outputs {
        scalars: &[
            "a", "coordination_number", "grain_contacts", "h0_m", "l0_m", "n", "packing_fraction",
        ],
        tables: &[crate::stages::kind::TableDecl {
            name: "table",
            columns: &["r_m", "x_m", "y_m"],
        }],
        measurements: &[],
        texts: &[],
    },
    reads: None,
    cost: None,
    atlas: None,
};

#[cfg(test)]
mod network_tests {
    use super::*;

    #[test]
    fn contacts_at_rest_finds_each_overlap_once() {
        // Three 1 mm disks on a line, centres 1.9 mm apart (δ = 0.1 mm each), and a fourth
        // far away; a brute-force count over all pairs agrees.
        let mut s = State::new();
        for x in [0.0, 1.9e-3, 3.8e-3, 9.0e-3] {
            s.insert(x, 0.0, 1.0e-3, 2500.0);
        }
        s.insert(0.95e-3, 1.7e-3, 1.0e-3, 2500.0); // on top of the first two: 2 more contacts
        let c = contacts_at_rest(&s);
        let mut brute = 0;
        for i in 0..s.x.len() {
            for j in i + 1..s.x.len() {
                if ((s.x[i] - s.x[j]).powi(2) + (s.y[i] - s.y[j]).powi(2)).sqrt() < s.r[i] + s.r[j] {
                    brute += 1;
                }
            }
        }
        assert_eq!(c.len(), brute);
        assert_eq!(c.len(), 4);
        assert!((c[0].2 - 0.1e-3).abs() < 1e-12, "{c:?}");
        assert!(c.iter().all(|&(i, j, d)| i < j && d > 0.0));
    }
}

//! Pile part A (issue 11): the series analysis of pile runs (`pile-series`), the base-friction
//! parameter of `pile-run` and the plot's per-value series. Bad input is refused at
//! validation (exit 2, naming the key); the derived columns are checked on a real small run.

mod common;
use common::TempProject;

/// The quick profile's pile on 60 grains: the shipped contact law (stages/pile/dem.yaml)
/// softened ×0.1, the shipped preparation in a box scaled by √(60/13000).
const PREP: &str = "  - id: psd\n    kind: psd\n    params: { n: 60, d_min_mm: 1.964, d_max_mm: 2.946 }\n  - id: pile\n    kind: dem-pile-prep\n    params_file: [dem=dem.yaml, prep.yaml]\n    params: { grains: 0, stiffness_factor: 0.1, pile: { deposition: { width: 0.0116 }, max_time: 3.0 } }\n    inputs: { psd: psd }\n";

fn project(extra: &str) -> TempProject {
    let t = TempProject::new(&format!("version: 1\nstages:\n{PREP}{extra}"));
    t.write("dem.yaml", include_str!("../stages/pile/dem.yaml"));
    t.write("prep.yaml", include_str!("../stages/pile/prep.yaml"));
    t
}

fn refused(extra: &str, needles: &[&str]) {
    let t = project(extra);
    let (code, _, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 2, "expected exit 2 for `{extra}`: {err}");
    for n in needles {
        assert!(err.contains(n), "missing `{n}` in: {err}");
    }
}

const RUN: &str = "  - id: run\n    kind: pile-run\n    params: { RUN }\n    inputs: { pile: pile }\n";

#[test]
fn base_friction_out_of_range_is_refused() {
    refused(
        &RUN.replace(
            "RUN",
            "method: mpm, mpm_friction: 0.22, energies_mgd: [5.0], mpm_base_friction: 1.5",
        ),
        &["mpm_base_friction", "1.5", "(0, 1]"],
    );
    refused(
        &RUN.replace(
            "RUN",
            "method: mpm, mpm_friction: 0.22, energies_mgd: [5.0], mpm_base_friction: -0.1",
        ),
        &["mpm_base_friction", "-0.1"],
    );
}

#[test]
fn series_statements_without_their_labels_are_refused() {
    let run = RUN.replace("RUN", "energies_mgd: [5.0]");
    let ser = "  - id: ser\n    kind: pile-series\n    params: { PARAMS }\n    inputs: { runs: run }\n";
    refused(
        &format!("{run}{}", ser.replace("PARAMS", "statements: { ppc: true }")),
        &["labels", "mpm.ppc"],
    );
    refused(
        &format!("{run}{}", ser.replace("PARAMS", "statements: { friction: true }")),
        &["labels", "mpm_base_friction"],
    );
    refused(
        &format!("{run}{}", ser.replace("PARAMS", "zero_ratio: 2.0")),
        &["zero_ratio", "2"],
    );
    refused(
        &format!("{run}{}", ser.replace("PARAMS", "statements: { dissipated_by: -5.0 }")),
        &["statements.dissipated_by", "-5"],
    );
}

#[test]
fn plot_group_needs_a_table_source() {
    let plot = "  - id: fig\n    kind: plot\n    params: { panels: [{ x: { label: t }, y: { label: e }, series: [{ from: p, source: scalars, x: a, y: b, group: c, label: g }] }] }\n    inputs: { p: pile }\n";
    refused(plot, &["group", "table source"]);
}

fn col(t: &TempProject, stage: &str, table: &str, name: &str) -> Vec<f64> {
    let p = t.path().join("reports/quick").join(format!("{stage}-{table}.csv"));
    let p = if table == "table" {
        t.path().join("reports/quick").join(format!("{stage}.csv"))
    } else {
        p
    };
    let text = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let k = head
        .iter()
        .position(|h| *h == name)
        .unwrap_or_else(|| panic!("no column {name} in {head:?}"));
    lines
        .map(|l| l.split(',').nth(k).unwrap().parse::<f64>().unwrap_or(f64::NAN))
        .collect()
}

#[test]
fn series_columns_follow_d12_to_d15_on_a_real_run() {
    // A 60-grain DEM pile at two energies; pile-series must give t' = t − t_1, E_kx/E'_kx0 = 1
    // at t_1, t'/τ = t'/τ of its table, t'_f = t_f − t_1, and one curve per E_0 in the plot.
    let run = "  - id: run\n    kind: pile-run\n    params_file: [dem=dem.yaml]\n    params: { stiffness_factor: 0.1, energies_mgd: [5.0, 60.0], stop: { t_max: 40.0 } }\n    inputs: { pile: pile }\n";
    let ser = "  - id: ser\n    kind: pile-series\n    params: { statements: { transient: true } }\n    inputs: { runs: run }\n";
    let plot = "  - id: fig\n    kind: plot\n    params: { panels: [{ x: { label: t }, y: { label: e, log: true }, series: [{ from: s, table: series, x: t, y: ek_over_e0, group: e0_mgd, label: E_0, draw: line }] }] }\n    inputs: { s: ser }\n";
    let t = project(&format!("{run}{ser}{plot}"));
    let (code, out, err) = t.cli(&["run", "--quiet"]);
    assert_eq!(code, 0, "{out}\n{err}");
    let (ts, tp, e0) = (
        col(&t, "ser", "series", "t"),
        col(&t, "ser", "series", "t_prime"),
        col(&t, "ser", "series", "e0_mgd"),
    );
    for k in 0..ts.len() {
        assert!((tp[k] - (ts[k] - 7.5)).abs() < 1e-12);
    }
    let (rx, tpt) = (
        col(&t, "ser", "series", "ekx_over_ekx0"),
        col(&t, "ser", "series", "t_prime_over_tau"),
    );
    let (te, tau, tf, tfp) = (
        col(&t, "ser", "table", "e0_mgd"),
        col(&t, "ser", "table", "tau"),
        col(&t, "ser", "table", "tf"),
        col(&t, "ser", "table", "tfp"),
    );
    assert_eq!(te.len(), 2);
    for r in 0..2 {
        assert!((tfp[r] - (tf[r] - 7.5)).abs() < 1e-9);
        // E'_kx0 = E_kx(t_1) by linear interpolation (D13): E_kx/E'_kx0 interpolated at t_1 is 1
        let b = (1..ts.len())
            .find(|&k| e0[k] == te[r] && e0[k - 1] == te[r] && ts[k - 1] <= 7.5 && ts[k] > 7.5)
            .expect("samples around t_1");
        let f = (7.5 - ts[b - 1]) / (ts[b] - ts[b - 1]);
        let at_t1 = rx[b - 1] + f * (rx[b] - rx[b - 1]);
        assert!((at_t1 - 1.0).abs() < 1e-9, "E_kx/E'_kx0 at t_1 = {at_t1}");
        let k = (0..ts.len()).find(|&k| e0[k] == te[r] && ts[k] > 9.0).unwrap();
        assert!((tpt[k] - (ts[k] - 7.5) / tau[r]).abs() < 1e-9);
    }
    let fig: serde_json::Value =
        serde_json::from_slice(&std::fs::read(t.path().join("reports/quick/fig.json")).unwrap()).unwrap();
    assert_eq!(fig["scalars"]["panel0_points"].as_f64(), Some(ts.len() as f64));
    let svg = std::fs::read_to_string(t.path().join("reports/quick/fig.svg")).unwrap();
    assert!(
        svg.contains("E_0 = 5") && svg.contains("E_0 = 60"),
        "one legend entry per E_0"
    );
}

//! `reports/<profile>/index.html`: opened by the chapter's headline results and the
//! ledger's counts per kind (`super::ledger`, from the one evaluation of
//! `stages/ledger.yaml`), then the "error vs run time" table (from `wp-summary`), then every
//! produced figure in the chapter's order with its caption and the ledger rows judged on
//! it (with numbers), each section closed by its ledger table, and the input checks listed
//! apart; rebuilt from the published `ID.json` / `ID.record.json` files after each run.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::Path;

use serde_json::Value;

use super::ledger::{esc, opening, rows_table, section_index};
use crate::claims::judge::Judged;

fn num(v: &Value) -> String {
    match v.as_f64() {
        Some(x) if x != 0.0 && (x.abs() < 1e-3 || x.abs() >= 1e5) => format!("{x:.4e}"),
        Some(x) => format!("{x:.4}"),
        None => "—".into(),
    }
}

/// Where a stage sits in the chapter: (section, order key). Figures and tables by their
/// number, tables at their first mention (table 4.1 before figure 4.1, 4.2 after figure
/// 4.2, 4.3 after figure 4.3); other stages after the figures of their section, in the
/// pipeline's order (`pos`).
fn chapter_place(id: &str, pos: usize) -> (usize, (u64, u64, String, usize)) {
    let num = |rest: &str| -> Option<(u64, String)> {
        let d: String = rest.chars().take_while(|c| c.is_ascii_digit()).collect();
        d.parse().ok().map(|n| (n, rest[d.len()..].to_string()))
    };
    let section_of_fig = |n: u64| {
        if n <= 14 {
            0
        } else if n <= 22 {
            1
        } else {
            2
        }
    };
    if let Some((n, suffix)) = id.strip_prefix("fig4-").and_then(num) {
        return (section_of_fig(n), (n, 0, suffix, pos));
    }
    if let Some((n, _)) = id.strip_prefix("tab4-").and_then(num) {
        let after = match n {
            1 => 0,
            k => k,
        };
        return (0, (after, 1, String::new(), pos));
    }
    let section = if id.starts_with("wp-") {
        3
    } else if id.contains("pile") || id.contains("-cd") || id.ends_with("cd") {
        2
    } else if id.contains("loose") || id.contains("dense") {
        1
    } else {
        0
    };
    (section, (u64::MAX, 2, String::new(), pos))
}

const SECTIONS: [&str; 4] = [
    "4.2 Granular column collapse",
    "4.3 Role of initial grain properties",
    "4.4 Slopes subjected to horizontal excitation",
    "Numerics: work-precision",
];

use super::measured::pct;

/// The profile's measured error and cost per method, from the atlas stage's published
/// table (`atlas` = (stage id, table name)): method → (setting, error, standard error, wall
/// time of one run).
fn profile_errors(
    dir: &Path,
    atlas: Option<(&str, &str)>,
) -> std::collections::BTreeMap<String, (String, f64, f64, f64)> {
    let text = atlas
        .and_then(|(id, table)| std::fs::read_to_string(dir.join(format!("{id}-{table}.csv"))).ok())
        .unwrap_or_default();
    super::measured::parse_profile_csv(&text)
        .into_iter()
        .map(|(m, e)| (m, (e.setting, e.error, e.error_se, e.wall_s)))
        .collect()
}

/// Rebuild the index of one profile's report directory listing exactly the stages `ids`
/// (the pipeline's stage list) that have published outputs. The page follows the
/// chapter: a claims summary per section, the "error vs run time" table (one row per
/// figure: its method's measured error at the profile's setting and the wall time of one
/// run there, read from the `wp-summary` stage), every figure and table in chapter order
/// (supporting stages after each section's figures), and the input and consistency
/// checks listed apart at the end.
/// `judged` is the ledger judged on this directory, `paper` on the committed paper results,
/// `atlas` the work-precision atlas stage and the table of its measured errors.
pub fn write_index_of(
    dir: &Path,
    profile: &str,
    ids: &[String],
    judged: Option<&[Judged]>,
    paper: Option<&[Judged]>,
    atlas: Option<(&str, &str)>,
    not_current: &BTreeMap<String, String>,
    methods: &std::collections::HashMap<String, Vec<&'static str>>,
) -> std::io::Result<()> {
    // Nothing judged here nor on the paper results (an on-demand study kept in
    // results/<study>/, or a pipeline without a ledger): no ledger tables, said once.
    let ledgerless = judged.is_none() && paper.is_none();
    let judged = judged.unwrap_or(&[]);
    let ids: Vec<String> = ids
        .iter()
        .filter(|id| dir.join(format!("{id}.json")).exists())
        .cloned()
        .collect();
    let mut placed: Vec<(usize, (u64, u64, String, usize), String)> = ids
        .iter()
        .enumerate()
        .map(|(pos, id)| {
            let (sec, key) = chapter_place(id, pos);
            (sec, key, id.clone())
        })
        .collect();
    placed.sort();
    let perr = profile_errors(dir, atlas);
    let locked_keys = locked_keys(dir);
    let mut h = String::new();
    let _ = write!(
        h,
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>granrepro — {p}</title>\
<style>body{{font-family:sans-serif;max-width:1000px;margin:auto}}table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:3px 6px;font-size:13px}}\
.pass{{color:#17801b}}.fail{{color:#b00020;font-weight:bold}}.unres{{color:#8a5a00}}table.ledger td{{vertical-align:top}}figure{{border-top:1px solid #ddd;padding-top:8px}}</style></head><body>\
<h1>granrepro report — profile <code>{p}</code></h1>\
<p>Regenerated figures and tables of K. Kumar, <i>Multi-scale multiphase modelling of granular flows</i>, PhD thesis, University of Cambridge (2015), chapter 4 (DOI 10.5281/zenodo.160339, CC BY 4.0). Every number below comes from a run of this pipeline at the profile named; the claims ledger compares it with the chapter, each claim once.</p>",
        p = esc(profile)
    );
    // all checks, gathered first
    struct ClaimRow {
        stage: String,
        id: String,
        statement: String,
        paper: Value,
        ours: Value,
        tol: Value,
        pass: bool,
    }
    let mut checks: Vec<ClaimRow> = Vec::new();
    let mut body = String::new();
    let mut ervt = String::new();
    let mut current = usize::MAX;
    for (sec, _, id) in &placed {
        let Ok(res) = std::fs::read(dir.join(format!("{id}.json")))
            .map(|b| serde_json::from_slice::<Value>(&b).unwrap_or(Value::Null))
        else {
            continue;
        };
        let (rec, rec_link) = record_of(dir, id, &locked_keys);
        let row = |c: &Value| ClaimRow {
            stage: id.clone(),
            id: c.get("id").and_then(|v| v.as_str()).unwrap_or("").to_string(),
            statement: c.get("statement").and_then(|v| v.as_str()).unwrap_or("").to_string(),
            paper: c["paper"].clone(),
            ours: c["ours"].clone(),
            tol: c["tolerance"].clone(),
            pass: c.get("pass").and_then(|p| p.as_bool()).unwrap_or(false),
        };
        let stage_measurements: Vec<ClaimRow> = res
            .get("measurements")
            .and_then(|c| c.as_array())
            .map(|a| a.iter().map(row).collect())
            .unwrap_or_default();
        let stage_checks: Vec<ClaimRow> = res
            .get("checks")
            .and_then(|c| c.as_array())
            .map(|a| a.iter().map(row).collect())
            .unwrap_or_default();
        if *sec != current {
            if current != usize::MAX {
                body.push_str(&section_ledger(judged, current));
            }
            current = *sec;
            let _ = write!(body, "<h2 id=\"section-{current}\">{}</h2>", esc(SECTIONS[current]));
        }
        let caption = rec.get("caption").and_then(|c| c.as_str()).unwrap_or("");
        let svg = figure_link(dir, id, &rec);
        let has_svg = svg.is_some();
        // the stage's methods, read off the pipeline's graph (as publishing does): a result
        // carried from the committed store keeps the measured block it was published with,
        // which may predate a change of that block
        let ms: Vec<&str> = if atlas.map(|a| a.0) == Some(id.as_str()) {
            vec![]
        } else {
            methods.get(id).cloned().unwrap_or_default()
        };
        let err_note: Vec<String> = ms
            .iter()
            .filter_map(|m| {
                perr.get(*m).map(|(set, e, se, w)| {
                    format!(
                        "{} error at the {profile} setting ({set}): {} · one run there {:.1} s",
                        m.to_uppercase(),
                        pct(*e, *se),
                        w
                    )
                })
            })
            .collect();
        if has_svg {
            let stage_wall = rec.get("wall_s").and_then(|v| v.as_f64());
            let (e_cell, w_cell) = if err_note.is_empty() {
                (
                    if ms.is_empty() {
                        "— (no simulation: inputs and stated laws)".to_string()
                    } else if perr.is_empty() {
                        "— (wp-summary not run for this profile)".to_string()
                    } else {
                        "— (no work-precision stage for this method)".to_string()
                    },
                    "—".to_string(),
                )
            } else {
                (
                    ms.iter()
                        .filter_map(|m| {
                            perr.get(*m)
                                .map(|(set, e, se, _)| format!("{} {} ({})", m.to_uppercase(), pct(*e, *se), esc(set)))
                        })
                        .collect::<Vec<_>>()
                        .join("; "),
                    ms.iter()
                        .filter_map(|m| {
                            perr.get(*m)
                                .map(|(_, _, _, w)| format!("{} {:.1} s", m.to_uppercase(), w))
                        })
                        .collect::<Vec<_>>()
                        .join("; "),
                )
            };
            let _ = write!(
                ervt,
                "<tr><td><a href=\"#{i}\">{i}</a></td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                esc(profile),
                e_cell,
                w_cell,
                stage_wall.map(|w| format!("{w:.1} s")).unwrap_or_default(),
                i = esc(id)
            );
        }
        let _ = write!(body, "<figure id=\"{i}\"><h3>{i}</h3>", i = esc(id));
        if let Some(why) = not_current.get(id) {
            let _ = write!(
                body,
                "<p class=\"fail\">Not current — {}. Shown as committed; no claim is judged on it (<code>granrepro status --profile {}</code>).</p>",
                esc(why),
                esc(profile)
            );
        }
        if let Some(src) = &svg {
            let _ = write!(
                body,
                "<img src=\"{}\" alt=\"{i}\" style=\"max-width:100%\">",
                esc(src),
                i = esc(id)
            );
        }
        let _ = write!(
            body,
            "<figcaption><p>{}</p><p><small>profile {} · kind {} v{} · wall {} s{} · {} · <a href=\"{i}.json\">scalars</a> · <a href=\"{r}\">run record</a></small></p>",
            esc(caption),
            esc(profile),
            esc(rec.get("kind").and_then(|v| v.as_str()).unwrap_or("?")),
            rec.get("solver_version").map(|v| v.to_string()).unwrap_or_default(),
            rec.get("wall_s")
                .and_then(|v| v.as_f64())
                .map(|w| format!("{w:.2}"))
                .unwrap_or_default(),
            if err_note.is_empty() {
                String::new()
            } else {
                format!(" · {} (wp-summary)", esc(&err_note.join("; ")))
            },
            table_link(dir, id, &rec),
            i = esc(id),
            r = esc(&rec_link)
        );
        if let Some(notes) = rec.get("notes").and_then(|n| n.as_array()) {
            for n in notes {
                let _ = write!(body, "<p><small>{}</small></p>", esc(n.as_str().unwrap_or("")));
            }
        }
        // The ledger rows judged on this stage, then its other measurements.
        let here: Vec<&Judged> = judged
            .iter()
            .filter(|j| j.row.measure.all_stages().contains(&id.as_str()))
            .collect();
        if !here.is_empty() {
            body.push_str(&rows_table(&here));
        }
        let unjudged: Vec<String> = stage_measurements
            .iter()
            .filter(|m| {
                !here
                    .iter()
                    .any(|j| j.row.measure.measurement.as_deref() == Some(m.id.as_str()))
            })
            .map(|m| format!("<code>{}</code> = {}", esc(&m.id), num(&m.ours)))
            .collect();
        if !unjudged.is_empty() {
            let _ = write!(
                body,
                "<p><small>Measured here, not judged on this run by the ledger (the ledger judges each sentence once, at the conditions the chapter states it): {}</small></p>",
                unjudged.join(" · ")
            );
        }
        if !stage_checks.is_empty() {
            let failed = stage_checks.iter().filter(|c| !c.pass).count();
            let _ = write!(
                body,
                "<p><small>{} consistency check(s), {failed} failed — listed under <a href=\"#checks\">input and consistency checks</a></small></p>",
                stage_checks.len()
            );
        }
        body.push_str("</figcaption></figure>\n");
        checks.extend(stage_checks);
    }
    if current != usize::MAX {
        body.push_str(&section_ledger(judged, current));
    }
    let (n_check_pass, n_check_fail) = (
        checks.iter().filter(|c| c.pass).count(),
        checks.iter().filter(|c| !c.pass).count(),
    );
    let _ = write!(
        h,
        "<p>{} stages · input and consistency checks (not claims of the chapter): {n_check_pass} ok, {n_check_fail} failed (<a href=\"#checks\">listed at the end</a>){}</p>",
        ids.len(),
        if ledgerless {
            ""
        } else {
            " · every ledger row with its numbers: <a href=\"claims.csv\">claims.csv</a>"
        }
    );
    if ledgerless {
        h.push_str("<p>No claim of the chapter is judged in this report: the claims ledger is judged on a profile's whole run (<code>granrepro claims</code>), and this directory holds an on-demand study or a pipeline without a ledger.</p>");
    } else {
        h.push_str(&opening(judged, profile, paper));
    }
    h.push_str("<h2 id=\"error-vs-run-time\">Error vs run time</h2>");
    let atlas_id = esc(atlas.map(|a| a.0).unwrap_or("wp-summary"));
    if perr.is_empty() {
        let _ = write!(
            h,
            "<p><small>The work-precision atlas (<code>{atlas_id}</code>) has not been run for this profile: no measured errors to show.</small></p>"
        );
    } else {
        let _ = write!(
            h,
            "<p><small>One row per figure: the measured error of its method at the {p} profile's setting (relative to that method's finest setting, ± standard error over an ensemble where one was run) and the wall time of one run at that setting, both read from <a href=\"#{atlas_id}\">{atlas_id}</a>; the last column is the wall time of the figure's own stage.</small></p>",
            p = esc(profile)
        );
    }
    h.push_str("<table><tr><th>figure</th><th>profile</th><th>measured error (setting)</th><th>one run at that setting</th><th>stage wall time</th></tr>");
    h.push_str(&ervt);
    h.push_str("</table>");
    h.push_str(&body);
    h.push_str("<h2 id=\"checks\">Input and consistency checks</h2><p><small>Numbers decided by our inputs and identities (k_n = 4ER, d_max/d_min, energy balance, settling): they show the runs are what they claim to be and are never counted as reproduced claims.</small></p>");
    if !checks.is_empty() {
        h.push_str("<table><tr><th>stage</th><th>check</th><th>statement</th><th>expected</th><th>ours</th><th>tolerance</th><th></th></tr>");
        for c in &checks {
            let _ = write!(
                h,
                "<tr><td><a href=\"#{s}\">{s}</a></td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"{}\">{}</td></tr>",
                esc(&c.id),
                esc(&c.statement),
                num(&c.paper),
                num(&c.ours),
                num(&c.tol),
                if c.pass { "pass" } else { "fail" },
                if c.pass { "ok" } else { "FAIL" },
                s = esc(&c.stage)
            );
        }
        h.push_str("</table>");
    }
    h.push_str("</body></html>\n");
    crate::pipeline::cache::write_atomic(&dir.join("index.html"), h.as_bytes())
}

/// Each stage's cache key in committed results (`lock.json` beside the index; empty in a
/// report directory, which has none).
fn locked_keys(dir: &Path) -> BTreeMap<String, String> {
    let lock: Value = std::fs::read(dir.join("lock.json"))
        .ok()
        .and_then(|b| serde_json::from_slice(&b).ok())
        .unwrap_or(Value::Null);
    lock.get("stages")
        .and_then(Value::as_object)
        .map(|st| {
            st.iter()
                .filter_map(|(id, l)| Some((id.clone(), l.get("key")?.as_str()?.to_string())))
                .collect()
        })
        .unwrap_or_default()
}

/// Stage `id`'s run record and the index's link to it: the published `ID.record.json`, or,
/// in committed results, the store entry's `record.json` (kept once when the two are the
/// same bytes; `crate::pipeline::store`), found by the stage's key in the lock.
fn record_of(dir: &Path, id: &str, keys: &BTreeMap<String, String>) -> (Value, String) {
    let published = format!("{id}.record.json");
    let link = match keys.get(id) {
        Some(k) if !dir.join(&published).exists() => format!("store/{k}/record.json"),
        _ => published,
    };
    let rec = std::fs::read(dir.join(&link))
        .ok()
        .and_then(|b| serde_json::from_slice(&b).ok())
        .unwrap_or(Value::Null);
    (rec, link)
}

/// Where a stage's main table is: its CSV when published beside the index, else (a
/// committed store, whose large tables are kept once, as Parquet) the store entry's
/// `table.parquet`, else nothing.
/// Where the index finds stage `id`'s figure: its published `ID.svg` (or `ID.compact.svg`),
/// or, in committed
/// results, the store's copy (a figure is committed once; the published twin differs only
/// by its footer stamp, which the index's table repeats).
fn figure_link(dir: &Path, id: &str, rec: &Value) -> Option<String> {
    // the published figure, or its compact form (a snapshot over the committed size cap)
    for published in [format!("{id}.svg"), format!("{id}.compact.svg")] {
        if dir.join(&published).exists() {
            return Some(published);
        }
    }
    rec.get("key")
        .and_then(|k| k.as_str())
        .map(|k| format!("store/{k}/figure.svg"))
        .filter(|f| dir.join(f).exists())
}

fn table_link(dir: &Path, id: &str, rec: &Value) -> String {
    if dir.join(format!("{id}.csv")).exists() {
        return format!("<a href=\"{i}.csv\">table (CSV)</a>", i = esc(id));
    }
    let in_store = rec
        .get("key")
        .and_then(|k| k.as_str())
        .map(|k| format!("store/{k}/table.parquet"))
        .filter(|f| dir.join(f).exists());
    match in_store {
        Some(f) => format!("<a href=\"{}\">table (Parquet)</a>", esc(&f)),
        None => "no table".to_string(),
    }
}

/// The ledger rows of section `k`, closing it.
fn section_ledger(judged: &[Judged], k: usize) -> String {
    let rows: Vec<&Judged> = judged.iter().filter(|j| section_index(j) == k).collect();
    if rows.is_empty() || k >= 3 {
        return String::new();
    }
    format!(
        "<h3 id=\"ledger-{k}\">Claims of {}: the ledger</h3>{}",
        esc(SECTIONS[k]),
        rows_table(&rows)
    )
}

#[cfg(test)]
mod tests {
    use std::collections::{BTreeMap, HashMap};

    use super::write_index_of;

    /// The index takes a stage's methods from the pipeline's graph, not from the measured
    /// block the result was published with: a DEM column carried from the committed store
    /// with an older block (no methods listed) read "no simulation" before.
    #[test]
    fn a_carried_result_keeps_the_methods_of_the_graph() {
        let dir = std::env::temp_dir().join(format!("granrepro-index-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let old_block = serde_json::json!({ "stage": "col-dem-a2", "measured": { "source": "wp-summary", "methods": [] } });
        std::fs::write(dir.join("col-dem-a2.json"), old_block.to_string()).unwrap();
        std::fs::write(dir.join("col-dem-a2.record.json"), r#"{"caption":"DEM column","kind":"column-collapse"}"#).unwrap();
        std::fs::write(dir.join("col-dem-a2.svg"), "<svg/>").unwrap();
        let methods = HashMap::from([("col-dem-a2".to_string(), vec!["dem"])]);
        let ids = vec!["col-dem-a2".to_string()];
        write_index_of(&dir, "paper", &ids, None, None, None, &BTreeMap::new(), &methods).unwrap();
        let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(html.contains("wp-summary not run for this profile"), "the DEM stage reads as a simulation");
        assert!(!html.contains("no simulation"), "the stale published block decided the row");
    }
}

//! `reports/<profile>/index.html`: every produced figure with its caption, profile and
//! claim checks (paper value, ours, tolerance, pass/fail), rebuilt from the published
//! `ID.json` / `ID.record.json` files after each run.

use std::fmt::Write;
use std::path::Path;

use serde_json::Value;

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

fn num(v: &Value) -> String {
    match v.as_f64() {
        Some(x) if x != 0.0 && (x.abs() < 1e-3 || x.abs() >= 1e5) => format!("{x:.4e}"),
        Some(x) => format!("{x:.4}"),
        None => "—".into(),
    }
}

/// Rebuild the index of one profile's report directory.
pub fn write_index(dir: &Path, profile: &str) -> std::io::Result<()> {
    let ids: Vec<String> = std::fs::read_dir(dir)?
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| n.ends_with(".json") && !n.ends_with(".record.json"))
        .map(|n| n.trim_end_matches(".json").to_string())
        .collect();
    write_index_of(dir, profile, &ids)
}

/// Rebuild the index of one profile's report directory listing exactly the stages `ids`
/// (the pipeline's stage list) that have published outputs.
pub fn write_index_of(dir: &Path, profile: &str, ids: &[String]) -> std::io::Result<()> {
    let mut ids: Vec<String> = ids.iter().filter(|id| dir.join(format!("{id}.json")).exists()).cloned().collect();
    ids.sort_by(|a, b| natural_key(a).cmp(&natural_key(b)));
    let mut h = String::new();
    let _ = write!(
        h,
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>granrepro — {p}</title>\
<style>body{{font-family:sans-serif;max-width:1000px;margin:auto}}table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:3px 6px;font-size:13px}}\
.pass{{color:#17801b}}.fail{{color:#b00020;font-weight:bold}}figure{{border-top:1px solid #ddd;padding-top:8px}}</style></head><body>\
<h1>granrepro report — profile <code>{p}</code></h1>\
<p>Regenerated figures and tables of K. Kumar, <i>Multi-scale multiphase modelling of granular flows</i>, PhD thesis, University of Cambridge (2015), chapter 4 (DOI 10.5281/zenodo.160339, CC BY 4.0). Every number below comes from a run of this pipeline at the profile named; claims compare it with the chapter.</p>",
        p = esc(profile)
    );
    let (mut n_pass, mut n_fail, mut n_calibrated, mut n_check_pass, mut n_check_fail) = (0, 0, 0, 0, 0);
    let mut body = String::new();
    for id in &ids {
        let Ok(res) = std::fs::read(dir.join(format!("{id}.json"))).map(|b| serde_json::from_slice::<Value>(&b).unwrap_or(Value::Null)) else { continue };
        let rec: Value = std::fs::read(dir.join(format!("{id}.record.json"))).ok().and_then(|b| serde_json::from_slice(&b).ok()).unwrap_or(Value::Null);
        let caption = rec.get("caption").and_then(|c| c.as_str()).unwrap_or("");
        let _ = write!(body, "<figure id=\"{i}\"><h2>{i}</h2>", i = esc(id));
        if dir.join(format!("{id}.svg")).exists() {
            let _ = write!(body, "<img src=\"{i}.svg\" alt=\"{i}\" style=\"max-width:100%\">", i = esc(id));
        }
        let _ = write!(
            body,
            "<figcaption><p>{}</p><p><small>profile {} · kind {} v{} · wall {} s · <a href=\"{i}.csv\">table (CSV)</a> · <a href=\"{i}.json\">scalars</a> · <a href=\"{i}.record.json\">run record</a></small></p>",
            esc(caption),
            esc(profile),
            esc(rec.get("kind").and_then(|v| v.as_str()).unwrap_or("?")),
            rec.get("solver_version").map(|v| v.to_string()).unwrap_or_default(),
            rec.get("wall_s").and_then(|v| v.as_f64()).map(|w| format!("{w:.2}")).unwrap_or_default(),
            i = esc(id)
        );
        if let Some(notes) = rec.get("notes").and_then(|n| n.as_array()) {
            for n in notes {
                let _ = write!(body, "<p><small>{}</small></p>", esc(n.as_str().unwrap_or("")));
            }
        }
        if let Some(claims) = res.get("claims").and_then(|c| c.as_array()).filter(|c| !c.is_empty()) {
            body.push_str("<table><tr><th>claim</th><th>statement</th><th>paper</th><th>ours</th><th>tolerance</th><th>verdict</th></tr>");
            for c in claims {
                let pass = c.get("pass").and_then(|p| p.as_bool()).unwrap_or(false);
                let calibrated = c.get("calibrated").and_then(|p| p.as_bool()).unwrap_or(false);
                if calibrated {
                    n_calibrated += 1;
                } else if pass {
                    n_pass += 1
                } else {
                    n_fail += 1
                }
                let _ = write!(
                    body,
                    "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}{}</td><td>{}</td><td class=\"{}\">{}</td></tr>",
                    esc(c.get("id").and_then(|v| v.as_str()).unwrap_or("")),
                    esc(c.get("statement").and_then(|v| v.as_str()).unwrap_or("")),
                    num(&c["paper"]),
                    num(&c["ours"]),
                    if calibrated { " <b>(calibrated)</b>" } else { "" },
                    num(&c["tolerance"]),
                    if pass { "pass" } else { "fail" },
                    match (pass, calibrated) {
                        (true, false) => "pass",
                        (false, false) => "FAIL",
                        (true, true) => "pass — calibrated, not a reproduction",
                        (false, true) => "FAIL — calibrated",
                    }
                );
            }
            body.push_str("</table>");
        }
        if let Some(checks) = res.get("checks").and_then(|c| c.as_array()).filter(|c| !c.is_empty()) {
            body.push_str("<details><summary><small>consistency checks (inputs and identities; not claims)</small></summary><table><tr><th>check</th><th>statement</th><th>expected</th><th>ours</th><th>tolerance</th><th></th></tr>");
            for c in checks {
                let pass = c.get("pass").and_then(|p| p.as_bool()).unwrap_or(false);
                if pass { n_check_pass += 1 } else { n_check_fail += 1 }
                let _ = write!(
                    body,
                    "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"{}\">{}</td></tr>",
                    esc(c.get("id").and_then(|v| v.as_str()).unwrap_or("")),
                    esc(c.get("statement").and_then(|v| v.as_str()).unwrap_or("")),
                    num(&c["paper"]),
                    num(&c["ours"]),
                    num(&c["tolerance"]),
                    if pass { "pass" } else { "fail" },
                    if pass { "ok" } else { "FAIL" }
                );
            }
            body.push_str("</table></details>");
        }
        body.push_str("</figcaption></figure>\n");
    }
    let _ = write!(
        h,
        "<p>{} stages · <b>claims of the chapter: {n_pass} reproduced, {n_fail} not reproduced</b>, {n_calibrated} rest on a calibrated parameter (not counted) · consistency checks (inputs, identities; not claims): {n_check_pass} ok, {n_check_fail} failed</p>",
        ids.len()
    );
    h.push_str(&body);
    h.push_str("</body></html>\n");
    crate::pipeline::cache::write_atomic(&dir.join("index.html"), h.as_bytes())
}

/// Sort key that orders `fig4-2` before `fig4-10`.
fn natural_key(s: &str) -> Vec<(String, u64)> {
    let mut out = Vec::new();
    let mut text = String::new();
    let mut digits = String::new();
    for c in s.chars() {
        if c.is_ascii_digit() {
            digits.push(c);
        } else {
            if !digits.is_empty() {
                out.push((std::mem::take(&mut text), digits.parse().unwrap_or(0)));
                digits.clear();
            }
            text.push(c);
        }
    }
    out.push((text, digits.parse().unwrap_or(0)));
    out
}

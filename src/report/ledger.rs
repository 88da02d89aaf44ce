//! The ledger's part of the report: the headline table the index opens with, the counts
//! per kind, one table of judged rows per chapter section, the rows beside each figure,
//! and `claims.json` / `claims.csv` (every row with its numbers) next to the index.

use std::fmt::Write;
use std::path::Path;

use crate::claims::Kind;
use crate::claims::judge::{Judged, Verdict, counts, headlines};

/// `s` escaped for HTML text and attributes (the report's one escaper).
pub(crate) fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A number with 4 significant digits, or "—".
pub fn n4(x: f64) -> String {
    if !x.is_finite() {
        "—".into()
    } else if x != 0.0 && (x.abs() < 1e-3 || x.abs() >= 1e5) {
        format!("{x:.3e}")
    } else {
        // four significant digits, trailing zeros dropped
        let decimals = if x == 0.0 {
            0
        } else {
            (3 - x.abs().log10().floor() as i32).clamp(0, 6) as usize
        };
        trim(format!("{x:.decimals$}"))
    }
}

fn trim(s: String) -> String {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// A value and its spread (sd or s.e.), the spread to two significant digits and the value
/// to the same decimal place: `36.51 ± 0.64`, `1.356 ± 0.062`. Very large or small values,
/// and a zero or non-finite spread, fall back to [`n4`] for each.
pub fn with_spread(x: f64, spread: f64) -> String {
    let plain = || format!("{} ± {}", n4(x), n4(spread));
    if !(x.is_finite() && spread.is_finite() && spread > 0.0) || (x != 0.0 && (x.abs() < 1e-3 || x.abs() >= 1e5)) {
        return plain();
    }
    let decimals = 1 - spread.log10().floor() as i32;
    if !(0..=6).contains(&decimals) {
        return plain();
    }
    let d = decimals as usize;
    format!("{x:.d$} ± {spread:.d$}")
}

fn class(v: Verdict) -> &'static str {
    match v {
        Verdict::Reproduced => "pass",
        Verdict::Missed | Verdict::NoMeasurement => "fail",
        Verdict::NotResolved | Verdict::NotRun => "unres",
    }
}

/// The chapter's value as stated: `22.2 ± 0.2`, `≥ 1`, `50–55`.
fn paper_cell(j: &Judged) -> String {
    use crate::claims::Tolerance::*;
    let r = &j.row;
    match (&r.tolerance, r.stated) {
        (_, Some(pm)) => format!("{} ± {}", n4(r.paper), n4(pm)),
        (AtLeast(b), _) => format!("≥ {}", n4(*b)),
        (AtMost(b), _) => format!("≤ {}", n4(*b)),
        (Range(lo, hi), _) => format!("{}–{}", n4(*lo), n4(*hi)),
        _ => n4(r.paper),
    }
}

fn tol_cell(j: &Judged) -> String {
    use crate::claims::Tolerance::*;
    match &j.row.tolerance {
        Abs(t) => format!("± {}", n4(*t)),
        Rel(r) => format!("± {:.0} % ({})", r * 100.0, n4(r * j.paper.abs())),
        AtLeast(_) | AtMost(_) => "bound".into(),
        Range(lo, hi) => format!("{}–{}", n4(*lo), n4(*hi)),
    }
}

/// Ours: mean ± sd (n), or the single value (± fit s.e.).
/// Ours as plain text: mean ± sd (n) for an ensemble, ± s.e. for a fit, "(n = 1)" for one
/// member of a chaotic output, "—" when not run.
pub fn ours_text(j: &Judged) -> String {
    if j.values.is_empty() {
        return "—".into();
    }
    match (j.sd, j.se) {
        (Some(sd), _) => format!("{} (sd, n = {})", with_spread(j.mean, sd), j.values.len()),
        (None, Some(se)) if se > 0.0 => format!("{} (s.e.)", with_spread(j.mean, se)),
        (None, None) => format!("{} (n = 1)", n4(j.mean)),
        _ => n4(j.mean),
    }
}

fn ours_cell(j: &Judged) -> String {
    let cal = if j.calibrated.is_empty() || j.values.is_empty() {
        ""
    } else {
        " <b title=\"rests on a tuned value\">(calibrated)</b>"
    };
    format!("{}{cal}", esc(&ours_text(j)))
}

fn verdict_cell(j: &Judged) -> String {
    let mut s = format!("<span class=\"{}\">{}</span>", class(j.verdict), j.verdict.name());
    if !j.note.is_empty() && j.verdict != Verdict::Reproduced {
        let _ = write!(s, "<br><small>{}</small>", esc(&j.note));
    }
    if matches!(j.verdict, Verdict::Missed | Verdict::NotResolved)
        && let Some(d) = &j.row.diagnosis
    {
        let _ = write!(s, "<br><small><i>why:</i> {}</small>", esc(d));
    }
    s.push_str(&not_comparable(j));
    s
}

/// The mark of a row whose scene this profile runs too small to compare with the chapter.
fn not_comparable(j: &Judged) -> String {
    if !j.not_comparable_here() {
        return String::new();
    }
    format!(
        "<br><small class=\"reduced\"><b>not comparable with the chapter at this size</b>: {} (<a href=\"#reduced\">why</a>)</small>",
        esc(&scenes(j).join(", "))
    )
}

fn scenes(j: &Judged) -> Vec<String> {
    j.not_comparable.iter().map(|n| n.scene.clone()).collect()
}

/// The reduced scenes the rows are judged on, each once with its reason (empty: none).
fn reduced_paragraph(j: &[Judged], profile: &str) -> String {
    let mut seen: Vec<&crate::claims::judge::NotComparable> = Vec::new();
    for n in j
        .iter()
        .filter(|x| !x.values.is_empty())
        .flat_map(|x| x.not_comparable.iter())
    {
        if !seen.iter().any(|s| s.scene == n.scene) {
            seen.push(n);
        }
    }
    if seen.is_empty() {
        return String::new();
    }
    let rows = j.iter().filter(|x| x.not_comparable_here()).count();
    let mut h = format!(
        "<div id=\"reduced\" style=\"border-left:4px solid #b00020;padding:2px 10px;margin:8px 0\"><p><b>Not the chapter's verdicts.</b> The {p} profile runs these scenes too small to set against the chapter; the {rows} rows judged on them (marked <i>not comparable at this size</i>) test the pipeline, not the chapter. The paper profile runs them at the chapter's size (the column <i>ours (paper)</i>).</p><ul>",
        p = esc(profile)
    );
    for n in seen {
        let _ = write!(h, "<li><b>{}</b>: {}</li>", esc(&n.scene), esc(&n.why));
    }
    h.push_str("</ul></div>");
    h
}

/// The rows' table (section tables and beside figures).
pub fn rows_table(rows: &[&Judged]) -> String {
    let mut h = String::from(
        "<table class=\"ledger\"><tr><th>claim</th><th>the chapter</th><th>kind · method</th><th>chapter's value</th><th>tolerance</th><th>ours</th><th>verdict</th></tr>",
    );
    for j in rows {
        let cal = if j.calibrated.is_empty() {
            String::new()
        } else {
            format!(
                "<br><small><b>calibrated:</b> {}</small>",
                esc(&j.calibrated.join("; "))
            )
        };
        let reading = j
            .row
            .reading
            .as_deref()
            .map(|r| format!("<br><small><i>reading:</i> {}</small>", esc(r)))
            .unwrap_or_default();
        let _ = write!(
            h,
            "<tr id=\"claim-{id}\"><td><code>{id}</code><br><small>§{}</small></td><td>{}<br><small><i>measured:</i> {} — <code>{}</code></small>{reading}{cal}</td><td>{} · {}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(&j.row.section),
            esc(&j.row.chapter),
            esc(&j.row.measured),
            esc(&j.row.measure.label()),
            j.kind,
            esc(&j.row.method),
            paper_cell(j),
            tol_cell(j),
            ours_cell(j),
            verdict_cell(j),
            id = esc(&j.id),
        );
    }
    h.push_str("</table>");
    h
}

/// The index's opening: the headline table, then the counts per kind and verdict.
/// `paper` is the ledger judged on the committed paper results, when they exist.
pub fn opening(j: &[Judged], profile: &str, paper: Option<&[Judged]>) -> String {
    let mut h = String::new();
    h.push_str("<h2 id=\"headline\">The chapter's headline results</h2><p><small>One row per principal result of §4.2–4.4, judged once in the claims ledger (<code>stages/ledger.yaml</code>). A row with several parts (two aspect ratios, two methods) is reproduced only if every part is. <i>Reproduced</i>: the mean is within the tolerance and 2 s.e. &lt; tolerance; <i>not resolved</i>: the uncertainty is as large as the tolerance, or a chaotic output has one member (its spread unknown); <i>missed</i> otherwise. The tolerance is the chapter's ± where it states one, else 15 %; it is never widened by the spread. <b>calibrated</b>: rests on a tuned value.</small></p>");
    h.push_str(&reduced_paragraph(j, profile));
    let _ = write!(
        h,
        "<table class=\"ledger\"><tr><th>result</th><th>the chapter</th><th>chapter's value</th><th>ours ({p})</th>{paper_col}<th>verdict ({p})</th><th>if missed or not resolved: why</th></tr>",
        p = esc(profile),
        // the paper profile's own report has no second paper column
        paper_col = if profile == "paper" {
            ""
        } else {
            "<th>ours (paper, committed and fresh)</th>"
        }
    );
    let paper_of = |id: &str| paper.and_then(|p| p.iter().find(|x| x.id == id));
    for hl in headlines(j) {
        let parts = &hl.parts;
        let cell =
            |f: &dyn Fn(&Judged) -> String| -> String { parts.iter().map(|p| f(p)).collect::<Vec<_>>().join("<br>") };
        let label = |p: &Judged| -> String {
            if parts.len() > 1 {
                format!("<small>{}:</small> ", esc(&p.id))
            } else {
                String::new()
            }
        };
        let mut why: Vec<String> = parts
            .iter()
            .filter(|p| {
                matches!(p.verdict, Verdict::Missed | Verdict::NotResolved)
                    || (p.verdict == Verdict::NotRun && !p.note.is_empty())
            })
            .map(|p| {
                let mut s = String::new();
                if parts.len() > 1 {
                    let _ = write!(s, "{}: ", esc(&p.id));
                }
                s.push_str(p.verdict.name());
                if !p.note.is_empty() {
                    let _ = write!(s, " ({})", esc(&p.note));
                }
                // a diagnosis explains a verdict; a row not run has none to explain
                if let Some(d) = p.row.diagnosis.as_ref().filter(|_| p.verdict != Verdict::NotRun) {
                    let _ = write!(s, " — {}", esc(d));
                }
                s
            })
            .collect();
        // Once per headline: the scenes too small here (the reasons are above the table).
        let mut reduced: Vec<String> = Vec::new();
        for p in parts.iter().filter(|p| !p.values.is_empty()) {
            for s in scenes(p) {
                if !reduced.contains(&s) {
                    reduced.push(s);
                }
            }
        }
        if !reduced.is_empty() {
            why.push(format!(
                "<b>not comparable at the {} size</b>: {} (<a href=\"#reduced\">why</a>)",
                esc(profile),
                esc(&reduced.join(", "))
            ));
        }
        let _ = write!(
            h,
            "<tr><td><a href=\"#claim-{first}\"><b>{id}</b></a><br><small>§{sec} · {method}</small></td><td><small>{chapter}</small></td><td>{paper}</td><td>{ours}</td>{ours_paper}<td>{verdict}</td><td><small>{why}</small></td></tr>",
            first = esc(&parts[0].id),
            id = esc(&hl.id),
            sec = esc(&parts[0].row.section),
            method = esc(&parts[0].row.method),
            chapter = esc(&parts[0].row.chapter),
            paper = cell(&|p| format!("{}{}", label(p), paper_cell(p))),
            ours = cell(&|p| format!("{}{}", label(p), ours_cell(p))),
            ours_paper = if profile == "paper" {
                String::new()
            } else if parts
                .iter()
                .any(|p| paper_of(&p.id).is_some_and(|q| !q.values.is_empty()))
            {
                let c = cell(&|p| match paper_of(&p.id) {
                    Some(q) if !q.values.is_empty() => format!("{}{} ({})", label(p), ours_cell(q), q.verdict.name()),
                    _ => format!("{}not run yet", label(p)),
                });
                format!("<td>{c}</td>")
            } else {
                "<td>not run yet</td>".to_string()
            },
            verdict = format!(
                "<span class=\"{}\">{}</span>{}",
                class(hl.verdict),
                hl.verdict.name(),
                if parts.iter().any(|p| p.not_comparable_here()) {
                    "<br><small class=\"reduced\"><b>not comparable at this size</b></small>"
                } else {
                    ""
                }
            ),
            why = why.join("<br>"),
        );
    }
    h.push_str("</table>");
    // counts per kind
    let c = counts(j);
    let get = |k: Kind, v: Verdict| c.get(&(k, v)).copied().unwrap_or(0);
    let cal = |k: Kind| j.iter().filter(|x| x.row.kind == k && !x.calibrated.is_empty()).count();
    let reduced = |k: Kind| j.iter().filter(|x| x.row.kind == k && x.not_comparable_here()).count();
    h.push_str("<h2 id=\"counts\">Every claim of the ledger, counted by kind</h2><table><tr><th>kind</th><th>rows</th><th>reproduced</th><th>missed</th><th>not resolved</th><th>not run</th><th>of which rest on a tuned value (calibrated)</th><th>of which judged on a scene too small to compare with the chapter</th></tr>");
    for (k, what) in [
        (Kind::Quantitative, "quantitative (a number of the chapter)"),
        (Kind::Qualitative, "qualitative (a direction only)"),
        (Kind::Check, "check (a number our inputs decide)"),
    ] {
        let total = j.iter().filter(|x| x.row.kind == k).count();
        let _ = write!(
            h,
            "<tr><td>{what}</td><td>{total}</td><td class=\"pass\">{}</td><td class=\"fail\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            get(k, Verdict::Reproduced),
            get(k, Verdict::Missed) + get(k, Verdict::NoMeasurement),
            get(k, Verdict::NotResolved),
            get(k, Verdict::NotRun),
            cal(k),
            reduced(k)
        );
    }
    h.push_str("</table>");
    h
}

/// The section (0: §4.2, 1: §4.3, 2: §4.4) of a ledger row.
pub fn section_index(j: &Judged) -> usize {
    let s = j.row.section.as_str();
    if s.starts_with("4.3") {
        1
    } else if s.starts_with("4.4") {
        2
    } else {
        0
    }
}

/// `claims.json` and `claims.csv` beside the index.
pub fn write_files(dir: &Path, j: &[Judged]) -> std::io::Result<()> {
    let json = serde_json::to_vec_pretty(j).map_err(std::io::Error::other)?;
    crate::pipeline::cache::write_atomic(&dir.join("claims.json"), &json)?;
    let mut csv = String::from("id,kind,section,method,paper,mean,sd,se,n,tolerance,verdict,calibrated,measure\n");
    let q = |s: &str| format!("\"{}\"", s.replace('"', "\"\""));
    let f = |x: Option<f64>| {
        x.filter(|v| v.is_finite())
            .map(|v| format!("{v:e}"))
            .unwrap_or_default()
    };
    for x in j {
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{},{},{},{},{},{},{}",
            q(&x.id),
            x.kind,
            q(&x.row.section),
            q(&x.row.method),
            f(Some(x.paper)),
            f(Some(x.mean)),
            f(x.sd),
            f(x.se),
            x.values.len(),
            f(Some(x.tolerance)),
            x.verdict.name(),
            !x.calibrated.is_empty(),
            q(&x.row.measure.label())
        );
    }
    crate::pipeline::cache::write_atomic(&dir.join("claims.csv"), csv.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn single_values_keep_four_significant_digits() {
        assert_eq!(n4(19.5989), "19.6");
        assert_eq!(n4(1.9059), "1.906");
        assert_eq!(n4(-0.0373), "-0.0373");
        assert_eq!(n4(0.12345), "0.1235");
        assert_eq!(n4(22.2), "22.2");
        assert_eq!(n4(3.0), "3");
        assert_eq!(n4(0.0), "0");
        assert_eq!(n4(1.98e6), "1.980e6");
        assert_eq!(n4(f64::NAN), "—");
    }

    #[test]
    fn a_spread_has_two_significant_digits_and_the_value_its_decimals() {
        assert_eq!(with_spread(36.506, 0.6368), "36.51 ± 0.64");
        assert_eq!(with_spread(1.356, 0.0621), "1.356 ± 0.062");
        assert_eq!(with_spread(52.8436, 1.1842), "52.8 ± 1.2");
        assert_eq!(with_spread(1200.0, 35.0), "1200 ± 35");
        assert_eq!(with_spread(0.0, 0.0), "0 ± 0");
        assert_eq!(with_spread(2.158e5, 1e3), "2.158e5 ± 1000");
    }
}

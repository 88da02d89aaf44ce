//! The profile's measured error and cost beside every figure (issue 12): one mechanism for
//! every stage kind. The `wp-summary` stage's `profile` table holds, per method (DEM, MPM,
//! CD), the relative error of the setting the profile's figures use against that method's
//! finest setting (± standard error where an ensemble was run) and the wall time of one
//! run there. When a stage is published, its figures get one footer line and its
//! `ID.json` a `measured` block with those numbers for the stage's method(s) — stamped on
//! what is published, never on the cache entry, so no stage's cache key depends on the
//! atlas. The stage's own wall time stays in its run record (`ID.record.json`, shown on
//! the report page): a figure of a stage with no simulation behind it stays bit-identical
//! across runs; one with a method carries that method's one-run wall time, fixed by the
//! `wp-summary` cache entry it was read from.

use std::collections::BTreeMap;

use serde_json::{Value, json};

/// One method's measured error at the profile's setting.
#[derive(Debug, Clone, PartialEq)]
pub struct MethodError {
    /// The work-precision setting that stands for the profile (`k0.01-dt0.05`, …).
    pub setting: String,
    /// Relative error against the finest setting.
    pub error: f64,
    /// Its standard error (NaN: a single deterministic run).
    pub error_se: f64,
    /// Wall time of one run at the setting [s].
    pub wall_s: f64,
}

/// Method → its measured error.
pub type ProfileErrors = BTreeMap<String, MethodError>;

/// Parse the `wp-summary` stage's `profile` table (CSV: method, setting, …, rel_error,
/// rel_error_se, wall_s).
pub fn parse_profile_csv(text: &str) -> ProfileErrors {
    let mut out = ProfileErrors::new();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap_or("").split(',').collect();
    let col = |k: &str| head.iter().position(|h| *h == k);
    let (Some(m), Some(s), Some(e), Some(se), Some(w)) = (
        col("method"),
        col("setting"),
        col("rel_error"),
        col("rel_error_se"),
        col("wall_s"),
    ) else {
        return out;
    };
    for l in lines {
        let f: Vec<&str> = l.split(',').collect();
        let x = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(f64::NAN);
        if let (Some(mm), Some(ss)) = (f.get(m), f.get(s)) {
            out.insert(
                mm.to_string(),
                MethodError {
                    setting: ss.to_string(),
                    error: x(e),
                    error_se: x(se),
                    wall_s: x(w),
                },
            );
        }
    }
    out
}

/// "7.3 ± 9.4 %" (or "5.2 %" without a spread). A spread under 0.05 % keeps its first
/// significant digit ("6.0 ± 0.02 %"): an ensemble whose members nearly agree is not one
/// with no spread.
pub fn pct(e: f64, se: f64) -> String {
    if !e.is_finite() {
        return "—".into();
    }
    if se.is_finite() {
        let s = 100.0 * se;
        let digits = if s > 0.0 && s < 0.05 {
            ((-s.log10()).ceil() as usize).min(6)
        } else {
            1
        };
        format!("{:.1} ± {:.*} %", 100.0 * e, digits, s)
    } else {
        format!("{:.1} %", 100.0 * e)
    }
}

/// The footer line of a stage's figures: its methods' measured errors and one-run wall
/// times at the profile's setting.
pub fn footer_line(profile: &str, ms: &[&str], errs: &ProfileErrors) -> String {
    let parts: Vec<String> = ms
        .iter()
        .filter_map(|m| {
            errs.get(*m).map(|e| {
                format!(
                    "{} error {} at {}, the setting standing for the {profile} profile (one run {:.1} s)",
                    m.to_uppercase(),
                    pct(e.error, e.error_se),
                    e.setting,
                    e.wall_s
                )
            })
        })
        .collect();
    if parts.is_empty() {
        if ms.is_empty() {
            "measured error: — (no simulation)".to_string()
        } else {
            "measured error: — (wp-summary not run for this profile)".to_string()
        }
    } else {
        format!("measured (wp-summary): {}", parts.join("; "))
    }
}

/// The `measured` block of a stage's published `ID.json`: every method the stage runs, with
/// its measured error where the atlas has one (null fields where it has none, so a reader
/// still sees that a simulation stands behind the stage).
pub fn json_block(profile: &str, ms: &[&str], errs: &ProfileErrors) -> Value {
    let per: Vec<Value> = ms
        .iter()
        .map(|m| {
            let e = errs.get(*m);
            json!({
                "method": m,
                "setting": e.map(|e| &e.setting),
                "rel_error": e.map(|e| e.error),
                "rel_error_se": e.map(|e| e.error_se),
                "one_run_wall_s": e.map(|e| e.wall_s),
            })
        })
        .collect();
    json!({ "source": "wp-summary", "profile": profile, "methods": per })
}

/// Add one footer line under an SVG figure: the canvas grows by 16 px (root `height` and
/// `viewBox`), the line is drawn in the new strip. An SVG whose root tag cannot be read is
/// returned unchanged.
pub fn stamp_svg(bytes: Vec<u8>, line: &str) -> Vec<u8> {
    let Ok(text) = String::from_utf8(bytes.clone()) else {
        return bytes;
    };
    let Some(start) = text.find("<svg") else { return bytes };
    let Some(len) = text[start..].find('>') else {
        return bytes;
    };
    let tag = &text[start..start + len];
    let attr = |name: &str| -> Option<(usize, usize, String)> {
        let key = format!(" {name}=\"");
        let a = tag.find(&key)? + key.len();
        let b = a + tag[a..].find('"')?;
        Some((a, b, tag[a..b].to_string()))
    };
    let (Some((ha, hb, h)), Some((va, vb, vb_text))) = (attr("height"), attr("viewBox")) else {
        return bytes;
    };
    let (Ok(height), vb_nums) = (
        h.parse::<f64>(),
        vb_text
            .split_whitespace()
            .map(|v| v.parse::<f64>())
            .collect::<Result<Vec<f64>, _>>(),
    ) else {
        return bytes;
    };
    let Ok(vbn) = vb_nums else { return bytes };
    if vbn.len() != 4 {
        return bytes;
    }
    // font-size 10 sans-serif: about 5.6 px per character; wrapped inside the width
    let lines = super::plot::wrap_words(line, ((vbn[2] - 20.0).max(100.0) / 5.6) as usize);
    let strip = 16.0 + 13.0 * (lines.len().max(1) - 1) as f64;
    // the lines sit in the viewBox's coordinates, below its old bottom
    let y0 = vbn[1] + vbn[3];
    let mut new_tag = tag.to_string();
    // replace the later attribute first so the earlier offsets stay valid
    let mut edits = [
        (ha, hb, format!("{}", height + strip)),
        (va, vb, format!("{} {} {} {}", vbn[0], vbn[1], vbn[2], vbn[3] + strip)),
    ];
    edits.sort_by(|a, b| b.0.cmp(&a.0));
    for (a, b, v) in edits {
        new_tag.replace_range(a..b, &v);
    }
    let Some(end) = text.rfind("</svg>") else { return bytes };
    let esc = |s: &str| s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;");
    let mut out = String::with_capacity(text.len() + 400);
    out.push_str(&text[..start]);
    out.push_str(&new_tag);
    out.push_str(&text[start + len..end]);
    out.push_str(&format!(
        "<rect x=\"{x}\" y=\"{y0}\" width=\"{w}\" height=\"{strip}\" fill=\"#FFFFFF\" stroke=\"none\"/>\n",
        x = vbn[0],
        w = vbn[2],
    ));
    for (i, l) in lines.iter().enumerate() {
        out.push_str(&format!(
            "<text x=\"{tx}\" y=\"{ty}\" font-family=\"sans-serif\" font-size=\"10\" fill=\"#5A5A5A\">{}</text>\n",
            esc(l),
            tx = vbn[0] + 10.0,
            ty = y0 + 12.0 + 13.0 * i as f64,
        ));
    }
    out.push_str(&text[end..]);
    out.into_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stamp_grows_the_canvas_and_adds_the_line() {
        let svg = "<svg width=\"760\" height=\"520\" viewBox=\"0 0 760 520\" xmlns=\"http://www.w3.org/2000/svg\">\n<rect/>\n</svg>\n".as_bytes().to_vec();
        let out = String::from_utf8(stamp_svg(svg, "DEM error 7.3 ± 9.4 % <x>")).unwrap();
        assert!(
            out.starts_with("<svg width=\"760\" height=\"536\" viewBox=\"0 0 760 536\""),
            "{out}"
        );
        assert!(out.contains(">DEM error 7.3 ± 9.4 % &lt;x&gt;</text>\n</svg>"), "{out}");
        assert!(out.contains("y=\"532\""), "{out}");
        // snapshot figures write xmlns first and fractional sizes
        let svg = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"900\" height=\"410\" viewBox=\"0 0 900.0 410.5\">\n</svg>".as_bytes().to_vec();
        let out = String::from_utf8(stamp_svg(svg, "l")).unwrap();
        assert!(out.contains("height=\"426\" viewBox=\"0 0 900 426.5\""), "{out}");
        // not an SVG we can read: unchanged
        assert_eq!(stamp_svg(b"<svg>".to_vec(), "l"), b"<svg>".to_vec());
        // a line longer than the figure is wide wraps inside it (fig4-33's ran off the edge)
        let svg = "<svg width=\"300\" height=\"100\" viewBox=\"0 0 300 100\">\n</svg>"
            .as_bytes()
            .to_vec();
        let long = "measured (wp-summary): CD error 3.8 ± 3.9 % at dt1e-4-tol1e-4; DEM error 7.3 ± 9.4 %";
        let out = String::from_utf8(stamp_svg(svg, long)).unwrap();
        let texts: Vec<&str> = out.split("<text").skip(1).collect();
        assert!(texts.len() >= 2, "{out}");
        assert!(out.contains("height=\"129\""), "{out}");
        for t in texts {
            let body = t.split('>').nth(1).unwrap().split('<').next().unwrap();
            assert!(body.chars().count() as f64 * 5.6 <= 280.0, "{body}");
        }
    }

    #[test]
    fn profile_table_gives_the_line() {
        let errs = parse_profile_csv(
            "method,setting,quantity,rel_error,rel_error_se,wall_s\ndem,k0.01-dt0.05,runout,0.073,0.094,10.8\nmpm,ppc4-h2mm-C0.5,runout,0.052,,1.7\n",
        );
        assert_eq!(errs["dem"].setting, "k0.01-dt0.05");
        assert!(errs["mpm"].error_se.is_nan());
        let l = footer_line("quick", &["dem"], &errs);
        assert_eq!(
            l,
            "measured (wp-summary): DEM error 7.3 ± 9.4 % at k0.01-dt0.05, the setting standing for the quick profile (one run 10.8 s)"
        );
        assert_eq!(footer_line("quick", &[], &errs), "measured error: — (no simulation)");
        // A method without a measurement is still listed (the index must not read it as
        // "no simulation": every paper stage did before wp-summary ran).
        let j = json_block("paper", &["cd"], &errs);
        assert_eq!(j["methods"][0]["method"], json!("cd"));
        assert!(j["methods"][0]["rel_error"].is_null());
        let j = json_block("quick", &["mpm"], &errs);
        assert_eq!(j["methods"][0]["rel_error"], json!(0.052));
        assert!(j["methods"][0]["rel_error_se"].is_null());
    }

    /// The quick MPM's error, 6.0 % with a s.e. of 0.018 %, was shown "± 0.0 %", as if the
    /// ensemble had no spread.
    #[test]
    fn a_small_spread_keeps_its_first_digit() {
        assert_eq!(pct(0.0601, 1.846e-4), "6.0 ± 0.02 %");
        assert_eq!(pct(0.073, 0.094), "7.3 ± 9.4 %");
        assert_eq!(pct(0.052, f64::NAN), "5.2 %");
        assert_eq!(pct(0.052, 0.0), "5.2 ± 0.0 %");
        assert_eq!(pct(0.05, 4.0e-6), "5.0 ± 0.0004 %");
    }
}

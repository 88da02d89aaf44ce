//! A compact form of a particle snapshot figure, for the committed results (issue 28:
//! "commit snapshot figures in a compact form").
//!
//! A snapshot panel draws one marker per grain or material point: a `<circle>` (grains)
//! or a square `<rect>` (points), each 50–70 bytes, so a 13,000-grain figure of six panels
//! is 4–5 MB. The compact form draws the same markers as one `<path>` per marker size and
//! colour, each marker a zero-length segment (`M x y h0`) whose round (circle) or square
//! (rect) cap of the marker's width paints the same disk or square (SVG 2, §13.5.5: a
//! zero-length subpath with round or square caps is painted). Centres are kept to a tenth of
//! a pixel (the drawing's 0.01, rounded: invisible at the figure's size), the first of each
//! path absolute and the others as moves from the one before: about 9–12 bytes per marker.
//! The paths of one marker size sit in one `<g>` that carries the fill, width and cap, so a
//! path writes only its colour: a colour-mapped field has hundreds of colours per panel.
//!
//! What changes: within one run of consecutive markers, the markers of one colour are
//! painted together, so where two markers of different colours overlap, which one is on top
//! may differ. Everything else (axes, labels, colour bars, the order of markers against
//! other elements) is copied line for line. The figure's source is unchanged: this is a
//! derived file, written by `granrepro keep` in place of a published figure over the size
//! cap, and named as compact in the lock.

use std::collections::HashMap;
use std::fmt::Write;

/// A marker parsed from one line of plotters' SVG output.
#[derive(Debug, Clone, PartialEq)]
struct Marker {
    /// Centre [px].
    x: f64,
    y: f64,
    /// Cap style: "round" (circle) or "square" (square rect).
    cap: &'static str,
    /// Stroke width = diameter or side [px], as written.
    width: String,
    /// Fill colour, as written.
    fill: String,
}

/// The value of attribute `name` in an element's text.
fn attr<'a>(line: &'a str, name: &str) -> Option<&'a str> {
    let key = format!(" {name}=\"");
    let a = line.find(&key)? + key.len();
    let b = a + line[a..].find('"')?;
    Some(&line[a..b])
}

/// A circle or square rect with a plain fill and no other attributes; None otherwise.
fn marker(line: &str) -> Option<Marker> {
    let t = line.trim();
    if !t.ends_with("/>") || t.contains(" stroke") || t.contains(" opacity") || t.contains(" transform") {
        return None;
    }
    let num = |n: &str| attr(t, n).and_then(|v| v.parse::<f64>().ok());
    if t.starts_with("<circle ") {
        let r = num("r")?;
        return Some(Marker {
            x: num("cx")?,
            y: num("cy")?,
            cap: "round",
            width: fmt(2.0 * r),
            fill: attr(t, "fill")?.to_string(),
        });
    }
    if t.starts_with("<rect ") {
        let (w, h) = (num("width")?, num("height")?);
        if (w - h).abs() > 1e-9 || w <= 0.0 {
            return None;
        }
        return Some(Marker {
            x: num("x")? + 0.5 * w,
            y: num("y")? + 0.5 * h,
            cap: "square",
            width: fmt(w),
            fill: attr(t, "fill")?.to_string(),
        });
    }
    None
}

/// The markers of one path in the earlier compact form, which wrote fill, width and cap on
/// every path (`<path d="M.. ..h0m.. ..h0" fill="none" stroke=".." stroke-width=".."
/// stroke-linecap=".."/>`), so that a figure committed in that form can be compacted again
/// without its source. None for any other line.
fn earlier_path(line: &str) -> Option<Vec<Marker>> {
    let t = line.trim();
    if !t.starts_with("<path d=\"M") || !t.ends_with("/>") || attr(t, "fill") != Some("none") {
        return None;
    }
    let cap = match attr(t, "stroke-linecap")? {
        "round" => "round",
        "square" => "square",
        _ => return None,
    };
    let (width, fill) = (attr(t, "stroke-width")?.to_string(), attr(t, "stroke")?.to_string());
    let d = attr(t, "d")?;
    let mut out = Vec::new();
    let mut at = (0i64, 0i64);
    for seg in d.split_terminator("h0") {
        let (rel, nums) = match seg.as_bytes().first()? {
            b'M' => (false, &seg[1..]),
            b'm' => (true, &seg[1..]),
            _ => return None,
        };
        let (a, b) = two_tenths(nums)?;
        at = if rel { (at.0 + a, at.1 + b) } else { (a, b) };
        out.push(Marker {
            x: at.0 as f64 / 10.0,
            y: at.1 as f64 / 10.0,
            cap,
            width: width.clone(),
            fill: fill.clone(),
        });
    }
    (!out.is_empty() && d.ends_with("h0")).then_some(out)
}

/// Two numbers written by `tenths` one after the other ("1.5 -2", ".3-.1"), in tenths.
fn two_tenths(s: &str) -> Option<(i64, i64)> {
    // the second number starts at a space or at a minus sign after the first character
    let split = s.char_indices().skip(1).find(|&(_, c)| c == ' ' || c == '-')?.0;
    let (a, b) = (&s[..split], s[split..].trim_start());
    let t = |v: &str| {
        v.parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .map(|x| (x * 10.0).round() as i64)
    };
    Some((t(a)?, t(b)?))
}

/// A coordinate with at most 2 decimals, trailing zeros dropped ("72.1", "95.02", "60").
fn fmt(v: f64) -> String {
    let s = format!("{v:.2}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

/// A length in tenths of a pixel, shortest form ("8" → ".8", "-3" → "-.3", "20" → "2").
fn tenths(v: i64) -> String {
    let s = fmt(v as f64 / 10.0);
    if let Some(r) = s.strip_prefix("0.") {
        format!(".{r}")
    } else if let Some(r) = s.strip_prefix("-0.") {
        format!("-.{r}")
    } else {
        s
    }
}

/// Write one run of consecutive markers as one `<g>` per marker size and cap (fill, width
/// and cap written once) holding one path per colour, groups and colours in the order they
/// first appear. A path's own attributes are then its colour and its moves alone: about 30
/// bytes per path where one path per (cap, width, colour) carrying all four cost 85.
fn flush(run: &mut Vec<Marker>, out: &mut String) {
    type Style = (&'static str, String);
    // per style, in first-appearance order: its colours in first-appearance order, each
    // with the path so far and its last point in tenths of a pixel
    let mut styles: Vec<(Style, Vec<(String, String, (i64, i64))>)> = Vec::new();
    let mut at: HashMap<Style, usize> = HashMap::new();
    let mut colour_at: HashMap<(usize, String), usize> = HashMap::new();
    for m in run.drain(..) {
        let style = (m.cap, m.width.clone());
        let si = *at.entry(style.clone()).or_insert_with(|| {
            styles.push((style, Vec::new()));
            styles.len() - 1
        });
        let colours = &mut styles[si].1;
        let p = ((m.x * 10.0).round() as i64, (m.y * 10.0).round() as i64);
        match colour_at.get(&(si, m.fill.clone())) {
            // the first marker absolute, the others relative to the one before (exact in
            // tenths: no drift)
            None => {
                colour_at.insert((si, m.fill.clone()), colours.len());
                colours.push((m.fill, format!("M{} {}h0", tenths(p.0), tenths(p.1)), p));
            }
            Some(&ci) => {
                let (_, d, last) = &mut colours[ci];
                let dy = tenths(p.1 - last.1);
                let sep = if dy.starts_with('-') { "" } else { " " };
                let _ = write!(d, "m{}{sep}{dy}h0", tenths(p.0 - last.0));
                *last = p;
            }
        }
    }
    for ((cap, width), colours) in styles {
        let _ = writeln!(
            out,
            "<g fill=\"none\" stroke-width=\"{width}\" stroke-linecap=\"{cap}\">"
        );
        for (fill, d, _) in colours {
            let _ = writeln!(out, "<path stroke=\"{fill}\" d=\"{d}\"/>");
        }
        let _ = writeln!(out, "</g>");
    }
}

/// The compact form of an SVG figure, and how many markers it merged (0: nothing to do).
pub fn compact_svg(text: &str) -> (String, usize) {
    let mut out = String::with_capacity(text.len() / 3);
    let mut run: Vec<Marker> = Vec::new();
    let mut merged = 0;
    for line in text.split_inclusive('\n') {
        if let Some(ms) = earlier_path(line) {
            merged += ms.len();
            run.extend(ms);
            continue;
        }
        match marker(line) {
            Some(m) => {
                run.push(m);
                merged += 1;
            }
            None => {
                flush(&mut run, &mut out);
                out.push_str(line);
            }
        }
    }
    flush(&mut run, &mut out);
    (out, merged)
}

#[cfg(test)]
mod tests {
    use super::*;

    const SVG: &str = "<svg width=\"10\" height=\"10\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n<circle cx=\"1.50\" cy=\"2.00\" r=\"0.30\" fill=\"#aa0000\"/>\n<circle cx=\"3.00\" cy=\"4.25\" r=\"0.30\" fill=\"#00aa00\"/>\n<circle cx=\"5.00\" cy=\"6.00\" r=\"0.30\" fill=\"#aa0000\"/>\n<text x=\"1\" y=\"1\">t</text>\n<rect x=\"60.00\" y=\"334.00\" width=\"10.50\" height=\"10.50\" fill=\"#7a9cc6\"/>\n<rect x=\"0\" y=\"0\" width=\"5\" height=\"1\" fill=\"#7a9cc6\"/>\n</svg>\n";

    #[test]
    fn markers_become_one_path_per_size_and_colour_and_everything_else_is_copied() {
        let (c, n) = compact_svg(SVG);
        assert_eq!(n, 4, "three circles and one square");
        // the circles: one group of their size, one path per colour
        assert!(
            c.contains(
                "<g fill=\"none\" stroke-width=\"0.6\" stroke-linecap=\"round\">\n<path stroke=\"#aa0000\" d=\"M1.5 2h0m3.5 4h0\"/>\n<path stroke=\"#00aa00\" d=\"M3 4.3h0\"/>\n</g>\n"
            ),
            "{c}"
        );
        // the square's centre, side as stroke width, square cap
        assert!(
            c.contains(
                "<g fill=\"none\" stroke-width=\"10.5\" stroke-linecap=\"square\">\n<path stroke=\"#7a9cc6\" d=\"M65.3 339.3h0\"/>\n</g>\n"
            ),
            "{c}"
        );
        // not markers: the background, the text, a non-square rect, in place
        for keep in [
            "<rect width=\"100%\"",
            "<text x=\"1\" y=\"1\">t</text>",
            "<rect x=\"0\" y=\"0\" width=\"5\" height=\"1\"",
        ] {
            assert!(c.contains(keep), "{keep} lost");
        }
        // order against other elements: the circles' paths come before the text
        assert!(c.find("#aa0000").unwrap() < c.find("<text").unwrap());
        assert!(c.find("<text").unwrap() < c.find("M65.3").unwrap());
        assert_eq!(c.matches("h0").count(), 4, "one segment per marker");
        assert_eq!(c.matches("<g ").count(), c.matches("</g>").count(), "groups closed");
    }

    #[test]
    fn markers_of_two_sizes_and_one_colour_keep_their_sizes() {
        let svg = "<circle cx=\"1\" cy=\"1\" r=\"0.3\" fill=\"#000\"/>\n<circle cx=\"2\" cy=\"1\" r=\"0.4\" fill=\"#000\"/>\n<circle cx=\"3\" cy=\"1\" r=\"0.3\" fill=\"#000\"/>\n";
        let (c, n) = compact_svg(svg);
        assert_eq!(n, 3);
        assert!(
            c.contains("stroke-width=\"0.6\" stroke-linecap=\"round\">\n<path stroke=\"#000\" d=\"M1 1h0m2 0h0\"/>"),
            "{c}"
        );
        assert!(
            c.contains("stroke-width=\"0.8\" stroke-linecap=\"round\">\n<path stroke=\"#000\" d=\"M2 1h0\"/>"),
            "{c}"
        );
    }

    #[test]
    fn relative_moves_are_exact_in_tenths() {
        assert_eq!(tenths(8), ".8");
        assert_eq!(tenths(-3), "-.3");
        assert_eq!(tenths(20), "2");
        assert_eq!(tenths(-1234), "-123.4");
        assert_eq!(tenths(0), "0");
        // three markers of one colour: absolute, then deltas that sum back exactly
        let svg = "<circle cx=\"1.01\" cy=\"1.01\" r=\"0.5\" fill=\"#000\"/>\n<circle cx=\"1.34\" cy=\"0.99\" r=\"0.5\" fill=\"#000\"/>\n<circle cx=\"1.00\" cy=\"2.00\" r=\"0.5\" fill=\"#000\"/>\n";
        let (c, _) = compact_svg(svg);
        assert!(c.contains("d=\"M1 1h0m.3 0h0m-.3 1h0\""), "{c}");
    }

    #[test]
    fn the_earlier_compact_form_compacts_to_the_same_figure_as_its_source() {
        // the earlier form of SVG's markers, as `granrepro keep` committed it
        let earlier = "<svg width=\"10\" height=\"10\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n<path d=\"M1.5 2h0m3.5 4h0\" fill=\"none\" stroke=\"#aa0000\" stroke-width=\"0.6\" stroke-linecap=\"round\"/>\n<path d=\"M3 4.3h0\" fill=\"none\" stroke=\"#00aa00\" stroke-width=\"0.6\" stroke-linecap=\"round\"/>\n<text x=\"1\" y=\"1\">t</text>\n<path d=\"M65.3 339.3h0\" fill=\"none\" stroke=\"#7a9cc6\" stroke-width=\"10.5\" stroke-linecap=\"square\"/>\n<rect x=\"0\" y=\"0\" width=\"5\" height=\"1\" fill=\"#7a9cc6\"/>\n</svg>\n";
        let (again, n) = compact_svg(earlier);
        assert_eq!(n, 4);
        assert_eq!(again, compact_svg(SVG).0);
        // negative moves, with and without a separating space, decode exactly
        let line = "<path d=\"M10 10h0m-.3-1.2h0m2 -.5h0m.1 3h0\" fill=\"none\" stroke=\"#000\" stroke-width=\"1\" stroke-linecap=\"round\"/>\n";
        let ms = earlier_path(line).unwrap();
        let at: Vec<(f64, f64)> = ms.iter().map(|m| (m.x, m.y)).collect();
        assert_eq!(at, [(10.0, 10.0), (9.7, 8.8), (11.7, 8.3), (11.8, 11.3)]);
        // the current form is left as it is
        assert_eq!(compact_svg(&again), (again.clone(), 0));
    }

    #[test]
    fn a_figure_without_markers_is_unchanged() {
        let plain = "<svg>\n<line x1=\"0\" y1=\"0\" x2=\"1\" y2=\"1\"/>\n<text>a</text>\n</svg>\n";
        assert_eq!(compact_svg(plain), (plain.to_string(), 0));
    }
}

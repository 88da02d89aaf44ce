//! Snapshots drawn to scale as SVG: disks (DEM grains) or squares (MPM material-point
//! domains) at their true size on equal axes, optionally coloured by a field with a
//! colour bar, with walls, gate and grid lines. Pure: returns the SVG text.

use std::fmt::Write;

/// How each body is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// Disk of radius `half`.
    Disk,
    /// Square of half-width `half` (GIMP particle domain).
    Square,
}

/// A line segment (wall, gate, grid line) in metres.
#[derive(Debug, Clone)]
pub struct Segment {
    /// Start (x, y) [m].
    pub a: (f64, f64),
    /// End (x, y) [m].
    pub b: (f64, f64),
    /// Stroke colour (CSS).
    pub color: &'static str,
    /// Stroke width [px].
    pub width: f64,
    /// Dashed?
    pub dashed: bool,
}

/// Field used for colouring.
#[derive(Debug, Clone)]
pub struct Field<'a> {
    /// One value per body.
    pub values: &'a [f64],
    /// Colour-bar label with unit.
    pub label: String,
    /// Colour range (min, max); values outside are clamped.
    pub range: (f64, f64),
}

/// A snapshot to draw.
#[derive(Debug, Clone)]
pub struct Snapshot<'a> {
    /// Title.
    pub title: String,
    /// Footer (profile, numbers).
    pub footer: String,
    /// Centres x [m].
    pub x: &'a [f64],
    /// Centres y [m].
    pub y: &'a [f64],
    /// Radius or half-width [m].
    pub half: &'a [f64],
    /// Shape.
    pub shape: Shape,
    /// Colouring field (uniform grey-blue when absent).
    pub field: Option<Field<'a>>,
    /// Bodies drawn black (e.g. the fixed layers of the shear cell).
    pub black: Option<&'a [bool]>,
    /// Uniform fill when there is no field (CSS colour; default grey-blue).
    pub fill: Option<&'static str>,
    /// Walls and other lines.
    pub segments: Vec<Segment>,
    /// View window (x0, x1, y0, y1) [m]; from the data when absent.
    pub view: Option<(f64, f64, f64, f64)>,
    /// Target width of the drawing area [px].
    pub width_px: f64,
}

/// Perceptually ordered colour map (viridis-like, 5 anchors, linear in between).
pub fn colormap(t: f64) -> (u8, u8, u8) {
    const A: [(f64, f64, f64); 5] = [
        (68.0, 1.0, 84.0),
        (59.0, 82.0, 139.0),
        (33.0, 145.0, 140.0),
        (94.0, 201.0, 98.0),
        (253.0, 231.0, 37.0),
    ];
    let t = if t.is_finite() { t.clamp(0.0, 1.0) } else { 0.0 };
    let s = t * 4.0;
    let i = (s.floor() as usize).min(3);
    let f = s - i as f64;
    let (a, b) = (A[i], A[i + 1]);
    (
        (a.0 + f * (b.0 - a.0)) as u8,
        (a.1 + f * (b.1 - a.1)) as u8,
        (a.2 + f * (b.2 - a.2)) as u8,
    )
}

impl Snapshot<'_> {
    /// Render.
    pub fn to_svg(&self) -> String {
        let n = self.x.len();
        let (x0, x1, y0, y1) = self.view.unwrap_or_else(|| {
            let (mut a, mut b, mut c, mut d) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
            for i in 0..n {
                a = a.min(self.x[i] - self.half[i]);
                b = b.max(self.x[i] + self.half[i]);
                c = c.min(self.y[i] - self.half[i]);
                d = d.max(self.y[i] + self.half[i]);
            }
            for s in &self.segments {
                a = a.min(s.a.0.min(s.b.0));
                b = b.max(s.a.0.max(s.b.0));
                c = c.min(s.a.1.min(s.b.1));
                d = d.max(s.a.1.max(s.b.1));
            }
            if !a.is_finite() {
                (0.0, 1.0, 0.0, 1.0)
            } else {
                let pad = 0.03 * (b - a).max(d - c);
                (a - pad, b + pad, c - pad, d + pad)
            }
        });
        let w = self.width_px.max(200.0);
        let scale = w / (x1 - x0).max(1e-12);
        let mut h = (y1 - y0) * scale;
        let mut scale = scale;
        if h > 900.0 {
            scale *= 900.0 / h;
            h = 900.0;
        }
        let w = (x1 - x0) * scale;
        let (ml, mt, mb) = (60.0, 40.0, 70.0);
        let mr = if self.field.is_some() { 110.0 } else { 20.0 };
        let (tw, th) = (w + ml + mr, h + mt + mb);
        let px = |x: f64| ml + (x - x0) * scale;
        let py = |y: f64| mt + (y1 - y) * scale;
        let mut s = String::with_capacity(120 * n + 4096);
        let _ = write!(
            s,
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{tw:.0}\" height=\"{th:.0}\" viewBox=\"0 0 {tw:.1} {th:.1}\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
        );
        let _ = writeln!(
            s,
            "<text x=\"{:.1}\" y=\"24\" font-family=\"sans-serif\" font-size=\"{:.1}\" text-anchor=\"middle\">{}</text>",
            tw / 2.0,
            (1.9 * tw / self.title.chars().count().max(1) as f64).clamp(8.0, 15.0),
            esc(&self.title)
        );
        let _ = writeln!(
            s,
            "<rect x=\"{ml}\" y=\"{mt}\" width=\"{w:.1}\" height=\"{h:.1}\" fill=\"none\" stroke=\"#bbb\"/>"
        );
        let _ = writeln!(s, "<g stroke=\"none\">");
        for i in 0..n {
            let fill = if self.black.is_some_and(|b| b[i]) {
                "#000".to_string()
            } else if let Some(f) = &self.field {
                let t = (f.values[i] - f.range.0) / (f.range.1 - f.range.0).max(1e-300);
                let (r, g, b) = colormap(t);
                format!("#{r:02x}{g:02x}{b:02x}")
            } else {
                self.fill.unwrap_or("#7a9cc6").to_string()
            };
            match self.shape {
                Shape::Disk => {
                    let _ = writeln!(
                        s,
                        "<circle cx=\"{:.2}\" cy=\"{:.2}\" r=\"{:.2}\" fill=\"{fill}\"/>",
                        px(self.x[i]),
                        py(self.y[i]),
                        (self.half[i] * scale).max(0.3)
                    );
                }
                Shape::Square => {
                    let hw = (self.half[i] * scale).max(0.3);
                    let _ = writeln!(
                        s,
                        "<rect x=\"{:.2}\" y=\"{:.2}\" width=\"{:.2}\" height=\"{:.2}\" fill=\"{fill}\"/>",
                        px(self.x[i]) - hw,
                        py(self.y[i]) - hw,
                        2.0 * hw,
                        2.0 * hw
                    );
                }
            }
        }
        s.push_str("</g>\n");
        for seg in &self.segments {
            let _ = writeln!(
                s,
                "<line x1=\"{:.2}\" y1=\"{:.2}\" x2=\"{:.2}\" y2=\"{:.2}\" stroke=\"{}\" stroke-width=\"{}\"{}/>",
                px(seg.a.0),
                py(seg.a.1),
                px(seg.b.0),
                py(seg.b.1),
                seg.color,
                seg.width,
                if seg.dashed { " stroke-dasharray=\"6 4\"" } else { "" }
            );
        }
        // Axes ticks in mm.
        let ticks = |lo: f64, hi: f64| -> Vec<f64> {
            let span = (hi - lo) * 1e3;
            let raw = span / 6.0;
            let mag = 10f64.powf(raw.log10().floor());
            let step = [1.0, 2.0, 5.0, 10.0]
                .iter()
                .map(|m| m * mag)
                .find(|s| *s >= raw)
                .unwrap_or(10.0 * mag);
            let mut v = Vec::new();
            let mut t = (lo * 1e3 / step).ceil() * step;
            while t <= hi * 1e3 + 1e-9 {
                v.push(t);
                t += step;
            }
            v
        };
        for t in ticks(x0, x1) {
            let _ = writeln!(
                s,
                "<text x=\"{:.1}\" y=\"{:.1}\" font-family=\"sans-serif\" font-size=\"11\" text-anchor=\"middle\">{}</text>",
                px(t * 1e-3),
                mt + h + 16.0,
                fmt_tick(t)
            );
        }
        for t in ticks(y0, y1) {
            let _ = writeln!(
                s,
                "<text x=\"{:.1}\" y=\"{:.1}\" font-family=\"sans-serif\" font-size=\"11\" text-anchor=\"end\">{}</text>",
                ml - 5.0,
                py(t * 1e-3) + 4.0,
                fmt_tick(t)
            );
        }
        let _ = writeln!(
            s,
            "<text x=\"{:.1}\" y=\"{:.1}\" font-family=\"sans-serif\" font-size=\"12\" text-anchor=\"middle\">x [mm]</text>",
            ml + w / 2.0,
            mt + h + 34.0
        );
        let _ = writeln!(
            s,
            "<text x=\"14\" y=\"{:.1}\" font-family=\"sans-serif\" font-size=\"12\" text-anchor=\"middle\" transform=\"rotate(-90 14 {:.1})\">y [mm]</text>",
            mt + h / 2.0,
            mt + h / 2.0
        );
        if let Some(f) = &self.field {
            let bx = ml + w + 25.0;
            let bh = h.clamp(60.0, 300.0);
            for k in 0..50 {
                let t = 1.0 - k as f64 / 49.0;
                let (r, g, b) = colormap(t);
                let _ = writeln!(
                    s,
                    "<rect x=\"{bx:.1}\" y=\"{:.2}\" width=\"16\" height=\"{:.2}\" fill=\"#{r:02x}{g:02x}{b:02x}\"/>",
                    mt + bh * k as f64 / 50.0,
                    bh / 50.0 + 0.5
                );
            }
            let _ = writeln!(
                s,
                "<text x=\"{:.1}\" y=\"{:.1}\" font-family=\"sans-serif\" font-size=\"11\">{}</text>",
                bx + 20.0,
                mt + 9.0,
                fmt_val(f.range.1)
            );
            let _ = writeln!(
                s,
                "<text x=\"{:.1}\" y=\"{:.1}\" font-family=\"sans-serif\" font-size=\"11\">{}</text>",
                bx + 20.0,
                mt + bh,
                fmt_val(f.range.0)
            );
            let _ = writeln!(
                s,
                "<text x=\"{:.1}\" y=\"{:.1}\" font-family=\"sans-serif\" font-size=\"11\" transform=\"rotate(-90 {:.1} {:.1})\" text-anchor=\"middle\">{}</text>",
                bx + 75.0,
                mt + bh / 2.0,
                bx + 75.0,
                mt + bh / 2.0,
                esc(&f.label)
            );
        }
        let _ = writeln!(
            s,
            "<text x=\"8\" y=\"{:.1}\" font-family=\"sans-serif\" font-size=\"10\" fill=\"#555\">{}</text>",
            th - 8.0,
            esc(&self.footer)
        );
        s.push_str("</svg>\n");
        s
    }
}

fn fmt_tick(t: f64) -> String {
    if (t - t.round()).abs() < 1e-9 {
        format!("{}", t.round() as i64)
    } else {
        format!("{t:.1}")
    }
}

fn fmt_val(v: f64) -> String {
    if v != 0.0 && (v.abs() < 1e-2 || v.abs() >= 1e4) {
        format!("{v:.2e}")
    } else {
        format!("{v:.3}")
    }
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn draws_every_body_to_scale() {
        let x = [0.001, 0.003];
        let y = [0.001, 0.001];
        let r = [0.001, 0.001];
        let v = [0.0, 1.0];
        let snap = Snapshot {
            title: "t".into(),
            footer: "f".into(),
            x: &x,
            y: &y,
            half: &r,
            shape: Shape::Disk,
            field: Some(Field {
                values: &v,
                label: "|v| [m/s]".into(),
                range: (0.0, 1.0),
            }),
            black: None,
            fill: None,
            segments: vec![Segment {
                a: (0.0, 0.0),
                b: (0.0, 0.002),
                color: "black",
                width: 2.0,
                dashed: false,
            }],
            view: Some((0.0, 0.004, 0.0, 0.002)),
            width_px: 400.0,
        };
        let s = snap.to_svg();
        assert_eq!(s.matches("<circle").count(), 2);
        // 4 mm over 400 px: a 1 mm radius is 100 px.
        assert!(s.contains("r=\"100.00\""), "{s}");
        assert_eq!(colormap(0.0), (68, 1, 84));
        assert_eq!(colormap(1.0), (253, 231, 37));
    }
}

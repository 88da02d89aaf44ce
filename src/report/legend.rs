//! Legends, method markers and the coefficient table of the charts of [`super::plot`].
//!
//! Contract:
//! - **Markers.** One table, [`METHOD_MARKERS`], maps a series' method to the marker the
//!   chapter's figures draw it with (figures 4.5, 4.6, 4.33); the method is the first
//!   keyword of the table found, as whole words, in the series' label. Unknown → a disk.
//! - **Entries.** A fit's coefficients never sit in the legend: every dashed series labelled
//!   "fit …" goes to a table under the figure ([`Row`]), and one legend entry "fits" stands
//!   for them all. When more than [`MAX_ENTRIES`] entries remain, the other dashed series
//!   (stated laws, bands) follow the fits into the table.
//! - **Placement.** The legend box goes in the corner of the plot area that holds no data
//!   pixel (marker, line or error-bar sample); among empty corners the chart's preferred one,
//!   then upper right, upper left, lower right, lower left. When no corner is empty the
//!   legend goes in a margin right of the plot, or below it when the panel is too narrow.
//! - **Deterministic.** Only pixel positions from plotters' coordinate mapping and a fixed
//!   per-character text width ([`text_width`]) enter: no font metrics, no randomness.

use plotters::coord::Shift;
use plotters::element::{Drawable, PointCollection};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters_backend::{BackendCoord, DrawingErrorKind};

/// Most legend entries a panel shows before dashed lines move to the table.
pub const MAX_ENTRIES: usize = 6;
/// Legend and table font size (plotters' size; the SVG's is 1.24 times smaller, 12 px).
pub const FONT: f64 = 15.0;
/// Height of one legend or table row [px].
pub const ROW: i32 = 17;
/// Width of a swatch (line sample or marker) [px].
const SWATCH: i32 = 24;
/// Padding inside the legend box and between box and axes [px].
const PAD: i32 = 6;

/// Legend corner: the chart's preference among the corners the data leave empty.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Legend {
    /// Upper left (time series starting at zero).
    #[default]
    UpperLeft,
    /// Upper right.
    UpperRight,
    /// Lower left (work-precision: error falls as wall time grows).
    LowerLeft,
    /// Lower right (growing power laws).
    LowerRight,
}

/// A marker shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Marker {
    /// Filled disk.
    Circle,
    /// Filled square.
    Square,
    /// Open square.
    SquareOpen,
    /// Filled diamond.
    Diamond,
    /// Diagonal cross (×).
    Cross,
    /// Asterisk (× and +).
    Star,
}

/// Method → marker, as the chapter's figures draw them; the first row whose keyword occurs
/// in a label (as whole words, case-insensitive) wins, so the specific rows come first.
pub const METHOD_MARKERS: [(&str, Marker); 8] = [
    // fig 4.5: DEM hexagonal packing, red asterisks
    ("hexagonal", Marker::Star),
    // figs 4.5, 4.6: DEM random packing, filled disks
    ("dem random", Marker::Circle),
    // figs 4.5, 4.6: the experiments (Lajeunesse et al. 2005), filled squares
    ("experiment", Marker::Square),
    ("lajeunesse", Marker::Square),
    // figs 4.5, 4.6: MPM, filled diamonds (fig 4.33 is inconsistent between its panels)
    ("mpm", Marker::Diamond),
    // fig 4.33: Contact Dynamics, crosses
    ("cd", Marker::Cross),
    ("contact dynamics", Marker::Cross),
    // fig 4.33(a): the DEM pile, open squares
    ("dem", Marker::SquareOpen),
];

fn words(s: &str) -> Vec<String> {
    s.split(|c: char| !c.is_alphanumeric())
        .filter(|w| !w.is_empty())
        .map(str::to_lowercase)
        .collect()
}

impl Marker {
    /// The marker of the method a label names ([`METHOD_MARKERS`]), else a disk.
    pub fn for_label(label: &str) -> Marker {
        let w = words(label);
        for (key, m) in METHOD_MARKERS {
            let k = words(key);
            if w.windows(k.len()).any(|win| win == k.as_slice()) {
                return m;
            }
        }
        Marker::Circle
    }
}

/// A marker at a point, drawn in pixels around the point's pixel position.
pub struct Mark<C> {
    /// Position (data or pixel coordinates).
    pub at: C,
    /// Shape.
    pub marker: Marker,
    /// Colour.
    pub color: RGBColor,
}

impl<'a, C> PointCollection<'a, C> for &'a Mark<C> {
    type Point = &'a C;
    type IntoIter = std::iter::Once<&'a C>;
    fn point_iter(self) -> Self::IntoIter {
        std::iter::once(&self.at)
    }
}

impl<C, DB: DrawingBackend> Drawable<DB> for Mark<C> {
    fn draw<I: Iterator<Item = BackendCoord>>(
        &self,
        mut pos: I,
        backend: &mut DB,
        _: (u32, u32),
    ) -> Result<(), DrawingErrorKind<DB::ErrorType>> {
        let Some((x, y)) = pos.next() else { return Ok(()) };
        let fill = self.color.filled();
        let line = self.color.stroke_width(2);
        let r = 3;
        match self.marker {
            Marker::Circle => backend.draw_circle((x, y), 3, &fill, true),
            Marker::Square => backend.draw_rect((x - r, y - r), (x + r, y + r), &fill, true),
            Marker::SquareOpen => backend.draw_rect((x - r - 1, y - r - 1), (x + r + 1, y + r + 1), &line, false),
            Marker::Diamond => backend.fill_polygon(
                vec![(x, y - r - 2), (x + r + 1, y), (x, y + r + 2), (x - r - 1, y)],
                &fill,
            ),
            Marker::Cross | Marker::Star => {
                backend.draw_line((x - r, y - r), (x + r, y + r), &line)?;
                backend.draw_line((x - r, y + r), (x + r, y - r), &line)?;
                if self.marker == Marker::Star {
                    backend.draw_line((x - r - 1, y), (x + r + 1, y), &line)?;
                    backend.draw_line((x, y - r - 1), (x, y + r + 1), &line)?;
                }
                Ok(())
            }
        }
    }
}

/// How a legend entry or table row shows its series.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Swatch {
    /// Solid line.
    Line,
    /// Dashed line.
    Dashed,
    /// A marker.
    Marker(Marker),
    /// A thin line through a marker.
    LineMarker(Marker),
}

/// One legend entry (or one row of the table under the figure).
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// Text.
    pub label: String,
    /// Swatch.
    pub swatch: Swatch,
    /// Colour.
    pub color: RGBColor,
}

/// Estimated width [px] of a text at a plotters font size: 0.52 em per character of the em
/// the SVG backend writes, `size / 1.24` (Chromium's sans-serif measures 0.42 em on the
/// figures' labels, DejaVu Sans about 0.5; over-estimating only makes a box a little wide).
pub fn text_width(s: &str, size: f64) -> i32 {
    (s.chars().count() as f64 * size / 1.24 * 0.52).ceil() as i32
}

/// A pixel rectangle, `x0 ≤ x < x1`, `y0 ≤ y < y1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rect {
    /// Left.
    pub x0: i32,
    /// Top.
    pub y0: i32,
    /// Right.
    pub x1: i32,
    /// Bottom.
    pub y1: i32,
}

impl Rect {
    /// Is the point inside, grown by `m` pixels on every side?
    pub fn contains(&self, (x, y): (i32, i32), m: i32) -> bool {
        x >= self.x0 - m && x < self.x1 + m && y >= self.y0 - m && y < self.y1 + m
    }
}

/// Size (w, h) of the legend box of these entries [px].
pub fn box_size(entries: &[Row]) -> (i32, i32) {
    let text = entries.iter().map(|e| text_width(&e.label, FONT)).max().unwrap_or(0);
    (2 * PAD + SWATCH + PAD + text, 2 * PAD + ROW * entries.len() as i32)
}

/// The corner box for the legend: inside `plot`, holding none of `samples` (pixel positions
/// of the drawn data, grown by a marker's half-size); `None` when every corner holds data or
/// the box does not fit. Preference among empty corners: `prefer`, then UR, UL, LR, LL.
pub fn choose_corner(samples: &[(i32, i32)], plot: Rect, size: (i32, i32), prefer: Legend) -> Option<Rect> {
    let (w, h) = size;
    if w + 2 * PAD > plot.x1 - plot.x0 || h + 2 * PAD > plot.y1 - plot.y0 {
        return None;
    }
    let at = |c: Legend| {
        let x0 = match c {
            Legend::UpperLeft | Legend::LowerLeft => plot.x0 + PAD,
            Legend::UpperRight | Legend::LowerRight => plot.x1 - PAD - w,
        };
        let y0 = match c {
            Legend::UpperLeft | Legend::UpperRight => plot.y0 + PAD,
            Legend::LowerLeft | Legend::LowerRight => plot.y1 - PAD - h,
        };
        Rect {
            x0,
            y0,
            x1: x0 + w,
            y1: y0 + h,
        }
    };
    let order = [
        prefer,
        Legend::UpperRight,
        Legend::UpperLeft,
        Legend::LowerRight,
        Legend::LowerLeft,
    ];
    order
        .into_iter()
        .map(at)
        .find(|r| !samples.iter().any(|&p| r.contains(p, 5)))
}

/// Points every `step` pixels along a polyline (its vertices included).
pub fn sample_polyline(px: &[(i32, i32)], step: f64, out: &mut Vec<(i32, i32)>) {
    out.extend(px.first().copied());
    for s in px.windows(2) {
        let (dx, dy) = ((s[1].0 - s[0].0) as f64, (s[1].1 - s[0].1) as f64);
        // a segment leaving the canvas far away (a log axis near zero) is sampled within reach
        let n = ((dx.hypot(dy) / step).ceil() as usize).clamp(1, 4000);
        for k in 1..=n {
            let t = k as f64 / n as f64;
            out.push((
                (s[0].0 as f64 + t * dx).round() as i32,
                (s[0].1 as f64 + t * dy).round() as i32,
            ));
        }
    }
}

fn err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow::anyhow!("{e:?}")
}

/// Draw a swatch centred vertically at `y`, starting at `x`.
fn swatch<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, r: &Row, x: i32, y: i32) -> anyhow::Result<()> {
    let c = r.color;
    let (line, dashed, marker) = match r.swatch {
        Swatch::Line => (true, false, None),
        Swatch::Dashed => (false, true, None),
        Swatch::Marker(m) => (false, false, Some(m)),
        Swatch::LineMarker(m) => (true, false, Some(m)),
    };
    if line {
        area.draw(&PathElement::new(vec![(x, y), (x + SWATCH, y)], c.stroke_width(2)))
            .map_err(err)?;
    }
    if dashed {
        for (a, b) in [(0, 7), (11, 18), (22, SWATCH)] {
            area.draw(&PathElement::new(vec![(x + a, y), (x + b, y)], c.stroke_width(2)))
                .map_err(err)?;
        }
    }
    if let Some(m) = marker {
        area.draw(&Mark {
            at: (x + SWATCH / 2, y),
            marker: m,
            color: c,
        })
        .map_err(err)?;
    }
    Ok(())
}

/// Draw the legend box with its entries at `at` (pixels of `area`).
pub fn draw_legend<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, entries: &[Row], at: Rect) -> anyhow::Result<()> {
    area.draw(&Rectangle::new(
        [(at.x0, at.y0), (at.x1, at.y1)],
        WHITE.mix(0.85).filled(),
    ))
    .map_err(err)?;
    area.draw(&Rectangle::new(
        [(at.x0, at.y0), (at.x1, at.y1)],
        RGBColor(180, 180, 180),
    ))
    .map_err(err)?;
    for (k, e) in entries.iter().enumerate() {
        let y = at.y0 + PAD + ROW * k as i32 + ROW / 2;
        swatch(area, e, at.x0 + PAD, y)?;
        area.draw(&Text::new(
            e.label.clone(),
            (at.x0 + 2 * PAD + SWATCH, y),
            ("sans-serif", FONT)
                .into_font()
                .color(&BLACK)
                .pos(Pos::new(HPos::Left, VPos::Center)),
        ))
        .map_err(err)?;
    }
    Ok(())
}

/// Columns of the table under a figure `width` pixels wide: (columns, column width, height).
pub fn table_layout(rows: &[Row], width: u32) -> (usize, i32, i32) {
    if rows.is_empty() {
        return (1, width as i32, 0);
    }
    let col_w = rows.iter().map(|r| text_width(&r.label, FONT)).max().unwrap_or(0) + SWATCH + 4 * PAD;
    let cols = ((width as i32 - 2 * PAD) / col_w.max(1)).clamp(1, rows.len() as i32) as usize;
    let n_rows = rows.len().div_ceil(cols) as i32;
    (cols, col_w, n_rows * ROW + 2 * PAD)
}

/// Draw the table of fitted coefficients (column-major) into `area`.
pub fn draw_table<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, rows: &[Row]) -> anyhow::Result<()> {
    let (cols, col_w, _) = table_layout(rows, area.dim_in_pixel().0);
    let per_col = rows.len().div_ceil(cols);
    for (k, r) in rows.iter().enumerate() {
        let (c, i) = ((k / per_col) as i32, (k % per_col) as i32);
        let (x, y) = (2 * PAD + c * col_w, PAD + i * ROW + ROW / 2);
        swatch(area, r, x, y)?;
        area.draw(&Text::new(
            r.label.clone(),
            (x + SWATCH + PAD, y),
            ("sans-serif", FONT)
                .into_font()
                .color(&RGBColor(40, 40, 40))
                .pos(Pos::new(HPos::Left, VPos::Center)),
        ))
        .map_err(err)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn methods_get_the_chapters_markers() {
        assert_eq!(Marker::for_label("DEM random packing"), Marker::Circle);
        assert_eq!(Marker::for_label("DEM hexagonal packing"), Marker::Star);
        assert_eq!(Marker::for_label("MPM Mohr–Coulomb"), Marker::Diamond);
        assert_eq!(Marker::for_label("CD"), Marker::Cross);
        assert_eq!(Marker::for_label("DEM"), Marker::SquareOpen);
        // whole words only: "cd" inside a word is not Contact Dynamics
        assert_eq!(Marker::for_label("abcd run"), Marker::Circle);
    }

    #[test]
    fn corner_avoids_samples_and_keeps_preference() {
        let plot = Rect {
            x0: 0,
            y0: 0,
            x1: 400,
            y1: 300,
        };
        let full_ur: Vec<(i32, i32)> = (0..20)
            .flat_map(|i| (0..20).map(move |j| (300 + 5 * i, 5 * j)))
            .collect();
        let r = choose_corner(&full_ur, plot, (80, 40), Legend::UpperRight).unwrap();
        assert!(full_ur.iter().all(|&p| !r.contains(p, 0)), "{r:?}");
        assert_eq!(r.x0, PAD, "upper left is next in order: {r:?}");
        // an empty chart keeps the preferred corner
        let r = choose_corner(&[], plot, (80, 40), Legend::LowerLeft).unwrap();
        assert_eq!((r.x0, r.y1), (PAD, 300 - PAD));
        // data in all four corners: no corner
        let corners = [(10, 10), (390, 10), (10, 290), (390, 290)];
        assert!(choose_corner(&corners, plot, (80, 40), Legend::UpperLeft).is_none());
    }
}

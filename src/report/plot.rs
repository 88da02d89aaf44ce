//! Line/point charts as SVG strings (plotters, SVG backend only). One declarative
//! [`Chart`] covers every plot of the chapter: linear or log axes, data series as lines,
//! markers or steps, and the chapter's stated laws as dashed lines labelled as such —
//! never drawn as data.

use plotters::coord::Shift;
use plotters::prelude::*;

pub use super::legend::Legend;
use super::legend::{
    MAX_ENTRIES, Mark, Marker, Rect, Row, Swatch, box_size, choose_corner, draw_legend, draw_table, sample_polyline,
    table_layout,
};

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Style {
    /// Solid line (simulation time series, target curves).
    Line,
    /// Markers only (measured points).
    Points,
    /// Markers joined by a thin line.
    LinePoints,
    /// Dashed line: a stated law or a fit, labelled "stated law: …" / "fit: …".
    Dashed,
}

/// One series.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Drawing style.
    pub style: Style,
    /// (x, y) points.
    pub points: Vec<(f64, f64)>,
    /// Palette index (same index = same colour across figures).
    pub color: usize,
    /// Symmetric y error per point (± spread over seeds), drawn as bars.
    pub y_err: Option<Vec<f64>>,
    /// Marker of its points: the method its label names (`legend::METHOD_MARKERS`).
    pub marker: Marker,
}

impl Series {
    /// New series.
    pub fn new(label: impl Into<String>, style: Style, points: Vec<(f64, f64)>, color: usize) -> Series {
        let label = label.into();
        Series {
            marker: Marker::for_label(&label),
            label,
            style,
            points,
            color,
            y_err: None,
        }
    }
    /// How its legend entry shows it.
    fn swatch(&self) -> Swatch {
        match self.style {
            Style::Line => Swatch::Line,
            Style::Dashed => Swatch::Dashed,
            Style::Points => Swatch::Marker(self.marker),
            Style::LinePoints => Swatch::LineMarker(self.marker),
        }
    }
    /// The same series with ± `err` bars (one per point).
    pub fn with_errors(mut self, err: Vec<f64>) -> Series {
        self.y_err = Some(err);
        self
    }
}

/// A chart.
#[derive(Debug, Clone, Default)]
pub struct Chart {
    /// Title (first line of the caption).
    pub title: String,
    /// Footer: profile and measured error of that profile.
    pub footer: String,
    /// X axis label with unit.
    pub x_label: String,
    /// Y axis label with unit.
    pub y_label: String,
    /// Log x axis.
    pub x_log: bool,
    /// Log y axis.
    pub y_log: bool,
    /// Fixed x range (else from data).
    pub x_range: Option<(f64, f64)>,
    /// Fixed y range (else from data).
    pub y_range: Option<(f64, f64)>,
    /// Series.
    pub series: Vec<Series>,
    /// The preferred legend corner, taken when the data leave it empty (`report::legend`).
    pub legend: Legend,
}

impl Chart {
    /// A chart on log–log axes.
    pub fn log_log(title: String, footer: String, x_label: &str, y_label: &str, series: Vec<Series>) -> Chart {
        Chart {
            title,
            footer,
            x_label: x_label.into(),
            y_label: y_label.into(),
            x_log: true,
            y_log: true,
            series,
            legend: Legend::LowerRight,
            ..Default::default()
        }
    }
    /// A work-precision chart: run-out error against the finest run vs wall time.
    pub fn work_precision(title: String, footer: String, series: Vec<Series>) -> Chart {
        Chart {
            legend: Legend::LowerLeft,
            ..Chart::log_log(title, footer, "wall time [s]", "|ΔL − ΔL_ref| / ΔL_ref", series)
        }
    }
}

const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(0, 0, 0),
];

/// Colour of a palette index.
pub fn color(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

fn range(vals: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in vals {
        if v.is_finite() && (!log || v > 0.0) {
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    if !lo.is_finite() {
        return if log { (0.1, 10.0) } else { (0.0, 1.0) };
    }
    if log {
        (lo / 1.3, hi * 1.3)
    } else {
        let pad = ((hi - lo) * 0.05).max(1e-12 + hi.abs() * 1e-6);
        (lo - pad, hi + pad)
    }
}

/// Is a series a fitted curve (dashed, labelled "fit …")? Its label carries coefficients,
/// which go to the table under the figure, not into the legend.
fn is_fit(s: &Series) -> bool {
    s.style == Style::Dashed && s.label.to_lowercase().starts_with("fit")
}

/// A chart as drawn: the plot area and every data pixel (markers, line and error-bar
/// samples), relative to the panel's origin.
struct Drawn {
    plot: Rect,
    samples: Vec<(i32, i32)>,
}

fn err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow::anyhow!("{e:?}")
}

impl Chart {
    /// Render to an SVG document.
    pub fn to_svg(&self) -> anyhow::Result<String> {
        panels_to_svg(std::slice::from_ref(self), 1, &self.footer)
    }

    /// The legend entries and the rows it sends to the table under the figure (`tag`
    /// prefixes the rows: "(a) " in a figure of several panels). See `report::legend`.
    fn legend_plan(&self, tag: &str) -> (Vec<Row>, Vec<Row>) {
        let (mut entries, mut table) = (Vec::new(), Vec::new());
        let mut fit_colors: Vec<usize> = Vec::new();
        let mut fits_at = None;
        for s in self.series.iter().filter(|s| !s.label.is_empty()) {
            let row = Row {
                label: s.label.clone(),
                swatch: s.swatch(),
                color: color(s.color),
            };
            if is_fit(s) {
                fits_at.get_or_insert(entries.len());
                fit_colors.push(s.color % PALETTE.len());
                table.push(Row {
                    label: format!("{tag}{}", s.label),
                    ..row
                });
            } else {
                entries.push(row);
            }
        }
        fit_colors.sort_unstable();
        fit_colors.dedup();
        let grey = RGBColor(90, 90, 90);
        if let Some(at) = fits_at {
            let (label, c) = match (fit_colors.as_slice(), table.len()) {
                ([c], 1) => ("fit (coefficients below)", color(*c)),
                ([c], _) => ("fits (coefficients below)", color(*c)),
                _ => ("fits, in their data's colour (below)", grey),
            };
            entries.insert(
                at,
                Row {
                    label: label.into(),
                    swatch: Swatch::Dashed,
                    color: c,
                },
            );
        }
        if entries.len() > MAX_ENTRIES {
            // the other dashed lines (stated laws, bands) follow the fits into the table
            let first = entries.iter().position(|e| e.swatch == Swatch::Dashed);
            if let Some(at) = first {
                let fits_entry = fits_at.map(|_| entries[at].label.clone());
                let mut kept = Vec::new();
                for e in entries.drain(..) {
                    if e.swatch != Swatch::Dashed {
                        kept.push(e);
                    } else if Some(&e.label) != fits_entry.as_ref() {
                        table.push(Row {
                            label: format!("{tag}{}", e.label),
                            ..e
                        });
                    }
                }
                entries = kept;
                entries.insert(
                    at,
                    Row {
                        label: "fits and stated laws (below)".into(),
                        swatch: Swatch::Dashed,
                        color: grey,
                    },
                );
            }
        }
        (entries, table)
    }

    /// Draw the chart (title, axes, series; no legend) into `area`.
    fn draw_chart<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> anyhow::Result<Drawn> {
        let xr = self.x_range.unwrap_or_else(|| {
            range(
                self.series.iter().flat_map(|s| s.points.iter().map(|p| p.0)),
                self.x_log,
            )
        });
        let yr = self.y_range.unwrap_or_else(|| {
            range(
                self.series.iter().flat_map(|s| s.points.iter().map(|p| p.1)),
                self.y_log,
            )
        });
        // Long captions shrink to fit the panel's width (plotters captions are one line).
        let avail = area.dim_in_pixel().0 as f64 - 24.0;
        let title_size = (avail * 1.24 / (0.6 * self.title.chars().count().max(1) as f64)).clamp(9.0, 17.0);
        let base = area.get_base_pixel();
        let rel = |p: (i32, i32)| (p.0 - base.0, p.1 - base.1);
        let mut samples = Vec::new();
        let plot;
        macro_rules! draw {
            ($xspec:expr, $yspec:expr) => {{
                let mut chart = ChartBuilder::on(area)
                    .caption(&self.title, ("sans-serif", title_size))
                    .margin(12)
                    .x_label_area_size(45)
                    .y_label_area_size(65)
                    .build_cartesian_2d($xspec, $yspec)
                    .map_err(err)?;
                chart
                    .configure_mesh()
                    .x_desc(self.x_label.as_str())
                    .y_desc(self.y_label.as_str())
                    .x_label_formatter(&|v| tick(*v))
                    .y_label_formatter(&|v| tick(*v))
                    .light_line_style(RGBColor(235, 235, 235))
                    .draw()
                    .map_err(err)?;
                let ok = |x: f64, y: f64| {
                    x.is_finite() && y.is_finite() && (!self.x_log || x > 0.0) && (!self.y_log || y > 0.0)
                };
                for s in &self.series {
                    let c = color(s.color);
                    let pts: Vec<(f64, f64)> = s.points.iter().copied().filter(|&(x, y)| ok(x, y)).collect();
                    let px: Vec<(i32, i32)> = pts.iter().map(|p| rel(chart.backend_coord(p))).collect();
                    if let Some(e) = &s.y_err {
                        let bars: Vec<Vec<(f64, f64)>> = s
                            .points
                            .iter()
                            .zip(e)
                            .filter(|((x, y), e)| ok(*x, *y) && e.is_finite())
                            .map(|(&(x, y), &e)| {
                                let lo = if self.y_log { (y - e).max(y * 1e-3) } else { y - e };
                                vec![(x, lo), (x, y + e)]
                            })
                            .collect();
                        for b in &bars {
                            let bp: Vec<(i32, i32)> = b.iter().map(|p| rel(chart.backend_coord(p))).collect();
                            sample_polyline(&bp, 3.0, &mut samples);
                        }
                        chart
                            .draw_series(bars.into_iter().map(|b| PathElement::new(b, c.stroke_width(1))))
                            .map_err(err)?;
                    }
                    let marks = |pts: &[(f64, f64)]| {
                        pts.iter()
                            .map(|&at| Mark {
                                at,
                                marker: s.marker,
                                color: c,
                            })
                            .collect::<Vec<_>>()
                    };
                    match s.style {
                        Style::Line => {
                            sample_polyline(&px, 3.0, &mut samples);
                            chart
                                .draw_series(LineSeries::new(pts, c.stroke_width(2)))
                                .map_err(err)?;
                        }
                        Style::Dashed => {
                            sample_polyline(&px, 3.0, &mut samples);
                            chart
                                .draw_series(DashedLineSeries::new(pts, 8, 5, c.stroke_width(2)))
                                .map_err(err)?;
                        }
                        Style::Points => {
                            samples.extend(&px);
                            chart.draw_series(marks(&pts)).map_err(err)?;
                        }
                        Style::LinePoints => {
                            sample_polyline(&px, 3.0, &mut samples);
                            chart
                                .draw_series(LineSeries::new(pts.clone(), c.stroke_width(1)))
                                .map_err(err)?;
                            chart.draw_series(marks(&pts)).map_err(err)?;
                        }
                    }
                }
                let (xp, yp) = chart.plotting_area().get_pixel_range();
                let (a, b) = (rel((xp.start, yp.start)), rel((xp.end, yp.end)));
                plot = Rect {
                    x0: a.0,
                    y0: a.1,
                    x1: b.0,
                    y1: b.1,
                };
            }};
        }
        match (self.x_log, self.y_log) {
            (false, false) => draw!(xr.0..xr.1, yr.0..yr.1),
            (true, false) => draw!((xr.0..xr.1).log_scale(), yr.0..yr.1),
            (false, true) => draw!(xr.0..xr.1, (yr.0..yr.1).log_scale()),
            (true, true) => draw!((xr.0..xr.1).log_scale(), (yr.0..yr.1).log_scale()),
        }
        Ok(Drawn { plot, samples })
    }

    /// Where the legend of `entries` goes in a panel `w` pixels wide: in the corner the
    /// data leave empty (a trial drawing at the panel's size gives the data's pixels; the
    /// layout does not depend on where the panel sits), else in a margin right of the plot,
    /// or below it when the panel is too narrow for that.
    fn place(&self, entries: &[Row], w: u32) -> anyhow::Result<Place> {
        if entries.is_empty() {
            return Ok(Place::None);
        }
        let size = box_size(entries);
        let mut scratch = String::new();
        let trial = self.draw_chart(&SVGBackend::with_string(&mut scratch, (w, PANEL_HEIGHT)).into_drawing_area())?;
        Ok(match choose_corner(&trial.samples, trial.plot, size, self.legend) {
            Some(at) => Place::Inside(at),
            None if size.0 as f64 <= 0.4 * w as f64 => Place::Right,
            None => Place::Below,
        })
    }

    /// Draw the chart (the top `PANEL_HEIGHT` pixels of `area`) and its legend where
    /// [`Chart::place`] put it (a legend below goes under the panel, in `area`'s rest).
    fn draw_into<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        entries: &[Row],
        place: Place,
    ) -> anyhow::Result<()> {
        let (w, h) = area.dim_in_pixel();
        let (top, rest) = area.split_vertically(PANEL_HEIGHT.min(h));
        let size = box_size(entries);
        match place {
            Place::None => self.draw_chart(&top).map(|_| ()),
            Place::Inside(at) => {
                self.draw_chart(&top)?;
                draw_legend(&top, entries, at)
            }
            Place::Right => {
                let (left, right) = top.split_horizontally(w as i32 - size.0 - 8);
                let d = self.draw_chart(&left)?;
                let at = Rect {
                    x0: 0,
                    y0: d.plot.y0,
                    x1: size.0,
                    y1: d.plot.y0 + size.1,
                };
                draw_legend(&right, entries, at)
            }
            Place::Below => {
                self.draw_chart(&top)?;
                let x0 = ((w as i32 - size.0) / 2).max(0);
                let at = Rect {
                    x0,
                    y0: 0,
                    x1: x0 + size.0,
                    y1: size.1,
                };
                draw_legend(&rest, entries, at)
            }
        }
    }
}

/// Where a panel's legend goes.
#[derive(Debug, Clone, Copy)]
enum Place {
    /// No entries.
    None,
    /// In an empty corner of the plot.
    Inside(Rect),
    /// In a margin right of the plot.
    Right,
    /// Under the panel (the row grows by the legend's height).
    Below,
}

/// Widest figure [px]: the report page's body is 1000 px wide (`report::html`), so the
/// panels of a row share this width instead of growing past it (a wider figure is shrunk
/// by the page until its text cannot be read).
pub const MAX_WIDTH: u32 = 1000;
/// Width of a panel when there is room [px].
pub const PANEL_WIDTH: u32 = 760;
/// Height of a panel [px].
const PANEL_HEIGHT: u32 = 495;
/// Height of the footer line [px].
const FOOTER: u32 = 25;

/// Figure width and the x offsets and widths of the `cols` panels of a row: `PANEL_WIDTH`
/// each while the row fits in `MAX_WIDTH`, else `MAX_WIDTH` split evenly. The panels never
/// reach past the figure's width.
pub fn panel_columns(cols: usize) -> (u32, Vec<(i32, u32)>) {
    let cols = cols.max(1) as u32;
    let w = (PANEL_WIDTH * cols).min(MAX_WIDTH.max(PANEL_WIDTH));
    let each = w / cols;
    (w, (0..cols).map(|k| ((k * each) as i32, each)).collect())
}

/// Several charts as panels of one figure (`cols` per row, row-major), the table of fitted
/// coefficients under them (`report::legend`), one footer.
pub fn panels_to_svg(charts: &[Chart], cols: usize, footer: &str) -> anyhow::Result<String> {
    let cols = cols.clamp(1, charts.len().max(1));
    let rows = charts.len().div_ceil(cols).max(1);
    let (w, columns) = panel_columns(cols);
    let mut entries = Vec::new();
    // rows of the coefficient table, per column of panels (each column's under it)
    let mut table: Vec<Vec<Row>> = vec![Vec::new(); cols];
    for (k, c) in charts.iter().enumerate() {
        let tag = if charts.len() > 1 {
            format!("({}) ", (b'a' + (k % 26) as u8) as char)
        } else {
            String::new()
        };
        let (e, t) = c.legend_plan(&tag);
        entries.push(e);
        table[k % cols].extend(t);
    }
    let places = charts
        .iter()
        .zip(&entries)
        .enumerate()
        .map(|(k, (c, e))| c.place(e, columns[k % cols].1))
        .collect::<anyhow::Result<Vec<Place>>>()?;
    // a row grows by the tallest legend placed under one of its panels
    let row_h: Vec<u32> = (0..rows)
        .map(|r| {
            let below = (r * cols..((r + 1) * cols).min(charts.len()))
                .filter(|&k| matches!(places[k], Place::Below))
                .map(|k| box_size(&entries[k]).1 as u32 + 8)
                .max()
                .unwrap_or(0);
            PANEL_HEIGHT + below
        })
        .collect();
    let table_h = (0..cols)
        .map(|c| table_layout(&table[c], columns[c].1).2)
        .max()
        .unwrap_or(0);
    let body_h: u32 = row_h.iter().sum();
    let foot_lines = wrap_footer(footer, w);
    let h = body_h + table_h as u32 + FOOTER + FOOTER_LINE * (foot_lines.len().max(1) as u32 - 1);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let (body, rest) = root.split_vertically(body_h);
        let (tab, foot) = rest.split_vertically(table_h);
        for (i, line) in foot_lines.iter().enumerate() {
            foot.draw(&Text::new(
                line.clone(),
                (10, 5 + (FOOTER_LINE as usize * i) as i32),
                ("sans-serif", 12).into_font().color(&RGBColor(90, 90, 90)),
            ))
            .map_err(err)?;
        }
        for (c, rows) in table.iter().enumerate() {
            let (x, pw) = columns[c];
            draw_table(&tab.clone().shrink((x, 0), (pw, table_h as u32)), rows)?;
        }
        for (k, c) in charts.iter().enumerate() {
            let (x, pw) = columns[k % cols];
            let y = row_h[..k / cols].iter().sum::<u32>() as i32;
            let area = body.clone().shrink((x, y), (pw, row_h[k / cols]));
            c.draw_into(&area, &entries[k], places[k])?;
        }
        root.present().map_err(err)?;
    }
    Ok(svg)
}

/// An axis tick label: at most 3 significant digits, no binary-fraction noise (a log
/// axis otherwise prints "0.30000000000000004"), exponent form outside [1e-3, 1e5).
pub fn tick(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        return format!("{v:.2e}").replace(".00e", "e").replace("0e", "e");
    }
    let s = format!("{:.*}", (2 - a.log10().floor() as i32).max(0) as usize, v);
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_long_footer_wraps_inside_the_figure() {
        // fig4-33's footer ran past the figure's right edge on one line
        let long = format!(
            "profile: quick · {}",
            "measured (wp-summary): CD error 3.8 ± 3.9 % at dt1e-4 ".repeat(6)
        );
        let lines = super::wrap_footer(&long, 1000);
        assert!(lines.len() > 1, "{lines:?}");
        assert!(
            lines.iter().all(|l| l.chars().count() as f64 * 6.6 <= 980.0),
            "{lines:?}"
        );
        assert_eq!(lines.join(" "), long);
    }

    use super::*;

    /// `name="value"` of an SVG tag, as a number.
    fn attr(tag: &str, name: &str) -> f64 {
        let k = format!(" {name}=\"");
        let i = tag.find(&k).unwrap_or_else(|| panic!("no {name} in {tag}")) + k.len();
        tag[i..].split('"').next().unwrap().parse().unwrap()
    }

    /// The legend box (the rect drawn with the legend's grey border) and the centres of the
    /// data markers drawn before it (disks: the legend's own swatches come after it).
    fn legend_and_points(svg: &str) -> ((f64, f64, f64, f64), Vec<(f64, f64)>) {
        let at = svg.find("stroke=\"#B4B4B4\"").expect("a legend box");
        let start = svg[..at].rfind("<rect").unwrap();
        let tag = &svg[start..at];
        let (x, y) = (attr(tag, "x"), attr(tag, "y"));
        let bx = (x, y, x + attr(tag, "width"), y + attr(tag, "height"));
        let pts = svg[..start]
            .split("<circle")
            .skip(1)
            .map(|t| (attr(t, "cx"), attr(t, "cy")))
            .collect();
        (bx, pts)
    }

    fn grid(x: (f64, f64), y: (f64, f64), n: usize) -> Vec<(f64, f64)> {
        let at = |r: (f64, f64), k: usize| r.0 + (r.1 - r.0) * k as f64 / (n - 1) as f64;
        (0..n).flat_map(|i| (0..n).map(move |j| (at(x, i), at(y, j)))).collect()
    }

    fn svg_width(svg: &str) -> f64 {
        attr(&svg[..svg.find('>').unwrap()], "width")
    }

    /// Issue 26: the legend covered the data in the corner it was told to use. Points fill
    /// the upper right, where the chart asks for its legend: the box must go elsewhere and
    /// cover no point. Failed before the fix (the legend box covered 10 of the 64 points).
    #[test]
    fn legend_leaves_the_data_uncovered() {
        let mut pts = grid((5.0, 10.0), (5.0, 10.0), 8);
        pts.push((0.0, 0.0));
        let chart = Chart {
            series: vec![
                Series::new("DEM random packing", Style::Points, pts, 0),
                Series::new("a second entry with a longer label", Style::Points, vec![(0.0, 0.0)], 0),
            ],
            legend: Legend::UpperRight,
            ..Default::default()
        };
        let svg = chart.to_svg().unwrap();
        let ((x0, y0, x1, y1), pts) = legend_and_points(&svg);
        assert!(pts.len() >= 64, "{} markers found", pts.len());
        let covered: Vec<_> = pts
            .iter()
            .filter(|&&(x, y)| x >= x0 - 3.0 && x <= x1 + 3.0 && y >= y0 - 3.0 && y <= y1 + 3.0)
            .collect();
        assert!(
            covered.is_empty(),
            "legend ({x0}, {y0})–({x1}, {y1}) covers {covered:?}"
        );
    }

    /// With data in every corner the legend goes into a margin: still over no point, still
    /// inside the figure.
    #[test]
    fn legend_leaves_a_full_plot_for_the_margin() {
        let chart = Chart {
            series: vec![Series::new(
                "DEM random packing",
                Style::Points,
                grid((0.0, 1.0), (0.0, 1.0), 12),
                0,
            )],
            ..Default::default()
        };
        let svg = chart.to_svg().unwrap();
        let ((x0, y0, x1, y1), pts) = legend_and_points(&svg);
        assert!(
            pts.iter()
                .all(|&(x, y)| x < x0 - 3.0 || x > x1 + 3.0 || y < y0 - 3.0 || y > y1 + 3.0),
            "legend ({x0}, {y0})–({x1}, {y1}) over the data"
        );
        assert!(x1 <= svg_width(&svg), "legend leaves the figure: {x1}");
    }

    /// Issue 26: fig4-05 listed 13 entries, fitted coefficients among them, in a box over
    /// half the plot. Fits leave the legend for the table under the figure; past
    /// `MAX_ENTRIES` the stated laws follow; each coefficient is printed once.
    #[test]
    fn fits_leave_the_legend_for_the_table() {
        let line = vec![(1.0, 1.0), (2.0, 2.0)];
        let mut series: Vec<Series> = ["DEM random packing", "DEM hexagonal packing", "MPM Mohr–Coulomb"]
            .iter()
            .enumerate()
            .map(|(k, l)| Series::new(*l, Style::Points, vec![(1.0 + k as f64, 1.5)], k))
            .collect();
        for k in 0..8 {
            series.push(Series::new(
                format!("fit {k}: 1.{k}·x^(0.5 ± 0.1)"),
                Style::Dashed,
                line.clone(),
                k % 3,
            ));
        }
        for l in [
            "stated law one", "stated law two", "stated law three", "stated law four",
        ] {
            series.push(Series::new(l, Style::Dashed, line.clone(), 5));
        }
        let chart = Chart {
            series,
            ..Default::default()
        };
        let (entries, table) = chart.legend_plan("");
        assert!(entries.len() <= MAX_ENTRIES, "{entries:?}");
        assert!(entries.iter().all(|e| !e.label.contains('±')), "{entries:?}");
        assert_eq!(table.len(), 12, "8 fits and 4 laws in the table: {table:?}");
        let svg = chart.to_svg().unwrap();
        for k in 0..8 {
            assert_eq!(
                svg.matches(&format!("fit {k}: 1.{k}·x^(0.5 ± 0.1)")).count(),
                1,
                "fit {k}"
            );
        }
        // the markers are the chapter's: disk, asterisk (4 strokes), diamond
        assert_eq!(chart.series[1].marker, Marker::Star);
        assert_eq!(chart.series[2].marker, Marker::Diamond);
    }

    /// Issue 26: fig4-33's second panel was cut at the figure's right edge. The panels of a
    /// row share the figure's width, which stays within `MAX_WIDTH` (the report page), and
    /// every title fits its panel.
    #[test]
    fn panels_share_the_figure_width() {
        for cols in 1..=4 {
            let (w, columns) = panel_columns(cols);
            assert!(w <= MAX_WIDTH.max(PANEL_WIDTH), "{cols} columns: {w}");
            assert_eq!(columns.len(), cols);
            assert!(columns.iter().map(|c| c.1).sum::<u32>() <= w, "{cols}: {columns:?}");
            assert!(
                columns.windows(2).all(|p| p[0].0 + p[0].1 as i32 <= p[1].0),
                "{columns:?}"
            );
        }
        let long = "(b) Duration of run-out as a function of normalised input kinetic energy".to_string();
        let chart = Chart {
            title: long.clone(),
            series: vec![Series::new("DEM", Style::Points, vec![(1.0, 1.0), (2.0, 3.0)], 0)],
            ..Default::default()
        };
        let svg = panels_to_svg(&[chart.clone(), chart], 2, "footer").unwrap();
        let w = svg_width(&svg);
        assert!(w <= MAX_WIDTH as f64, "figure {w} px wide");
        // each title, at the font size the SVG states and 0.6 em per character, fits its panel
        for t in svg.split("<text").skip(1).filter(|t| t.contains(long.as_str())) {
            let size = attr(t, "font-size");
            let width = 0.6 * size * long.chars().count() as f64;
            let x = attr(t, "x");
            assert!(
                x + width / 2.0 <= w && x - width / 2.0 >= 0.0,
                "title at {x}, {width} px wide in {w}"
            );
            assert!(width <= w / 2.0, "title {width} px in a {} px panel", w / 2.0);
        }
    }

    #[test]
    fn tick_labels_are_short() {
        assert_eq!(tick(0.30000000000000004), "0.3");
        assert_eq!(tick(0.1 + 0.2), "0.3");
        assert_eq!(tick(2.5), "2.5");
        assert_eq!(tick(150.0), "150");
        assert_eq!(tick(12345.0), "12345");
        assert_eq!(tick(0.0123), "0.0123");
        assert_eq!(tick(-0.5), "-0.5");
        assert!(tick(1e-5).contains('e'), "{}", tick(1e-5));
    }
}

/// Height of each further footer line [px].
const FOOTER_LINE: u32 = 16;

/// The footer's lines, broken at its newlines and between words so that none passes the
/// figure's width (12 px sans-serif: about 6.6 px per character).
fn wrap_footer(footer: &str, width: u32) -> Vec<String> {
    wrap_words(footer, ((width.saturating_sub(20)) as f64 / 6.6) as usize)
}

/// `text` broken at its newlines and between words into lines of at most `max` characters
/// (a longer word keeps its own line).
pub(crate) fn wrap_words(text: &str, max: usize) -> Vec<String> {
    let footer = text;
    let mut out = Vec::new();
    for para in footer.lines() {
        let mut line = String::new();
        for word in para.split(' ') {
            if !line.is_empty() && line.chars().count() + 1 + word.chars().count() > max {
                out.push(std::mem::take(&mut line));
            }
            if !line.is_empty() {
                line.push(' ');
            }
            line.push_str(word);
        }
        out.push(line);
    }
    out
}

/// Footer text every figure carries: profile and the measured error of that profile.
pub fn footer(profile: &str, error_note: &str) -> String {
    let mut s = format!("profile: {profile}");
    if !error_note.is_empty() {
        s.push_str(" · ");
        s.push_str(error_note);
    }
    s.push_str(" · granrepro — after K. Kumar (2015), PhD thesis ch. 4, CC BY 4.0");
    s
}

//! Line/point charts as SVG strings (plotters, SVG backend only). One declarative
//! [`Chart`] covers every plot of the chapter: linear or log axes, data series as lines,
//! markers or steps, and the chapter's stated laws as dashed lines labelled as such —
//! never drawn as data.

use plotters::prelude::*;

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
}

impl Series {
    /// New series.
    pub fn new(label: impl Into<String>, style: Style, points: Vec<(f64, f64)>, color: usize) -> Series {
        Series {
            label: label.into(),
            style,
            points,
            color,
            y_err: None,
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
    /// Where the legend goes (choose the corner the data leave empty).
    pub legend: Legend,
}

/// Legend corner.
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

impl Chart {
    /// Render to an SVG document.
    pub fn to_svg(&self) -> anyhow::Result<String> {
        panels_to_svg(std::slice::from_ref(self), 1, &self.footer)
    }

    /// Draw the chart (without its footer) into one panel of a drawing.
    fn draw_into<DB: DrawingBackend>(&self, body: &DrawingArea<DB, plotters::coord::Shift>) -> anyhow::Result<()> {
        {
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
            // Long captions shrink to fit the width (plotters captions are one line).
            let title_size = (17.0 * (88.0 / self.title.chars().count().max(1) as f64).min(1.0)).max(9.0);
            macro_rules! draw {
                ($xspec:expr, $yspec:expr) => {{
                    let mut chart = ChartBuilder::on(body)
                        .caption(&self.title, ("sans-serif", title_size))
                        .margin(12)
                        .x_label_area_size(45)
                        .y_label_area_size(65)
                        .build_cartesian_2d($xspec, $yspec)
                        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
                    chart
                        .configure_mesh()
                        .x_desc(self.x_label.as_str())
                        .y_desc(self.y_label.as_str())
                        .x_label_formatter(&|v| tick(*v))
                        .y_label_formatter(&|v| tick(*v))
                        .light_line_style(RGBColor(235, 235, 235))
                        .draw()
                        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
                    for s in &self.series {
                        let c = color(s.color);
                        let pts: Vec<(f64, f64)> = s
                            .points
                            .iter()
                            .copied()
                            .filter(|(x, y)| {
                                x.is_finite() && y.is_finite() && (!self.x_log || *x > 0.0) && (!self.y_log || *y > 0.0)
                            })
                            .collect();
                        let legend_style = c.stroke_width(2);
                        if let Some(err) = &s.y_err {
                            let bars: Vec<Vec<(f64, f64)>> = s
                                .points
                                .iter()
                                .zip(err)
                                .filter(|((x, y), e)| {
                                    x.is_finite()
                                        && y.is_finite()
                                        && e.is_finite()
                                        && (!self.x_log || *x > 0.0)
                                        && (!self.y_log || *y > 0.0)
                                })
                                .map(|(&(x, y), &e)| {
                                    let lo = if self.y_log { (y - e).max(y * 1e-3) } else { y - e };
                                    vec![(x, lo), (x, y + e)]
                                })
                                .collect();
                            chart
                                .draw_series(bars.into_iter().map(|b| PathElement::new(b, c.stroke_width(1))))
                                .map_err(|e| anyhow::anyhow!("{e:?}"))?;
                        }
                        let ann = match s.style {
                            Style::Line => chart
                                .draw_series(LineSeries::new(pts, c.stroke_width(2)))
                                .map_err(|e| anyhow::anyhow!("{e:?}"))?,
                            Style::Dashed => chart
                                .draw_series(DashedLineSeries::new(pts, 8, 5, c.stroke_width(2)))
                                .map_err(|e| anyhow::anyhow!("{e:?}"))?,
                            Style::Points => chart
                                .draw_series(pts.iter().map(|&p| Circle::new(p, 3, c.filled())))
                                .map_err(|e| anyhow::anyhow!("{e:?}"))?,
                            Style::LinePoints => {
                                chart
                                    .draw_series(LineSeries::new(pts.clone(), c.stroke_width(1)))
                                    .map_err(|e| anyhow::anyhow!("{e:?}"))?;
                                chart
                                    .draw_series(pts.iter().map(|&p| Circle::new(p, 3, c.filled())))
                                    .map_err(|e| anyhow::anyhow!("{e:?}"))?
                            }
                        };
                        // an empty label draws without a legend entry (e.g. the second edge of a band)
                        if !s.label.is_empty() {
                            let ann = ann.label(s.label.as_str());
                            match s.style {
                                Style::Line => {
                                    ann.legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], legend_style));
                                }
                                Style::Dashed => {
                                    ann.legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 6, y)], legend_style));
                                }
                                Style::Points | Style::LinePoints => {
                                    ann.legend(move |(x, y)| Circle::new((x + 9, y), 3, c.filled()));
                                }
                            }
                        }
                    }
                    chart
                        .configure_series_labels()
                        .background_style(WHITE.mix(0.85))
                        .border_style(RGBColor(180, 180, 180))
                        .position(match self.legend {
                            Legend::UpperLeft => SeriesLabelPosition::UpperLeft,
                            Legend::UpperRight => SeriesLabelPosition::UpperRight,
                            Legend::LowerLeft => SeriesLabelPosition::LowerLeft,
                            Legend::LowerRight => SeriesLabelPosition::LowerRight,
                        })
                        .draw()
                        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
                }};
            }
            match (self.x_log, self.y_log) {
                (false, false) => draw!(xr.0..xr.1, yr.0..yr.1),
                (true, false) => draw!((xr.0..xr.1).log_scale(), yr.0..yr.1),
                (false, true) => draw!(xr.0..xr.1, (yr.0..yr.1).log_scale()),
                (true, true) => draw!((xr.0..xr.1).log_scale(), (yr.0..yr.1).log_scale()),
            }
        }
        Ok(())
    }
}

/// Several charts as panels of one figure (`cols` per row, row-major), one footer.
pub fn panels_to_svg(charts: &[Chart], cols: usize, footer: &str) -> anyhow::Result<String> {
    let cols = cols.clamp(1, charts.len().max(1));
    let rows = charts.len().div_ceil(cols).max(1);
    let (w, h) = (760 * cols as u32, 495 * rows as u32 + 25);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e:?}"))?;
        let (body, foot) = root.split_vertically(h - 25);
        foot.draw(&Text::new(
            footer.to_string(),
            (10, 5),
            ("sans-serif", 12).into_font().color(&RGBColor(90, 90, 90)),
        ))
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
        let areas = body.split_evenly((rows, cols));
        for (c, area) in charts.iter().zip(areas.iter()) {
            c.draw_into(area)?;
        }
        root.present().map_err(|e| anyhow::anyhow!("{e:?}"))?;
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
    use super::tick;

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

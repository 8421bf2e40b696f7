//! Figures as SVG: one or more panels stacked vertically, each with line or
//! point series. Enough for traces, hysteresis loops, parameter trends and
//! convergence curves; every figure of the project goes through here.

use std::path::Path;

use plotters::prelude::*;

use crate::data::write_atomic;

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    Line,
    Points,
}

/// One curve: `(x, y)` pairs and a legend label.
#[derive(Debug, Clone)]
pub struct Series {
    pub label: String,
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    pub style: Style,
}

impl Series {
    pub fn line(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Series {
            label: label.into(),
            x,
            y,
            style: Style::Line,
        }
    }

    pub fn points(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Series {
            label: label.into(),
            x,
            y,
            style: Style::Points,
        }
    }
}

/// One set of axes.
#[derive(Debug, Clone, Default)]
pub struct Panel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    /// Logarithmic y axis (convergence curves); non-positive values are skipped.
    pub log_y: bool,
}

impl Panel {
    pub fn new(
        title: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
    ) -> Self {
        Panel {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            ..Panel::default()
        }
    }

    pub fn with(mut self, series: Series) -> Self {
        self.series.push(series);
        self
    }

    pub fn log_y(mut self) -> Self {
        self.log_y = true;
        self
    }
}

/// A figure of stacked panels.
#[derive(Debug, Clone)]
pub struct Figure {
    pub title: String,
    pub panels: Vec<Panel>,
    /// Width in pixels; each panel is `panel_height` tall.
    pub width: u32,
    pub panel_height: u32,
}

impl Figure {
    pub fn new(title: impl Into<String>) -> Self {
        Figure {
            title: title.into(),
            panels: Vec::new(),
            width: 900,
            panel_height: 320,
        }
    }

    pub fn with(mut self, panel: Panel) -> Self {
        self.panels.push(panel);
        self
    }

    /// Renders to an SVG string.
    pub fn to_svg(&self) -> anyhow::Result<String> {
        anyhow::ensure!(
            !self.panels.is_empty(),
            "figure `{}` has no panels",
            self.title
        );
        let height = 40 + self.panel_height * self.panels.len() as u32;
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, (self.width, height)).into_drawing_area();
            root.fill(&WHITE).map_err(plot_err)?;
            let root = root
                .titled(&self.title, ("sans-serif", 22))
                .map_err(plot_err)?;
            let areas = root.split_evenly((self.panels.len(), 1));
            for (panel, area) in self.panels.iter().zip(areas.iter()) {
                draw_panel(panel, area)?;
            }
            root.present().map_err(plot_err)?;
        }
        Ok(svg)
    }

    /// Renders and writes atomically to `path`.
    pub fn save(&self, path: &Path) -> anyhow::Result<()> {
        let svg = self.to_svg()?;
        write_atomic(path, svg.as_bytes())
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))
    }
}

fn plot_err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow::anyhow!("plotting failed: {e:?}")
}

/// Finite range of the values, padded by 5 %; a flat range is widened.
fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let pad = if hi > lo {
        0.05 * (hi - lo)
    } else {
        0.5 * lo.abs().max(1.0)
    };
    (lo - pad, hi + pad)
}

/// Positive range of the values for a log axis, padded by a quarter decade.
fn log_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if !lo.is_finite() {
        return (1.0, 10.0);
    }
    let hi = if hi > lo { hi } else { lo * 10.0 };
    (lo / 10f64.powf(0.25), hi * 10f64.powf(0.25))
}

const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(127, 127, 127),
];

fn draw_panel<DB: DrawingBackend>(
    panel: &Panel,
    area: &DrawingArea<DB, plotters::coord::Shift>,
) -> anyhow::Result<()> {
    let (x0, x1) = range(panel.series.iter().flat_map(|s| s.x.iter().copied()));
    let ok = |v: &f64| v.is_finite() && (!panel.log_y || *v > 0.0);
    let ys = panel
        .series
        .iter()
        .flat_map(|s| s.y.iter().copied())
        .filter(ok);
    let (y0, y1) = if panel.log_y {
        log_range(ys)
    } else {
        range(ys)
    };
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(&panel.title, ("sans-serif", 16))
        .margin(10)
        .x_label_area_size(36)
        .y_label_area_size(64);
    if panel.log_y {
        let mut chart = builder
            .build_cartesian_2d(x0..x1, (y0..y1).log_scale())
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .x_desc(&panel.x_label)
            .y_desc(&panel.y_label)
            .y_label_formatter(&log_tick)
            .draw()
            .map_err(plot_err)?;
        for (i, s) in panel.series.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            let pts: Vec<(f64, f64)> =
                s.x.iter()
                    .copied()
                    .zip(s.y.iter().copied())
                    .filter(|(x, y)| x.is_finite() && ok(y))
                    .collect();
            let pts = thinned(pts, s.style, |p| chart.backend_coord(p));
            draw_series(&mut chart, s, pts, color)?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(plot_err)?;
    } else {
        let mut chart = builder
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .x_desc(&panel.x_label)
            .y_desc(&panel.y_label)
            .draw()
            .map_err(plot_err)?;
        for (i, s) in panel.series.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            let pts: Vec<(f64, f64)> =
                s.x.iter()
                    .copied()
                    .zip(s.y.iter().copied())
                    .filter(|(x, y)| x.is_finite() && y.is_finite())
                    .collect();
            let pts = thinned(pts, s.style, |p| chart.backend_coord(p));
            draw_series(&mut chart, s, pts, color)?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(plot_err)?;
    }
    Ok(())
}

/// `pts`, drawn as `style` at the pixels `pixel` maps them to, with what
/// the pixels cannot show left out, so that a record of 200 000 samples
/// draws as some thousands of points (its figures were 5–25 MB, which a
/// browser opens slowly, if at all). Points: the first at each pixel. A
/// line against an `x` that never falls (a trace in time): each pixel
/// column keeps its first, lowest, highest and last points, in order, so
/// the envelope of noise and every spike stay. Another line (a loop): a
/// point where it reaches another pixel than the last kept one.
fn thinned(
    pts: Vec<(f64, f64)>,
    style: Style,
    pixel: impl Fn(&(f64, f64)) -> (i32, i32),
) -> Vec<(f64, f64)> {
    if pts.len() < 1000 {
        return pts;
    }
    if style == Style::Points {
        let mut drawn = std::collections::HashSet::new();
        return pts.into_iter().filter(|p| drawn.insert(pixel(p))).collect();
    }
    if pts.windows(2).all(|w| w[0].0 <= w[1].0) {
        let mut kept = Vec::new();
        let mut start = 0;
        while start < pts.len() {
            let column = pixel(&pts[start]).0;
            let len = pts[start..]
                .iter()
                .take_while(|p| pixel(p).0 == column)
                .count();
            let bucket = &pts[start..start + len];
            let by_y = |a: &(usize, &(f64, f64)), b: &(usize, &(f64, f64))| a.1.1.total_cmp(&b.1.1);
            let low = bucket.iter().enumerate().min_by(by_y).map(|l| l.0);
            let high = bucket.iter().enumerate().max_by(by_y).map(|h| h.0);
            let mut at: Vec<usize> = [Some(0), low, high, Some(len - 1)]
                .into_iter()
                .flatten()
                .collect();
            at.sort_unstable();
            at.dedup();
            kept.extend(at.into_iter().map(|i| bucket[i]));
            start += len;
        }
        return kept;
    }
    let mut kept = vec![pts[0]];
    for &p in &pts[1..] {
        if pixel(&p) != pixel(&kept[kept.len() - 1]) {
            kept.push(p);
        }
    }
    // The path ends where the data end.
    if kept[kept.len() - 1] != pts[pts.len() - 1] {
        kept.push(pts[pts.len() - 1]);
    }
    kept
}

fn draw_series<DB, CT>(
    chart: &mut ChartContext<'_, DB, CT>,
    s: &Series,
    pts: Vec<(f64, f64)>,
    color: RGBColor,
) -> anyhow::Result<()>
where
    DB: DrawingBackend,
    CT: plotters::coord::CoordTranslate<From = (f64, f64)>,
{
    let anno = match s.style {
        Style::Line => chart
            .draw_series(LineSeries::new(pts, color.stroke_width(1)))
            .map_err(plot_err)?,
        Style::Points => chart
            .draw_series(pts.into_iter().map(|p| Circle::new(p, 2, color.filled())))
            .map_err(plot_err)?,
    };
    if !s.label.is_empty() {
        anno.label(s.label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], color));
    }
    Ok(())
}

/// A tick of a log axis, in four significant digits without trailing
/// zeros (`1e-5`, `2.5e3`): a decade's tick is a power of ten computed,
/// `9.999999999999999e-6` where it should read `1e-5`.
fn log_tick(v: &f64) -> String {
    let s = format!("{v:.3e}");
    match s.split_once('e') {
        Some((mantissa, exponent)) if mantissa.contains('.') => {
            let mantissa = mantissa.trim_end_matches('0').trim_end_matches('.');
            format!("{mantissa}e{exponent}")
        }
        _ => s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_line_point_and_log_panels() {
        let x: Vec<f64> = (0..50).map(|k| k as f64).collect();
        let y: Vec<f64> = x.iter().map(|v| (v / 5.0).sin()).collect();
        let fig = Figure::new("test")
            .with(Panel::new("lines", "t (s)", "y").with(Series::line("sin", x.clone(), y.clone())))
            .with(Panel::new("points", "x", "y").with(Series::points("pts", y.clone(), x.clone())))
            .with(
                Panel::new("log", "gen", "SSE")
                    .with(Series::line(
                        "best",
                        x.clone(),
                        x.iter().map(|v| v + 1.0).collect(),
                    ))
                    .log_y(),
            );
        let svg = fig.to_svg().unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("sin") && svg.contains("SSE"));
    }

    /// A long record draws as what the panel's pixels can show: a trace of
    /// 200 000 samples made a 20 MB figure. The envelope stays: the lowest
    /// and the highest sample of every column, a lone spike among them.
    #[test]
    fn a_long_series_draws_as_its_pixels_show_it() {
        let n = 200_000;
        let t: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let mut y: Vec<f64> = t
            .iter()
            .map(|v| (v * 0.5).sin() + 0.01 * (v * 977.0).sin())
            .collect();
        y[123_457] = 5.0;
        let loop_x: Vec<f64> = t.iter().map(|v| (v * 0.05).sin()).collect();
        let svg = |panel: Panel| Figure::new("long").with(panel).to_svg().unwrap();
        let trace =
            svg(Panel::new("trace", "t", "y").with(Series::line("y", t.clone(), y.clone())));
        let loop_ = svg(Panel::new("loop", "u", "y").with(Series::points("y", loop_x, y.clone())));
        assert!(trace.len() < 1_000_000, "{} bytes", trace.len());
        assert!(loop_.len() < 1_000_000, "{} bytes", loop_.len());
        // The spike is drawn, and the lowest sample, and the last.
        let pixel = |p: &(f64, f64)| ((p.0 * 20.0) as i32, (p.1 * 1000.0) as i32);
        let pts: Vec<(f64, f64)> = t.iter().copied().zip(y.iter().copied()).collect();
        let kept = thinned(pts, Style::Line, pixel);
        assert!(kept.len() < n / 10, "{}", kept.len());
        assert!(kept.contains(&(t[123_457], 5.0)));
        let lowest = y.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(kept.iter().any(|p| p.1 == lowest));
        assert_eq!(kept.last(), Some(&(t[n - 1], y[n - 1])));
        // Points: one a pixel, none lost from a pixel not yet drawn.
        assert_eq!(trace.matches("<circle").count(), 0);
        let circles: Vec<&str> = loop_
            .match_indices("<circle")
            .map(|(at, _)| &loop_[at..at + 30])
            .collect();
        let distinct: std::collections::HashSet<&&str> = circles.iter().collect();
        assert_eq!(distinct.len(), circles.len());
        // A short series is drawn whole.
        let short: Vec<(f64, f64)> = (0..999).map(|k| (k as f64, 0.0)).collect();
        assert_eq!(thinned(short.clone(), Style::Line, pixel), short);
    }

    #[test]
    fn a_log_tick_reads_as_its_decade() {
        assert_eq!(log_tick(&9.999999999999999e-6), "1e-5");
        assert_eq!(log_tick(&2500.0), "2.5e3");
        assert_eq!(log_tick(&0.12345), "1.235e-1");
        // A log axis over 1e-7..1e-3 draws its decades so.
        let x = vec![0.0, 1.0];
        let svg = Figure::new("t")
            .with(
                Panel::new("log", "x", "y")
                    .with(Series::line("s", x, vec![1e-7, 1e-3]))
                    .log_y(),
            )
            .to_svg()
            .unwrap();
        assert!(svg.contains("\n1e-5\n") && !svg.contains("99999"), "{svg}");
    }
}

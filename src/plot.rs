//! Line charts (plotters) written as PNG and SVG side by side, atomically.

use std::path::Path;

use plotters::prelude::*;

use crate::error::{Error, Result};

/// One named series of (x, y) points.
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
}

pub struct LineChart<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub series: Vec<Series>,
    /// Logarithmic y axis (for values spanning decades, e.g. cycles per frame across modes).
    pub log_y: bool,
}

const PALETTE: [RGBColor; 12] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
    RGBColor(0, 0, 0),
    RGBColor(255, 187, 120),
];

impl LineChart<'_> {
    /// Writes `stem.png` and `stem.svg`.
    pub fn write(&self, stem: &Path) -> Result<()> {
        let png = stem.with_extension("png");
        let svg = stem.with_extension("svg");
        let (w, h) = (900u32, 560u32);
        // plotters writes to a path itself: draw into temporary names, then rename, so an error
        // never leaves a half-drawn chart under the real name.
        let tmp_png = stem.with_extension("tmp.png");
        let tmp_svg = stem.with_extension("tmp.svg");
        if let Some(dir) = stem.parent() {
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        }
        let result = (|| -> std::result::Result<(), String> {
            self.draw(BitMapBackend::new(&tmp_png, (w, h)).into_drawing_area())?;
            self.draw(SVGBackend::new(&tmp_svg, (w, h)).into_drawing_area())?;
            Ok(())
        })();
        if let Err(message) = result {
            let _ = std::fs::remove_file(&tmp_png);
            let _ = std::fs::remove_file(&tmp_svg);
            return Err(Error::Invalid(format!(
                "drawing {}: {message}",
                png.display()
            )));
        }
        std::fs::rename(&tmp_png, &png).map_err(|e| Error::io(&png, e))?;
        std::fs::rename(&tmp_svg, &svg).map_err(|e| Error::io(&svg, e))?;
        Ok(())
    }

    fn draw<DB: DrawingBackend>(
        &self,
        area: DrawingArea<DB, plotters::coord::Shift>,
    ) -> std::result::Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        area.fill(&WHITE).map_err(err)?;
        let all = self.series.iter().flat_map(|s| s.points.iter());
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &(x, y) in all {
            if x.is_finite() && y.is_finite() {
                x0 = x0.min(x);
                x1 = x1.max(x);
                y0 = y0.min(y);
                y1 = y1.max(y);
            }
        }
        if x0 > x1 {
            (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
        }
        let mut builder = ChartBuilder::on(&area);
        builder
            .caption(self.title, ("sans-serif", 22))
            .margin(14)
            .x_label_area_size(44)
            .y_label_area_size(72);
        let x_range = x0..x1.max(x0 + 1e-9);
        // A log axis only pays when the values span a decade; below that plotters has few
        // labels to put on it.
        let positive_min = self
            .series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.1))
            .filter(|y| y.is_finite() && *y > 0.0)
            .fold(f64::MAX, f64::min);
        if self.log_y && y1 / positive_min > 8.0 {
            let low = self
                .series
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.1))
                .filter(|y| y.is_finite() && *y > 0.0)
                .fold(f64::MAX, f64::min)
                .min(y1.max(1e-9))
                / 1.3;
            // log10 values on a linear axis, labelled with the values at 1, 2, 5 × 10^k (or
            // finer when the span is short): plotters' own log axis labels only whole decades.
            let high = y1.max(low) * 1.3;
            let y_axis = LogAxis {
                linear: (low.log10()..high.log10()).into(),
                ticks: log_ticks(low, high),
                grid: log_grid(low, high),
            };
            let chart = builder
                .build_cartesian_2d(x_range.clone(), y_axis)
                .map_err(err)?;
            self.draw_lines(chart, true, (x_range, low.log10()..high.log10()))?;
        } else {
            let pad = ((y1 - y0) * 0.05).max(1e-9);
            let y_range = (y0 - pad)..(y1 + pad);
            let chart = builder
                .build_cartesian_2d(x_range.clone(), y_range.clone())
                .map_err(err)?;
            self.draw_lines(chart, false, (x_range, y_range))?;
        }
        area.present().map_err(err)?;
        Ok(())
    }

    fn draw_lines<'a, DB: DrawingBackend + 'a, Y>(
        &self,
        mut chart: ChartContext<'a, DB, Cartesian2d<plotters::coord::types::RangedCoordf64, Y>>,
        log: bool,
        (x_range, y_range): (std::ops::Range<f64>, std::ops::Range<f64>),
    ) -> std::result::Result<(), String>
    where
        DB::ErrorType: 'static,
        Y: Ranged<ValueType = f64> + plotters::coord::ranged1d::ValueFormatter<f64>,
    {
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        // Integer x values (frames, exponents, counts) get integer ticks.
        let xs: Vec<f64> = self
            .series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.0))
            .filter(|x| x.is_finite())
            .collect();
        let integer_x = !xs.is_empty() && xs.iter().all(|x| x.fract() == 0.0);
        let span =
            xs.iter().fold(f64::MIN, |a, &b| a.max(b)) - xs.iter().fold(f64::MAX, |a, &b| a.min(b));
        let x_ticks = if integer_x && span <= 12.0 {
            span as usize + 1
        } else {
            10
        };
        let x_format = |x: &f64| {
            if integer_x {
                format!("{}", x.round() as i64)
            } else {
                format!("{x:.2}")
            }
        };
        chart
            .configure_mesh()
            .x_desc(self.x_label)
            .y_desc(if log {
                format!("{} (log scale)", self.y_label)
            } else {
                self.y_label.to_string()
            })
            .x_labels(x_ticks)
            .y_labels(12)
            .x_label_formatter(&x_format)
            .y_label_formatter(&|y: &f64| si_number(if log { 10f64.powf(*y) } else { *y }))
            .label_style(("sans-serif", 15))
            .draw()
            .map_err(err)?;
        let drawn: Vec<Vec<(f64, f64)>> = self
            .series
            .iter()
            .map(|s| {
                s.points
                    .iter()
                    .copied()
                    .filter(|(x, y)| x.is_finite() && y.is_finite() && (!log || *y > 0.0))
                    .map(|(x, y)| (x, if log { y.log10() } else { y }))
                    .collect()
            })
            .collect();
        for (i, (s, points)) in self.series.iter().zip(&drawn).enumerate() {
            let colour = PALETTE[i % PALETTE.len()];
            chart
                .draw_series(LineSeries::new(
                    points.iter().copied(),
                    colour.stroke_width(2),
                ))
                .map_err(err)?
                .label(s.name.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
                });
            chart
                .draw_series(points.iter().map(|&p| Circle::new(p, 3, colour.filled())))
                .map_err(err)?;
        }
        let longest_name = self.series.iter().map(|s| s.name.chars().count()).max();
        let legend_size = (
            (longest_name.unwrap_or(0) as f64 * 8.0 + 50.0) / PLOT_AREA.0,
            (self.series.len() as f64 * 20.0 + 12.0) / PLOT_AREA.1,
        );
        chart
            .configure_series_labels()
            .position(emptiest_corner(&drawn, &x_range, &y_range, legend_size))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 15))
            .draw()
            .map_err(err)?;
        Ok(())
    }
}

/// The plotting area inside the axes, in pixels (approximately: the chart size less label areas,
/// margins and caption); used to size the legend in the chart's coordinates.
const PLOT_AREA: (f64, f64) = (790.0, 440.0);

/// The legend corner that covers the fewest data points (lines are sampled between their
/// points), preferring the upper right on ties. `legend_size` is the legend's width and height as
/// fractions of the plotting area.
fn emptiest_corner(
    series: &[Vec<(f64, f64)>],
    x: &std::ops::Range<f64>,
    y: &std::ops::Range<f64>,
    legend_size: (f64, f64),
) -> SeriesLabelPosition {
    let to_unit = |(px, py): (f64, f64)| {
        (
            (px - x.start) / (x.end - x.start).max(1e-12),
            (py - y.start) / (y.end - y.start).max(1e-12),
        )
    };
    let mut samples = Vec::new();
    for points in series {
        for pair in points.windows(2) {
            let (a, b) = (to_unit(pair[0]), to_unit(pair[1]));
            for k in 0..16 {
                let t = k as f64 / 16.0;
                samples.push((a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t));
            }
        }
        samples.extend(points.last().map(|&p| to_unit(p)));
    }
    let (w, h) = (legend_size.0.min(1.0), legend_size.1.min(1.0));
    let corners = [
        (SeriesLabelPosition::UpperRight, 1.0 - w, 1.0 - h),
        (SeriesLabelPosition::UpperLeft, 0.0, 1.0 - h),
        (SeriesLabelPosition::LowerRight, 1.0 - w, 0.0),
        (SeriesLabelPosition::LowerLeft, 0.0, 0.0),
    ];
    let covered = |x0: f64, y0: f64| {
        samples
            .iter()
            .filter(|(sx, sy)| *sx >= x0 && *sx <= x0 + w && *sy >= y0 && *sy <= y0 + h)
            .count()
    };
    corners
        .into_iter()
        .min_by_key(|&(_, x0, y0)| covered(x0, y0))
        .map(|(position, _, _)| position)
        .unwrap_or(SeriesLabelPosition::UpperRight)
}

/// A y axis of log10 values with ticks at chosen round values (plotters' `WithKeyPoints` lacks the
/// value formatter its mesh needs for f64).
struct LogAxis {
    linear: plotters::coord::types::RangedCoordf64,
    ticks: Vec<f64>,
    grid: Vec<f64>,
}

impl Ranged for LogAxis {
    type ValueType = f64;
    type FormatOption = plotters::coord::ranged1d::DefaultFormatting;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        self.linear.map(value, limit)
    }

    fn key_points<Hint: plotters::coord::ranged1d::KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.grid.clone()
        } else {
            self.ticks.clone()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.linear.range()
    }
}

/// Labelled ticks of a log axis from `low` to `high` (log10 values): 1, 2, 5 × 10^k, or every
/// integer multiple when that gives too few.
fn log_ticks(low: f64, high: f64) -> Vec<f64> {
    let ticks = log_values(low, high, &[1.0, 2.0, 5.0]);
    if ticks.len() >= 4 {
        ticks
    } else {
        log_values(
            low,
            high,
            &[1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0],
        )
    }
}

/// The light grid of a log axis: every integer multiple of each decade.
fn log_grid(low: f64, high: f64) -> Vec<f64> {
    log_values(low, high, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0])
}

fn log_values(low: f64, high: f64, mantissas: &[f64]) -> Vec<f64> {
    let mut out = Vec::new();
    if !(low > 0.0 && high > low) {
        return out;
    }
    for decade in low.log10().floor() as i32..=high.log10().ceil() as i32 {
        for m in mantissas {
            let v = m * 10f64.powi(decade);
            if v >= low && v <= high {
                out.push(v.log10());
            }
        }
    }
    out
}

/// Axis numbers: 1.5M, 250k, 12.5, 0.25.
fn si_number(v: f64) -> String {
    let a = v.abs();
    let trim = |t: String| {
        if t.contains('.') {
            t.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            t
        }
    };
    if a >= 1e6 {
        format!("{}M", trim(format!("{:.2}", v / 1e6)))
    } else if a >= 1e4 {
        format!("{}k", trim(format!("{:.1}", v / 1e3)))
    } else if a >= 10.0 {
        trim(format!("{v:.1}"))
    } else {
        trim(format!("{v:.3}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_ticks_are_round_values_inside_the_range() {
        let ticks: Vec<f64> = log_ticks(1.5e6, 2.1e7)
            .into_iter()
            .map(|t| 10f64.powf(t).round())
            .collect();
        assert_eq!(ticks, vec![2e6, 5e6, 1e7, 2e7]);
        // A short span falls back to every multiple.
        let short: Vec<f64> = log_ticks(2.5e6, 4.5e6)
            .into_iter()
            .map(|t| 10f64.powf(t).round())
            .collect();
        assert_eq!(short, vec![3e6, 4e6]);
    }

    #[test]
    fn legend_goes_where_the_lines_are_not() {
        // A line rising from lower left to upper right: the upper left corner is free (the
        // lower right too, but upper corners come first).
        let rising = vec![vec![(0.0, 0.0), (1.0, 1.0)]];
        let pos = emptiest_corner(&rising, &(0.0..1.0), &(0.0..1.0), (0.3, 0.3));
        assert!(matches!(pos, SeriesLabelPosition::UpperLeft));
        // A line along the top: a lower corner.
        let top = vec![vec![(0.0, 0.95), (1.0, 0.95)]];
        let pos = emptiest_corner(&top, &(0.0..1.0), &(0.0..1.0), (0.3, 0.3));
        assert!(matches!(pos, SeriesLabelPosition::LowerRight));
    }
}

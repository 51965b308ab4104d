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
            // log10 values on a linear axis, labelled with the values: plotters' own log axis
            // labels only whole decades.
            let chart = builder
                .build_cartesian_2d(x_range, low.log10()..(y1.max(low) * 1.3).log10())
                .map_err(err)?;
            self.draw_lines(chart, true)?;
        } else {
            let pad = ((y1 - y0) * 0.05).max(1e-9);
            let chart = builder
                .build_cartesian_2d(x_range, (y0 - pad)..(y1 + pad))
                .map_err(err)?;
            self.draw_lines(chart, false)?;
        }
        area.present().map_err(err)?;
        Ok(())
    }

    fn draw_lines<'a, DB: DrawingBackend + 'a, Y>(
        &self,
        mut chart: ChartContext<'a, DB, Cartesian2d<plotters::coord::types::RangedCoordf64, Y>>,
        log: bool,
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
        for (i, s) in self.series.iter().enumerate() {
            let colour = PALETTE[i % PALETTE.len()];
            let points: Vec<(f64, f64)> = s
                .points
                .iter()
                .copied()
                .filter(|(x, y)| x.is_finite() && y.is_finite() && (!log || *y > 0.0))
                .map(|(x, y)| (x, if log { y.log10() } else { y }))
                .collect();
            chart
                .draw_series(LineSeries::new(points.clone(), colour.stroke_width(2)))
                .map_err(err)?
                .label(s.name.as_str())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
                });
            chart
                .draw_series(points.iter().map(|&p| Circle::new(p, 3, colour.filled())))
                .map_err(err)?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 15))
            .draw()
            .map_err(err)?;
        Ok(())
    }
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

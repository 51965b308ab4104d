//! Line charts and horizontal bar charts (plotters) written as PNG and SVG side by side,
//! atomically, and contact sheets of frames with a text label above each panel.
//!
//! Every series gets its own colour, line pattern (solid, dashed, dotted, long or short dashes) and point
//! marker (● □ ▲ ◇ × ▽), so identical curves stay distinguishable where they overlap and a
//! series of one point is still drawn. The legend is a column to the right of the plotting
//! area, never over the data; the title wraps over the whole width.

use std::path::{Path, PathBuf};

use plotters::coord::types::RangedCoordf64;
use plotters::coord::{CoordTranslate, Shift};
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::error::{Error, Result};
use crate::render::Frame;

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

/// What a chart may set beyond [`LineChart`]'s fields.
#[derive(Clone, Debug, Default)]
pub struct ChartOptions {
    /// Labelled x ticks at these positions (e.g. log2 of the sub-cube edge labelled `8³`, or
    /// the index of a category labelled with its name); default: round values of the range.
    pub x_ticks: Option<Vec<(f64, String)>>,
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

/// Line patterns: None is solid, Some((dash, gap)) in pixels.
const DASHES: [Option<(i32, i32)>; 5] = [
    None,
    Some((10, 5)),
    Some((2, 4)),
    Some((20, 6)),
    Some((5, 4)),
];

/// Point markers, cycled per series.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Marker {
    Circle,
    Square,
    Triangle,
    Diamond,
    Cross,
    InvertedTriangle,
}

const MARKERS: [(Marker, bool); 6] = [
    (Marker::Circle, true),
    (Marker::Square, false),
    (Marker::Triangle, true),
    (Marker::Diamond, false),
    (Marker::Cross, false),
    (Marker::InvertedTriangle, true),
];

/// How series `i` is drawn: colour, line pattern, marker (and whether it is filled).
#[derive(Clone, Copy)]
struct SeriesStyle {
    colour: RGBColor,
    dash: Option<(i32, i32)>,
    marker: Marker,
    filled: bool,
}

fn series_style(i: usize) -> SeriesStyle {
    let (marker, filled) = MARKERS[i % MARKERS.len()];
    SeriesStyle {
        colour: PALETTE[i % PALETTE.len()],
        dash: DASHES[i % DASHES.len()],
        marker,
        filled,
    }
}

/// The chart's size without the legend column.
const CHART_SIZE: (u32, u32) = (900, 560);
const TITLE_FONT: u32 = 22;
const LABEL_FONT: u32 = 15;
const LEGEND_ROW: u32 = 22;
/// Legend column: the sample line (with its marker), the gap before the name, the padding.
const LEGEND_SAMPLE: u32 = 40;
const LEGEND_PAD: u32 = 10;
/// Longest legend name drawn in full (pixels); longer ones are shortened with "...".
const LEGEND_TEXT_MAX: u32 = 360;
const MARGIN: u32 = 14;

fn text_width(text: &str, size: u32) -> u32 {
    ("sans-serif", size)
        .into_font()
        .box_size(text)
        .map(|(w, _)| w)
        // Without font metrics, a generous estimate.
        .unwrap_or(text.chars().count() as u32 * size * 6 / 10)
}

/// `text` shortened with "..." to at most `max` pixels wide.
fn fit_text(text: &str, size: u32, max: u32) -> String {
    if text_width(text, size) <= max {
        return text.to_string();
    }
    let chars: Vec<char> = text.chars().collect();
    for keep in (0..chars.len()).rev() {
        let t: String = chars[..keep].iter().collect::<String>() + "...";
        if text_width(&t, size) <= max {
            return t;
        }
    }
    String::new()
}

/// Words of `text` wrapped into lines at most `max` pixels wide (a single word longer than
/// that gets its own line; `a = b` stays on one line).
fn wrap_text(text: &str, size: u32, max: u32) -> Vec<String> {
    let mut words: Vec<String> = Vec::new();
    for word in text.split(' ') {
        match words.last_mut() {
            Some(last) if word == "=" || last.ends_with(" =") => {
                last.push(' ');
                last.push_str(word);
            }
            _ => words.push(word.to_string()),
        }
    }
    let mut lines: Vec<String> = Vec::new();
    let mut line = String::new();
    for word in words {
        let candidate = if line.is_empty() {
            word.clone()
        } else {
            format!("{line} {word}")
        };
        if !line.is_empty() && text_width(&candidate, size) > max {
            lines.push(std::mem::replace(&mut line, word));
        } else {
            line = candidate;
        }
    }
    if !line.is_empty() {
        lines.push(line);
    }
    lines
}

/// Where everything goes: the canvas, the title lines, the legend column and its names.
struct Layout {
    size: (u32, u32),
    title: Vec<String>,
    title_height: u32,
    legend_width: u32,
    names: Vec<String>,
}

/// `stem` with `.ext` appended (stems may hold dots, e.g. `ray_queue.rays=8`).
fn with_suffix(stem: &Path, ext: &str) -> PathBuf {
    let mut s = stem.as_os_str().to_owned();
    s.push(".");
    s.push(ext);
    PathBuf::from(s)
}

impl LineChart<'_> {
    /// Writes `stem.png` and `stem.svg`.
    pub fn write(&self, stem: &Path) -> Result<()> {
        self.write_with(stem, &ChartOptions::default())
    }

    /// Writes `stem.png` and `stem.svg` with `options`.
    pub fn write_with(&self, stem: &Path, options: &ChartOptions) -> Result<()> {
        write_chart(&LineWithOptions(self, options), stem)
    }

    fn layout(&self) -> Layout {
        let names = self.series.iter().map(|s| s.name.as_str());
        layout_of(self.title, names, CHART_SIZE.1)
    }

    fn draw<DB: DrawingBackend>(
        &self,
        area: DrawingArea<DB, Shift>,
        layout: &Layout,
        options: &ChartOptions,
    ) -> std::result::Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        let (plot, legend) = draw_title(&area, layout).map_err(err)?;

        let log = self.log_y_pays();
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
        let (x_axis, x_labels) = self.x_axis(&drawn, options);
        let y_axis = self.y_axis(&drawn, log);
        let mut chart = ChartBuilder::on(&plot)
            .margin(MARGIN)
            .x_label_area_size(44)
            .y_label_area_size(72)
            .build_cartesian_2d(x_axis, y_axis)
            .map_err(err)?;
        let x_format = |x: &f64| {
            x_labels
                .iter()
                .find(|(at, _)| (at - x).abs() < 1e-9)
                .map(|(_, label)| label.clone())
                .unwrap_or_else(|| si_number(*x))
        };
        chart
            .configure_mesh()
            .x_desc(self.x_label)
            .y_desc(if log {
                format!("{} (log scale)", self.y_label)
            } else {
                self.y_label.to_string()
            })
            .x_label_formatter(&x_format)
            .y_label_formatter(&|y: &f64| si_number(if log { 10f64.powf(*y) } else { *y }))
            .label_style(("sans-serif", LABEL_FONT))
            .draw()
            .map_err(err)?;
        // Solid lines first, then the longest dashes down to dots: where two series coincide the
        // gaps of the later pattern show the line beneath. Markers go on top of every line.
        let mut order: Vec<usize> = (0..drawn.len()).collect();
        order.sort_by_key(|&i| match series_style(i).dash {
            None => 0,
            Some((dash, _)) => 100 - dash,
        });
        for &i in &order {
            let points = &drawn[i];
            let style = series_style(i);
            let line = style.colour.stroke_width(2);
            match style.dash {
                None => chart
                    .draw_series(LineSeries::new(points.iter().copied(), line))
                    .map(|_| ()),
                Some((dash, gap)) => chart
                    .draw_series(DashedLineSeries::new(
                        points.iter().copied(),
                        dash,
                        gap,
                        line,
                    ))
                    .map(|_| ()),
            }
            .map_err(err)?;
        }
        for (i, points) in drawn.iter().enumerate() {
            for &p in points {
                draw_marker(chart.plotting_area(), p, series_style(i)).map_err(err)?;
            }
        }
        draw_legend(&legend, layout, |legend, i, (a, b), y| {
            let style = series_style(i);
            let line = style.colour.stroke_width(2);
            match style.dash {
                None => legend.draw(&PathElement::new(vec![(a, y), (b, y)], line)),
                Some((dash, gap)) => legend.draw(&DashedPathElement::new(
                    vec![(a, y), (b, y)],
                    dash,
                    gap,
                    line,
                )),
            }?;
            draw_marker(legend, ((a + b) / 2, y), style)
        })
        .map_err(err)?;
        area.present().map_err(err)?;
        Ok(())
    }

    /// A log axis only pays when the values span a decade; below that it has few labels.
    fn log_y_pays(&self) -> bool {
        let ys = || {
            self.series
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.1))
                .filter(|y| y.is_finite() && *y > 0.0)
        };
        let (low, high) = (ys().fold(f64::MAX, f64::min), ys().fold(f64::MIN, f64::max));
        self.log_y && low < high && high / low > 8.0
    }

    /// The x axis over the drawn points, padded so markers at the ends stay inside, and the
    /// labels of explicit ticks.
    fn x_axis(
        &self,
        drawn: &[Vec<(f64, f64)>],
        options: &ChartOptions,
    ) -> (KeyedAxis, Vec<(f64, String)>) {
        let xs: Vec<f64> = drawn.iter().flatten().map(|p| p.0).collect();
        let (mut x0, mut x1) = bounds(&xs).unwrap_or((0.0, 1.0));
        if let Some(ticks) = &options.x_ticks {
            for (x, _) in ticks {
                x0 = x0.min(*x);
                x1 = x1.max(*x);
            }
        }
        let span = x1 - x0;
        // Explicit ticks (categories, sizes) are labelled at the ends too: pad a quarter step.
        let tick_step = options.x_ticks.as_ref().and_then(|ticks| {
            ticks
                .windows(2)
                .map(|w| (w[1].0 - w[0].0).abs())
                .filter(|d| *d > 0.0)
                .min_by(f64::total_cmp)
        });
        let pad = match tick_step {
            Some(step) => step * 0.25,
            None if span > 0.0 => span * 0.03,
            None => 1.0,
        };
        let linear: RangedCoordf64 = ((x0 - pad)..(x1 + pad)).into();
        if let Some(ticks) = &options.x_ticks {
            let at: Vec<f64> = ticks.iter().map(|t| t.0).collect();
            return (
                KeyedAxis {
                    linear,
                    ticks: at.clone(),
                    grid: at,
                },
                ticks.clone(),
            );
        }
        // Integer x values (frames, counts) get integer ticks: every integer over a short
        // span, else each value when there are few (frames 0, 9, 18, 27).
        let integer = !xs.is_empty() && xs.iter().all(|x| x.fract() == 0.0);
        let distinct: std::collections::BTreeSet<i64> = xs.iter().map(|x| *x as i64).collect();
        let ticks: Vec<f64> = if integer && span <= 12.0 {
            (0..=span as i64).map(|k| x0 + k as f64).collect()
        } else if integer && distinct.len() <= 12 {
            distinct.iter().map(|&x| x as f64).collect()
        } else {
            linear
                .key_points(10)
                .into_iter()
                .filter(|x| !integer || x.fract() == 0.0)
                .collect()
        };
        (
            KeyedAxis {
                grid: ticks.clone(),
                linear,
                ticks,
            },
            Vec::new(),
        )
    }

    /// The y axis: log10 values ticked at 1, 2, 5 × 10^k, or linear, padded 5 %.
    fn y_axis(&self, drawn: &[Vec<(f64, f64)>], log: bool) -> KeyedAxis {
        let ys: Vec<f64> = drawn.iter().flatten().map(|p| p.1).collect();
        let (y0, y1) = bounds(&ys).unwrap_or((0.0, 1.0));
        if log {
            // log10 values on a linear axis, labelled with the values at 1, 2, 5 × 10^k (or
            // finer when the span is short): plotters' own log axis labels only whole decades.
            let (low, high) = (10f64.powf(y0) / 1.3, 10f64.powf(y1) * 1.3);
            return KeyedAxis {
                linear: (low.log10()..high.log10()).into(),
                ticks: log_ticks(low, high),
                grid: log_grid(low, high),
            };
        }
        let span = y1 - y0;
        let pad = if span > 0.0 {
            span * 0.05
        } else {
            (y0.abs() * 0.05).max(1e-3)
        };
        let linear: RangedCoordf64 = ((y0 - pad)..(y1 + pad)).into();
        let ticks = linear.key_points(12);
        KeyedAxis {
            grid: linear.key_points(40),
            linear,
            ticks,
        }
    }
}

/// One named series of a bar chart: a value per category (`None`: no bar there).
pub struct BarSeries {
    pub name: String,
    pub values: Vec<Option<f64>>,
}

/// Horizontal grouped bars: one group per category, listed top to bottom, one bar per series
/// in each group, its value written at its end. The largest value of each series is marked
/// "fastest" when `mark_largest` (a frame-rate chart), every bar that equals it.
pub struct BarChart<'a> {
    pub title: &'a str,
    pub value_label: &'a str,
    pub categories: Vec<String>,
    pub series: Vec<BarSeries>,
    pub mark_largest: Option<&'a str>,
}

/// A bar's thickness and the gap between groups (pixels).
const BAR_HEIGHT: u32 = 16;
const BAR_GROUP_GAP: u32 = 12;
const BAR_VALUE_FONT: u32 = 13;
/// The x axis's label area below the bars (pixels).
const X_LABEL_AREA: u32 = 44;

impl BarChart<'_> {
    /// Writes `stem.png` and `stem.svg`.
    pub fn write(&self, stem: &Path) -> Result<()> {
        write_chart(self, stem)
    }

    /// The text at the end of series `s`'s bar in category `c`.
    fn value_text(&self, s: usize, c: usize) -> Option<String> {
        let v = self.series[s].values.get(c).copied().flatten()?;
        let best = self.series[s]
            .values
            .iter()
            .flatten()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        Some(match self.mark_largest {
            Some(word) if v >= best => format!("{} {word}", bar_number(v)),
            _ => bar_number(v),
        })
    }
}

impl Chart for BarChart<'_> {
    fn layout(&self) -> Layout {
        let group = self.series.len().max(1) as u32 * BAR_HEIGHT + BAR_GROUP_GAP;
        let body = self.categories.len() as u32 * group + X_LABEL_AREA + 2 * MARGIN;
        layout_of(
            self.title,
            self.series.iter().map(|s| s.name.as_str()),
            body.max(240),
        )
    }

    fn draw<DB: DrawingBackend>(
        &self,
        area: DrawingArea<DB, Shift>,
        layout: &Layout,
    ) -> std::result::Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        let (plot, legend) = draw_title(&area, layout).map_err(err)?;
        let n = self.categories.len();
        let values = || {
            self.series
                .iter()
                .flat_map(|s| s.values.iter().flatten().copied())
                .filter(|v| v.is_finite())
        };
        let high = values().fold(0.0, f64::max);
        let low = values().fold(0.0, f64::min);
        // Room right of the longest bar for its value and the mark.
        let longest_text = (0..self.series.len())
            .flat_map(|s| (0..n).filter_map(move |c| self.value_text(s, c)))
            .map(|t| text_width(&t, BAR_VALUE_FONT))
            .max()
            .unwrap_or(0);
        let labels: Vec<String> = self
            .categories
            .iter()
            .map(|c| fit_text(c, LABEL_FONT, LEGEND_TEXT_MAX))
            .collect();
        let label_area = labels
            .iter()
            .map(|l| text_width(l, LABEL_FONT))
            .max()
            .unwrap_or(0)
            + 16;
        let plot_width = (layout.size.0 - layout.legend_width)
            .saturating_sub(label_area + 2 * MARGIN)
            .max(1);
        let span = if high > low { high - low } else { 1.0 };
        // The value text needs `longest_text` of the plot's pixels beyond the longest bar.
        let room = (longest_text + 10) as f64 / plot_width as f64;
        let right = high + span * (room / (1.0 - room).max(0.2));
        let x_axis: RangedCoordf64 = (low..right).into();
        let x_ticks = x_axis.key_points(10);
        // Category c at y = n - 1 - c, so the first is at the top.
        let y_axis = KeyedAxis {
            linear: (-0.5..n as f64 - 0.5).into(),
            ticks: (0..n).map(|c| c as f64).collect(),
            grid: Vec::new(),
        };
        let mut chart = ChartBuilder::on(&plot)
            .margin(MARGIN)
            .x_label_area_size(X_LABEL_AREA)
            .y_label_area_size(label_area)
            .build_cartesian_2d(
                KeyedAxis {
                    linear: x_axis,
                    grid: x_ticks.clone(),
                    ticks: x_ticks,
                },
                y_axis,
            )
            .map_err(err)?;
        let category_of = |y: &f64| -> String {
            let c = n as i64 - 1 - y.round() as i64;
            usize::try_from(c)
                .ok()
                .and_then(|c| labels.get(c))
                .cloned()
                .unwrap_or_default()
        };
        chart
            .configure_mesh()
            .disable_y_mesh()
            .x_desc(self.value_label)
            .x_label_formatter(&|x: &f64| si_number(*x))
            .y_label_formatter(&category_of)
            .label_style(("sans-serif", LABEL_FONT))
            .draw()
            .map_err(err)?;
        let k = self.series.len().max(1) as f64;
        // The group fills this share of a category's height; the rest is the gap.
        let band = k * BAR_HEIGHT as f64 / (k * BAR_HEIGHT as f64 + BAR_GROUP_GAP as f64);
        let thickness = band / k;
        let text_style = ("sans-serif", BAR_VALUE_FONT)
            .into_text_style(chart.plotting_area())
            .pos(Pos::new(HPos::Left, VPos::Center));
        for (s, series) in self.series.iter().enumerate() {
            let colour = series_style(s).colour;
            for (c, value) in series.values.iter().enumerate() {
                let Some(v) = value.filter(|v| v.is_finite()) else {
                    continue;
                };
                let top = (n - 1 - c) as f64 + band / 2.0 - s as f64 * thickness;
                let bottom = top - thickness;
                let inset = thickness * 0.08;
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        [(0.0, bottom + inset), (v, top - inset)],
                        colour.filled(),
                    )))
                    .map_err(err)?;
                if let Some(text) = self.value_text(s, c) {
                    chart
                        .plotting_area()
                        .draw(
                            &(EmptyElement::at((v.max(0.0), (top + bottom) / 2.0))
                                + Text::new(text, (4, 0), text_style.clone())),
                        )
                        .map_err(err)?;
                }
            }
        }
        draw_legend(&legend, layout, |legend, i, (a, b), y| {
            let half = (LEGEND_ROW as i32 - 8) / 2;
            legend.draw(&Rectangle::new(
                [(a, y - half), (b, y + half)],
                series_style(i).colour.filled(),
            ))
        })
        .map_err(err)?;
        area.present().map_err(err)?;
        Ok(())
    }
}

/// A chart `write_chart` can draw: its layout and its drawing on any backend.
trait Chart {
    fn layout(&self) -> Layout;
    fn draw<DB: DrawingBackend>(
        &self,
        area: DrawingArea<DB, Shift>,
        layout: &Layout,
    ) -> std::result::Result<(), String>
    where
        DB::ErrorType: 'static;
}

struct LineWithOptions<'c, 'a>(&'c LineChart<'a>, &'c ChartOptions);

impl Chart for LineWithOptions<'_, '_> {
    fn layout(&self) -> Layout {
        self.0.layout()
    }

    fn draw<DB: DrawingBackend>(
        &self,
        area: DrawingArea<DB, Shift>,
        layout: &Layout,
    ) -> std::result::Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        self.0.draw(area, layout, self.1)
    }
}

/// Writes `stem.png` and `stem.svg`.
fn write_chart(chart: &impl Chart, stem: &Path) -> Result<()> {
    let png = with_suffix(stem, "png");
    let svg = with_suffix(stem, "svg");
    let layout = chart.layout();
    // plotters writes to a path itself: draw into temporary names, then rename, so an error
    // never leaves a half-drawn chart under the real name.
    // (hidden, with this process's id, so a later run removes what a kill left behind).
    let tmp_png = crate::output::temporary_path_keeping_extension(&png)?;
    let tmp_svg = crate::output::temporary_path_keeping_extension(&svg)?;
    // Made here first, so that a folder that cannot be written is an error naming the file,
    // not the drawing backend's debug text.
    for (tmp, real) in [(&tmp_png, &png), (&tmp_svg, &svg)] {
        if let Err(e) = std::fs::File::create(tmp) {
            let _ = std::fs::remove_file(&tmp_png);
            return Err(Error::io(real, e));
        }
    }
    let result = (|| -> std::result::Result<(), String> {
        chart.draw(
            BitMapBackend::new(&tmp_png, layout.size).into_drawing_area(),
            &layout,
        )?;
        chart.draw(
            SVGBackend::new(&tmp_svg, layout.size).into_drawing_area(),
            &layout,
        )?;
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
    // Placed with the command's other outputs when it writes them all or none.
    if let Err(e) = crate::output::place_finished(&tmp_png, &png) {
        let _ = std::fs::remove_file(&tmp_svg);
        return Err(e);
    }
    crate::output::place_finished(&tmp_svg, &svg)
}

/// The canvas for a chart titled `title` with a legend of `names` and a plotting area
/// `body_height` pixels high (the legend may make it higher).
fn layout_of<'n>(title: &str, names: impl Iterator<Item = &'n str>, body_height: u32) -> Layout {
    let names: Vec<String> = names
        .map(|n| fit_text(n, LABEL_FONT, LEGEND_TEXT_MAX))
        .collect();
    let longest = names
        .iter()
        .map(|n| text_width(n, LABEL_FONT))
        .max()
        .unwrap_or(0);
    let legend_width = if names.is_empty() {
        0
    } else {
        LEGEND_SAMPLE + longest + 3 * LEGEND_PAD
    };
    let width = CHART_SIZE.0 + legend_width;
    let title = wrap_text(title, TITLE_FONT, width - 2 * MARGIN);
    let title_height = MARGIN + title.len() as u32 * (TITLE_FONT + 6);
    let legend_height = names.len() as u32 * LEGEND_ROW + 2 * LEGEND_PAD + 2 * MARGIN;
    let height = (body_height + title_height).max(title_height + legend_height);
    Layout {
        size: (width, height),
        title,
        title_height,
        legend_width,
        names,
    }
}

type Area<DB> = DrawingArea<DB, Shift>;
type Drawn<T, DB> = std::result::Result<T, DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// Fills the canvas white and draws the title; returns the plotting area and the legend column.
fn draw_title<DB: DrawingBackend>(
    area: &Area<DB>,
    layout: &Layout,
) -> Drawn<(Area<DB>, Area<DB>), DB> {
    area.fill(&WHITE)?;
    let title_style = ("sans-serif", TITLE_FONT)
        .into_text_style(area)
        .pos(Pos::new(HPos::Center, VPos::Top));
    for (i, line) in layout.title.iter().enumerate() {
        area.draw_text(
            line,
            &title_style,
            (
                layout.size.0 as i32 / 2,
                (MARGIN + i as u32 * (TITLE_FONT + 6)) as i32,
            ),
        )?;
    }
    let (_, body) = area.split_vertically(layout.title_height);
    Ok(body.split_horizontally(layout.size.0 - layout.legend_width))
}

/// The legend: a framed column right of the plotting area, top-aligned with it; `sample` draws
/// series `i`'s sample between x = a and b at height y.
fn draw_legend<DB: DrawingBackend>(
    legend: &Area<DB>,
    layout: &Layout,
    sample: impl Fn(
        &Area<DB>,
        usize,
        (i32, i32),
        i32,
    ) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>>,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    if layout.names.is_empty() {
        return Ok(());
    }
    let rows = layout.names.len() as i32;
    let (x0, y0) = (LEGEND_PAD as i32 / 2, MARGIN as i32);
    let box_w = layout.legend_width as i32 - LEGEND_PAD as i32;
    let box_h = rows * LEGEND_ROW as i32 + 2 * LEGEND_PAD as i32;
    legend.draw(&Rectangle::new(
        [(x0, y0), (x0 + box_w, y0 + box_h)],
        BLACK.stroke_width(1),
    ))?;
    let text_style = ("sans-serif", LABEL_FONT)
        .into_text_style(legend)
        .pos(Pos::new(HPos::Left, VPos::Center));
    for (i, name) in layout.names.iter().enumerate() {
        let y = y0 + LEGEND_PAD as i32 + i as i32 * LEGEND_ROW as i32 + LEGEND_ROW as i32 / 2;
        let (a, b) = (
            x0 + LEGEND_PAD as i32,
            x0 + (LEGEND_PAD + LEGEND_SAMPLE) as i32 - 6,
        );
        sample(legend, i, (a, b), y)?;
        legend.draw_text(
            name,
            &text_style,
            (x0 + (LEGEND_PAD + LEGEND_SAMPLE) as i32, y),
        )?;
    }
    Ok(())
}

fn bounds(values: &[f64]) -> Option<(f64, f64)> {
    let finite = values.iter().copied().filter(|v| v.is_finite());
    let low = finite.clone().fold(f64::MAX, f64::min);
    let high = finite.fold(f64::MIN, f64::max);
    (low <= high).then_some((low, high))
}

/// Draws a series' marker centred at `at` (in the area's coordinates).
fn draw_marker<DB: DrawingBackend, CT: CoordTranslate>(
    area: &DrawingArea<DB, CT>,
    at: CT::From,
    style: SeriesStyle,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let r = 5;
    let shape = if style.filled {
        style.colour.filled()
    } else {
        style.colour.stroke_width(2)
    };
    let centre = EmptyElement::at(at);
    let closed = |points: Vec<(i32, i32)>| {
        let mut path = points.clone();
        path.push(points[0]);
        path
    };
    let triangle = vec![(0, -r - 1), (r + 1, r), (-r - 1, r)];
    let inverted = vec![(0, r + 1), (r + 1, -r), (-r - 1, -r)];
    let diamond = vec![(0, -r - 1), (r + 1, 0), (0, r + 1), (-r - 1, 0)];
    match (style.marker, style.filled) {
        (Marker::Circle, _) => area.draw(&(centre + Circle::new((0, 0), r, shape))),
        (Marker::Square, _) => {
            area.draw(&(centre + Rectangle::new([(-r + 1, -r + 1), (r - 1, r - 1)], shape)))
        }
        (Marker::Cross, _) => area.draw(
            &(centre
                + PathElement::new(vec![(-r, -r), (r, r)], shape)
                + PathElement::new(vec![(-r, r), (r, -r)], shape)),
        ),
        (Marker::Triangle, true) => area.draw(&(centre + Polygon::new(triangle, shape))),
        (Marker::InvertedTriangle, true) => area.draw(&(centre + Polygon::new(inverted, shape))),
        (Marker::Diamond, true) => area.draw(&(centre + Polygon::new(diamond, shape))),
        (Marker::Triangle, false) => {
            area.draw(&(centre + PathElement::new(closed(triangle), shape)))
        }
        (Marker::InvertedTriangle, false) => {
            area.draw(&(centre + PathElement::new(closed(inverted), shape)))
        }
        (Marker::Diamond, false) => area.draw(&(centre + PathElement::new(closed(diamond), shape))),
    }
}

/// An axis of values on a linear scale (log10 values for a log axis) with ticks and grid lines
/// at chosen values (plotters' `WithKeyPoints` lacks the value formatter its mesh needs for
/// f64).
struct KeyedAxis {
    linear: RangedCoordf64,
    ticks: Vec<f64>,
    grid: Vec<f64>,
}

impl Ranged for KeyedAxis {
    type ValueType = f64;
    type FormatOption = plotters::coord::ranged1d::DefaultFormatting;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        self.linear.map(value, limit)
    }

    fn key_points<Hint: plotters::coord::ranged1d::KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        let range = self.linear.range();
        let inside = |v: &&f64| range.start <= **v && **v <= range.end;
        if hint.weight().allow_light_points() {
            self.grid.iter().filter(inside).copied().collect()
        } else {
            self.ticks.iter().filter(inside).copied().collect()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.linear.range()
    }
}

/// Label strip font size and line height over each panel of a contact sheet (pixels).
const SHEET_FONT: u32 = 13;
const SHEET_LINE: u32 = 16;
/// The label strip's background (dark grey; the text is white).
pub const SHEET_STRIP_BACKGROUND: [u8; 4] = [40, 40, 40, 255];
const SHEET_SEPARATOR: [u8; 4] = [110, 110, 110, 255];

/// The height of a label strip of `lines` lines of text.
pub fn label_strip_height(lines: usize) -> u32 {
    lines as u32 * SHEET_LINE + 6
}

/// Tiles frames of equal size into one image, `columns` per row, each panel under a strip with
/// its label lines (white on dark grey, drawn with the charts' font; a line too wide for the
/// panel is set smaller, then shortened with "..."). All panels have the same size: the frame's
/// plus a strip as high as the most lines any label has.
pub fn contact_sheet(panels: &[(&Frame, Vec<String>)], columns: usize) -> Result<Frame> {
    let Some((first, _)) = panels.first() else {
        return Err(Error::Invalid(
            "a contact sheet needs at least one frame".into(),
        ));
    };
    let (w, h) = (first.width, first.height);
    if let Some((f, _)) = panels.iter().find(|(f, _)| (f.width, f.height) != (w, h)) {
        return Err(Error::Invalid(format!(
            "contact sheet: a {}x{} frame among {w}x{h} frames",
            f.width, f.height
        )));
    }
    let strip = label_strip_height(panels.iter().map(|(_, l)| l.len()).max().unwrap_or(0));
    let columns = columns.max(1);
    let cols = columns.min(panels.len()) as u32;
    let rows = panels.len().div_ceil(columns) as u32;
    let (cell_w, cell_h) = (w, h + strip);
    let (sheet_w, sheet_h) = (cell_w * cols, cell_h * rows);
    // RGB, as plotters' bitmap backend draws.
    let mut rgb = vec![0u8; (sheet_w * sheet_h * 3) as usize];
    for (i, (frame, _)) in panels.iter().enumerate() {
        let (ox, oy) = ((i as u32 % cols) * cell_w, (i as u32 / cols) * cell_h);
        for y in 0..strip {
            for x in 0..w {
                let at = (((oy + y) * sheet_w + ox + x) * 3) as usize;
                // A lighter line left of the strip separates it from its neighbour's.
                let colour = if x == 0 && ox > 0 {
                    &SHEET_SEPARATOR
                } else {
                    &SHEET_STRIP_BACKGROUND
                };
                rgb[at..at + 3].copy_from_slice(&colour[..3]);
            }
        }
        for y in 0..h {
            for x in 0..w {
                let [r, g, b, a] = frame.pixels[(y * w + x) as usize];
                // Over black, as the frame would show on the sheet.
                let over = |c: u8| (c as u32 * a as u32 / 255) as u8;
                let at = (((oy + strip + y) * sheet_w + ox + x) * 3) as usize;
                rgb[at..at + 3].copy_from_slice(&[over(r), over(g), over(b)]);
            }
        }
    }
    {
        let area = BitMapBackend::with_buffer(&mut rgb, (sheet_w, sheet_h)).into_drawing_area();
        let err = |e: DrawingAreaErrorKind<_>| Error::Invalid(format!("contact sheet label: {e}"));
        for (i, (_, lines)) in panels.iter().enumerate() {
            let (ox, oy) = ((i as u32 % cols) * cell_w, (i as u32 / cols) * cell_h);
            for (k, line) in lines.iter().enumerate() {
                let room = w.saturating_sub(8);
                let size = (8..=SHEET_FONT)
                    .rev()
                    .find(|&s| text_width(line, s) <= room)
                    .unwrap_or(8);
                let text = fit_text(line, size, room);
                let style = ("sans-serif", size)
                    .into_font()
                    .color(&WHITE)
                    .pos(Pos::new(HPos::Left, VPos::Center));
                let y = oy + 3 + k as u32 * SHEET_LINE + SHEET_LINE / 2;
                area.draw_text(&text, &style, (ox as i32 + 4, y as i32))
                    .map_err(err)?;
            }
        }
        area.present().map_err(err)?;
    }
    Ok(Frame {
        width: sheet_w,
        height: sheet_h,
        pixels: rgb
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2], 255])
            .collect(),
        rays: Vec::new(),
    })
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

/// A bar's value to three significant digits (5.72, 14.0, 49.6, 123), so bars read alike; from
/// 10,000 up as the axis writes it (12.5k).
fn bar_number(v: f64) -> String {
    if v.abs() >= 1e4 || v == 0.0 || !v.is_finite() {
        return si_number(v);
    }
    let decimals = (2 - v.abs().log10().floor() as i32).max(0) as usize;
    format!("{v:.decimals$}")
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
    fn series_styles_differ_in_more_than_colour() {
        // Neighbouring series (the likeliest to be identical curves) differ in pattern and marker.
        for i in 0..11 {
            let (a, b) = (series_style(i), series_style(i + 1));
            assert_ne!(a.dash, b.dash);
            assert_ne!(a.marker, b.marker);
        }
    }

    #[test]
    fn titles_wrap_between_words_but_not_around_equals_signs() {
        let title = "fuel: frame rate against skip.latency at ray_queue.rays = 8, ray_queue.selection = lagging-first (cycle model)";
        let lines = wrap_text(title, TITLE_FONT, 400);
        assert!(lines.len() > 1, "{lines:?}");
        assert_eq!(lines.join(" "), title);
        assert!(
            lines.iter().any(|l| l.contains("ray_queue.rays = 8")),
            "{lines:?}"
        );
        assert!(lines
            .iter()
            .all(|l| !l.starts_with('=') && !l.ends_with('=')));
    }

    #[test]
    fn stems_keep_their_dots() {
        let stem = Path::new("out/cycle-fps-vs-skip.latency-fuel-ray_queue.rays=8");
        assert_eq!(
            with_suffix(stem, "png"),
            Path::new("out/cycle-fps-vs-skip.latency-fuel-ray_queue.rays=8.png")
        );
    }

    #[test]
    fn bar_values_have_three_significant_digits() {
        let texts: Vec<String> = [5.7189, 14.0, 49.64, 123.4, 0.04567, 0.0, 25_300.0]
            .into_iter()
            .map(bar_number)
            .collect();
        assert_eq!(
            texts,
            ["5.72", "14.0", "49.6", "123", "0.0457", "0", "25.3k"]
        );
    }

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
}

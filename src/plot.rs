//! Line charts (plotters) written as PNG and SVG side by side, atomically, and contact sheets
//! of frames with a text label above each panel.
//!
//! Every series gets its own colour, line pattern (solid, dashed, dotted, long or short dashes) and point
//! marker (● □ ▲ ◇ × ▽), so identical curves stay distinguishable where they overlap and a
//! series of one point is still drawn. The legend is a column to the right of the plotting
//! area, never over the data; the title wraps over the whole width.

use std::path::{Path, PathBuf};

use plotters::coord::types::RangedCoordf64;
use plotters::coord::CoordTranslate;
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
        let png = with_suffix(stem, "png");
        let svg = with_suffix(stem, "svg");
        let layout = self.layout();
        // plotters writes to a path itself: draw into temporary names, then rename, so an error
        // never leaves a half-drawn chart under the real name.
        // (hidden, with this process's id, so a later run removes what a kill left behind).
        let tmp_png = crate::output::temporary_path_keeping_extension(&png)?;
        let tmp_svg = crate::output::temporary_path_keeping_extension(&svg)?;
        let result = (|| -> std::result::Result<(), String> {
            self.draw(
                BitMapBackend::new(&tmp_png, layout.size).into_drawing_area(),
                &layout,
                options,
            )?;
            self.draw(
                SVGBackend::new(&tmp_svg, layout.size).into_drawing_area(),
                &layout,
                options,
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

    fn layout(&self) -> Layout {
        let names: Vec<String> = self
            .series
            .iter()
            .map(|s| fit_text(&s.name, LABEL_FONT, LEGEND_TEXT_MAX))
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
        let title = wrap_text(self.title, TITLE_FONT, width - 2 * MARGIN);
        let title_height = MARGIN + title.len() as u32 * (TITLE_FONT + 6);
        let legend_height = names.len() as u32 * LEGEND_ROW + 2 * LEGEND_PAD + 2 * MARGIN;
        let height = (CHART_SIZE.1 + title_height).max(title_height + legend_height);
        Layout {
            size: (width, height),
            title,
            title_height,
            legend_width,
            names,
        }
    }

    fn draw<DB: DrawingBackend>(
        &self,
        area: DrawingArea<DB, plotters::coord::Shift>,
        layout: &Layout,
        options: &ChartOptions,
    ) -> std::result::Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        area.fill(&WHITE).map_err(err)?;
        let title_style = ("sans-serif", TITLE_FONT)
            .into_text_style(&area)
            .pos(Pos::new(HPos::Center, VPos::Top));
        for (i, line) in layout.title.iter().enumerate() {
            area.draw_text(
                line,
                &title_style,
                (
                    layout.size.0 as i32 / 2,
                    (MARGIN + i as u32 * (TITLE_FONT + 6)) as i32,
                ),
            )
            .map_err(err)?;
        }
        let (_, body) = area.split_vertically(layout.title_height);
        let (plot, legend) = body.split_horizontally(layout.size.0 - layout.legend_width);

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
        // The legend: a framed column right of the plotting area, top-aligned with it.
        if !layout.names.is_empty() {
            let rows = layout.names.len() as i32;
            let (x0, y0) = (LEGEND_PAD as i32 / 2, MARGIN as i32);
            let box_w = layout.legend_width as i32 - LEGEND_PAD as i32;
            let box_h = rows * LEGEND_ROW as i32 + 2 * LEGEND_PAD as i32;
            legend
                .draw(&Rectangle::new(
                    [(x0, y0), (x0 + box_w, y0 + box_h)],
                    BLACK.stroke_width(1),
                ))
                .map_err(err)?;
            let text_style = ("sans-serif", LABEL_FONT)
                .into_text_style(&legend)
                .pos(Pos::new(HPos::Left, VPos::Center));
            for (i, name) in layout.names.iter().enumerate() {
                let style = series_style(i);
                let y =
                    y0 + LEGEND_PAD as i32 + i as i32 * LEGEND_ROW as i32 + LEGEND_ROW as i32 / 2;
                let (a, b) = (
                    x0 + LEGEND_PAD as i32,
                    x0 + (LEGEND_PAD + LEGEND_SAMPLE) as i32 - 6,
                );
                let line = style.colour.stroke_width(2);
                match style.dash {
                    None => legend.draw(&PathElement::new(vec![(a, y), (b, y)], line)),
                    Some((dash, gap)) => legend.draw(&DashedPathElement::new(
                        vec![(a, y), (b, y)],
                        dash,
                        gap,
                        line,
                    )),
                }
                .map_err(err)?;
                draw_marker(&legend, ((a + b) / 2, y), style).map_err(err)?;
                legend
                    .draw_text(
                        name,
                        &text_style,
                        (x0 + (LEGEND_PAD + LEGEND_SAMPLE) as i32, y),
                    )
                    .map_err(err)?;
            }
        }
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

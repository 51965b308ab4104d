//! Charts of sweep results (`vizsim plot`), in the published figure style: cycles (or steps)
//! per frame against the frame number, one line per acceleration mode, one chart per dataset
//! and classification; the frame rate of every mode side by side (bars, the fastest marked);
//! skippable sub-cubes and frame rate against the sub-cube size; the frame
//! rate (and, for lines with `float_reference`, the image PSNR) against every swept hardware
//! field.
//!
//! A chart never averages over configurations: every swept field (a key of a result line's
//! `axes`) with two or more values among the lines of a chart, other than the chart's x axis,
//! splits it into one chart per combination of values, named in the title and the file name
//! (`cycle-fps-vs-skip.latency-fuel-ray_queue.rays=8`). The one mean taken is over frames, and
//! the y label says so. A field that advances together with the x axis (a `zip`) is named in
//! the x label instead. Skippable sub-cubes are a property of the occupancy map: that chart is
//! split only by the fields that change the map.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use serde_json::Value;

use crate::error::{Error, Result};
use crate::experiment::spec::Mode;
use crate::plot::{BarChart, BarSeries, ChartOptions, LineChart, Series};
use crate::tables::{field_text, mode_label, Metric};

fn text(line: &Value, field: &str) -> String {
    field_text(line, field).unwrap_or_default()
}

fn num(line: &Value, field: &str) -> Option<f64> {
    line.get(field).and_then(Value::as_f64)
}

/// Transfer functions as the tables and charts name them: '0' and class.
pub fn tf_label(tf: &str) -> &str {
    if tf == "zero" {
        "'0'"
    } else {
        tf
    }
}

/// Longest piece of a file name `file_safe` makes: a chart's name joins several (dataset, tf,
/// axis values) and must stay under the file system's 255 bytes.
const FILE_SAFE_MAX: usize = 80;

/// File names keep letters, digits, `.`, `_`, `=` and `-`; anything else becomes `-`. A name
/// longer than 80 characters (a dataset named by a long path) keeps its first 20 and last 42
/// (a path's file name, which tells datasets apart) and a hash of the whole, so distinct names
/// stay distinct (a chart's name over 255 bytes failed to write).
pub fn file_safe(name: &str) -> String {
    let safe: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '=' | '-') {
                c
            } else {
                '-'
            }
        })
        .collect();
    if safe.len() <= FILE_SAFE_MAX {
        return safe;
    }
    // FNV-1a: stable across builds and platforms, unlike the standard library's hasher.
    let hash = name.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
    });
    // Every character of `safe` is ASCII, so these are character boundaries.
    format!("{}-{}-{hash:016x}", &safe[..20], &safe[safe.len() - 42..])
}

/// The value of swept field `axis` in a line, as text ("" when the line does not sweep it).
fn axis_text(line: &Value, axis: &str) -> String {
    match line.get("axes").and_then(|a| a.get(axis)) {
        Some(Value::String(s)) => s.clone(),
        Some(other) => other.to_string(),
        None => String::new(),
    }
}

fn num_axis(line: &Value, axis: &str) -> Option<f64> {
    line.get("axes")?.get(axis)?.as_f64()
}

/// The swept fields of the lines.
fn swept_axes(lines: &[&Value]) -> BTreeSet<String> {
    lines
        .iter()
        .filter_map(|l| l.get("axes").and_then(Value::as_object))
        .flat_map(|a| a.keys().cloned())
        .collect()
}

/// The distinct values of a swept field among the lines, numbers in numeric order.
fn axis_values(lines: &[&Value], axis: &str) -> Vec<String> {
    let mut values: Vec<String> = lines
        .iter()
        .map(|l| axis_text(l, axis))
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect();
    values.sort_by(|a, b| match (a.parse::<f64>(), b.parse::<f64>()) {
        (Ok(x), Ok(y)) => x.total_cmp(&y),
        _ => a.cmp(b),
    });
    values
}

/// One chart's share of the lines: the swept fields held fixed in it and their values.
struct Facet<'a> {
    fixed: Vec<(String, String)>,
    lines: Vec<&'a Value>,
}

impl Facet<'_> {
    /// " at ray_queue.rays = 8, skip.latency = 4" (empty without fixed fields).
    fn title(&self) -> String {
        if self.fixed.is_empty() {
            return String::new();
        }
        let pairs: Vec<String> = self
            .fixed
            .iter()
            .map(|(axis, value)| format!("{axis} = {value}"))
            .collect();
        format!(" at {}", pairs.join(", "))
    }

    /// "-ray_queue.rays=8-skip.latency=4" (empty without fixed fields).
    fn file_suffix(&self) -> String {
        self.fixed
            .iter()
            .map(|(axis, value)| format!("-{}", file_safe(&format!("{axis}={value}"))))
            .collect()
    }
}

/// Splits `lines` into one facet per combination of values of `split_by` (fields with one value
/// among the lines are left out of it), in the fields' value order.
fn facets<'a>(lines: &[&'a Value], split_by: &[String]) -> Vec<Facet<'a>> {
    let split: Vec<(&String, Vec<String>)> = split_by
        .iter()
        .map(|axis| (axis, axis_values(lines, axis)))
        .filter(|(_, values)| values.len() >= 2)
        .collect();
    let mut groups: BTreeMap<Vec<usize>, Vec<&'a Value>> = BTreeMap::new();
    for &line in lines {
        let key = split
            .iter()
            .map(|(axis, values)| {
                let v = axis_text(line, axis);
                values.iter().position(|x| *x == v).unwrap_or(0)
            })
            .collect();
        groups.entry(key).or_default().push(line);
    }
    groups
        .into_iter()
        .map(|(key, lines)| Facet {
            fixed: split
                .iter()
                .zip(key)
                .map(|((axis, values), k)| {
                    // Lines that do not sweep the field (results merged from other sweeps).
                    let value = if values[k].is_empty() {
                        "unswept".to_string()
                    } else {
                        values[k].clone()
                    };
                    ((*axis).clone(), value)
                })
                .collect(),
            lines,
        })
        .collect()
}

/// The swept fields that split a chart whose x axis is `x_axis` (when it is a swept field):
/// every field with 2+ values among the lines, except the x axis and the fields that advance
/// with it (one value of theirs per x value: a `zip`), which are returned second.
fn split_fields(lines: &[&Value], x_axis: Option<&str>) -> (Vec<String>, Vec<String>) {
    let mut split = Vec::new();
    let mut tied = Vec::new();
    for axis in swept_axes(lines) {
        if Some(axis.as_str()) == x_axis || axis_values(lines, &axis).len() < 2 {
            continue;
        }
        let advances_with_x = x_axis.is_some_and(|x| {
            let mut of_x: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
            for l in lines {
                of_x.entry(axis_text(l, x))
                    .or_default()
                    .insert(axis_text(l, &axis));
            }
            of_x.values().all(|v| v.len() == 1)
        });
        if advances_with_x {
            tied.push(axis);
        } else {
            split.push(axis);
        }
    }
    (split, tied)
}

/// Everything that identifies a run's configuration except the frame: the fields a table
/// requires as a row or column when they vary (`tables::build`), the image size and the
/// sampling rate among them (a folder resumed with another size, or sampled after exact runs,
/// must not plot as one configuration).
fn configuration(line: &Value) -> String {
    let mut text_of = vec![raw_dataset(line)];
    text_of.extend(
        crate::tables::CONFIGURATION_FIELDS
            .iter()
            // The dataset as its raw name, first (above).
            .filter(|f| **f != "dataset")
            .filter_map(|f| field_text(line, f).map(|v| format!("{f} {v}"))),
    );
    text_of.push(line.get("axes").map(Value::to_string).unwrap_or_default());
    text_of.join(", ")
}

/// One chart point before it is drawn: the values of its lines, their frames and the
/// configurations they come from.
#[derive(Default)]
struct Point {
    x: f64,
    values: Vec<f64>,
    frames: BTreeSet<String>,
    configurations: BTreeSet<String>,
}

impl Point {
    fn mean(&self) -> f64 {
        crate::tables::mean(&self.values)
    }
}

/// Points grouped by (series, x), series in name order.
fn points(
    lines: &[&Value],
    series_of: impl Fn(&Value) -> Option<String>,
    x_of: impl Fn(&Value) -> Option<f64>,
    y_of: impl Fn(&Value) -> Option<f64>,
) -> BTreeMap<String, BTreeMap<i64, Point>> {
    let mut acc: BTreeMap<String, BTreeMap<i64, Point>> = BTreeMap::new();
    for &line in lines {
        let (Some(s), Some(x), Some(y)) = (series_of(line), x_of(line), y_of(line)) else {
            continue;
        };
        // Keyed by the exact value in numeric order (not rounded: on a log axis two swept
        // values 0.1 % apart fell into one point).
        let bits = x.to_bits() as i64;
        let key = if bits < 0 { bits ^ i64::MAX } else { bits };
        let p = acc.entry(s).or_default().entry(key).or_default();
        p.x = x;
        p.values.push(y);
        p.frames.insert(text(line, "frame"));
        p.configurations.insert(configuration(line));
    }
    acc
}

/// The series of a chart whose points must each come from one configuration (averaged over
/// its frames only), and what the mean is over ("" when every point is one frame).
fn mean_over_frames(
    chart: &str,
    grouped: BTreeMap<String, BTreeMap<i64, Point>>,
) -> Result<(Vec<Series>, String)> {
    let mut counts = BTreeSet::new();
    let mut series = Vec::new();
    for (name, points) in grouped {
        for p in points.values() {
            if p.configurations.len() > 1 {
                let mixed: Vec<&String> = p.configurations.iter().take(2).collect();
                return Err(Error::Invalid(format!(
                    "chart {chart}: a point of `{}` would average over configurations ({} and {})",
                    name.rsplit('\u{0}').next().unwrap_or_default(),
                    mixed[0],
                    mixed[1]
                )));
            }
            counts.insert(p.frames.len());
        }
        series.push(Series {
            name,
            points: points.values().map(|p| (p.x, p.mean())).collect(),
        });
    }
    let (low, high) = (
        counts.first().copied().unwrap_or(1),
        counts.last().copied().unwrap_or(1),
    );
    let note = match (low, high) {
        (_, 1) => String::new(),
        (l, h) if l == h => format!("mean over {h} frames"),
        (l, h) => format!("mean over {l}–{h} frames"),
    };
    Ok((series, note))
}

fn with_note(label: &str, note: &str) -> String {
    if note.is_empty() {
        label.to_string()
    } else {
        format!("{label} ({note})")
    }
}

/// Ticks of a sub-cube axis (log2 of the edge): every power of two from the smallest to the
/// largest edge drawn, labelled `8³`.
fn subcube_ticks(series: &[Series]) -> Vec<(f64, String)> {
    let xs: Vec<f64> = series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.0))
        .collect();
    let low = xs.iter().copied().fold(f64::MAX, f64::min).floor() as i32;
    let high = xs.iter().copied().fold(f64::MIN, f64::max).ceil() as i32;
    (low..=high)
        .map(|k| (k as f64, format!("{}³", 1u64 << k.clamp(0, 62))))
        .collect()
}

fn mode_rank(m: &str) -> i64 {
    m.split('+')
        .find_map(|t| t.strip_prefix("leap"))
        .and_then(|n| n.parse::<i64>().ok())
        .map(|n| n * 4 + m.contains("hier") as i64 + 2 * (!m.contains("ert")) as i64)
        .unwrap_or(if m == "none" { -2 } else { -1 })
}

fn tf_rank(tf: &str) -> (bool, String) {
    (tf != "zero", tf.to_string())
}

/// The per-frame charts' x label: the orbit's step in degrees when every result is a frame of
/// one orbit of N views (`orbit:K/N`).
fn frame_axis_label(lines: &[Value]) -> String {
    // Only orbit views are parsed (a path view would load its file).
    let orbits: BTreeSet<Option<u32>> = lines
        .iter()
        .map(
            |l| match l["view"].as_str().filter(|v| v.starts_with("orbit:")) {
                Some(v) => match crate::camera::View::parse(v) {
                    Ok(crate::camera::View::Orbit { n, .. }) => Some(n),
                    _ => None,
                },
                None => None,
            },
        )
        .collect();
    let orbit = match orbits.into_iter().collect::<Vec<_>>()[..] {
        [Some(n)] => Some(n),
        _ => None,
    };
    match orbit {
        Some(n) => format!(
            "frame ({}° per frame for {} {n}-frame orbit)",
            fmt_degrees(360.0 / n as f64),
            // "an 8-frame", "an 11-frame", "an 18-frame"; "a 72-frame".
            if n.to_string().starts_with('8')
                || [11, 18].contains(&n)
                || (11_000..=11_999).contains(&n)
                || (18_000..=18_999).contains(&n)
            {
                "an"
            } else {
                "a"
            }
        ),
        None => "frame".to_string(),
    }
}

fn fmt_degrees(d: f64) -> String {
    let text = format!("{d:.2}");
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// The kinds of chart `write_all` draws; `vizsim plot --only` picks some.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ChartKind {
    /// `MODEL-per-frame-DATASET-TF`: cycles (or steps) per frame, one line per mode.
    PerFrame,
    /// `MODEL-fps-by-mode-DATASET`: every mode's frame rate side by side, the fastest marked.
    ByMode,
    /// `MODEL-fps-vs-subcube-DATASET`: frame rate against the sub-cube size.
    VsSubcube,
    /// `MODEL-METRIC-vs-FIELD-DATASET`: frame rate (and PSNR) against each swept field.
    VsField,
    /// `skippable-vs-subcube`: the share of empty sub-cubes against their size.
    Skippable,
}

impl ChartKind {
    pub const ALL: [ChartKind; 5] = [
        ChartKind::PerFrame,
        ChartKind::ByMode,
        ChartKind::VsSubcube,
        ChartKind::VsField,
        ChartKind::Skippable,
    ];
}

/// Writes every chart of the given kinds that the results support into `out`; returns how
/// many.
pub fn write_all(lines: &[Value], out: &Path, kinds: &[ChartKind]) -> Result<usize> {
    let wanted = |kind: ChartKind| kinds.contains(&kind);
    let mut written = 0;
    // Two datasets whose names make the same file name (`a/v.raw`, `a-v.raw`) get a numbered
    // second file rather than one chart overwriting the other.
    let mut used = BTreeSet::new();
    let mut stem = |name: String| {
        let mut unique = name.clone();
        for n in 2.. {
            if used.insert(unique.clone()) {
                break;
            }
            unique = format!("{name}-{n}");
        }
        out.join(unique)
    };
    let frame_label = frame_axis_label(lines);
    let all: Vec<&Value> = lines.iter().collect();
    let models: BTreeSet<String> = lines.iter().map(|l| text(l, "model")).collect();
    // Grouped and named by the dataset's name; titled with its label (stand-ins marked).
    let datasets: BTreeSet<String> = lines.iter().map(raw_dataset).collect();
    let tfs: BTreeSet<String> = lines.iter().map(|l| text(l, "tf")).collect();
    for model in &models {
        // Sampled simulation (docs/sampling.md): the figures are estimates, marked ≈.
        let model_title = if lines
            .iter()
            .any(|l| text(l, "model") == *model && crate::tables::is_estimate(l))
        {
            format!("{model} model, ≈ sampled")
        } else {
            format!("{model} model")
        };
        let (metric, y_label) = if model == "cycle" {
            (Metric::Cycles, "clock cycles per frame")
        } else {
            (Metric::Steps, "steps per frame")
        };
        for dataset in &datasets {
            let of: Vec<&Value> = all
                .iter()
                .copied()
                .filter(|l| text(l, "model") == *model && raw_dataset(l) == *dataset)
                .collect();
            let label = of.first().map(|l| text(l, "dataset")).unwrap_or_default();
            // 1. Per frame, one line per mode (with several frames).
            for tf in tfs.iter().filter(|_| wanted(ChartKind::PerFrame)) {
                let these: Vec<&Value> = of
                    .iter()
                    .copied()
                    .filter(|l| text(l, "tf") == *tf)
                    .collect();
                let (split, _) = split_fields(&these, None);
                for facet in facets(&these, &split) {
                    let frames: BTreeSet<String> =
                        facet.lines.iter().map(|l| text(l, "frame")).collect();
                    if frames.len() < 2 {
                        continue;
                    }
                    let title =
                        format!("{label}, {}{} ({model_title})", tf_label(tf), facet.title());
                    let grouped = points(
                        &facet.lines,
                        |l| Some(text(l, "mode")),
                        |l| num(l, "frame"),
                        |l| metric.value(l),
                    );
                    let (mut series, note) = mean_over_frames(&title, grouped)?;
                    series.sort_by_key(|s| mode_rank(&s.name));
                    for s in &mut series {
                        s.name = mode_label(&s.name);
                    }
                    LineChart {
                        title: &title,
                        x_label: &frame_label,
                        y_label: &with_note(y_label, &note),
                        series,
                        log_y: true,
                    }
                    .write(&stem(format!(
                        "{model}-per-frame-{}-{}{}",
                        file_safe(dataset),
                        file_safe(tf),
                        facet.file_suffix()
                    )))?;
                    written += 1;
                }
            }
            // 2. Frame rate by mode: every mode of the dataset side by side, a bar per
            //    transfer function, the fastest marked (which acceleration wins here). Not for
            //    a sequence's time steps, whose rates a bar would average without saying so.
            let frames: Vec<&Value> = of
                .iter()
                .copied()
                .filter(|l| wanted(ChartKind::ByMode) && l.get("time_step").is_none())
                .collect();
            let (split, _) = split_fields(&frames, None);
            for facet in facets(&frames, &split) {
                let modes: Vec<String> = {
                    let mut modes: Vec<String> = facet
                        .lines
                        .iter()
                        .map(|l| text(l, "mode"))
                        .collect::<BTreeSet<_>>()
                        .into_iter()
                        .collect();
                    modes.sort_by_key(|m| crate::tables::sort_key("mode", m));
                    modes
                };
                if modes.len() < 2 {
                    continue;
                }
                let title = format!(
                    "{label}: frame rate by mode{} ({model_title})",
                    facet.title()
                );
                let grouped = points(
                    &facet.lines,
                    |l| {
                        let tf = text(l, "tf");
                        let (tf_order, name) = tf_rank(&tf);
                        Some(format!("{}{name}\u{0}{}", tf_order as u8, tf_label(&tf)))
                    },
                    |l| {
                        let mode = text(l, "mode");
                        modes.iter().position(|m| *m == mode).map(|i| i as f64)
                    },
                    |l| Metric::Fps.value(l),
                );
                let (series, note) = mean_over_frames(&title, grouped)?;
                let series = series
                    .into_iter()
                    .map(|s| {
                        let mut values = vec![None; modes.len()];
                        for (x, y) in s.points {
                            values[x as usize] = Some(y);
                        }
                        BarSeries {
                            name: s.name.rsplit('\u{0}').next().unwrap_or_default().into(),
                            values,
                        }
                    })
                    .collect();
                // As in the tables: `*` on a mode whose map needs more than the default SRAM.
                let raised = |mode: &str| {
                    facet.lines.iter().any(|l| {
                        text(l, "mode") == mode && l["fits_default_sram"] == Value::Bool(false)
                    })
                };
                let any_raised = modes.iter().any(|m| raised(m));
                let value_label = with_note("frames per second", &note)
                    + if any_raised {
                        "; * map larger than the default SRAM, run with it raised"
                    } else {
                        ""
                    };
                BarChart {
                    title: &title,
                    value_label: &value_label,
                    categories: modes
                        .iter()
                        .map(|m| mode_label(m) + if raised(m) { "*" } else { "" })
                        .collect(),
                    series,
                    mark_largest: Some("fastest"),
                }
                .write(&stem(format!(
                    "{model}-fps-by-mode-{}{}",
                    file_safe(dataset),
                    facet.file_suffix()
                )))?;
                written += 1;
            }
            // 3. Frame rate against the sub-cube size, '0' and class, with and without the
            //    hierarchy (ERT + leaping modes).
            let leaping: Vec<&Value> = of
                .iter()
                .copied()
                .filter(|l| {
                    wanted(ChartKind::VsSubcube)
                        && num(l, "subcube").unwrap_or(0.0) > 0.0
                        && l["ert"] == Value::Bool(true)
                })
                .collect();
            let (split, _) = split_fields(&leaping, None);
            for facet in facets(&leaping, &split) {
                let sizes: BTreeSet<i64> = facet
                    .lines
                    .iter()
                    .filter_map(|l| num(l, "subcube").map(|s| s as i64))
                    .collect();
                if sizes.len() < 2 {
                    continue;
                }
                let title = format!(
                    "{label}: frame rate against sub-cube size{} ({model_title})",
                    facet.title()
                );
                let grouped = points(
                    &facet.lines,
                    |l| {
                        let tf = text(l, "tf");
                        let hierarchy = l["hierarchy"] == Value::Bool(true);
                        // What the mode adds to its map (bricks, iso, ...) makes a series of
                        // its own: `ert+leap8+bricks16` is not a point of `ert+leap8`'s line.
                        let extras = match Mode::parse(&text(l, "mode")) {
                            Ok(mut m) => {
                                (m.ert, m.subcube, m.hierarchy) = (false, 0, false);
                                Some(m.name()).filter(|n| n != "none")
                            }
                            Err(_) => None,
                        }
                        .map(|n| format!(" + {n}"))
                        .unwrap_or_default();
                        // Sorted: '0' before class, each without the hierarchy first.
                        Some(format!(
                            "{}{tf}\u{0}{}{extras}\u{0}{}{}{extras}",
                            (tf != "zero") as u8,
                            hierarchy as u8,
                            tf_label(&tf),
                            if hierarchy { " + hierarchy" } else { "" }
                        ))
                    },
                    |l| num(l, "subcube").map(f64::log2),
                    |l| Metric::Fps.value(l),
                );
                let (mut series, note) = mean_over_frames(&title, grouped)?;
                for s in &mut series {
                    s.name = s.name.rsplit('\u{0}').next().unwrap_or_default().into();
                }
                let x_ticks = Some(subcube_ticks(&series));
                LineChart {
                    title: &title,
                    x_label: "sub-cube size (log scale)",
                    y_label: &with_note("frames per second", &note),
                    series,
                    log_y: false,
                }
                .write_with(
                    &stem(format!(
                        "{model}-fps-vs-subcube-{}{}",
                        file_safe(dataset),
                        facet.file_suffix()
                    )),
                    &ChartOptions { x_ticks },
                )?;
                written += 1;
            }
            // 4. Frame rate (and with `float_reference` the PSNR) against each swept hardware
            //    field (numbers on a linear axis, or a
            //    logarithmic one when they span a decade or more; other values in their order,
            //    evenly spaced). Fields that advance together (a `zip`) make one chart, against
            //    the first of them.
            let mut charted = BTreeSet::new();
            for axis in swept_axes(&of)
                .into_iter()
                .filter(|_| wanted(ChartKind::VsField))
            {
                let values = axis_values(&of, &axis);
                if values.len() < 2 || charted.contains(&axis) {
                    continue;
                }
                let numeric = of.iter().all(|l| num_axis(l, &axis).is_some());
                let numbers: Vec<f64> = values.iter().filter_map(|v| v.parse().ok()).collect();
                let log_x = numeric
                    && numbers.iter().all(|&v| v > 0.0)
                    && numbers.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                        >= 10.0 * numbers.iter().copied().fold(f64::INFINITY, f64::min);
                let x_of = |l: &Value| {
                    if log_x {
                        num_axis(l, &axis).map(f64::log10)
                    } else if numeric {
                        num_axis(l, &axis)
                    } else {
                        let v = axis_text(l, &axis);
                        values.iter().position(|x| *x == v).map(|i| i as f64)
                    }
                };
                let (split, tied) = split_fields(&of, Some(&axis));
                charted.extend(tied.iter().cloned());
                let x_label = if tied.is_empty() {
                    axis.clone()
                } else {
                    format!("{axis} ({} advancing with it)", tied.join(", "))
                } + if log_x { " (log scale)" } else { "" };
                // With `float_reference` in the lines, the image error against the field too:
                // the other side of a bit-width sweep.
                let image = of.iter().any(|l| Metric::Psnr.value(l).is_some());
                let metrics = [
                    (Metric::Fps, "frame rate", "frames per second"),
                    (
                        Metric::Psnr,
                        "image PSNR (float reference)",
                        "PSNR against the float reference (dB)",
                    ),
                ];
                for (facet, &(metric, what, y_name)) in facets(&of, &split)
                    .iter()
                    .flat_map(|f| metrics.iter().take(1 + image as usize).map(move |m| (f, m)))
                {
                    if axis_values(&facet.lines, &axis).len() < 2 {
                        continue;
                    }
                    let title = format!(
                        "{label}: {what} against {axis}{} ({model_title})",
                        facet.title()
                    );
                    let grouped = points(
                        &facet.lines,
                        |l| {
                            let (tf, mode) = (text(l, "tf"), text(l, "mode"));
                            let (tf_order, mode_order) = (tf_rank(&tf), mode_rank(&mode));
                            Some(format!(
                                "{}{}\u{0}{:06}\u{0}{}, {}",
                                tf_order.0 as u8,
                                tf_order.1,
                                mode_order + 100,
                                tf_label(&tf),
                                mode_label(&mode)
                            ))
                        },
                        x_of,
                        |l| metric.value(l),
                    );
                    let (mut series, note) = mean_over_frames(&title, grouped)?;
                    for s in &mut series {
                        s.name = s.name.rsplit('\u{0}').next().unwrap_or_default().into();
                    }
                    let x_ticks = if log_x {
                        Some(
                            values
                                .iter()
                                .filter_map(|v| Some((v.parse::<f64>().ok()?.log10(), v.clone())))
                                .collect(),
                        )
                    } else {
                        (!numeric).then(|| {
                            values
                                .iter()
                                .enumerate()
                                .map(|(i, v)| (i as f64, v.clone()))
                                .collect()
                        })
                    };
                    LineChart {
                        title: &title,
                        x_label: &x_label,
                        y_label: &with_note(y_name, &note),
                        series,
                        log_y: false,
                    }
                    .write_with(
                        &stem(format!(
                            "{model}-{}-vs-{}-{}{}",
                            metric.file_name(),
                            file_safe(&axis),
                            file_safe(dataset),
                            facet.file_suffix()
                        )),
                        &ChartOptions { x_ticks },
                    )?;
                    written += 1;
                }
            }
        }
    }
    // 5. Skippable sub-cubes against the sub-cube size ('0' and class): a property of the
    //    dataset, transfer function and map, one chart for all datasets (split by the swept
    //    fields that change the map).
    let maps: Vec<&Value> = all
        .iter()
        .copied()
        .filter(|l| {
            wanted(ChartKind::Skippable)
                && l.get("skippable_subcubes_percent").is_some()
                && l["hierarchy"] != Value::Bool(true)
        })
        .collect();
    let map_fields: Vec<String> = swept_axes(&maps)
        .into_iter()
        .filter(|axis| changes_the_map(&maps, axis))
        .collect();
    for facet in facets(&maps, &map_fields) {
        let grouped = points(
            &facet.lines,
            |l| {
                Some(format!(
                    "{}\u{0}{}\u{0}{} {}",
                    raw_dataset(l),
                    (text(l, "tf") != "zero") as u8,
                    text(l, "dataset"),
                    tf_label(&text(l, "tf"))
                ))
            },
            |l| num(l, "subcube").map(f64::log2),
            |l| Metric::Skippable.value(l),
        );
        // One map, one value: frames, models and modes that share a map agree.
        let differing = grouped.values().flat_map(|p| p.values()).any(|p| {
            p.values
                .iter()
                .any(|v| (v - p.values[0]).abs() > 1e-9 * p.values[0].abs().max(1.0))
        });
        let series: Vec<Series> = grouped
            .into_iter()
            .map(|(name, points)| Series {
                name: name.rsplit('\u{0}').next().unwrap_or_default().into(),
                points: points.values().map(|p| (p.x, p.mean())).collect(),
            })
            .collect();
        let x_ticks = Some(subcube_ticks(&series));
        let title = format!(
            "skippable (empty) sub-cubes against sub-cube size{}",
            facet.title()
        );
        LineChart {
            title: &title,
            x_label: "sub-cube size (log scale)",
            y_label: if differing {
                "skippable sub-cubes (%, mean over the runs of a map)"
            } else {
                "skippable sub-cubes (%)"
            },
            series,
            log_y: false,
        }
        .write_with(
            &stem(format!("skippable-vs-subcube{}", facet.file_suffix())),
            &ChartOptions { x_ticks },
        )?;
        written += 1;
    }
    Ok(written)
}

/// Whether the skippable share differs between values of `axis` for the same dataset,
/// classification, sub-cube size and other swept fields.
fn changes_the_map(maps: &[&Value], axis: &str) -> bool {
    let mut by_map: BTreeMap<String, BTreeMap<String, f64>> = BTreeMap::new();
    for l in maps {
        let Some(v) = Metric::Skippable.value(l) else {
            continue;
        };
        let mut others = l.get("axes").cloned().unwrap_or(Value::Null);
        if let Some(o) = others.as_object_mut() {
            o.remove(axis);
        }
        let key = format!(
            "{} {} {} {}",
            raw_dataset(l),
            text(l, "tf"),
            text(l, "subcube"),
            others
        );
        let seen = by_map.entry(key).or_default();
        seen.entry(axis_text(l, axis)).or_insert(v);
    }
    by_map.values().any(|of_axis| {
        let first = of_axis.values().next().copied().unwrap_or(0.0);
        of_axis.values().any(|v| (v - first).abs() > 1e-9)
    })
}

fn raw_dataset(line: &Value) -> String {
    line.get("dataset")
        .and_then(Value::as_str)
        .unwrap_or_default()
        .to_string()
}

//! Charts of sweep results (`vizsim plot`), in the published figure style: cycles (or steps)
//! per frame against the frame number, one line per acceleration mode, one chart per dataset
//! and classification; skippable sub-cubes and frame rate against the sub-cube size; the frame
//! rate against every swept hardware field.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use serde_json::Value;

use crate::error::Result;
use crate::plot::{LineChart, Series};
use crate::tables::{field_text, mode_label, Metric};

fn text(line: &Value, field: &str) -> String {
    field_text(line, field).unwrap_or_default()
}

fn num(line: &Value, field: &str) -> Option<f64> {
    line.get(field).and_then(Value::as_f64)
}

fn tf_label(tf: &str) -> &str {
    if tf == "zero" {
        "'0'"
    } else {
        tf
    }
}

fn file_safe(name: &str) -> String {
    name.chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .collect()
}

/// Mean of `value` over lines grouped by (series, x).
fn series_means(
    lines: &[&Value],
    series_of: impl Fn(&Value) -> Option<String>,
    x_of: impl Fn(&Value) -> Option<f64>,
    y_of: impl Fn(&Value) -> Option<f64>,
) -> Vec<Series> {
    let mut acc: BTreeMap<String, BTreeMap<i64, (f64, f64, u32)>> = BTreeMap::new();
    for line in lines {
        let (Some(s), Some(x), Some(y)) = (series_of(line), x_of(line), y_of(line)) else {
            continue;
        };
        let e = acc
            .entry(s)
            .or_default()
            .entry((x * 1000.0).round() as i64)
            .or_insert((x, 0.0, 0));
        e.1 += y;
        e.2 += 1;
    }
    acc.into_iter()
        .map(|(name, points)| Series {
            name,
            points: points
                .values()
                .map(|&(x, y, n)| (x, y / n as f64))
                .collect(),
        })
        .collect()
}

/// Writes every chart the results support into `out`; returns how many.
pub fn write_all(lines: &[Value], out: &Path) -> Result<usize> {
    let mut written = 0;
    let models: BTreeSet<String> = lines.iter().map(|l| text(l, "model")).collect();
    // Grouped and named by the dataset's name; titled with its label (stand-ins marked).
    let datasets: BTreeSet<String> = lines.iter().map(raw_dataset).collect();
    let tfs: BTreeSet<String> = lines.iter().map(|l| text(l, "tf")).collect();
    let axes: BTreeSet<String> = lines
        .iter()
        .filter_map(|l| l.get("axes").and_then(Value::as_object))
        .flat_map(|a| a.keys().cloned())
        .collect();
    let mode_rank = |m: &str| {
        m.split('+')
            .find_map(|t| t.strip_prefix("leap"))
            .and_then(|n| n.parse::<i64>().ok())
            .map(|n| n * 2 + m.contains("hier") as i64)
            .unwrap_or(if m == "none" { -2 } else { -1 })
    };
    for model in &models {
        let (metric, y_label) = if model == "cycle" {
            (Metric::Cycles, "clock cycles per frame")
        } else {
            (Metric::Steps, "steps per frame")
        };
        for dataset in &datasets {
            let of: Vec<&Value> = lines
                .iter()
                .filter(|l| text(l, "model") == *model && raw_dataset(l) == *dataset)
                .collect();
            let label = of.first().map(|l| text(l, "dataset")).unwrap_or_default();
            // 1. Per frame, one line per mode (with several frames).
            for tf in &tfs {
                let these: Vec<&Value> = of
                    .iter()
                    .copied()
                    .filter(|l| text(l, "tf") == *tf)
                    .collect();
                let frames: BTreeSet<String> = these.iter().map(|l| text(l, "frame")).collect();
                if frames.len() < 2 {
                    continue;
                }
                let mut series = series_means(
                    &these,
                    |l| Some(text(l, "mode")),
                    |l| num(l, "frame"),
                    |l| metric.value(l),
                );
                series.sort_by_key(|s| mode_rank(&s.name));
                for s in &mut series {
                    s.name = mode_label(&s.name);
                }
                let title = format!("{label}, {} ({model} model)", tf_label(tf));
                LineChart {
                    title: &title,
                    x_label: "frame (5° per frame for a 72-frame orbit)",
                    y_label,
                    series,
                    log_y: true,
                }
                .write(&out.join(format!(
                    "{model}-per-frame-{}-{}",
                    file_safe(dataset),
                    file_safe(tf)
                )))?;
                written += 1;
            }
            // 2. Frame rate against the sub-cube size, '0' and class, with and without the
            //    hierarchy (ERT + leaping modes).
            let leaping: Vec<&Value> = of
                .iter()
                .copied()
                .filter(|l| num(l, "subcube").unwrap_or(0.0) > 0.0 && l["ert"] == Value::Bool(true))
                .collect();
            let sizes: BTreeSet<i64> = leaping
                .iter()
                .filter_map(|l| num(l, "subcube").map(|s| s as i64))
                .collect();
            if sizes.len() >= 2 {
                let series = series_means(
                    &leaping,
                    |l| {
                        Some(format!(
                            "{}{}",
                            tf_label(&text(l, "tf")),
                            if l["hierarchy"] == Value::Bool(true) {
                                " + hierarchy"
                            } else {
                                ""
                            }
                        ))
                    },
                    |l| num(l, "subcube").map(f64::log2),
                    |l| Metric::Fps.value(l),
                );
                let title = format!("{label}: frame rate against sub-cube size ({model} model)");
                LineChart {
                    title: &title,
                    x_label: "log2 of the sub-cube edge (2 = 4³, 3 = 8³, 4 = 16³ …)",
                    y_label: "frames per second (mean over frames)",
                    series,
                    log_y: false,
                }
                .write(&out.join(format!("{model}-fps-vs-subcube-{}", file_safe(dataset))))?;
                written += 1;
            }
            // 3. Frame rate against each swept hardware field.
            for axis in &axes {
                let values: BTreeSet<String> = of.iter().map(|l| text(l, axis)).collect();
                if values.len() < 2 || of.iter().any(|l| num_axis(l, axis).is_none()) {
                    continue;
                }
                let series = series_means(
                    &of,
                    |l| {
                        Some(format!(
                            "{} {}",
                            tf_label(&text(l, "tf")),
                            mode_label(&text(l, "mode"))
                        ))
                    },
                    |l| num_axis(l, axis),
                    |l| Metric::Fps.value(l),
                );
                let title = format!("{label}: frame rate against {axis} ({model} model)");
                LineChart {
                    title: &title,
                    x_label: axis,
                    y_label: "frames per second (mean over frames)",
                    series,
                    log_y: false,
                }
                .write(&out.join(format!(
                    "{model}-fps-vs-{}-{}",
                    file_safe(axis),
                    file_safe(dataset)
                )))?;
                written += 1;
            }
        }
    }
    // 4. Skippable sub-cubes against the sub-cube size ('0' and class): a property of the
    //    dataset and transfer function, one chart for all datasets.
    let maps: Vec<&Value> = lines
        .iter()
        .filter(|l| {
            l.get("skippable_subcubes_percent").is_some() && l["hierarchy"] != Value::Bool(true)
        })
        .collect();
    if !maps.is_empty() {
        let series = series_means(
            &maps,
            |l| {
                Some(format!(
                    "{} {}",
                    text(l, "dataset"),
                    tf_label(&text(l, "tf"))
                ))
            },
            |l| num(l, "subcube").map(f64::log2),
            |l| Metric::Skippable.value(l),
        );
        LineChart {
            title: "skippable (empty) sub-cubes against sub-cube size",
            x_label: "log2 of the sub-cube edge (2 = 4³, 3 = 8³, 4 = 16³ …)",
            y_label: "skippable sub-cubes (%)",
            series,
            log_y: false,
        }
        .write(&out.join("skippable-vs-subcube"))?;
        written += 1;
    }
    Ok(written)
}

fn raw_dataset(line: &Value) -> String {
    line.get("dataset")
        .and_then(Value::as_str)
        .unwrap_or_default()
        .to_string()
}

fn num_axis(line: &Value, axis: &str) -> Option<f64> {
    line.get("axes")?.get(axis)?.as_f64()
}

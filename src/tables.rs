//! Tables of sweep results (`vizsim table`): one cell per (row, column) group, the metric
//! averaged over the frames of that group. The default layout is the published one: rows
//! dataset × classification ('0', class), columns the acceleration modes none, ERT, 2³ … 64³
//! (and the hierarchy), cells the frame rate.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use serde_json::Value;

use crate::error::{Error, Result};

/// Reads a results file (one JSON object per line) as a sweep's resume reads it
/// (`experiment::store::read_lines`): a torn last line (a sweep killed while writing, or one
/// still writing) is left out, and the second value says so; any other malformed line is an
/// error naming the file and line.
pub fn read_results(path: &Path) -> Result<(Vec<Value>, bool)> {
    if let Err(e) = std::fs::symlink_metadata(path) {
        return Err(Error::io(path, e));
    }
    let (lines, torn) = crate::experiment::store::read_lines_and_torn(path)?;
    // A figure that is there but no number (an edited file) would be tabulated as missing.
    for (line, _) in &lines {
        let not_a_number = <Metric as clap::ValueEnum>::value_variants()
            .iter()
            .flat_map(|m| m.inputs())
            .find_map(|field| {
                // Every part of the path: a section that is there must be one (an object), the
                // figure a number; either may be null (no figure).
                (1..=field.len()).find_map(|n| {
                    let leaf = n == field.len();
                    lookup(line, &field[..n])
                        .filter(|v| {
                            !(v.is_null() || if leaf { v.is_number() } else { v.is_object() })
                        })
                        .map(|v| (&field[..n], v, leaf))
                })
            });
        if let Some((field, v, leaf)) = not_a_number {
            return Err(Error::format(
                path,
                format!(
                    "run {}: `{}` is {v}, not {}",
                    line["key"].as_str().unwrap_or("?"),
                    field.join("."),
                    if leaf {
                        "a number"
                    } else {
                        "a section of figures"
                    }
                ),
            ));
        }
    }
    Ok((lines.into_iter().map(|(line, _)| line).collect(), torn))
}

/// The value at a path of field names in a result line (`["stall_cycles", "memory"]`).
fn lookup<'a>(line: &'a Value, path: &[&str]) -> Option<&'a Value> {
    path.iter().try_fold(line, |v, name| v.get(name))
}

/// What a cell shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Metric {
    /// Frames per second (step model: 1 / (steps × clock.step_time_ns); cycle model: clock / cycles).
    Fps,
    /// Clock cycles per frame (cycle model).
    Cycles,
    /// Steps (samples + leaps) per frame.
    Steps,
    /// Samples per frame.
    Samples,
    /// SDRAM row (page) hit rate, % (cycle model).
    PageHits,
    /// Average ns per voxel access (cycle model).
    NsPerAccess,
    /// Samples discarded after ERT (cycle model).
    DiscardedAfterErt,
    /// Memory stall cycles: the selected sample's address FIFOs were full (cycle model). A
    /// ray waiting for its distance or leap-value word is `leap-word-waits`.
    MemoryStalls,
    /// Cycles every ray waited for a distance word or its last sample's words (cycle model;
    /// distance volume, leap values and iso-surface refinement, 0 for the others).
    LeapWordWaits,
    /// SDRAM row misses, i.e. page reloads (cycle model).
    RowMisses,
    /// Clock cycles per step: 1 is the ideal of one step per clock (cycle model).
    CyclesPerStep,
    /// Skippable (empty) sub-cubes, %.
    Skippable,
    /// Cycles with the ray queue empty (cycle model): ray setup did not keep up.
    QueueEmpty,
    /// Positions in the box that the rays' start and end cut (bricks, clipping), %.
    PositionsCut,
    /// Clock cycles of a sequence's whole time step: update, map and render (sequence
    /// experiments; `cycles` is the render's alone).
    TotalCycles,
    /// Mean absolute difference from the float reference's image, 8-bit levels over all
    /// channels (experiments with `float_reference = true`).
    ImageError,
    /// PSNR against the float reference's image over R, G, B, dB (experiments with
    /// `float_reference = true`; a frame equal to its reference has none).
    Psnr,
    /// Pixels with a channel more than 1 level off the float reference's image (experiments
    /// with `float_reference = true`).
    PixelsOff,
    /// On-chip bits the run's structures need: the occupancy map's SRAM, the brick flags and
    /// blocking's indirection table (0 for a run without any).
    OnChipBits,
    /// SDRAM rows per bank beyond the volume's: the distance array adds rows, blocking saves
    /// them (negative); 0 for the others.
    SdramRows,
}

impl Metric {
    pub fn label(self) -> &'static str {
        match self {
            Metric::Fps => "frame rate (fps)",
            Metric::Cycles => "cycles per frame",
            Metric::Steps => "steps per frame",
            Metric::Samples => "samples per frame",
            Metric::PageHits => "row (page) hit rate (%)",
            Metric::NsPerAccess => "ns per voxel access",
            Metric::DiscardedAfterErt => "samples discarded after ERT per frame",
            Metric::MemoryStalls => "memory stall cycles per frame",
            Metric::LeapWordWaits => "cycles waiting for distance or leap-value words per frame",
            Metric::RowMisses => "row misses (page reloads) per frame",
            Metric::CyclesPerStep => "cycles per step",
            Metric::Skippable => "skippable sub-cubes (%)",
            Metric::QueueEmpty => "cycles with the ray queue empty per frame",
            Metric::PositionsCut => "positions cut by ray start and end (%)",
            Metric::TotalCycles => "cycles per time step (update + map + render)",
            Metric::ImageError => "mean error against the float reference (8-bit levels)",
            Metric::Psnr => "PSNR against the float reference (dB)",
            Metric::PixelsOff => "pixels more than 1 level off the float reference",
            Metric::OnChipBits => "on-chip bits (map SRAM + brick flags + blocking table)",
            Metric::SdramRows => "SDRAM rows per bank beyond the volume's",
        }
    }

    pub fn file_name(self) -> &'static str {
        match self {
            Metric::Fps => "fps",
            Metric::Cycles => "cycles",
            Metric::Steps => "steps",
            Metric::Samples => "samples",
            Metric::PageHits => "page-hits",
            Metric::NsPerAccess => "ns-per-access",
            Metric::DiscardedAfterErt => "discarded-after-ert",
            Metric::MemoryStalls => "memory-stalls",
            Metric::LeapWordWaits => "leap-word-waits",
            Metric::RowMisses => "row-misses",
            Metric::CyclesPerStep => "cycles-per-step",
            Metric::Skippable => "skippable",
            Metric::QueueEmpty => "queue-empty",
            Metric::PositionsCut => "positions-cut",
            Metric::TotalCycles => "total-cycles",
            Metric::ImageError => "image-error",
            Metric::Psnr => "psnr",
            Metric::PixelsOff => "pixels-off",
            Metric::OnChipBits => "on-chip-bits",
            Metric::SdramRows => "sdram-rows",
        }
    }

    /// Whether the metric counts something (cycles, steps, samples, stalls, pixels): whole
    /// numbers per frame, so its table's cells are written as whole numbers.
    pub fn is_count(self) -> bool {
        match self {
            Metric::Cycles
            | Metric::Steps
            | Metric::Samples
            | Metric::DiscardedAfterErt
            | Metric::MemoryStalls
            | Metric::LeapWordWaits
            | Metric::RowMisses
            | Metric::QueueEmpty
            | Metric::TotalCycles
            | Metric::PixelsOff
            | Metric::OnChipBits
            | Metric::SdramRows => true,
            Metric::Fps
            | Metric::PageHits
            | Metric::NsPerAccess
            | Metric::CyclesPerStep
            | Metric::Skippable
            | Metric::PositionsCut
            | Metric::ImageError
            | Metric::Psnr => false,
        }
    }

    /// The result fields the metric reads, as paths of field names: the one list both
    /// `value` and the check that a present figure is a number (`read_results`) follow.
    pub fn inputs(self) -> &'static [&'static [&'static str]] {
        match self {
            Metric::Fps => &[&["fps"]],
            Metric::Cycles => &[&["cycles"]],
            Metric::Steps => &[&["steps"]],
            Metric::Samples => &[&["samples"]],
            Metric::PageHits => &[&["page_hit_rate"]],
            Metric::NsPerAccess => &[&["avg_ns_per_voxel_access"]],
            Metric::DiscardedAfterErt => &[&["discarded_after_ert"]],
            Metric::MemoryStalls => &[&["stall_cycles", "memory"]],
            Metric::LeapWordWaits => &[
                &["stall_cycles", "distance_word"],
                &["stall_cycles", "leap_word"],
            ],
            Metric::RowMisses => &[&["row_misses"]],
            Metric::CyclesPerStep => &[&["cycles"], &["steps"]],
            Metric::Skippable => &[&["skippable_subcubes_percent"]],
            Metric::QueueEmpty => &[&["stall_cycles", "ray_queue_empty"]],
            Metric::PositionsCut => &[
                &["ray_range", "positions_cut"],
                &["ray_range", "positions_in_box"],
            ],
            Metric::TotalCycles => &[&["total_cycles"]],
            Metric::ImageError => &[&["float_reference", "mean_abs_error"]],
            Metric::Psnr => &[&["float_reference", "psnr_db"]],
            Metric::PixelsOff => &[&["float_reference", "pixels_over_1_lsb"]],
            Metric::OnChipBits => &[
                &["structure_memory", "map_sram_bits"],
                &["structure_memory", "brick_flag_bits"],
                &["blocking", "table_sram_bits"],
            ],
            Metric::SdramRows => &[
                &["structure_memory", "extra_sdram_rows_per_bank"],
                &["blocking", "rows_blocked"],
                &["blocking", "rows_unblocked"],
            ],
        }
    }

    /// The metric's value in one result line (None when the line's model does not have it).
    pub fn value(self, line: &Value) -> Option<f64> {
        let inputs: Vec<Option<f64>> = self
            .inputs()
            .iter()
            .map(|path| lookup(line, path).and_then(Value::as_f64))
            .collect();
        match (self, inputs.as_slice()) {
            (Metric::PageHits, [rate]) => rate.map(|r| 100.0 * r),
            (Metric::CyclesPerStep, [cycles, steps]) => {
                let steps = (*steps)?;
                (steps > 0.0).then(|| cycles.map(|c| c / steps))?
            }
            // Written out only when not 0: a cycle-model line without them waited 0 cycles.
            (Metric::LeapWordWaits, [distance, leap]) => line
                .get("stall_cycles")
                .filter(|s| s.is_object())
                .map(|_| distance.unwrap_or(0.0) + leap.unwrap_or(0.0)),
            (Metric::PositionsCut, [cut, total]) => {
                let total = (*total)?;
                (total > 0.0).then(|| cut.map(|c| 100.0 * c / total))?
            }
            // Written only for runs that store something: a run without either stores nothing.
            (Metric::OnChipBits, [map, flags, table]) => {
                Some(map.unwrap_or(0.0) + flags.unwrap_or(0.0) + table.unwrap_or(0.0))
            }
            (Metric::SdramRows, [distance, blocked, unblocked]) => Some(
                distance.unwrap_or(0.0)
                    + blocked
                        .zip(*unblocked)
                        .map_or(0.0, |(blocked, unblocked)| blocked - unblocked),
            ),
            (_, [figure]) => *figure,
            _ => unreachable!("every metric with several inputs is combined above"),
        }
    }
}

/// What a table's cells of `model` ("step" or "cycle") are measured by, for its title: the
/// clock of the model's timing, or the image or map the metric reads. The step model's clock
/// is the step time the lines ran with (their frame time / steps, as no line names it unless
/// it is swept): "published" only for 12.5 ns, each value when the runs used several.
pub fn measured_by(metric: Metric, model: &str, lines: &[&Value]) -> String {
    match (metric, model) {
        // Skippable sub-cubes are a property of the map, not of a model's timing.
        (Metric::Skippable, _) => "occupancy map".into(),
        // Storage: from the configuration and the volume's dimensions, whatever the model.
        (Metric::OnChipBits | Metric::SdramRows, _) => {
            "the configuration and the volume's dimensions".into()
        }
        // The image, not the timing: the model's frame, whatever its clock.
        (Metric::ImageError | Metric::Psnr | Metric::PixelsOff, "step") => {
            "step model's image".into()
        }
        (Metric::ImageError | Metric::Psnr | Metric::PixelsOff, _) => {
            "cycle-accurate model's image".into()
        }
        (_, "step") => {
            let step_times: BTreeSet<String> = lines
                .iter()
                .filter_map(|l| {
                    let ns = l.get("frame_time_ns").and_then(Value::as_f64)?;
                    let steps = l.get("steps").and_then(Value::as_f64)?;
                    (steps > 0.0).then(|| crate::config::ns_text(ns / steps))
                })
                .collect();
            let published = crate::config::ns_text(crate::config::PUBLISHED_STEP_TIME_NS);
            let mut by_value: Vec<&String> = step_times.iter().collect();
            by_value.sort_by(|a, b| {
                let number = |t: &str| t.parse::<f64>().unwrap_or(f64::INFINITY);
                number(a).total_cmp(&number(b))
            });
            match by_value.as_slice() {
                // No line took a step: no step time to name.
                [] => "step model".into(),
                [one] if **one == published => {
                    format!("step model, published cost {published} ns per step")
                }
                [one] => format!(
                    "step model, {}",
                    crate::config::step_cost_text(one.parse().unwrap_or(f64::NAN))
                ),
                several => format!(
                    "step model, clock.step_time_ns per run: {} ns per step",
                    several
                        .iter()
                        .map(|s| s.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            }
        }
        _ => "cycle-accurate model at its clock".into(),
    }
}

/// A grouping field of a result line: a top-level field (`dataset`, `tf`, `mode`, `model`,
/// `frame`) or a swept hardware field by its dotted path (`ray_queue.rays`).
/// ": " and the swept fields of `lines`, comma-separated ("" when nothing is swept).
fn axes_listed(lines: &[&Value]) -> String {
    let axes: BTreeSet<&String> = lines
        .iter()
        .filter_map(|l| l.get("axes").and_then(Value::as_object))
        .flat_map(|a| a.keys())
        .collect();
    if axes.is_empty() {
        String::new()
    } else {
        let axes: Vec<&str> = axes.into_iter().map(String::as_str).collect();
        format!(": {}", axes.join(", "))
    }
}

pub fn field_text(line: &Value, field: &str) -> Option<String> {
    let value = match field {
        "dataset" => line.get("dataset_label").or_else(|| line.get("dataset")),
        _ => line
            .get(field)
            .or_else(|| line.get("axes").and_then(|a| a.get(field))),
    }?;
    Some(match value {
        Value::String(s) => s.clone(),
        other => other.to_string(),
    })
}

/// How modes are named in column headers and in which order they appear: `none`, `ERT`, `8³`,
/// `8³+h` (occupancy map), `dist8` (distance volume, 8 bits), `LV` / `LV-h` (leap values in
/// the volume, empty / homogeneous regions); "no ERT, " in front when the mode has no ERT but
/// leaps.
pub fn mode_label(mode: &str) -> String {
    let mut ert = false;
    let mut hierarchy = false;
    let mut structure = None;
    let mut bricks = None;
    let mut table = false;
    let mut iso = None;
    for token in mode.split('+') {
        match token {
            "ert" => ert = true,
            "hier" => hierarchy = true,
            "none" => {}
            "leapvalues" => structure = Some("LV".to_string()),
            "leapvalues-homogeneous" => structure = Some("LV-h".to_string()),
            t if t.starts_with("distance") => {
                structure = Some(format!("dist{}", t.trim_start_matches("distance")))
            }
            t if t.starts_with("leap") => {
                structure = Some(format!("{}³", t.trim_start_matches("leap")))
            }
            t if t.starts_with("bricks") => {
                bricks = Some(t.trim_start_matches("bricks").to_string())
            }
            "table" => table = true,
            t if t.starts_with("iso") => iso = Some(t.trim_start_matches("iso").to_string()),
            _ => return mode.to_string(),
        }
    }
    let base = match (structure, ert) {
        (None, true) => "ERT".to_string(),
        (None, false) if bricks.is_some() => "no ERT".into(),
        (None, false) => "none".into(),
        (Some(s), e) => format!(
            "{}{s}{}",
            if e { "" } else { "no ERT, " },
            if hierarchy { "+h" } else { "" }
        ),
    };
    // Bounding bricks come on top of any structure: `ERT+bricks8`, `8³+bricks16 (table)`.
    let label = match bricks {
        Some(n) => format!("{base}+bricks{n}{}", if table { " (table)" } else { "" }),
        None => base,
    };
    // Iso mode on top of everything: `8³, iso (6 ref.)`.
    match iso {
        Some(n) => format!("{label}, iso ({n} ref.)"),
        None => label,
    }
}

/// The mean of a cell's or a chart point's values, the same whatever their order: summed in
/// ascending order, so modes whose frames took the same time show the same rate to the last
/// digit and tie, where a sum in run order could differ in the last bit.
pub fn mean(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted.iter().sum::<f64>() / sorted.len() as f64
}

/// Where a value of `field` goes among its row or column headers (modes: `none`, `ERT`, maps by
/// size, distance volumes, leap values, each with its variants after it).
pub fn sort_key(field: &str, text: &str) -> (i64, String) {
    match field {
        "mode" => {
            let tokens = || text.split('+');
            let number = |prefix: &str| -> Option<i64> {
                tokens().find_map(|t| t.strip_prefix(prefix)?.parse().ok())
            };
            // The base mode: none, ERT, then occupancy maps by sub-cube size, distance volumes
            // by bits, leap values (empty before homogeneous); with and without the hierarchy
            // and ERT next to each other.
            let structure: Option<i64> = if tokens().any(|t| t == "leapvalues") {
                Some(2000)
            } else if tokens().any(|t| t == "leapvalues-homogeneous") {
                Some(2001)
            } else if let Some(bits) = number("distance") {
                Some(1000 + bits)
            } else {
                number("leap")
            };
            let base = match structure {
                None if tokens().any(|t| t == "ert") => 1,
                None => 0,
                Some(size) => {
                    10 + size * 4
                        + text.contains("hier") as i64
                        + 2 * (!text.contains("ert")) as i64
                }
            };
            // Then its variants right after it: bounding bricks by size (the table version
            // after each), then iso mode by refinement steps, each with its bricks likewise.
            let bricks =
                number("bricks").map_or(0, |n| 1 + 2 * n + tokens().any(|t| t == "table") as i64);
            let iso = number("iso").map_or(0, |steps| 1 + steps);
            let variant = iso * 1000 + bricks;
            let rank = if text == "none" {
                0
            } else {
                base * 10_000 + variant
            };
            (rank, text.to_string())
        }
        "tf" => ((text != "zero") as i64, text.to_string()),
        _ => match text.parse::<f64>() {
            Ok(v) => ((v * 1000.0) as i64, text.to_string()),
            Err(_) => (0, text.to_string()),
        },
    }
}

fn display(field: &str, text: &str) -> String {
    match field {
        "mode" => mode_label(text),
        "tf" if text == "zero" => "'0'".into(),
        _ => text.to_string(),
    }
}

/// One table: rows × columns of means over the frames of each cell.
pub struct Table {
    pub title: String,
    /// What the cells hold (their number format follows it).
    pub metric: Metric,
    pub row_fields: Vec<String>,
    pub column_field: String,
    pub rows: Vec<(Vec<String>, Vec<Option<f64>>)>,
    pub columns: Vec<String>,
    /// Cells (row, column) whose leaping map does not fit the default SRAM (run with more).
    pub raised_sram: BTreeSet<(usize, usize)>,
    /// Cells (row, column) with a sampled simulation's estimate among their lines.
    pub sampled: BTreeSet<(usize, usize)>,
    /// Cells (row, column) with fewer result lines than the table's fullest cells (a sweep
    /// still running or interrupted), with their count: counted whether or not a line has
    /// the metric's figure, so a frame without one (no steps) does not mark its cell.
    pub fewer_frames: BTreeMap<(usize, usize), u32>,
    pub stand_ins: BTreeSet<String>,
    /// Fields that vary among the lines with one value per cell (zipped with the column or a
    /// row): not averaged over, named under the table.
    pub tied: Vec<String>,
    /// The lines are a sequence's time steps (a note says what their figures are), with the
    /// most views a cell holds.
    pub sequence: Option<usize>,
    /// The command that made the table (a line under it), when known.
    pub made_by: Option<String>,
}

/// The fields of a result line that, with its swept fields (`axes`), say which configuration
/// it ran: the run's own, those of sequence results (map strategy, time step length, brick),
/// the image size and the sampling rate. A table or chart never averages over two values of
/// one.
pub const CONFIGURATION_FIELDS: [&str; 10] = [
    "dataset",
    "tf",
    "mode",
    "model",
    "map",
    "dt",
    "brick",
    "width",
    "height",
    "sample_rate",
];

/// Whether a result line's timing is a sampled estimate: sampled, with an interval (a frame
/// simulated whole under `--sample`, one of fewer than 512 units or at rate 1, is exact).
pub fn is_estimate(line: &Value) -> bool {
    line.get("sampled") == Some(&Value::Bool(true))
        && line
            .get("cycles_ci95")
            .and_then(Value::as_f64)
            .is_some_and(|c| c > 0.0)
}

/// Builds the table of `metric` for the lines of one model. Every field that varies among the
/// lines, other than the frame, must be a row or the column field: averaging over a swept
/// hardware field silently would mix configurations. The title is `subject` followed by what a
/// cell holds, counted from the cells themselves ("mean over 4 frames", or "one frame per cell"
/// when the frame is a row or the column), so it cannot claim a mean that was not taken.
pub fn build(
    lines: &[&Value],
    metric: Metric,
    row_fields: &[String],
    column_field: &str,
    subject: &str,
) -> Result<Table> {
    let mut varying = BTreeSet::new();
    let mut first: BTreeMap<String, String> = BTreeMap::new();
    for line in lines {
        // The run's own fields, those of sequence results (map strategy, time step length,
        // brick) and the image size: any that varies must be a row or the column.
        let mut fields: Vec<String> = CONFIGURATION_FIELDS.iter().map(|s| s.to_string()).collect();
        if let Some(axes) = line.get("axes").and_then(Value::as_object) {
            fields.extend(axes.keys().cloned());
        }
        for f in fields {
            let v = field_text(line, &f).unwrap_or_default();
            match first.get(&f) {
                None => {
                    first.insert(f, v);
                }
                Some(seen) if *seen != v => {
                    varying.insert(f);
                }
                _ => {}
            }
        }
    }
    // A misspelt field would tabulate as an empty column: name it, and the option, instead.
    let fields = row_fields
        .iter()
        .map(|f| ("--rows", f.as_str()))
        .chain([("--columns", column_field)]);
    for (option, f) in fields {
        if !lines.iter().any(|l| field_text(l, f).is_some()) {
            return Err(Error::Invalid(format!(
                "{option}: `{f}` is not a field of these results; fields: dataset, tf, mode, \
                 model, frame, view, the sequence fields (map, dt, brick, time_step) or a swept \
                 field{}",
                axes_listed(lines)
            )));
        }
    }
    // A field twice would repeat a column, or tabulate a diagonal.
    if let Some(f) = row_fields
        .iter()
        .enumerate()
        .find(|(i, f)| row_fields[..*i].contains(f) || *f == column_field)
        .map(|(_, f)| f)
    {
        return Err(Error::Invalid(format!(
            "`{f}` is given twice: --rows {} (by default dataset,tf), --columns {column_field}",
            row_fields.join(",")
        )));
    }
    // A varying field that is neither a row nor the column is fine when it has one value per
    // cell: it advances with them (a `zip` partner of the column, such as sdram.t_rp with
    // sdram.t_rcd), and no cell mixes its values. It is named under the table.
    let cell_of = |line: &Value| -> (Vec<(i64, String)>, (i64, String)) {
        (
            row_fields
                .iter()
                .map(|f| sort_key(f, &field_text(line, f).unwrap_or_default()))
                .collect(),
            sort_key(
                column_field,
                &field_text(line, column_field).unwrap_or_default(),
            ),
        )
    };
    let mut tied = Vec::new();
    for f in &varying {
        if row_fields.contains(f) || column_field == f {
            continue;
        }
        let mut per_cell: BTreeMap<_, String> = BTreeMap::new();
        let one_per_cell = lines.iter().all(|line| {
            let v = field_text(line, f).unwrap_or_default();
            per_cell.entry(cell_of(line)).or_insert_with(|| v.clone()) == &v
        });
        if !one_per_cell {
            return Err(Error::Invalid(format!(
                "`{f}` varies among the results; add it to --rows or --columns (rows: {}, columns: {column_field})",
                row_fields.join(",")
            )));
        }
        tied.push(f.clone());
    }
    // Lines in key order, not in the order the runs finished, so that the same results give
    // the same tables however the sweep was scheduled (errors name the same runs).
    let mut lines = lines.to_vec();
    lines.sort_by_key(|l| field_text(l, "key").unwrap_or_default());
    type Key = Vec<(i64, String)>;
    /// Values, whether any line ran with the SRAM raised, whether any line is sampled.
    type Cell = (Vec<f64>, bool, bool);
    let mut cells: BTreeMap<(Key, (i64, String)), Cell> = BTreeMap::new();
    // A cell is a mean over frames: two results of one frame (view and time step) in a cell
    // differ in something that is neither a row nor the column (a base configuration or image
    // size the sweep folder mixes), and averaging them would hide it.
    let mut frames: BTreeMap<(Key, (i64, String), String), String> = BTreeMap::new();
    let mut stand_ins = BTreeSet::new();
    // Lines per cell whether or not they have the metric's figure (a frame of no steps has no
    // cycles per step): a cell with fewer is one whose results are not all there.
    let mut lines_per_cell: BTreeMap<(Key, (i64, String)), u32> = BTreeMap::new();
    let mut views_per_cell: BTreeMap<(Key, (i64, String)), BTreeSet<String>> = BTreeMap::new();
    for line in &lines {
        let row: Key = row_fields
            .iter()
            .map(|f| sort_key(f, &field_text(line, f).unwrap_or_default()))
            .collect();
        let column = sort_key(
            column_field,
            &field_text(line, column_field).unwrap_or_default(),
        );
        *lines_per_cell
            .entry((row.clone(), column.clone()))
            .or_default() += 1;
        let Some(value) = metric.value(line) else {
            continue;
        };
        let frame = ["view", "frame", "time_step"]
            .iter()
            .filter_map(|f| field_text(line, f).map(|v| format!("{f} {v}")))
            .collect::<Vec<_>>()
            .join(", ");
        let key = field_text(line, "key").unwrap_or_default();
        if frames.get(&(row.clone(), column.clone(), frame.clone())) == Some(&key) {
            return Err(Error::Invalid(format!(
                "run {key} is in the results twice (a results file joined with itself?)"
            )));
        }
        if let Some(other) =
            frames.insert((row.clone(), column.clone(), frame.clone()), key.clone())
        {
            return Err(Error::Invalid(format!(
                "runs {other} and {key} are the same frame ({frame}) in one table cell: the \
                 results differ in something that is neither a row nor the column (a base \
                 configuration or image size changed between sweeps into one folder?); \
                 tabulate them from separate folders, or add the field that differs to --rows"
            )));
        }
        let raised = line.get("fits_default_sram") == Some(&Value::Bool(false));
        if line.get("stand_in") == Some(&Value::Bool(true)) {
            stand_ins.extend(field_text(line, "dataset"));
        }
        // A sequence's views (each with its time steps): a cell may hold several.
        let view = ["view", "frame"]
            .iter()
            .filter_map(|f| field_text(line, f))
            .collect::<Vec<_>>()
            .join(" ");
        views_per_cell
            .entry((row.clone(), column.clone()))
            .or_default()
            .insert(view);
        let cell = cells.entry((row, column)).or_default();
        cell.0.push(value);
        cell.1 |= raised;
        // Only timing is estimated: steps, samples and structure figures stay exact.
        let counted = matches!(
            metric,
            Metric::Steps
                | Metric::Samples
                | Metric::Skippable
                | Metric::PositionsCut
                | Metric::OnChipBits
                | Metric::SdramRows
        );
        cell.2 |= !counted && is_estimate(line);
    }
    let row_keys: Vec<Key> = cells
        .keys()
        .map(|(r, _)| r.clone())
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect();
    let column_keys: Vec<(i64, String)> = cells
        .keys()
        .map(|(_, c)| c.clone())
        .collect::<BTreeSet<_>>()
        .into_iter()
        .collect();
    let frames_per_cell: BTreeSet<u32> = cells.values().map(|c| c.0.len() as u32).collect();
    // A sequence's line is one time step of one view: its cells are means over time steps,
    // and over views when a cell holds several (the frame neither a row nor the column).
    let sequence = lines.iter().any(|l| l.get("time_step").is_some());
    let most_views = views_per_cell
        .values()
        .map(BTreeSet::len)
        .max()
        .unwrap_or(1);
    let frame = match (sequence, most_views) {
        (false, _) => "frame",
        (true, 1) => "time step",
        (true, _) => "time step of every view",
    };
    let held = match (frames_per_cell.first(), frames_per_cell.last()) {
        (Some(&low), Some(&high)) if high > 1 && low == high => {
            format!("mean over {high} {}", plural(frame))
        }
        (Some(&low), Some(&high)) if high > 1 => {
            format!("mean over {low}–{high} {}", plural(frame))
        }
        _ => format!("one {frame} per cell"),
    };
    let mut raised_sram = BTreeSet::new();
    let mut sampled = BTreeSet::new();
    let most_lines = lines_per_cell.values().copied().max().unwrap_or(1);
    let mut fewer_frames = BTreeMap::new();
    let rows = row_keys
        .iter()
        .enumerate()
        .map(|(ri, r)| {
            let values = column_keys
                .iter()
                .enumerate()
                .map(|(ci, c)| {
                    cells
                        .get(&(r.clone(), c.clone()))
                        .map(|(values, raised, estimate)| {
                            if *raised {
                                raised_sram.insert((ri, ci));
                            }
                            if *estimate {
                                sampled.insert((ri, ci));
                            }
                            let there = lines_per_cell[&(r.clone(), c.clone())];
                            if there < most_lines {
                                fewer_frames.insert((ri, ci), there);
                            }
                            mean(values)
                        })
                })
                .collect();
            let labels = row_fields
                .iter()
                .zip(r)
                .map(|(f, (_, t))| display(f, t))
                .collect();
            (labels, values)
        })
        .collect::<Vec<(Vec<String>, Vec<Option<f64>>)>>();
    // Finite values whose sum overflows (near the largest float: an edited file) would show
    // as "inf": refused, naming the cell.
    for (labels, values) in &rows {
        if let Some(ci) = values
            .iter()
            .position(|v| v.is_some_and(|v| !v.is_finite()))
        {
            return Err(Error::Invalid(format!(
                "{subject}: the mean of row {} in column {} is not finite (values near the \
                 largest number: an edited results file?)",
                labels.join(", "),
                display(column_field, &column_keys[ci].1)
            )));
        }
    }
    Ok(Table {
        title: format!("{subject}, {held}"),
        metric,
        row_fields: row_fields.to_vec(),
        column_field: column_field.to_string(),
        rows,
        columns: column_keys
            .iter()
            .map(|(_, t)| display(column_field, t))
            .collect(),
        raised_sram,
        sampled,
        fewer_frames,
        stand_ins,
        tied,
        sequence: sequence.then_some(most_views),
        made_by: None,
    })
}

/// "time step" → "time steps", "time step of every view" → "time steps of every view".
fn plural(noun: &str) -> String {
    match noun.split_once(" of ") {
        Some((head, tail)) => format!("{head}s of {tail}"),
        None => format!("{noun}s"),
    }
}

/// How the cells of a table are written. A count (cycles, steps, stalls: `Metric::is_count`)
/// is a whole number in every cell of its table, plain digits as in the CSV: a mean over frames
/// differs from its cell's digits by less than 1, where "0.25 M" beside "124572" lost three
/// digits. Another figure gets about four significant digits, its decimals chosen per column
/// from the column's largest magnitude. A value that is not 0 never shows as 0 (`< 1`,
/// `< 0.01`), as `text::percent` does.
#[derive(Clone, Copy, Debug, PartialEq)]
enum NumberFormat {
    /// Beyond any real frame's figure (an edited or corrupt result): `1.700e308`, not 300 digits.
    Scientific,
    Whole,
    Decimals(usize),
}

impl NumberFormat {
    fn for_values(values: impl Iterator<Item = f64>, count: bool) -> NumberFormat {
        let largest = values.map(f64::abs).fold(0.0, f64::max);
        if largest >= 1e12 {
            NumberFormat::Scientific
        } else if count || largest >= 1000.0 {
            NumberFormat::Whole
        } else if largest >= 100.0 {
            NumberFormat::Decimals(1)
        } else {
            NumberFormat::Decimals(2)
        }
    }

    fn write(self, v: f64) -> String {
        let decimals = match self {
            NumberFormat::Scientific => return format!("{v:.3e}"),
            NumberFormat::Whole => 0,
            NumberFormat::Decimals(d) => d,
        };
        let text = format!("{v:.decimals$}");
        // The smallest step the format shows, for a value that would print as 0.
        if v > 0.0 && text.parse::<f64>() == Ok(0.0) {
            format!("< {:.decimals$}", 10f64.powi(-(decimals as i32)))
        } else {
            text
        }
    }
}

/// Fields every result line has; any other column field is a swept one and its name goes into
/// the column headers.
const RESULT_FIELDS: [&str; 5] = ["dataset", "tf", "mode", "model", "frame"];

impl Table {
    /// Row-field names, then the column labels (`field = value` for a swept field).
    fn header(&self) -> Vec<String> {
        let swept = !RESULT_FIELDS.contains(&self.column_field.as_str());
        self.row_fields
            .iter()
            .cloned()
            .chain(self.columns.iter().map(|c| {
                if swept {
                    format!("{} = {c}", self.column_field)
                } else {
                    c.clone()
                }
            }))
            .collect()
    }

    /// Whether the Markdown names each row's fastest column: frame-rate tables with two
    /// columns or more (which mode or value wins where, as an architect asks first).
    fn ranks_columns(&self) -> bool {
        self.metric == Metric::Fps && self.columns.len() >= 2
    }

    /// A row's fastest column and its lead over the next ("8³+h, 1.21× 8³"); columns that tie
    /// at the top, or for second place, are named together. A cell's marks (the SRAM raised) stay on its label.
    fn fastest_text(&self, row: usize) -> String {
        let values = &self.rows[row].1;
        let header = self.header();
        let label = |ci: usize| {
            let mark = if self.raised_sram.contains(&(row, ci)) {
                "*"
            } else {
                ""
            };
            format!("{}{mark}", header[self.row_fields.len() + ci])
        };
        let mut ranked: Vec<(usize, f64)> = values
            .iter()
            .enumerate()
            .filter_map(|(ci, v)| Some((ci, (*v)?)))
            .collect();
        // Highest first; equal rates in column order.
        ranked.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        let Some(&(_, best)) = ranked.first() else {
            return "–".into();
        };
        let top: Vec<String> = ranked
            .iter()
            .take_while(|(_, v)| *v == best)
            .map(|&(ci, _)| label(ci))
            .collect();
        let tied = top.len() > 1;
        let mut text = top.join(" = ");
        if tied {
            text += " (tied)";
        }
        // The runner-up, with the columns that tie it.
        if let Some(&(_, next)) = ranked.get(top.len()).filter(|_| !tied) {
            if next > 0.0 {
                let runners_up: Vec<String> = ranked[top.len()..]
                    .iter()
                    .take_while(|(_, v)| *v == next)
                    .map(|&(ci, _)| label(ci))
                    .collect();
                text += &format!(", {:.2}× {}", best / next, runners_up.join(" = "));
            }
        }
        text
    }

    pub fn markdown(&self) -> String {
        let mut s = format!("### {}\n\n", self.title);
        let header = self.header();
        let escaped: Vec<String> = header.iter().map(|h| markdown_cell(h)).collect();
        s += &format!("| {} |\n", escaped.join(" | "));
        let ranked = self.ranks_columns();
        let fastest_header = if ranked { " fastest |" } else { "" };
        s.insert_str(s.len() - 1, fastest_header);
        s += &format!(
            "|{}|{}\n",
            header
                .iter()
                .enumerate()
                .map(|(i, _)| if i < self.row_fields.len() {
                    "---"
                } else {
                    "---:"
                })
                .collect::<Vec<_>>()
                .join("|"),
            if ranked { "---|" } else { "" }
        );
        let count = self.metric.is_count();
        // A count's format is the table's (one style, whole numbers); another figure's is its
        // column's.
        let table_format = NumberFormat::for_values(
            self.rows
                .iter()
                .flat_map(|(_, v)| v.iter().flatten().copied()),
            true,
        );
        let formats: Vec<NumberFormat> = (0..self.columns.len())
            .map(|ci| {
                if count {
                    table_format
                } else {
                    NumberFormat::for_values(self.rows.iter().filter_map(|(_, v)| v[ci]), false)
                }
            })
            .collect();
        for (ri, (labels, values)) in self.rows.iter().enumerate() {
            let cells: Vec<String> = values
                .iter()
                .enumerate()
                .map(|(ci, v)| match v {
                    Some(v) => {
                        let mark = if self.raised_sram.contains(&(ri, ci)) {
                            "*"
                        } else {
                            ""
                        };
                        let approx = if self.sampled.contains(&(ri, ci)) {
                            "≈ "
                        } else {
                            ""
                        };
                        let fewer = match self.fewer_frames.get(&(ri, ci)) {
                            Some(n) => format!(" ({n})"),
                            None => String::new(),
                        };
                        format!("{approx}{}{mark}{fewer}", formats[ci].write(*v))
                    }
                    None => "–".into(),
                })
                .collect();
            let labels: Vec<String> = labels
                .iter()
                .map(|l| {
                    if self.stand_ins.contains(l) {
                        format!("{l} †")
                    } else {
                        l.clone()
                    }
                })
                .collect();
            let labels: Vec<String> = labels.iter().map(|l| markdown_cell(l)).collect();
            let fastest = if ranked {
                format!(" {} |", markdown_cell(&self.fastest_text(ri)))
            } else {
                String::new()
            };
            s += &format!(
                "| {} | {} |{fastest}\n",
                labels.join(" | "),
                cells.join(" | ")
            );
        }
        if ranked {
            s +=
                "\nfastest: the column with the highest frame rate in the row, and how many times \
                  the next one's rate it is.\n";
        }
        if !self.raised_sram.is_empty() {
            s += "\n\\* the occupancy map does not fit the default SRAM (occupancy.sram_bits); run with the SRAM raised.\n";
        }
        if !self.sampled.is_empty() {
            s += "\n≈ estimated by sampled simulation (docs/sampling.md): the timing figures of these cells are estimates with a 95 % interval per frame (`cycles_ci95` in the results).\n";
        }
        if !self.fewer_frames.is_empty() {
            s += "\n(n) only n frames of this cell are in the results, fewer than in the other cells: a sweep still running or interrupted, or frames the experiment selects per mode; compare such cells with care.\n";
        }
        if !self.stand_ins.is_empty() {
            s += "\n† stand-in dataset (see docs/results.md): not the published data.\n";
        }
        if !self.tied.is_empty() {
            s +=
                &format!(
                "\n{} {} with the rows and columns (one value per cell, e.g. a zipped axis): not \
                 averaged over.\n",
                self.tied
                    .iter()
                    .map(|f| format!("`{f}`"))
                    .collect::<Vec<_>>()
                    .join(", "),
                if self.tied.len() == 1 { "varies" } else { "vary" }
            );
        }
        if let Some(views) = self.sequence {
            s += "\nSequence steps (docs/experiments.md, \"Sequences: a time axis\"): a cell is the mean of its time \
                  steps' figures, step 0 (the download) included. A step's `fps` is the clock over \
                  the whole step's cycles (update + map + render, `--metric total-cycles`); its \
                  `cycles` and the other counts are the render's. The sequence's frame rate is the \
                  clock over the mean `total-cycles` (`vizsim sequence`)";
            s += if views > 1 {
                "; these cells mix several views' sequences: put `frame` in --rows or --columns \
                 for each one's.\n"
            } else {
                ".\n"
            };
        }
        if let Some(command) = &self.made_by {
            s += &format!("\nMade by `{command}`.\n");
        }
        s
    }

    /// The table as CSV: numbers only in the cells, so that a tool reads them as numbers. A
    /// table with sampled estimates gets one more column, `sampled_columns`: per row, the
    /// header labels of its cells that are estimates (separated by `;`), where the markdown
    /// writes ≈.
    pub fn csv(&self) -> String {
        let mut s = String::new();
        let labels = self.header();
        // The value columns' labels as the header writes them.
        let column_labels = &labels[self.row_fields.len()..];
        let mut header: Vec<String> = labels.iter().map(|h| csv_field(h)).collect();
        let marks_sampled = !self.sampled.is_empty();
        if marks_sampled {
            header.push("sampled_columns".into());
        }
        s += &header.join(",");
        s += "\n";
        for (ri, (labels, values)) in self.rows.iter().enumerate() {
            let mut cells: Vec<String> = values
                .iter()
                .map(|v| v.map(|v| format!("{v}")).unwrap_or_default())
                .collect();
            if marks_sampled {
                let estimated: Vec<&str> = (0..self.columns.len())
                    .filter(|&ci| self.sampled.contains(&(ri, ci)))
                    .map(|ci| column_labels[ci].as_str())
                    .collect();
                cells.push(csv_field(&estimated.join(";")));
            }
            let labels: Vec<String> = labels.iter().map(|l| csv_field(l)).collect();
            s += &format!("{},{}\n", labels.join(","), cells.join(","));
        }
        s
    }
}

/// A label as a Markdown table cell: a `|` in it (a transfer-function file's path, say) would
/// end the cell.
fn markdown_cell(text: &str) -> String {
    text.replace('|', "\\|")
}

fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

/// The cells of one CSV line as `Table::csv` writes them (a cell holding a comma or a quote is
/// quoted, its quotes doubled); None for a quote left open.
pub fn csv_cells(line: &str) -> Option<Vec<String>> {
    let mut cells = Vec::new();
    let mut cell = String::new();
    let mut chars = line.chars().peekable();
    let mut quoted = false;
    while let Some(c) = chars.next() {
        match (quoted, c) {
            (true, '"') if chars.peek() == Some(&'"') => {
                chars.next();
                cell.push('"');
            }
            (true, '"') => quoted = false,
            (false, '"') if cell.is_empty() => quoted = true,
            (false, ',') => cells.push(std::mem::take(&mut cell)),
            (_, c) => cell.push(c),
        }
    }
    (!quoted).then(|| {
        cells.push(cell);
        cells
    })
}

#[cfg(test)]
mod tests {
    use super::{build, csv_cells, csv_field, mode_label, read_results, sort_key, Metric};

    /// `csv_cells` reads back what `csv_field` writes, commas and quotes included.
    #[test]
    fn csv_cells_read_back_the_written_fields() {
        let fields = [
            "dataset",
            "no ERT, 4³",
            "say \"hi\"",
            "",
            "a,\"b\",c",
            "8³+h",
        ];
        let line: Vec<String> = fields.iter().map(|f| csv_field(f)).collect();
        assert_eq!(csv_cells(&line.join(",")).unwrap(), fields);
        assert_eq!(csv_cells("a,\"open").as_deref(), None);
        assert_eq!(csv_cells("").unwrap(), [""]);
    }

    /// `vizsim table` reads a results file as a resumed sweep does: a torn last line is left
    /// out whether or not the kill left its newline (a probe found `table` refusing a folder
    /// that `merge` and the sweep took); a bad line with lines after it is an error.
    #[test]
    fn a_torn_last_line_is_left_out_as_a_resumed_sweep_leaves_it() {
        let dir = std::env::temp_dir().join(format!("vizsim-torn-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("results.jsonl");
        let line = |key: &str, cycles: u32| {
            format!(
                "{{\"key\":\"{key}\",\"model\":\"cycle\",\"mode\":\"none\",\"tf\":\"zero\",\
                 \"dataset\":\"d\",\"frame\":0,\"fps\":1,\"cycles\":{cycles}}}\n"
            )
        };
        let good = line("a", 1) + &line("b", 2);
        let good = good.as_str();
        for torn in ["{\"key\":\"c\",\"cyc", "{\"key\":\"c\",\"cyc\n"] {
            std::fs::write(&path, format!("{good}{torn}")).unwrap();
            let (lines, left_out) = read_results(&path).unwrap();
            assert_eq!(lines.len(), 2, "{torn:?}");
            assert!(left_out, "{torn:?}: the torn line is reported");
        }
        std::fs::write(&path, good).unwrap();
        let (lines, left_out) = read_results(&path).unwrap();
        assert_eq!(
            (lines.len(), left_out),
            (2, false),
            "a complete file leaves nothing out"
        );
        std::fs::write(&path, format!("{{\"key\":\"c\",\"cyc\n{good}")).unwrap();
        let error = read_results(&path).unwrap_err().to_string();
        assert!(error.contains("line 1"), "{error}");
        assert!(read_results(&dir.join("missing.jsonl")).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Every field a metric reads, nested ones included, is refused when present but no
    /// number (an edited `stall_cycles.memory` used to be tabulated as missing), and each
    /// metric reads a line holding only its inputs.
    #[test]
    fn a_figure_any_metric_reads_must_be_a_number() {
        use clap::ValueEnum;
        let dir = std::env::temp_dir().join(format!("vizsim-nan-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("results.jsonl");
        for metric in Metric::value_variants() {
            // With what every result line has (`experiment::store` refuses a line without).
            let mut only_inputs = serde_json::json!({"key": "a", "model": "cycle", "mode": "none",
                "tf": "zero", "dataset": "d", "frame": 0, "fps": null, "cycles": null});
            for field in metric.inputs() {
                let mut at = &mut only_inputs;
                for name in &field[..field.len() - 1] {
                    at = at
                        .as_object_mut()
                        .unwrap()
                        .entry(*name)
                        .or_insert(serde_json::json!({}));
                }
                at[field[field.len() - 1]] = 2.0.into();
            }
            assert!(metric.value(&only_inputs).is_some(), "{metric:?}");
            for field in metric.inputs() {
                let mut edited = only_inputs.clone();
                let at = field.iter().fold(&mut edited, |v, name| &mut v[*name]);
                *at = "lots".into();
                std::fs::write(&path, format!("{edited}\n")).unwrap();
                let error = read_results(&path).unwrap_err().to_string();
                let named = format!("`{}` is \"lots\", not a number", field.join("."));
                assert!(error.contains(&named), "{metric:?}: {error}");
                *field.iter().fold(&mut edited, |v, name| &mut v[*name]) = serde_json::Value::Null;
                std::fs::write(&path, format!("{edited}\n")).unwrap();
                assert!(read_results(&path).is_ok(), "{metric:?}: null is allowed");
                // A section on the way that is no section is refused too.
                if field.len() > 1 {
                    let mut edited = only_inputs.clone();
                    edited[field[0]] = "x".into();
                    std::fs::write(&path, format!("{edited}\n")).unwrap();
                    let error = read_results(&path).unwrap_err().to_string();
                    let named = format!("`{}` is \"x\", not a section of figures", field[0]);
                    assert!(error.contains(&named), "{metric:?}: {error}");
                }
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// A column reads one way, chosen by its largest figure; a figure beyond any real frame's
    /// (1.7e308 edited into a result) is written in scientific notation, not as 300 digits.
    #[test]
    fn a_column_is_written_in_one_format_chosen_by_its_largest_figure() {
        let written = |values: &[f64], count: bool| -> Vec<String> {
            let format = super::NumberFormat::for_values(values.iter().copied(), count);
            values.iter().map(|&v| format.write(v)).collect()
        };
        assert_eq!(written(&[1.5, 12.25], false), ["1.50", "12.25"]);
        assert_eq!(written(&[1.5, 120.25], false), ["1.5", "120.2"]);
        assert_eq!(written(&[1.5, 4096.0], false), ["2", "4096"]);
        // Millions keep every digit: 248779 was "0.25 M".
        assert_eq!(written(&[248779.0, 4.35e6], false), ["248779", "4350000"]);
        assert_eq!(written(&[4.35e6, 1.7e308], false), ["4.350e6", "1.700e308"]);
        // Counts are whole numbers, 0 as `0` (it was "0.00"), a small mean not as 0.
        assert_eq!(written(&[0.0, 12.0, 3.75], true), ["0", "12", "4"]);
        assert_eq!(written(&[0.25, 0.5, 0.75], true), ["< 1", "< 1", "1"]);
        assert_eq!(written(&[0.004, 0.0], false), ["< 0.01", "0.00"]);
    }

    /// The step model's title names the step time the lines ran with: "published" only for
    /// 12.5 ns (it said so at any `clock.step_time_ns`), each value when they differ.
    #[test]
    fn the_step_models_title_names_the_step_time_its_runs_used() {
        use super::measured_by;
        let run = |steps: u64, ns: f64| serde_json::json!({"steps": steps, "frame_time_ns": steps as f64 * ns});
        let title = |lines: &[serde_json::Value]| {
            let lines: Vec<&serde_json::Value> = lines.iter().collect();
            measured_by(Metric::Fps, "step", &lines)
        };
        let published = [run(1000, 12.5), run(777, 12.5)];
        assert_eq!(
            title(&published),
            "step model, published cost 12.5 ns per step"
        );
        let five = title(&[run(1000, 5.0), run(3, 5.0)]);
        assert_eq!(
            five,
            "step model, clock.step_time_ns = 5 ns per step, not the published 12.5 ns"
        );
        // Rounding noise of frame time / steps does not make two values of one.
        let odd = title(&[run(1000, 3.3), run(7, 3.3), run(123457, 3.3)]);
        assert!(odd.contains(" = 3.3 ns per step"), "{odd}");
        let both = title(&[run(1000, 12.5), run(1000, 5.0), run(0, 5.0)]);
        assert_eq!(
            both,
            "step model, clock.step_time_ns per run: 5, 12.5 ns per step"
        );
        assert_eq!(title(&[run(0, 12.5)]), "step model");
        // The cycle model's clock is not the step time.
        let lines: Vec<&serde_json::Value> = published.iter().collect();
        assert_eq!(
            measured_by(Metric::Fps, "cycle", &lines),
            "cycle-accurate model at its clock"
        );
    }

    /// Waits for distance and leap-value words are their own metric: 0 on a cycle-model line
    /// that had none (the fields are written only when not 0), none on a line of no timing.
    #[test]
    fn leap_word_waits_add_both_causes_and_are_zero_when_not_written() {
        let waits = |line: serde_json::Value| Metric::LeapWordWaits.value(&line);
        let stalls = |s: serde_json::Value| serde_json::json!({ "stall_cycles": s });
        assert_eq!(waits(stalls(serde_json::json!({"memory": 5}))), Some(0.0));
        let both = serde_json::json!({"memory": 5, "distance_word": 7, "leap_word": 3});
        assert_eq!(waits(stalls(both.clone())), Some(10.0));
        assert_eq!(Metric::MemoryStalls.value(&stalls(both)), Some(5.0));
        assert_eq!(waits(serde_json::json!({"steps": 4})), None);
    }

    /// A result line of the cycle model: one frame of `mode`, sampled or exact.
    fn line(mode: &str, frame: u64, cycles: u64, sampled: bool) -> serde_json::Value {
        let mut line = serde_json::json!({
            "key": format!("{mode}-{frame}"),
            "dataset": "phantom:metaballs:32",
            "tf": "class",
            "mode": mode,
            "model": "cycle",
            "frame": frame,
            "cycles": cycles,
            "steps": cycles / 2,
        });
        if sampled {
            line["sampled"] = true.into();
            line["cycles_ci95"] = 10.0.into();
        }
        line
    }

    /// A label holding `|` (a transfer-function file's path) stays in its cell: every row has
    /// the header's number of cells.
    #[test]
    fn a_bar_in_a_label_does_not_split_its_markdown_cell() {
        let mut lines = [line("ert", 0, 100, false), line("none", 0, 150, false)];
        for l in &mut lines {
            l["tf"] = "own | tf.toml".into();
        }
        let refs: Vec<&serde_json::Value> = lines.iter().collect();
        let rows = ["dataset".to_string(), "tf".to_string()];
        let md = build(&refs, Metric::Cycles, &rows, "mode", "t")
            .unwrap()
            .markdown();
        let table: Vec<&str> = md.lines().filter(|l| l.starts_with('|')).collect();
        let cells = |l: &str| l.replace("\\|", "").matches('|').count();
        assert_eq!(table.len(), 3, "{md}");
        assert!(table.iter().all(|l| cells(l) == cells(table[0])), "{md}");
        assert!(md.contains("own \\| tf.toml"), "{md}");
    }

    /// A frame-rate table names each row's fastest column and its lead over the next, or the
    /// columns that tie; other metrics' tables and the CSV have no such column.
    #[test]
    fn a_frame_rate_table_names_each_rows_fastest_column() {
        let with_fps = |mode: &str, fps: f64| {
            let mut l = line(mode, 0, 1000, false);
            l["fps"] = fps.into();
            l
        };
        let rows = ["dataset".to_string(), "tf".to_string()];
        let markdown = |rates: [f64; 3]| {
            let lines: Vec<serde_json::Value> = ["none", "ert", "ert+leap8"]
                .iter()
                .zip(rates)
                .map(|(m, r)| with_fps(m, r))
                .collect();
            let refs: Vec<&serde_json::Value> = lines.iter().collect();
            let table = build(&refs, Metric::Fps, &rows, "mode", "t").unwrap();
            assert!(!table.csv().contains("fastest"), "{}", table.csv());
            let cycles = build(&refs, Metric::Cycles, &rows, "mode", "t").unwrap();
            assert!(!cycles.markdown().contains("fastest"));
            table.markdown()
        };
        let md = markdown([80.0, 100.0, 125.0]);
        assert!(
            md.contains("| dataset | tf | none | ERT | 8³ | fastest |\n"),
            "{md}"
        );
        assert!(md.contains("| 8³, 1.25× ERT |"), "{md}");
        let md = markdown([80.0, 100.0, 100.0]);
        assert!(md.contains("| ERT = 8³ (tied) |"), "{md}");
        let md = markdown([130.0, 100.0, 100.0]);
        assert!(md.contains("| none, 1.30× ERT = 8³ |"), "{md}");
        let md = markdown([130.0, 100.0, 90.0]);
        assert!(md.contains("| none, 1.30× ERT |"), "{md}");
    }

    /// Two modes whose frames ran at the same rates have the same mean to the last digit, and
    /// tie, whatever order their lines come in (summed in run order, 0.1 + 0.2 + 0.3 and
    /// 0.3 + 0.2 + 0.1 differ in the last bit, and one mode was named fastest, 1.00× the other).
    #[test]
    fn equal_frames_give_equal_means_in_any_order() {
        let with_fps = |mode: &str, frame: u64, fps: f64| {
            let mut l = line(mode, frame, 1000, false);
            l["fps"] = fps.into();
            l
        };
        let rates = [0.1, 0.2, 0.3];
        let mut lines = Vec::new();
        for (frame, &fps) in rates.iter().enumerate() {
            lines.push(with_fps("ert", frame as u64, fps));
            lines.push(with_fps("ert+leap8", frame as u64, rates[2 - frame]));
        }
        assert_ne!(
            (0.1 + 0.2) + 0.3,
            (0.3 + 0.2) + 0.1,
            "the order matters here"
        );
        let refs: Vec<&serde_json::Value> = lines.iter().collect();
        let rows = ["dataset".to_string(), "tf".to_string()];
        let table = build(&refs, Metric::Fps, &rows, "mode", "t").unwrap();
        let values = &table.rows[0].1;
        assert_eq!(values[0], values[1], "{values:?}");
        assert!(
            table.markdown().contains("| ERT = 8³ (tied) |"),
            "{}",
            table.markdown()
        );
        assert_eq!(super::mean(&[0.3, 0.1, 0.2]), super::mean(&[0.1, 0.2, 0.3]));
    }

    /// The storage metrics add what each run stores: the map's SRAM, the brick flags and
    /// blocking's table on chip; the distance array's rows and blocking's saved rows in the
    /// SDRAM; a run that stores nothing has 0 of both.
    #[test]
    fn storage_metrics_add_each_structures_memory() {
        let mut lines = [
            line("ert", 0, 100, false),
            line("ert+leap8+bricks16", 0, 100, false),
            line("ert+distance8", 0, 100, false),
            line("ert+leap8", 0, 100, false),
        ];
        lines[1]["structure_memory"] = serde_json::json!({
            "map_sram_bits": 4096, "brick_flag_bits": 512,
            "extra_sdram_rows_per_bank": 0, "voxel_word_bits": 0
        });
        lines[2]["structure_memory"] = serde_json::json!({
            "map_sram_bits": 0, "brick_flag_bits": 0,
            "extra_sdram_rows_per_bank": 256, "voxel_word_bits": 0
        });
        lines[3]["structure_memory"] = serde_json::json!({
            "map_sram_bits": 4096, "brick_flag_bits": 0,
            "extra_sdram_rows_per_bank": 0, "voxel_word_bits": 0
        });
        lines[3]["blocking"] = serde_json::json!({
            "table_sram_bits": 6144, "rows_blocked": 100, "rows_unblocked": 256
        });
        let values = |metric: Metric| lines.iter().map(|l| metric.value(l)).collect::<Vec<_>>();
        assert_eq!(
            values(Metric::OnChipBits),
            [Some(0.0), Some(4608.0), Some(0.0), Some(10240.0)]
        );
        assert_eq!(
            values(Metric::SdramRows),
            [Some(0.0), Some(0.0), Some(256.0), Some(-156.0)]
        );
        let refs: Vec<&serde_json::Value> = lines.iter().collect();
        let rows = ["dataset".to_string(), "tf".to_string()];
        let md = build(&refs, Metric::SdramRows, &rows, "mode", "t")
            .unwrap()
            .markdown();
        assert!(md.contains("| -156 |"), "{md}");
        assert_eq!(
            super::measured_by(Metric::OnChipBits, "step", &refs),
            "the configuration and the volume's dimensions"
        );
    }

    /// A count's table is in one style: whole numbers in every column, every digit kept
    /// (a column over 1 M showed "0.25 M" for 248779 beside "124572" in the next), 0 as `0`
    /// (it was "0.00"); the CSV keeps the means as they are.
    #[test]
    fn a_count_is_written_whole_in_every_column() {
        let mut lines = [
            line("none", 0, 4_350_000, false),
            line("none", 1, 3_000_000, false),
            line("ert", 0, 248_779, false),
            line("ert", 1, 248_780, false),
            line("ert+leap8", 0, 124_572, false),
            line("ert+leap8", 1, 124_572, false),
        ];
        for (l, stalls) in lines.iter_mut().zip([2_000_000, 1, 0, 0, 7, 8]) {
            l["stall_cycles"] = serde_json::json!({ "memory": stalls });
        }
        let refs: Vec<&serde_json::Value> = lines.iter().collect();
        let rows = ["dataset".to_string(), "tf".to_string()];
        let table = |metric| build(&refs, metric, &rows, "mode", "t").unwrap();
        let cycles = table(Metric::Cycles);
        let md = cycles.markdown();
        assert!(md.contains("| 3675000 | 248780 | 124572 |"), "{md}");
        assert!(
            cycles.csv().contains(",3675000,248779.5,124572\n"),
            "{}",
            cycles.csv()
        );
        let md = table(Metric::MemoryStalls).markdown();
        assert!(md.contains("| 1000000 | 0 | 8 |"), "{md}");
        // A figure that is no count keeps its decimals.
        let md = table(Metric::CyclesPerStep).markdown();
        assert!(md.contains("| 2.00 | 2.00 | 2.00 |"), "{md}");
    }

    /// A field unknown, repeated in --rows, or in both --rows and --columns is refused, naming
    /// the option (a probe found an empty column, a repeated one and a diagonal table).
    #[test]
    fn rows_and_columns_name_the_option_and_take_a_field_once() {
        let lines = [line("ert", 0, 100, false), line("none", 0, 150, false)];
        let refs: Vec<&serde_json::Value> = lines.iter().collect();
        let fields = |list: &[&str]| list.iter().map(|f| f.to_string()).collect::<Vec<_>>();
        for (rows, column, expected) in [
            (fields(&["datset"]), "mode", "--rows: `datset`"),
            (fields(&["dataset"]), "mdoe", "--columns: `mdoe`"),
            (fields(&["dataset", "dataset"]), "mode", "given twice"),
            (fields(&["dataset", "mode"]), "mode", "given twice"),
        ] {
            let error = build(&refs, Metric::Cycles, &rows, column, "t")
                .err()
                .unwrap_or_else(|| panic!("{rows:?} / {column} accepted"))
                .to_string();
            assert!(error.contains(expected), "{rows:?} / {column}: {error}");
        }
        assert!(build(&refs, Metric::Cycles, &fields(&["dataset"]), "mode", "t").is_ok());
    }

    /// A field zipped with the column (one value per cell) is tabulated and named under the
    /// table (a probe found `sdram.t_rp` zipped with `sdram.t_rcd` refused); one that takes
    /// two values in a cell is still refused.
    #[test]
    fn a_field_with_one_value_per_cell_is_named_not_refused() {
        let with = |mode: &str, frame: u64, rcd: u64, rp: u64| {
            let mut l = line(mode, frame, 100 + rcd, false);
            l["key"] = format!("{mode}-{frame}-{rcd}-{rp}").into();
            l["axes"] = serde_json::json!({"sdram.t_rcd": rcd, "sdram.t_rp": rp});
            l
        };
        let rows = ["dataset".to_string()];
        let zipped = [
            with("ert", 0, 2, 2),
            with("ert", 0, 4, 4),
            with("ert", 1, 4, 4),
        ];
        let refs: Vec<&serde_json::Value> = zipped.iter().collect();
        let table = build(&refs, Metric::Cycles, &rows, "sdram.t_rcd", "t").unwrap();
        assert_eq!(table.tied, ["sdram.t_rp"]);
        assert!(table
            .markdown()
            .contains("`sdram.t_rp` varies with the rows and columns"));
        let crossed = [with("ert", 0, 2, 2), with("ert", 1, 2, 4)];
        let refs: Vec<&serde_json::Value> = crossed.iter().collect();
        let error = build(&refs, Metric::Cycles, &rows, "sdram.t_rcd", "t")
            .err()
            .expect("two values of sdram.t_rp in one cell")
            .to_string();
        assert!(error.contains("`sdram.t_rp` varies"), "{error}");
    }

    /// Two results of one frame in a cell (a sweep folder that mixes configurations the rows
    /// and columns do not show) are an error naming both runs, not an average; frames of one
    /// cell are fine.
    #[test]
    fn a_frame_twice_in_a_cell_is_an_error_not_an_average() {
        let lines = [line("ert", 0, 100, false), line("ert", 1, 120, false)];
        let refs: Vec<&serde_json::Value> = lines.iter().collect();
        let rows = ["dataset".to_string()];
        assert!(build(&refs, Metric::Cycles, &rows, "mode", "t").is_ok());
        let mut again = line("ert", 1, 300, false);
        again["key"] = "ert-1-other-config".into();
        let mixed = [lines[0].clone(), lines[1].clone(), again];
        let refs: Vec<&serde_json::Value> = mixed.iter().collect();
        let error = build(&refs, Metric::Cycles, &rows, "mode", "t")
            .err()
            .expect("a frame twice in a cell")
            .to_string();
        assert!(
            error.contains("ert-1") && error.contains("ert-1-other-config"),
            "{error}"
        );
    }

    /// A cell averaged over fewer frames than the others (a sweep still running) is marked
    /// with its count in markdown, with a note; the CSV keeps numbers only, and a table whose
    /// cells hold alike has no mark.
    #[test]
    fn cells_of_fewer_frames_are_marked_with_their_count() {
        let lines = [
            line("none", 0, 1000, false),
            line("none", 1, 1200, false),
            line("ert", 0, 800, false),
        ];
        let lines: Vec<&serde_json::Value> = lines.iter().collect();
        let rows = ["dataset".to_string()];
        let table = build(&lines, Metric::Cycles, &rows, "mode", "t").unwrap();
        let markdown = table.markdown();
        assert!(markdown.contains("| 1100 | 800 (1) |"), "{markdown}");
        assert!(
            markdown.contains("(n) only n frames of this cell"),
            "{markdown}"
        );
        // A frame without the figure (no steps: no cycles per step) does not mark its cell.
        let mut no_steps = line("ert", 1, 0, false);
        no_steps["steps"] = 0.into();
        let complete = [
            line("none", 0, 1000, false),
            line("none", 1, 1200, false),
            line("ert", 0, 800, false),
            no_steps,
        ];
        let complete: Vec<&serde_json::Value> = complete.iter().collect();
        let per_step = build(&complete, Metric::CyclesPerStep, &rows, "mode", "t").unwrap();
        assert!(
            !per_step.markdown().contains("(n)"),
            "{}",
            per_step.markdown()
        );
        assert!(
            table.title.contains("mean over 1–2 frames"),
            "{}",
            table.title
        );
        assert_eq!(
            table.csv().lines().nth(1),
            Some("phantom:metaballs:32,1100,800")
        );
        let whole = build(&lines[..1], Metric::Cycles, &rows, "mode", "t").unwrap();
        assert!(!whole.markdown().contains("(n)"));
    }

    /// A cell with a sampled line among its frames is marked in markdown (≈ and the note) and
    /// listed in the CSV's `sampled_columns`; counted figures (steps) are exact either way, and
    /// a table without estimates keeps its plain CSV.
    #[test]
    fn sampled_estimates_are_marked_in_markdown_and_csv() {
        let lines = [
            line("none", 0, 1000, false),
            line("ert", 0, 800, true),
            line("ert", 1, 900, false),
        ];
        let lines: Vec<&serde_json::Value> = lines.iter().collect();
        let rows = ["dataset".to_string()];
        let cycles = build(&lines, Metric::Cycles, &rows, "mode", "t").unwrap();
        let markdown = cycles.markdown();
        assert!(markdown.contains("| 1000 (1) | ≈ 850 |"), "{markdown}");
        assert!(markdown.contains("≈ estimated by sampled simulation"));
        let csv = cycles.csv();
        let csv_lines: Vec<&str> = csv.lines().collect();
        assert_eq!(csv_lines[0], "dataset,none,ERT,sampled_columns");
        assert_eq!(csv_lines[1], "phantom:metaballs:32,1000,850,ERT");

        let steps = build(&lines, Metric::Steps, &rows, "mode", "t").unwrap();
        assert!(!steps.markdown().contains('≈'));
        // A sampled frame simulated whole (no interval: a small frame, or rate 1) is exact.
        let mut whole = line("ert", 0, 800, true);
        whole["cycles_ci95"] = 0.0.into();
        let exact = build(&[&whole], Metric::Cycles, &rows, "mode", "t").unwrap();
        assert!(!exact.markdown().contains('≈'), "{}", exact.markdown());
        assert_eq!(steps.csv().lines().next(), Some("dataset,none,ERT"));

        // A swept column field: the marks name the columns as the header does.
        let mut swept = [line("ert", 0, 1000, false), line("ert", 0, 800, true)];
        for (line, banks) in swept.iter_mut().zip([4, 8]) {
            line["key"] = format!("banks-{banks}").into();
            line["axes"] = serde_json::json!({ "memory.banks": banks });
        }
        let swept: Vec<&serde_json::Value> = swept.iter().collect();
        let by_banks = build(&swept, Metric::Cycles, &rows, "memory.banks", "t").unwrap();
        let csv = by_banks.csv();
        let csv_lines: Vec<&str> = csv.lines().collect();
        assert_eq!(
            csv_lines[0],
            "dataset,memory.banks = 4,memory.banks = 8,sampled_columns"
        );
        assert_eq!(
            csv_lines[1],
            "phantom:metaballs:32,1000,800,memory.banks = 8"
        );
    }

    #[test]
    fn every_leaping_structure_has_its_own_label_and_place() {
        let modes = [
            "none",
            "ert",
            "ert+leap4",
            "ert+leap8+hier",
            "leap8",
            "ert+distance4",
            "ert+distance8",
            "ert+leapvalues",
            "ert+leapvalues-homogeneous",
        ];
        let labels: Vec<String> = modes.iter().map(|m| mode_label(m)).collect();
        assert_eq!(
            labels,
            [
                "none",
                "ERT",
                "4³",
                "8³+h",
                "no ERT, 8³",
                "dist4",
                "dist8",
                "LV",
                "LV-h"
            ]
        );
        assert_eq!(mode_label("ert+leap8+iso6"), "8³, iso (6 ref.)");
        assert_eq!(mode_label("ert+iso0"), "ERT, iso (0 ref.)");
        // `modes` is listed in table order: a reversed copy sorts back into it.
        let mut sorted = modes.to_vec();
        sorted.reverse();
        sorted.sort_by_key(|m| sort_key("mode", m));
        assert_eq!(sorted, modes);
        assert_eq!(mode_label("ert+octree"), "ert+octree");
        // Bricks and iso variants follow their base mode, bricks by size, not as text (the
        // ray start/end tables read `ERT+bricks16 | ERT+bricks32 | ERT+bricks8`, after 8³).
        let variants = [
            "none",
            "bricks16",
            "ert",
            "ert+bricks8",
            "ert+bricks16",
            "ert+bricks16+table",
            "ert+bricks32",
            "ert+iso0",
            "ert+bricks4+iso0",
            "ert+bricks16+iso0",
            "ert+iso2",
            "ert+bricks16+iso2",
            "ert+iso6",
            "ert+leap4+bricks8",
            "ert+leap8",
            "ert+leap8+bricks16",
            "ert+leap8+iso0",
            "ert+leap16+hier",
        ];
        let mut sorted = variants.to_vec();
        sorted.reverse();
        sorted.sort_by_key(|m| sort_key("mode", m));
        assert_eq!(sorted, variants);
    }
}

//! Fixed-point precision sweeps: one width at a time against the float reference, and the skip
//! calculator's widths against the step count (they change cost, never the image).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::compare::{compare, Comparison};
use crate::config::{apply_override, HardwareConfig};
use crate::error::{Error, Result};
use crate::occupancy::OccupancyKind;
use crate::plot::{LineChart, Series};
use crate::run::{self, Model, Probes, RunDescription, RunReport};
use crate::volume::Volume;

/// The image widths swept, with their ranges (the published question: increment fraction bits).
pub const IMAGE_AXES: &[(&str, std::ops::RangeInclusive<u32>)] = &[
    ("ray.increment_frac_bits", 4..=12),
    ("ray.position_frac_bits", 4..=16),
    ("interpolation.weight_bits", 2..=12),
    ("classification.lut_bits", 4..=12),
    ("compositing.accumulator_bits", 6..=16),
];

/// The gradient width, swept as an image axis when the base run shades.
pub const SHADING_AXIS: (&str, std::ops::RangeInclusive<u32>) = ("shading.gradient_bits", 2..=12);

/// The image axes a base run sweeps: `IMAGE_AXES`, and the gradient width when it shades.
pub fn image_axes(shading: bool) -> Vec<(&'static str, std::ops::RangeInclusive<u32>)> {
    let mut axes = IMAGE_AXES.to_vec();
    if shading {
        axes.push(SHADING_AXIS);
    }
    axes
}

/// The skip widths swept for cost (with leaping at `LEAP_SUBCUBE`).
pub const COST_AXES: &[(&str, std::ops::RangeInclusive<u32>)] = &[
    ("skip.reciprocal_bits", 2..=16),
    ("skip.distance_frac_bits", 0..=12),
];
pub const LEAP_SUBCUBE: usize = 8;

#[derive(Clone, Debug, serde::Serialize)]
pub struct ImagePoint {
    pub field: String,
    pub bits: u32,
    pub comparison: Comparison,
    /// Invariant (c) at these widths: the error against the bound they predict (`bound`);
    /// None when the base configuration is outside the bound (`PrecisionReport::no_bound`).
    pub bound: Option<crate::bound::BoundCheck>,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct CostPoint {
    pub field: String,
    pub bits: u32,
    pub steps: u64,
    pub leaps: u64,
    /// The leaping image equals the non-leaping fixed-point image at these widths.
    pub image_identical_to_no_leaping: bool,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct PrecisionReport {
    /// The command that made the report (set by the caller; written into every text file).
    pub made_by: String,
    /// Where the base configuration differs from the calibrated default (`section.field = value`).
    pub hardware_changes: Vec<String>,
    pub dataset: String,
    pub transfer_function: String,
    pub image: Vec<ImagePoint>,
    pub cost: Vec<CostPoint>,
    /// Why the image points have no predicted bound, when they have none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub no_bound: Option<String>,
}

impl PrecisionReport {
    /// Image points whose fixed-point image is over its predicted bound somewhere (a broken
    /// invariant (c)).
    pub fn points_over_bound(&self) -> Vec<&ImagePoint> {
        self.image
            .iter()
            .filter(|p| p.bound.as_ref().is_some_and(|b| !b.holds()))
            .collect()
    }
}

/// The configuration with one field changed, validated like `--set`. Positions must keep at
/// least the increment's fraction bits, so sweeping positions below the default increment width
/// narrows the increment with them.
fn with_field(base: &HardwareConfig, field: &str, bits: u32) -> Result<HardwareConfig> {
    let mut table = toml::Table::try_from(base)
        .map_err(|e| Error::Invalid(format!("serialising the configuration: {e}")))?;
    let mut overrides = vec![format!("{field}={bits}")];
    if field == "ray.position_frac_bits" && base.ray.increment_frac_bits > bits {
        overrides.push(format!("ray.increment_frac_bits={bits}"));
    }
    if field == "ray.position_frac_bits" && base.skip.distance_frac_bits > bits {
        overrides.push(format!("skip.distance_frac_bits={bits}"));
    }
    for o in &overrides {
        apply_override(&mut table, o)?;
    }
    HardwareConfig::from_toml_str(&table.to_string(), "precision sweep", &[])
}

/// Runs the precision sweep of `base` (its dataset, transfer function, view and hardware) on
/// `volume`, every point through the one run path: the float reference once, then the step
/// model with one width changed at a time.
pub fn sweep(base: &RunDescription, volume: &Volume) -> Result<PrecisionReport> {
    let frame_of = |run: &RunDescription| -> Result<RunReport> {
        run::execute(run, &run::prepare(run, volume)?, Probes::default())
    };
    let reference = frame_of(&RunDescription {
        model: Model::Float,
        ..base.clone()
    })?;
    let (width, height) = base.size;
    let mut plain_hardware = base.hardware.clone();
    plain_hardware.occupancy.subcube = 0;
    plain_hardware.occupancy.hierarchy = false;
    let no_bound = crate::bound::unsupported(&base.hardware);
    let mut image = Vec::new();
    for (field, range) in image_axes(base.shading) {
        for bits in range.clone() {
            // An increment cannot have more fraction bits than the base's positions (a base
            // with narrow positions failed on the sweep's own values).
            if field == "ray.increment_frac_bits" && bits > plain_hardware.ray.position_frac_bits {
                continue;
            }
            let point = RunDescription {
                model: Model::Step,
                hardware: with_field(&plain_hardware, field, bits)?,
                ..base.clone()
            };
            let frame = frame_of(&point)?.frame;
            let bound = match no_bound {
                None => Some(run::check_error_bound(&point, volume, Some(&frame))?),
                Some(_) => None,
            };
            image.push(ImagePoint {
                field: field.to_string(),
                bits,
                comparison: compare(&frame.pixels, &reference.frame.pixels, width, height)?,
                bound,
            });
        }
    }
    let mut cost = Vec::new();
    let mut roomy = plain_hardware.clone();
    roomy.occupancy.sram_bits = roomy.occupancy.sram_bits.max(1 << 24);
    let plain = frame_of(&RunDescription {
        model: Model::Step,
        hardware: roomy.clone(),
        ..base.clone()
    })?;
    let mut leaping = roomy.clone();
    leaping.occupancy.subcube = LEAP_SUBCUBE.min(*volume.dims.iter().max().unwrap_or(&2));
    leaping.occupancy.kind = OccupancyKind::Class;
    for (field, range) in COST_AXES {
        for bits in range.clone() {
            if field.ends_with("distance_frac_bits") && bits > roomy.ray.position_frac_bits {
                continue;
            }
            let report = frame_of(&RunDescription {
                model: Model::Step,
                hardware: with_field(&leaping, field, bits)?,
                ..base.clone()
            })?;
            cost.push(CostPoint {
                field: field.to_string(),
                bits,
                steps: report.measurements.steps,
                leaps: report.measurements.leaps,
                image_identical_to_no_leaping: report.frame.pixels == plain.frame.pixels,
            });
        }
    }
    Ok(PrecisionReport {
        made_by: String::new(),
        hardware_changes: base.hardware.differences_from_default(),
        dataset: volume.name.clone(),
        transfer_function: reference.transfer_function,
        image,
        cost,
        no_bound,
    })
}

/// The line every generated report carries: the command and what the configuration was.
pub fn provenance(made_by: &str, hardware_changes: &[String]) -> String {
    let hardware = if hardware_changes.is_empty() {
        "the default hardware configuration".to_string()
    } else {
        format!(
            "the default hardware configuration with {}",
            hardware_changes.join(", ")
        )
    };
    format!("Made by `{made_by}` with {hardware}.")
}

/// The file stem of a dataset's report: its name as a plain file name in the output folder
/// (`figures::file_safe`: no path separator, so never a path that leaves the folder, whatever a
/// descriptor's `name` says), without leading dots or dashes (no hidden file, no name that reads
/// as an option); `dataset` when nothing is left.
pub fn report_stem(dataset: &str) -> String {
    let safe = crate::figures::file_safe(dataset);
    match safe.trim_start_matches(['.', '-']) {
        "" => "dataset".to_string(),
        stem => stem.to_string(),
    }
}

/// Writes `<stem>.csv`, `<stem>.md`, `<stem>.json`, and the charts `<stem>-psnr`,
/// `<stem>-max-error` and `<stem>-steps` (PNG and SVG), `<stem>` the dataset's `report_stem`,
/// all in `out_dir`. Returns the files written.
pub fn write_report(report: &PrecisionReport, out_dir: &Path) -> Result<Vec<PathBuf>> {
    let stem = report_stem(&report.dataset);
    // Appended, not `with_extension`: a dataset name with a dot keeps all of it.
    let file = |ending: &str| out_dir.join(format!("{stem}{ending}"));
    let mut written = Vec::new();
    let mut csv = String::from(
        "dataset,field,bits,max_abs_error_r,max_abs_error_g,max_abs_error_b,max_abs_error_a,mean_abs_error,psnr_db,pixels_over_1_lsb,bound_max_r,bound_max_g,bound_max_b,bound_mean,channels_over_bound\n",
    );
    for p in &report.image {
        let c = &p.comparison;
        let bound = p.bound.as_ref().map_or(",,,,".to_string(), |b| {
            format!(
                "{},{},{},{:.4},{}",
                b.max_bound[0], b.max_bound[1], b.max_bound[2], b.mean_bound, b.violations
            )
        });
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{},{:.5},{:.3},{},{bound}",
            report.dataset,
            p.field,
            p.bits,
            c.max_abs_error[0],
            c.max_abs_error[1],
            c.max_abs_error[2],
            c.max_abs_error[3],
            c.mean_abs_error,
            c.psnr_db,
            c.pixels_over_1_lsb
        );
    }
    let path = file(".csv");
    crate::output::write_atomically(&path, |w| std::io::Write::write_all(w, csv.as_bytes()))?;
    written.push(path);

    let mut md = format!(
        "# Fixed-point precision: {} ({})\n\n{}\n\nFixed-point model (default widths, one field changed at a time) \
         against the float reference. Errors in 8-bit steps; PSNR over RGB. The bound is the \
         error the widths predict per pixel (invariant (c), docs/precision.md): its largest \
         value per channel, its mean over the pixels' colour channels, and the pixel channels \
         whose error exceeds it (0: the invariant holds).{}\n\n\
         | field | bits | max error (R,G,B,A) | mean error | PSNR dB | pixels > 1 LSB | bound max (R,G,B) | bound mean | over bound |\n|---|---:|---|---:|---:|---:|---|---:|---:|\n",
        report.dataset,
        report.transfer_function,
        provenance(&report.made_by, &report.hardware_changes),
        report
            .no_bound
            .as_ref()
            .map_or(String::new(), |reason| format!(" This configuration has {reason}.")),
    );
    for p in &report.image {
        let c = &p.comparison;
        let (bound_max, bound_mean, over) = match &p.bound {
            Some(b) => (
                format!("{:?}", &b.max_bound[..3]),
                format!("{:.3}", b.mean_bound),
                b.violations.to_string(),
            ),
            None => ("–".into(), "–".into(), "–".into()),
        };
        let _ = writeln!(
            md,
            "| {} | {} | {:?} | {:.4} | {:.2} | {} | {bound_max} | {bound_mean} | {over} |",
            p.field, p.bits, c.max_abs_error, c.mean_abs_error, c.psnr_db, c.pixels_over_1_lsb
        );
    }
    let _ = write!(
        md,
        "\n## Skip widths: cost, not image (leaping with {LEAP_SUBCUBE}³ sub-cubes)\n\n\
         | field | bits | steps | leaps | image = no-leaping image |\n|---|---:|---:|---:|:---:|\n"
    );
    for p in &report.cost {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} |",
            p.field,
            p.bits,
            p.steps,
            p.leaps,
            if p.image_identical_to_no_leaping {
                "yes"
            } else {
                "NO"
            }
        );
    }
    let path = file(".md");
    crate::output::write_atomically(&path, |w| std::io::Write::write_all(w, md.as_bytes()))?;
    written.push(path);
    let path = file(".json");
    crate::output::write_json(&path, report)?;
    written.push(path);

    let series = |metric: &dyn Fn(&Comparison) -> f64| -> Vec<Series> {
        image_axes(report.image.iter().any(|p| p.field == SHADING_AXIS.0))
            .iter()
            .map(|(field, _)| Series {
                name: field.to_string(),
                points: report
                    .image
                    .iter()
                    .filter(|p| p.field == *field)
                    .map(|p| (p.bits as f64, metric(&p.comparison)))
                    .collect(),
            })
            .collect()
    };
    let title = format!("{}: fixed point vs float", report.dataset);
    let charts = [
        (
            "psnr",
            LineChart {
                log_y: false,
                title: &title,
                x_label: "bits of the swept field",
                y_label: "PSNR vs float (dB, higher is better)",
                // Identical images have infinite PSNR; cap for the chart.
                series: series(&|c| c.psnr_db.min(80.0)),
            },
        ),
        (
            "max-error",
            LineChart {
                log_y: false,
                title: &title,
                x_label: "bits of the swept field",
                y_label: "max |error| over channels (8-bit steps)",
                series: series(&|c| *c.max_abs_error.iter().max().unwrap_or(&0) as f64),
            },
        ),
    ];
    for (suffix, chart) in charts {
        chart.write(&file(&format!("-{suffix}")))?;
        written.push(file(&format!("-{suffix}.png")));
        written.push(file(&format!("-{suffix}.svg")));
    }
    let cost_title = format!(
        "{}: skip widths vs steps ({LEAP_SUBCUBE}³ sub-cubes)",
        report.dataset
    );
    let cost_chart = LineChart {
        log_y: false,
        title: &cost_title,
        x_label: "bits of the swept field",
        y_label: "steps per frame (samples + leaps)",
        series: COST_AXES
            .iter()
            .map(|(field, _)| Series {
                name: field.to_string(),
                points: report
                    .cost
                    .iter()
                    .filter(|p| p.field == *field)
                    .map(|p| (p.bits as f64, p.steps as f64))
                    .collect(),
            })
            .collect(),
    };
    cost_chart.write(&file("-steps"))?;
    written.push(file("-steps.png"));
    written.push(file("-steps.svg"));
    Ok(written)
}

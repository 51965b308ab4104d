//! `vizsim precision`: fixed-point error against the float reference per bit width, and the
//! skip widths against the step count.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use vizsim::run::Model;

use super::{DataArgs, HardwareArgs};

#[derive(Args)]
pub struct PrecisionArgs {
    /// Dataset: a name in the data folder, phantom:KIND[:SIZE], or a file.
    #[arg(long)]
    dataset: String,
    #[command(flatten)]
    data: DataArgs,
    /// Transfer function: `zero`, `class` (the dataset's own), a preset name, or a TOML file.
    #[arg(long, default_value = "class")]
    tf: String,
    /// View: `front`, `orbit:K/N` or `path:FILE:K/N` (a camera path). An oblique view by
    /// default: axis-aligned views, and angles whose direction happens to be exact in few bits
    /// (25° is within 0.1 % of 27/64, 58/64), hide increment errors.
    #[arg(long, default_value = "orbit:7/72")]
    view: String,
    /// Projection. Perspective rays each round their own increment, so they show ray-to-ray
    /// differences an orthographic view (one increment for every ray) hides.
    #[arg(long, value_enum, default_value = "ortho")]
    projection: super::ProjectionArg,
    /// Image size WxH.
    #[arg(long, default_value = "128x128", allow_hyphen_values = true)]
    size: String,
    /// Disable early ray termination (the same as --set compositing.ert=false): with ERT the
    /// largest error sits near (1 − threshold) · 255 levels at any width, where one model
    /// stops a sample before the other.
    #[arg(long)]
    no_ert: bool,
    /// Phong shading from per-voxel gradients; the sweep then also covers
    /// `shading.gradient_bits` (2 to 12).
    #[arg(long)]
    shading: bool,
    /// Output folder for the tables (CSV, Markdown, JSON) and charts (PNG, SVG).
    #[arg(long, default_value = "reports/precision")]
    out: PathBuf,
    /// The base configuration; each point changes one width of it (without leaping flags:
    /// image points run without leaping, cost points with 8³ class-map leaping).
    #[command(flatten)]
    hardware: HardwareArgs,
}

pub fn run(args: PrecisionArgs) -> Result<()> {
    let frame = super::FrameArgs {
        dataset: args.dataset.clone(),
        data: args.data.clone(),
        tf: args.tf.clone(),
        view: args.view.clone(),
        projection: args.projection,
        size: args.size.clone(),
        spacing: 1.0,
        no_ert: args.no_ert,
        shading: args.shading,
    };
    let base = frame.describe(Model::Step, &args.hardware)?;
    // Its points set the leaping themselves: a leaping flag would only mislabel the report.
    let occupancy = &base.hardware.occupancy;
    anyhow::ensure!(
        !args.hardware.asks_for_leaping()
            && args.hardware.bricks.is_none()
            && occupancy.subcube == 0
            && !occupancy.hierarchy
            && base.hardware.bricks.is_off(),
        "precision runs its image points without leaping and its cost points with 8³ class-map \
         leaping: --subcube, --hierarchy, --occupancy, --bricks (or occupancy.subcube, \
         occupancy.hierarchy and bricks.size in the configuration) do not apply"
    );
    // The output folder before the sweep (it was found unwritable only after it).
    vizsim::experiment::store::must_be_a_folder(&args.out)?;
    vizsim::output::check_folder_writable(&args.out)
        .with_context(|| format!("--out {}", args.out.display()))?;
    // A failed precision leaves no new empty folder.
    vizsim::output::removing_new_folder_on_error(&args.out, || sweep_and_write(&args, &base))
}

fn sweep_and_write(args: &PrecisionArgs, base: &vizsim::run::RunDescription) -> Result<()> {
    println!(
        "{}",
        args.hardware
            .resolved_line(&base.hardware, base.config_use())
    );
    let volume = args.data.load(&args.dataset)?;
    let start = Instant::now();
    let mut report = vizsim::precision::sweep(base, &volume)?;
    report.made_by = super::invocation();
    // The tables, the JSON and the charts together or none (a failed run must not look done).
    let written =
        vizsim::output::all_or_none(|| vizsim::precision::write_report(&report, &args.out))?;
    for path in written {
        println!("wrote {}", path.display());
    }
    // A glance at the image points: each field's PSNR at its narrowest and widest width (the
    // table has every width, the errors and the bound).
    println!("PSNR against the float reference (R, G, B), narrowest and widest width:");
    let mut fields: Vec<&str> = report.image.iter().map(|p| p.field.as_str()).collect();
    fields.dedup();
    for field in fields {
        let points: Vec<_> = report.image.iter().filter(|p| p.field == field).collect();
        let (Some(narrow), Some(wide)) = (points.first(), points.last()) else {
            continue;
        };
        println!(
            "  {field}: {} bits {}, {} bits {}",
            narrow.bits,
            narrow.comparison.psnr_text(1),
            wide.bits,
            wide.comparison.psnr_text(1)
        );
    }
    println!("{} in {:.1} s", volume.name, start.elapsed().as_secs_f64());
    if let Some(reason) = &report.no_bound {
        println!("{reason}: the report gives the measured error only");
    }
    // The report is written either way: it shows where the bound broke.
    let over = report.points_over_bound();
    anyhow::ensure!(
        over.is_empty(),
        "invariant (c) broken at {} of {} widths, first {} = {}: {}",
        over.len(),
        report.image.len(),
        over[0].field,
        over[0].bits,
        over[0]
            .bound
            .as_ref()
            .map_or(String::new(), |b| b.describe())
    );
    Ok(())
}

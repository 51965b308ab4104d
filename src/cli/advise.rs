//! `vizsim advise`: predicted frame rate of every leaping configuration, the recommendation
//! that fits the SRAM, and (`--validate`) the advice against a sweep's cycle-model results.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use vizsim::advise::{self, AdviseOptions, Structure, ValidateOptions};
use vizsim::camera::parse_image_size;
use vizsim::config::HardwareConfig;
use vizsim::run::{Model, RunDescription};

use super::DataArgs;

#[derive(Args)]
#[command(after_help = "The model: docs/advise.md. Examples:\n  \
    vizsim advise --dataset aneurism --tf class\n  \
    vizsim advise --dataset bonsai --tf zero --structures map,distance --json\n  \
    vizsim advise --validate runs/advise-validation --out reports/advise")]
pub struct AdviseArgs {
    /// Dataset: a name in the data folder, phantom:KIND[:SIZE], or a file (not with --validate).
    #[arg(
        long,
        required_unless_present = "validate",
        conflicts_with = "validate"
    )]
    dataset: Option<String>,
    #[command(flatten)]
    data: DataArgs,
    /// Transfer function: `zero` ('0' map), `class` (the dataset's own), a preset or a file.
    #[arg(long, default_value = "class")]
    tf: String,
    /// Image size WxH the frame rate is predicted for.
    #[arg(long, default_value = "256x256")]
    size: String,
    /// Views the prediction averages over: this many, evenly spaced on the 72-frame orbit.
    #[arg(long, default_value_t = 4)]
    views: u32,
    /// Rays per view the functional model traces (the image is scaled down to at most this
    /// many; the counts are scaled back up). Larger is closer and slower.
    #[arg(long, default_value_t = 2048)]
    rays: u64,
    /// Structures to rank besides ERT, comma-separated: map, distance, leap-values (default:
    /// map,distance). The distance volume and leap values are built for each run (about a
    /// second each on 256³); leap values' cost is only a lower bound, so they are opt-in.
    /// With --validate: the structures the advice may pick (default: every structure the
    /// folder ran); the true best is always over every configuration there.
    #[arg(long, value_delimiter = ',')]
    structures: Option<Vec<String>>,
    /// Hardware configuration TOML (default: the embedded, calibrated vizard2.toml).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Override a configuration field: --set occupancy.sram_bits=262144.
    #[arg(long = "set", value_name = "FIELD=VALUE")]
    overrides: Vec<String>,
    /// Print JSON instead of the table.
    #[arg(long)]
    json: bool,
    /// Validate: run the advisor for every (dataset, tf) of this sweep results folder and
    /// compare its pick with the cycle model's fastest configuration that fits the SRAM. A
    /// `.csv` table of mean frame rates (`vizsim table`'s layout, e.g. the protocol's
    /// reports/paper-protocol/tables/cycle-fps.csv) is accepted too: then --size, --views and
    /// the hardware options say how it was run.
    #[arg(long, value_name = "RESULTS_DIR")]
    validate: Option<PathBuf>,
    /// With --validate: most frames of a pair the advisor uses (evenly spaced among them).
    #[arg(long, default_value_t = 4, requires = "validate")]
    max_views: usize,
    /// With --validate: write validation.md, validation.csv and validation.json here.
    #[arg(long, requires = "validate")]
    out: Option<PathBuf>,
}

pub fn run(args: AdviseArgs) -> Result<()> {
    if let Some(dir) = &args.validate {
        return validate(&args, dir);
    }
    let dataset = args.dataset.as_deref().expect("clap requires --dataset");
    // Maps alone lose up to 59 % where a distance volume is the best (docs/advise.md); with
    // both, the advice stays under 2 s for 256³.
    let structures =
        parse_structures(&args)?.unwrap_or_else(|| vec![Structure::Map, Structure::Distance]);
    let hardware = load_hardware(&args)?;
    let size = parse_image_size(&args.size).context("--size")?;
    anyhow::ensure!(args.views >= 1, "--views 0: at least one view");
    anyhow::ensure!(args.rays >= 64, "--rays {}: at least 64", args.rays);
    let base = RunDescription {
        size,
        ..RunDescription::new(dataset, &args.tf, Model::Step, hardware)
    };
    base.validate()?;
    let volume = args.data.load(dataset).context("--dataset")?;
    let options = AdviseOptions {
        views: advise::orbit_views(args.views, 0),
        sample_size: advise::reduced_size(size, args.rays),
        structures,
    };
    let advice = advise::advise(&base, &volume, &options)
        .with_context(|| format!("--dataset {dataset} --tf {}", args.tf))?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&advice)?);
        return Ok(());
    }
    print!("{}", advise::advice_text(&advice));
    Ok(())
}

fn validate(args: &AdviseArgs, dir: &std::path::Path) -> Result<()> {
    let data_dir = args.data.dir()?;
    let options = ValidateOptions {
        max_rays: args.rays,
        max_views: args.max_views,
        structures: parse_structures(args)?,
    };
    if let Some(out) = &args.out {
        std::fs::create_dir_all(out).with_context(|| format!("--out {}", out.display()))?;
    }
    let quiet = args.json;
    let report = |row: &advise::ValidationRow| {
        if !quiet {
            eprintln!(
                "{} {}: advised {} ({:.2} fps), best {} ({:.2} fps), loss {:.1} %, {:.2} s",
                row.dataset,
                row.tf,
                row.advised,
                row.advised_fps,
                row.best,
                row.best_fps,
                row.loss_percent,
                row.advice_seconds
            );
        }
    };
    let validation = if dir.extension().is_some_and(|e| e == "csv") {
        // A table of mean frame rates (the protocol's cycle-fps.csv): the advisor runs with
        // --size, --views and the hardware options, which the table cannot say.
        let size = parse_image_size(&args.size).context("--size")?;
        advise::validate_table(
            dir,
            data_dir.as_deref(),
            &load_hardware(args)?,
            size,
            &advise::orbit_views(args.views, 0),
            args.rays,
            report,
        )
    } else {
        advise::validate(dir, data_dir.as_deref(), &options, report)
    }
    .with_context(|| format!("--validate {}", dir.display()))?;
    let command = super::invocation();
    if let Some(out) = &args.out {
        advise::write_validation(out, &validation, &command)?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&validation)?);
    } else {
        print!("{}", advise::validation_markdown(&validation, &command));
    }
    Ok(())
}

/// `--config` with `--set` applied.
fn load_hardware(args: &AdviseArgs) -> Result<HardwareConfig> {
    let hardware = HardwareConfig::load(args.config.as_deref(), &args.overrides);
    Ok(match &args.config {
        Some(p) => hardware.with_context(|| format!("--config {}", p.display()))?,
        None => hardware?,
    })
}

/// `--structures`, when given.
fn parse_structures(args: &AdviseArgs) -> Result<Option<Vec<Structure>>> {
    args.structures
        .as_ref()
        .map(|list| {
            list.iter()
                .map(|s| Structure::parse(s).map_err(|e| anyhow::anyhow!("--structures {e}")))
                .collect::<Result<Vec<_>>>()
        })
        .transpose()
}

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
// One of --dataset and --validate, and a missing one names both (as a group: an argument's own
// `required_unless_present` names that argument alone).
#[command(group(clap::ArgGroup::new("advise_input").args(["dataset", "validate"]).required(true)))]
pub struct AdviseArgs {
    /// Dataset: a name in the data folder, phantom:KIND[:SIZE], or a file (not with --validate).
    #[arg(long, conflicts_with = "validate")]
    dataset: Option<String>,
    #[command(flatten)]
    data: DataArgs,
    /// Transfer function: `zero` ('0' map), `class` (the dataset's own, the default), a preset
    /// or a file. Not with --validate (each run or table row says).
    #[arg(long)]
    tf: Option<String>,
    /// Image size WxH the frame rate is predicted for (default 256x256). Not with a --validate
    /// folder (its runs say).
    #[arg(long)]
    size: Option<String>,
    /// Views the prediction averages over: this many (1..=72, default 4), evenly spaced on the
    /// 72-frame orbit. Not with a --validate folder (its runs say).
    #[arg(long, allow_negative_numbers = true, value_parser = super::unsigned::<u32>)]
    views: Option<u32>,
    /// Rays per view the functional model traces (the image is scaled down to at most this
    /// many; the counts are scaled back up). Larger is closer and slower.
    #[arg(
        long,
        default_value_t = 2048,
        allow_negative_numbers = true,
        value_parser = super::unsigned::<u64>
    )]
    rays: u64,
    /// Structures to rank besides ERT, comma-separated: map, distance, leap-values (default:
    /// map,distance). The distance volume and leap values are built for each run (about a
    /// second each on 256³); leap values' cost rests on one calibrated row-miss rate, so
    /// they are opt-in.
    /// With a --validate folder: the structures the advice may pick (default: every structure
    /// the folder ran; ERT alone always may); the true best is always over every configuration
    /// there.
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
    /// compare its pick with the cycle model's fastest configuration that fits the SRAM. The
    /// cycle model's table of mean frame rates, `cycle-fps.csv` (`vizsim table --model cycle
    /// --metric fps`, e.g. reports/paper-protocol/tables/cycle-fps.csv), is accepted too: then
    /// --size, --views and the hardware options say how it was run.
    #[arg(long, value_name = "RESULTS_DIR")]
    validate: Option<PathBuf>,
    /// With a --validate folder: most frames of a pair the advisor uses (evenly spaced among
    /// them; default 4).
    #[arg(
        long,
        requires = "validate",
        allow_negative_numbers = true,
        value_parser = super::unsigned::<usize>
    )]
    max_views: Option<usize>,
    /// With --validate: write validation.md, validation.csv and validation.json here.
    #[arg(long, requires = "validate")]
    out: Option<PathBuf>,
}

const DEFAULT_TF: &str = "class";
const DEFAULT_SIZE: &str = "256x256";
const DEFAULT_VIEWS: u32 = 4;
const DEFAULT_MAX_VIEWS: usize = 4;

pub fn run(args: AdviseArgs) -> Result<()> {
    anyhow::ensure!(args.rays >= 64, "--rays {}: at least 64", args.rays);
    advise::check_overrides(&args.overrides)?;
    if let Some(dir) = &args.validate {
        return validate(&args, dir);
    }
    // (clap's `requires` does not hold these back: checked here.)
    anyhow::ensure!(
        args.out.is_none() && args.max_views.is_none(),
        "--out and --max-views apply to --validate only"
    );
    let dataset = args.dataset.as_deref().expect("clap requires --dataset");
    let tf = args.tf.as_deref().unwrap_or(DEFAULT_TF);
    // Maps alone lose up to 59 % where a distance volume is the best (docs/advise.md); with
    // both, the advice stays under 2 s for 256³.
    let structures =
        parse_structures(&args)?.unwrap_or_else(|| vec![Structure::Map, Structure::Distance]);
    let hardware = load_hardware(&args)?;
    if let Some(field) = advise::not_modelled_in(&hardware) {
        anyhow::bail!(
            "--config {}: `{field}` is on, and the advisor's cost model has no per-ray setup or \
             ray range (bricks, iso mode, clip planes, geometry): it would predict such a run \
             13–22 % too fast (docs/advise.md); use `vizsim sim` for it",
            args.config
                .as_deref()
                .map(|p| p.display().to_string())
                .unwrap_or_default()
        );
    }
    let size = image_size(&args)?;
    let views = view_count(&args)?;
    let sample_size = advise::reduced_size(size, args.rays);
    let base = RunDescription {
        size,
        ..RunDescription::new(dataset, tf, Model::Step, hardware)
    };
    // Checked at the size the functional model traces: the frame itself is never rendered, so
    // the memory budget applies to the reduced image only.
    RunDescription {
        size: sample_size,
        ..base.clone()
    }
    .validate()?;
    let volume = args.data.load(dataset).context("--dataset")?;
    let options = AdviseOptions {
        views: advise::orbit_views(views, 0),
        sample_size,
        structures,
    };
    let advice = advise::advise(&base, &volume, &options)
        .with_context(|| format!("--dataset {dataset} --tf {tf}"))?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&advice)?);
        return Ok(());
    }
    print!("{}", advise::advice_text(&advice));
    Ok(())
}

/// `--size`, or the default.
fn image_size(args: &AdviseArgs) -> Result<(u32, u32)> {
    let text = args.size.as_deref().unwrap_or(DEFAULT_SIZE);
    parse_image_size(text).with_context(|| format!("--size {text}"))
}

/// `--views`, or the default: views of the 72-frame orbit.
fn view_count(args: &AdviseArgs) -> Result<u32> {
    let views = args.views.unwrap_or(DEFAULT_VIEWS);
    anyhow::ensure!(
        (1..=72).contains(&views),
        "--views {views}: 1 to 72 (views are frames of the 72-frame orbit)"
    );
    Ok(views)
}

fn validate(args: &AdviseArgs, dir: &std::path::Path) -> Result<()> {
    let data_dir = args.data.dir()?;
    let table = dir.extension().is_some_and(|e| e == "csv");
    // A folder's runs say how they were run; a table cannot, so only a table takes these.
    if !table {
        if args.tf.is_some() {
            anyhow::bail!(
                "--tf does not apply to --validate {}: each pair is validated for its runs' own \
                 transfer function",
                dir.display()
            );
        }
        let given = [
            ("--size", args.size.is_some()),
            ("--views", args.views.is_some()),
            ("--config", args.config.is_some()),
            ("--set", !args.overrides.is_empty()),
        ];
        if let Some((option, _)) = given.iter().find(|(_, given)| *given) {
            anyhow::bail!(
                "{option} does not apply to --validate {}: a results folder's runs say how they \
                 were run (only a `{}` table takes it)",
                dir.display(),
                advise::FPS_TABLE
            );
        }
    } else {
        let given = [
            ("--tf", args.tf.is_some()),
            ("--structures", args.structures.is_some()),
            ("--max-views", args.max_views.is_some()),
        ];
        if let Some((option, _)) = given.iter().find(|(_, given)| *given) {
            anyhow::bail!(
                "{option} does not apply to --validate {}: a table is validated for its rows' \
                 transfer functions, every structure it holds and --views views",
                dir.display()
            );
        }
    }
    let max_views = args.max_views.unwrap_or(DEFAULT_MAX_VIEWS);
    anyhow::ensure!(max_views >= 1, "--max-views 0: at least one view");
    let options = ValidateOptions {
        max_rays: args.rays,
        max_views,
        structures: parse_structures(args)?,
    };
    if let Some(out) = &args.out {
        vizsim::experiment::store::must_be_a_folder(out)?;
        vizsim::output::check_folder_writable(out)
            .with_context(|| format!("--out {}", out.display()))?;
    }
    let quiet = args.json;
    let report = |row: &advise::ValidationRow| {
        if !quiet {
            // The swept values tell apart the pairs of one dataset and classification.
            let axes = if row.axes.is_empty() {
                String::new()
            } else {
                format!(" ({})", row.axes)
            };
            let faster = if row.faster_not_ranked.is_empty() {
                String::new()
            } else {
                format!(
                    "; faster, a mode advise does not rank: {}",
                    row.faster_not_ranked
                        .iter()
                        .map(|u| format!(
                            "{} {:.2} fps (+{:.1} %)",
                            u.mode, u.fps, u.faster_percent
                        ))
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            };
            vizsim::note!(
                "{} {}{axes}: advised {} ({:.2} fps), best {} ({:.2} fps), loss {:.1} %, {:.2} s{faster}",
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
    let validation = if table {
        // A table of mean frame rates (the protocol's cycle-fps.csv): the advisor runs with
        // --size, --views and the hardware options, which the table cannot say.
        if args.size.is_none() {
            // A sweep at another size reads as an advisor far off (96x96 runs: 86 % "off").
            vizsim::note!(
                "note: {} does not record the image size of its runs: the advice is for \
                 {DEFAULT_SIZE} (the paper protocol's); give --size WxH for runs made at another",
                dir.display()
            );
        }
        advise::validate_table(
            dir,
            data_dir.as_deref(),
            &load_hardware(args)?,
            image_size(args)?,
            &advise::orbit_views(view_count(args)?, 0),
            args.rays,
            report,
        )
        .with_context(|| format!("--validate {}", dir.display()))?
    } else {
        advise::validate(dir, data_dir.as_deref(), &options, report)
            .with_context(|| format!("--validate {}", dir.display()))?
    };
    if validation.torn_last_line {
        vizsim::note!(
            "{}",
            vizsim::experiment::store::torn_note(&dir.join(vizsim::experiment::store::RESULTS))
        );
    }
    let command = super::invocation();
    if let Some(out) = &args.out {
        // Made only now: a validation that fails leaves no empty folder behind.
        // The three files or none (a folder in the way of one left the others), and no empty
        // folder after a failure.
        vizsim::output::removing_new_folder_on_error(out, || {
            std::fs::create_dir_all(out).with_context(|| format!("--out {}", out.display()))?;
            vizsim::output::all_or_none(|| advise::write_validation(out, &validation, &command))
                .map_err(anyhow::Error::from)
        })?;
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

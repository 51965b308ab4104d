//! `vizsim render`: one frame with the float reference or the functional fixed-point model.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use vizsim::run::{self, Model, Probes};

use super::{leaping_text, FrameArgs, HardwareArgs};

#[derive(Args)]
pub struct RenderArgs {
    #[command(flatten)]
    frame: FrameArgs,
    /// Output PNG.
    #[arg(short, long)]
    output: PathBuf,
    /// Also write the run and its statistics as JSON (`-`: to standard output, the text then
    /// to standard error).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Also write one CSV row per ray: samples, leaps, where it entered and left, ERT, the
    /// positions its start and end cut (bricks, clipping, geometry) and its refinement samples
    /// (iso).
    #[arg(long)]
    rays: Option<PathBuf>,
    /// `float`: the reference ray caster; `fixed` (or `step`): the functional fixed-point
    /// model, which counts steps. Both take ERT and sampling from the hardware configuration;
    /// leaping applies to `fixed`.
    #[arg(long, value_enum, default_value = "float")]
    model: RenderModel,
    /// Also check invariant (c): render the other model too and check every pixel of the
    /// fixed-point image against the float reference, within the error bound the bit widths
    /// predict (docs/precision.md). Prints the measured error and the bound; exits non-zero,
    /// writing nothing, when a pixel is over its bound.
    #[arg(long)]
    check_bound: bool,
    #[command(flatten)]
    hardware: HardwareArgs,
}

#[derive(clap::ValueEnum, Clone, Copy, PartialEq, Eq)]
enum RenderModel {
    Float,
    #[value(alias = "step")]
    Fixed,
}

pub fn run(args: RenderArgs) -> Result<()> {
    let model = match args.model {
        RenderModel::Float => Model::Float,
        RenderModel::Fixed => Model::Step,
    };
    anyhow::ensure!(
        model != Model::Float || !args.hardware.asks_for_leaping(),
        "--subcube, --hierarchy and --occupancy apply to --model fixed (the float reference takes every sample)"
    );
    let desc = args.frame.describe(model, &args.hardware)?;
    if args.check_bound {
        super::refuse_unbounded(&desc)?;
    }
    // Output paths are checked before the render, not after it.
    let outputs: Vec<(&str, &std::path::Path)> = [
        ("--output", Some(&args.output)),
        ("--json", args.json.as_ref()),
        ("--rays", args.rays.as_ref()),
    ]
    .into_iter()
    .filter_map(|(option, path)| Some((option, path?.as_path())))
    .collect();
    let inputs = args.frame.inputs(&args.hardware, &desc);
    let inputs: Vec<&std::path::Path> = inputs.iter().map(PathBuf::as_path).collect();
    vizsim::output::check_distinct(&inputs, &outputs)?;
    vizsim::output::check_png_name("--output", &args.output)?;
    super::refuse_standard_output(&[("--rays", args.rays.as_deref())])?;
    for path in [Some(&args.output), args.rays.as_ref(), args.json.as_ref()]
        .into_iter()
        .flatten()
    {
        vizsim::output::check_writable(path)?;
    }
    let json = args.json.as_deref();
    super::say(
        json,
        &format!(
            "{}\n",
            args.hardware
                .resolved_line(&desc.hardware, desc.config_use())
        ),
    );
    // The outputs appear together or not at all; what the run says is printed after them
    // (a failed print must not leave the outputs' temporaries behind).
    use std::fmt::Write as _;
    let said = vizsim::output::all_or_none(|| -> Result<String> {
        let mut said = String::new();
        let probes = Probes {
            check_bound: args.check_bound,
            compare_float: true,
            ..Probes::default()
        };
        let report = run::run(&desc, args.frame.data.dir()?.as_deref(), probes)?;
        let bound_line = super::bound_line(&report)?;
        report.frame.write_png(&args.output)?;
        if let Some(path) = &args.rays {
            report.frame.write_rays_csv(path)?;
        }
        let stats = &report.stats;
        let m = &report.measurements;
        writeln!(
            said,
        "{} ({} model, {}): {} rays, {} hit, {} samples ({} leap samples), {} leaps, {} terminated early{}, {:.3} s ({:.1} M samples/s) -> {}",
        report.volume,
        model.name(),
        leaping_text(&report.leaping),
        stats.rays,
        stats.rays_hit,
        m.samples,
        m.leap_samples,
        m.leaps,
        m.rays_terminated_early,
        m.frame_time_ns
            .map(|t| format!(
                ", {} steps = {:.3} ms/frame{} at {} (cycle-accurate: `vizsim sim`)",
                m.steps,
                t / 1e6,
                m.fps.map_or(", no frame rate (no ray took a step)".to_string(), |fps| format!(" = {fps:.1} fps")),
                vizsim::config::step_cost_text(desc.hardware.clock.step_time_ns)
            ))
            .unwrap_or_default(),
        report.wall_seconds,
        report.samples_per_second / 1e6,
        args.output.display()
    )?;
        for line in super::feature_lines(&report.run.hardware, &report.measurements)
            .into_iter()
            .chain(super::note_lines(&report))
        {
            writeln!(said, "{line}")?;
        }
        for line in super::reference_line(&report).into_iter().chain(bound_line) {
            writeln!(said, "{line}")?;
        }
        if let Some(json) = &args.json {
            vizsim::output::write_json(json, &report)?;
        }
        Ok(said)
    })?;
    super::say(json, &said);
    Ok(())
}

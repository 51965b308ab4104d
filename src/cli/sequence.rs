//! `vizsim sequence`: the frame loop of a dynamic volume sequence — per time step the update
//! engine's writes, the map's cycles and the frame on the cycle model, and the sequence's
//! frames per second (docs/dynamic.md). The loop is `vizsim::dynamic::run_sequence`.

use anyhow::{Context, Result};
use clap::Args;
use vizsim::dynamic::{MapMode, SequenceOptions};
use vizsim::run::{Model, RunDescription};

use super::HardwareArgs;
use vizsim::camera::parse_image_size;

#[derive(Args)]
pub struct SequenceArgs {
    /// The time steps: phantom:metaballs[:SIZE][:seed=N][:t=T0] (steps --dt apart),
    /// phantom:tsdf[:SIZE][:seed=N][:t=T0] (one depth image fused per step) or a folder of
    /// .raw/.nrrd/.nhdr files of one size (file-name order; it has no `class` transfer
    /// function: give --tf zero, a preset or a file).
    #[arg(long)]
    source: String,
    /// Number of time steps (step 0 downloads the whole volume).
    #[arg(
        long,
        default_value_t = 30,
        allow_negative_numbers = true,
        value_parser = super::unsigned::<usize>,
    )]
    steps: usize,
    /// Metaballs: time between steps (default 0.05). The TSDF phantom moves one unit per step,
    /// and a folder's steps are its files.
    #[arg(long, allow_negative_numbers = true)]
    dt: Option<f32>,
    /// Edge of the bricks a partial update sends (1 up to the volume's longest edge).
    #[arg(
        long,
        default_value_t = vizsim::dynamic::DEFAULT_BRICK,
        allow_negative_numbers = true,
        value_parser = super::unsigned::<usize>,
    )]
    brick: usize,
    /// How the occupancy map follows the volume: during-update (conservative), rescan (during
    /// the update, partly written sub-cubes read back: exact), scan (a scan pass per step:
    /// exact) or none (no leaping).
    #[arg(long, default_value = "during-update", value_parser = MapMode::parse)]
    map: MapMode,
    /// Transfer function: `zero`, `class`, a preset name, or a TOML file.
    #[arg(long, default_value = "class")]
    tf: String,
    /// `front`, `orbit:K/N` or `path:FILE:K/N` (a camera path, docs/model.md).
    #[arg(long, default_value = "front")]
    view: String,
    /// Projection, as for `sim` (a perspective fly-through over a moving volume).
    #[arg(long, value_enum, default_value = "ortho")]
    projection: super::ProjectionArg,
    /// Image size WxH.
    #[arg(long, default_value = "256x256", allow_hyphen_values = true)]
    size: String,
    /// Render every frame again without leaping and require the same image.
    #[arg(long)]
    verify: bool,
    #[command(flatten)]
    hardware: HardwareArgs,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

pub fn run(args: SequenceArgs) -> Result<()> {
    let config = args.hardware.load(&[])?;
    // Before anything is printed: a configuration the update model does not model.
    vizsim::dynamic::check_modelled(
        &config,
        vizsim::dynamic::UpdateUse::Sequence { map: args.map },
    )?;
    anyhow::ensure!(
        // The size as configured (--subcube, --set or the file), not only the flag.
        args.map == MapMode::None || config.occupancy.subcube > 0,
        "--map {}: give the map's sub-cube size with --subcube (or occupancy.subcube by --set \
         or --config; or --map none)",
        args.map.name()
    );
    let run = RunDescription {
        view: args.view.clone(),
        projection: args.projection.into(),
        size: parse_image_size(&args.size).context("--size")?,
        ..RunDescription::new(&args.source, &args.tf, Model::Cycle, config)
    };
    run.validate()?;
    if !args.json {
        // `--map none` renders every frame without the map the configuration may describe.
        let not_leaping = (args.map == MapMode::None).then_some("--map none: no leaping");
        println!(
            "{}",
            args.hardware.resolved_line(
                &run.hardware,
                vizsim::config::ConfigUse {
                    model: Model::Cycle,
                    not_leaping
                }
            )
        );
    }
    if args.dt.is_some() && !args.source.starts_with("phantom:metaballs") {
        vizsim::note!(
            "note: --dt is without effect on {} (only phantom:metaballs takes a time step)",
            args.source
        );
    }
    let options = SequenceOptions {
        steps: args.steps,
        dt: args.dt.unwrap_or(vizsim::dynamic::DEFAULT_DT),
        brick: args.brick,
        map: args.map,
        verify: args.verify,
    };
    let json = args.json;
    let report = vizsim::dynamic::run_sequence(&run, &args.source, &options, |view| {
        if !json {
            let s = view.report;
            println!(
                "step {:>3} {}: {} regions, {} voxels sent; update {} + map {} + render {} = {} cycles; \
                 {}{}",
                s.step,
                s.volume,
                s.regions,
                s.voxels_written,
                s.update_cycles,
                s.map_cycles,
                s.render_cycles,
                s.total_cycles,
                // Without a map there are no sub-cubes to count.
                if options.map == vizsim::dynamic::MapMode::None {
                    "no map".to_string()
                } else {
                    format!(
                        "{} % empty sub-cubes, {} stale",
                        vizsim::text::percent(s.empty_subcubes_percent, 1),
                        s.stale_subcubes
                    )
                },
                match s.equals_non_leaping {
                    Some(true) => "; image = non-leaping image",
                    _ => "",
                }
            );
        }
        Ok(())
    })?;
    if json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    let ms = |cycles: f64| vizsim::text::milliseconds(cycles / (report.clock_mhz * 1e3));
    println!(
        "{} {:?}, map {}{}{}, updates in {}³ bricks, ordering: {} (update, map, render in turn)",
        report.source,
        report.dims,
        report.map.name(),
        report
            .subcube
            .map(|s| format!(
                ", {s}³ sub-cubes{}",
                if run.hardware.occupancy.hierarchy {
                    " + hierarchy"
                } else {
                    ""
                }
            ))
            .unwrap_or_default(),
        match run.hardware.bricks.size {
            0 => String::new(),
            b => format!(
                ", {b}³ bounding bricks (their flags rebuilt from the map's table: a pass of \
                 one entry per cycle, in the map cycles)"
            ),
        },
        report.brick,
        report.ordering
    );
    match (
        report.mean_update_cycles,
        report.mean_map_cycles,
        report.mean_render_cycles,
        report.steady_fps,
    ) {
        (Some(update), Some(map), Some(render), Some(steady)) => {
            println!(
                "steps after the first, mean: update {update:.0} ({}) + map {map:.0} ({}) + \
                 render {render:.0} ({}) cycles",
                ms(update),
                ms(map),
                ms(render),
            );
            println!(
                "sequence: {steady:.2} frames/s after the first step ({:.2} frames/s with the \
                 download of step 0)",
                report.fps
            );
        }
        _ => println!(
            "sequence: one step, the download: {:.2} frames/s (--steps 2 or more for the rate of \
             the steps after it)",
            report.fps
        ),
    }
    if let Some(note) = report.table_on_chip_bits.and_then(|bits| {
        vizsim::dynamic::table_sram_note(
            bits,
            report.subcube.map_or(0, |subcube| {
                vizsim::occupancy::map_bits(report.dims, subcube, run.hardware.occupancy.hierarchy)
            }),
            run.hardware.occupancy.sram_bits,
            &format!("the maps --map {} builds from the table", report.map.name()),
            "--map scan",
        )
    }) {
        println!("{note}");
    }
    Ok(())
}

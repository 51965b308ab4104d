//! `vizsim demo`: the main job on the embedded default: orbits, a fly-through along the tube
//! phantom (virtual endoscopy), a short dynamic sequence (metaballs, update / map / render
//! cycles per step), a gallery of the phantoms and the datasets present, and the quick experiment's sweep, tables and charts.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use vizsim::config::HardwareConfig;
use vizsim::figures::{file_safe, tf_label};
use vizsim::run::{self, Model, Probes, RunDescription};
use vizsim::volume::dataset;

use super::DataArgs;

#[derive(Args)]
pub struct DemoArgs {
    #[command(flatten)]
    data: DataArgs,
    /// Output folder.
    #[arg(long, default_value = "reports/demo")]
    out: PathBuf,
    /// Frames of the orbit (the published animation has 72, 5 degrees each; at most 3600,
    /// a tenth of a degree each).
    #[arg(
        long,
        default_value_t = 72,
        allow_negative_numbers = true,
        value_parser = super::unsigned::<u32>,
    )]
    frames: u32,
}

/// The most orbit frames the demo renders: a tenth of a degree a frame (the edge of its
/// 128×128 frames then moves about a tenth of a pixel), and a bound on the time an orbit takes.
const MAX_FRAMES: u32 = 3600;

/// Orbits of a phantom (and of fuel when the data folder holds it) as contact sheets, and a
/// front-and-side gallery of every dataset with both of its transfer functions, all rendered
/// by the float reference through the one run path. Every panel is labelled with its dataset,
/// transfer function and view (orbit panels: "frame k/N").
pub fn run(args: DemoArgs) -> Result<()> {
    let (out, frames) = (args.out.as_path(), args.frames);
    anyhow::ensure!(frames >= 1, "--frames must be at least 1");
    anyhow::ensure!(
        frames <= MAX_FRAMES,
        "--frames {frames}: at most {MAX_FRAMES} (a tenth of a degree a frame; the published \
         orbit has 72)"
    );
    // The output folder and the quick experiment's folder in it, before anything renders.
    vizsim::experiment::store::must_be_a_folder(out)?;
    vizsim::output::check_folder_writable(out)
        .with_context(|| format!("--out {}", out.display()))?;
    let quick = out.join("quick");
    check_quick_folder(out, &quick)?;
    // A demo that fails before writing anything leaves no new empty folder.
    vizsim::output::removing_new_folder_on_error(out, || render_all(&args, &quick))
}

fn render_all(args: &DemoArgs, quick: &Path) -> Result<()> {
    let (out, frames) = (args.out.as_path(), args.frames);
    let dir = args.data.dir()?;
    let mut orbit_sets = vec!["phantom:metaballs:64".to_string()];
    let mut gallery: Vec<String> = vizsim::volume::phantom::PhantomKind::ALL
        .iter()
        .map(|k| format!("phantom:{}:64", k.name()))
        .collect();
    match &dir {
        Some(d) if d.is_dir() => {
            let present = dataset::scan(d)?;
            if present.iter().any(|e| e.name == "fuel") {
                orbit_sets.push("fuel".into());
            } else {
                println!("{}: no fuel, so no fuel orbit", d.display());
            }
            if present.is_empty() {
                println!("{}: no datasets found, phantoms only", d.display());
            }
            gallery.extend(present.into_iter().map(|e| e.name));
        }
        _ => {
            println!("no data directory (--data-dir / VIZSIM_DATA / ../shared/data): phantoms only")
        }
    }
    let hardware = HardwareConfig::default_config();
    for spec in &orbit_sets {
        let volume = dataset::load(spec, dir.as_deref())?;
        let base = RunDescription {
            size: (128, 128),
            ..RunDescription::new(spec, "class", Model::Float, hardware.clone())
        };
        let prepared = run::prepare(&base, &volume)?;
        let start = Instant::now();
        // Every frame is rendered (the orbit's time), only the sheet's 12 are kept.
        let step = (frames / 12).max(1);
        let mut images = Vec::new();
        for k in 0..frames {
            let view = RunDescription {
                view: format!("orbit:{k}/{frames}"),
                ..base.clone()
            };
            let frame = run::execute(&view, &prepared, Probes::default())?.frame;
            if k % step == 0 && images.len() < 12 {
                images.push((k, frame));
            }
        }
        let picked: Vec<(&vizsim::render::Frame, Vec<String>)> = images
            .iter()
            .map(|(k, image)| {
                (
                    image,
                    vec![
                        volume.name.clone(),
                        format!("{}, frame {k}/{frames}", tf_label(&base.tf)),
                    ],
                )
            })
            .collect();
        let path = out.join(format!("orbit-{}.png", file_safe(&volume.name)));
        write_contact_sheet(&picked, 6, &path)?;
        println!(
            "{}: {frames}-frame orbit in {:.2} s -> {}",
            volume.name,
            start.elapsed().as_secs_f64(),
            path.display()
        );
    }
    flythrough(out, frames, &hardware)?;
    dynamic_sequence(out, &hardware)?;
    for spec in &gallery {
        let volume = dataset::load(spec, dir.as_deref())?;
        let mut row = Vec::new();
        for kind in ["zero", "class"] {
            let base = RunDescription::new(spec, kind, Model::Float, hardware.clone());
            let prepared = run::prepare(&base, &volume)?;
            for (view, view_label) in [("front", "front"), ("orbit:1/4", "side (orbit 1/4)")] {
                let desc = RunDescription {
                    view: view.into(),
                    ..base.clone()
                };
                let label = vec![
                    volume.name.clone(),
                    format!("{}, {view_label}", tf_label(kind)),
                ];
                row.push((
                    run::execute(&desc, &prepared, Probes::default())?.frame,
                    label,
                ));
            }
        }
        let path = out.join(format!("gallery-{}.png", file_safe(&volume.name)));
        let panels: Vec<_> = row.iter().map(|(f, l)| (f, l.clone())).collect();
        write_contact_sheet(&panels, 4, &path)?;
        println!(
            "{}: zero | class, front and side -> {}",
            volume.name,
            path.display()
        );
    }
    quick_experiment(dir.as_deref(), out, quick)
}

/// Refuses, before anything renders, a quick experiment folder the demo may not write into:
/// one that holds another experiment's results, or one a sweep (or a merge) is writing into.
fn check_quick_folder(out: &Path, quick: &Path) -> Result<()> {
    use vizsim::experiment::store;
    store::ResultStore::check_same_experiment(quick, QUICK_NAME)
        .map_err(|e| quick_folder_taken(out, quick, e))?;
    if quick.is_dir() {
        // Taken and released: only to learn that no one holds it now.
        drop(store::lock_folder(quick).map_err(|e| quick_folder_taken(out, quick, e))?);
    }
    Ok(())
}

/// The error for a quick experiment folder the demo may not write into (`e` says why).
fn quick_folder_taken(out: &Path, quick: &Path, e: vizsim::error::Error) -> anyhow::Error {
    anyhow::anyhow!(
        "demo --out {}: its quick experiment goes into {}, and the demo leaves that folder \
         alone (give demo another --out): {e}",
        out.display(),
        quick.display()
    )
}

/// Virtual endoscopy: `frames` frames along the lumen of `phantom:tube:64`
/// (configs/paths/tube.toml, embedded and written beside the sheet so the views can name it),
/// perspective, as a contact sheet of 12.
fn flythrough(out: &Path, frames: u32, hardware: &HardwareConfig) -> Result<()> {
    const TUBE_PATH: &str = include_str!("../../configs/paths/tube.toml");
    std::fs::create_dir_all(out)?;
    let path_file = out.join("flythrough-tube.toml");
    std::fs::write(&path_file, TUBE_PATH)?;
    let spec = "phantom:tube:64";
    let volume = dataset::load(spec, None)?;
    let base = RunDescription {
        size: (128, 128),
        projection: vizsim::camera::Projection::Persp,
        ..RunDescription::new(spec, "class", Model::Float, hardware.clone())
    };
    let prepared = run::prepare(&base, &volume)?;
    let start = Instant::now();
    let step = (frames / 12).max(1);
    let mut images = Vec::new();
    for k in (0..frames).step_by(step as usize).take(12) {
        let desc = RunDescription {
            view: format!("path:{}:{k}/{frames}", path_file.display()),
            ..base.clone()
        };
        let frame = run::execute(&desc, &prepared, Probes::default())?.frame;
        images.push((frame, k));
    }
    let panels: Vec<_> = images
        .iter()
        .map(|(f, k)| {
            (
                f,
                vec![
                    volume.name.clone(),
                    format!("fly-through, frame {k}/{frames}"),
                ],
            )
        })
        .collect();
    let sheet = out.join("flythrough-tube.png");
    write_contact_sheet(&panels, 6, &sheet)?;
    println!(
        "{}: fly-through along configs/paths/tube.toml, {} frames in {:.2} s -> {}",
        volume.name,
        panels.len(),
        start.elapsed().as_secs_f64(),
        sheet.display()
    );
    Ok(())
}

/// A short dynamic sequence: 5 time steps of `phantom:metaballs:64` through the frame loop of
/// `vizsim sequence` (update, map built during the update, render on the cycle model), each
/// panel captioned with its update, map and render cycles.
fn dynamic_sequence(out: &Path, hardware: &HardwareConfig) -> Result<()> {
    use vizsim::dynamic::{MapMode, SequenceOptions};
    std::fs::create_dir_all(out)?;
    let source = "phantom:metaballs:64";
    let mut config = hardware.clone();
    config.occupancy.subcube = 8;
    let run = RunDescription {
        size: (128, 128),
        ..RunDescription::new(source, "class", Model::Cycle, config)
    };
    let options = SequenceOptions {
        steps: 5,
        dt: 0.1,
        brick: 8,
        map: MapMode::DuringUpdate,
        verify: false,
    };
    let start = Instant::now();
    let mut images = Vec::new();
    let report = vizsim::dynamic::run_sequence(&run, source, &options, |view| {
        let s = view.report;
        let t = s.volume.rsplit_once(":t=").map_or("0", |(_, t)| t);
        images.push((
            view.frame.clone(),
            vec![
                format!("step {}, t = {t}", s.step),
                format!("update {} cycles", super::thousands(s.update_cycles.into())),
                format!("map {} cycles", super::thousands(s.map_cycles.into())),
                format!("render {} cycles", super::thousands(s.render_cycles.into())),
            ],
        ));
        Ok(())
    })?;
    let panels: Vec<_> = images.iter().map(|(f, l)| (f, l.clone())).collect();
    let sheet = out.join("sequence-metaballs.png");
    write_contact_sheet(&panels, 5, &sheet)?;
    println!(
        "{source}: {} time steps (update, map during the update, render; cycle model) in {:.2} s: \
         {:.1} frames/s after the download -> {}",
        report.steps.len(),
        start.elapsed().as_secs_f64(),
        report.steady_fps.unwrap_or(report.fps),
        sheet.display()
    );
    Ok(())
}

/// The quick experiment, embedded.
const QUICK: &str = include_str!("../../configs/experiments/quick.toml");
/// Its name (the `name` in `QUICK`, checked where it is read).
const QUICK_NAME: &str = "quick";

/// The quick experiment (configs/experiments/quick.toml, embedded) into `out` (`demo_out`'s
/// quick folder): sweep, tables and charts. Without the data folder its real datasets are left
/// out.
fn quick_experiment(data_dir: Option<&Path>, demo_out: &Path, out: &Path) -> Result<()> {
    use vizsim::experiment::{self, spec};
    let mut file: spec::ExperimentFile = toml::from_str(QUICK)?;
    anyhow::ensure!(
        file.name == QUICK_NAME,
        "configs/experiments/quick.toml: named `{}`, the demo expects `{QUICK_NAME}`",
        file.name
    );
    let mut left_out = Vec::new();
    file.datasets.retain(|d| {
        let present = dataset::load(d, data_dir).is_ok();
        if !present {
            println!("quick experiment: {d} is not there, left out");
            left_out.push(d.clone());
        }
        present
    });
    let expansion = spec::expand(
        &toml::to_string(&file)?,
        "configs/experiments/quick.toml",
        data_dir,
    )?;
    // The demo's own folder: results of an earlier version of the quick experiment (other
    // defaults, other runs) are removed rather than mixed into its tables. Decided and done
    // under the folder's lock (a sweep writing into it keeps its results), and never for
    // another experiment's results. The lock is released before the sweep, which takes it.
    let lock =
        experiment::store::lock_folder(out).map_err(|e| quick_folder_taken(demo_out, out, e))?;
    experiment::store::ResultStore::check_same_experiment(out, QUICK_NAME)
        .map_err(|e| quick_folder_taken(demo_out, out, e))?;
    let results = out.join(experiment::store::RESULTS);
    let done = experiment::store::result_keys(&results)?;
    let mut runs: std::collections::HashSet<String> =
        expansion.runs.iter().map(|r| r.key.clone()).collect();
    // Results of a dataset left out this time (the data folder not there) are still runs of
    // the quick experiment: kept, not taken for an earlier version's.
    if !left_out.is_empty() && results.exists() {
        for (line, _) in experiment::store::read_lines(&results)? {
            let of_left_out = line["dataset"]
                .as_str()
                .is_some_and(|d| left_out.iter().any(|l| l == d));
            if let (true, Some(key)) = (of_left_out, line["key"].as_str()) {
                runs.insert(key.to_string());
            }
        }
    }
    if done.iter().any(|k| !runs.contains(k)) {
        println!(
            "quick experiment: {} holds results of an earlier version of it; they are removed",
            out.display()
        );
        for file in [
            experiment::store::RESULTS,
            experiment::store::TIMING,
            experiment::store::RESOLVED,
        ] {
            match std::fs::remove_file(out.join(file)) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(vizsim::error::Error::io(out.join(file), e).into())
                }
                _ => {}
            }
        }
    }
    drop(lock);
    let summary = experiment::sweep(&expansion, out, None, None, false)?;
    println!(
        "quick experiment: {} runs in {:.1} s -> {}",
        summary.total,
        summary.wall_seconds,
        out.display()
    );
    let results = super::results::ResultsArgs {
        dir: out.to_path_buf(),
        frame_step: 1,
        model: None,
        dataset: Vec::new(),
    };
    super::results::write_tables(
        &results,
        &[],
        &["dataset".to_string(), "tf".to_string()],
        "mode",
        None,
    )?;
    let lines = results.read()?;
    let charts =
        vizsim::figures::write_all(&lines, &out.join("plots"), &vizsim::figures::ChartKind::ALL)?;
    println!(
        "{} -> {}",
        vizsim::text::count(charts, "chart", "charts"),
        out.join("plots").display()
    );
    Ok(())
}

/// Tiles frames of equal size into one PNG, `columns` per row, each under a strip with its
/// label (dataset, transfer function, view).
fn write_contact_sheet(
    panels: &[(&vizsim::render::Frame, Vec<String>)],
    columns: usize,
    path: &Path,
) -> Result<()> {
    if panels.is_empty() {
        return Ok(());
    }
    vizsim::plot::contact_sheet(panels, columns)?.write_png(path)?;
    Ok(())
}

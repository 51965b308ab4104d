//! `vizsim sweep`: an experiment file's runs, in parallel, resumable, shardable.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use super::DataArgs;

#[derive(Args)]
pub struct SweepArgs {
    /// The experiment TOML.
    experiment: PathBuf,
    /// Output folder (results.jsonl, timing.jsonl, experiment.resolved.json).
    #[arg(long)]
    out: PathBuf,
    /// Print how many runs there are, what is already done and a time estimate; run nothing.
    #[arg(long)]
    dry_run: bool,
    /// Run only runs i with i mod N = I (I/N, 0-based): for clusters; `vizsim merge` joins.
    #[arg(long, allow_hyphen_values = true)]
    shard: Option<String>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
    /// Run only this model's runs (`step` or `cycle`), e.g. to time them apart.
    #[arg(long)]
    model: Option<String>,
    #[command(flatten)]
    data: DataArgs,
}

pub fn run(args: SweepArgs) -> Result<()> {
    let (experiment, out, dry_run, shard, model, quiet) = (
        args.experiment.as_path(),
        args.out.as_path(),
        args.dry_run,
        args.shard.as_deref(),
        args.model.as_deref(),
        args.quiet,
    );
    use std::io::IsTerminal;
    use vizsim::experiment::{self, spec, Shard};
    let shard = shard.map(Shard::parse).transpose()?;
    let dir = args.data.dir()?;
    if let Some(model) = model {
        anyhow::ensure!(
            model == "step" || model == "cycle",
            "--model {model}: expected `step` or `cycle`"
        );
    }
    // The dry run streams the runs (only their keys are held, to drop repeats), so it can
    // count and estimate an experiment whose expansion would not fit in memory; the sweep
    // needs them all.
    let plan = spec::load_plan(experiment, dir.as_deref())?;
    let name = plan.experiment.name.clone();
    let plan_models = plan.experiment.models.clone();
    experiment::store::ResultStore::check_same_experiment(out, &name)?;
    let done = experiment::store::result_keys(&out.join(experiment::store::RESULTS))?;
    let mut tally = Tally::default();
    // The folder's results that are runs of the experiment (whatever the model and shard).
    let mut still_runs = std::collections::HashSet::new();
    let mut count = |r: &spec::RunSpec, volumes: &spec::Volumes| {
        if done.contains(&r.key) {
            still_runs.insert(r.key.clone());
        }
        if model.is_some_and(|m| r.run.model.name() != m) {
            return;
        }
        tally.of_model += 1;
        if shard.is_some_and(|s| !s.contains(r)) {
            return;
        }
        tally.mine += 1;
        tally.raised += !r.fits_default_sram as usize;
        for path in r.axes.keys() {
            let without_effect = r.run.hardware.why_without_effect(path, r.run.config_use());
            let counts = tally.idle_axes.entry(path.clone()).or_default();
            counts.0 += 1;
            if let Some(why) = without_effect {
                *counts.1.entry(why).or_default() += 1;
            }
        }
        if !done.contains(&r.key) {
            let m = (r.run.model == spec::Model::Cycle) as usize;
            tally.pending[m] += 1;
            tally.seconds[m] += experiment::run_seconds(volumes, r);
        }
    };
    let (expansion, omitted) = if dry_run {
        let omitted = plan.for_each_run(|r| {
            count(&r, &plan.volumes);
            Ok(())
        })?;
        (None, omitted)
    } else {
        let e = spec::expand_plan(plan)?;
        for r in &e.runs {
            count(r, &e.volumes);
        }
        let omitted = spec::Omitted {
            skipped: e.skipped.clone(),
            duplicates: e.duplicates,
        };
        (Some(e), omitted)
    };
    experiment::store::ResultStore::check_results_are_runs(out, &done, |key| {
        still_runs.contains(key)
    })?;
    if let Some(model) = model.filter(|_| tally.of_model == 0) {
        anyhow::bail!(
            "--model {model}: {} has no {model}-model runs (its `models` are {:?})",
            experiment.display(),
            plan_models
        );
    }
    // A folder another sweep writes into, or one that cannot be written, is refused before the
    // plan is printed; the lock is held from here to the sweep's end.
    let lock = if dry_run {
        None
    } else {
        Some(experiment::store::lock_folder(out)?)
    };
    let threads = rayon::current_num_threads();
    let per_thread = |seconds: f64| duration_text(seconds / threads.max(1) as f64);
    println!(
        "{name}: {} runs{} ({} step model, {} cycle model to run; {} already done in {}); \
         estimate {} + {} on {threads} thread{} (step + cycle model; rough)",
        tally.mine,
        shard
            .map(|s| format!(" in shard {}/{}", s.index, s.count))
            .unwrap_or_default(),
        tally.pending[0],
        tally.pending[1],
        tally.mine - tally.pending[0] - tally.pending[1],
        out.display(),
        per_thread(tally.seconds[0]),
        per_thread(tally.seconds[1]),
        if threads == 1 { "" } else { "s" },
    );
    if tally.pending[1] > 0 {
        println!(
            "  the cycle model's estimate counts every run; runs that time alike share one \
             simulation (docs/experiments.md), so the sweep may take less"
        );
    }
    if omitted.duplicates > 0 {
        println!(
            "  {} runs are listed more than once (repeated datasets, transfer functions, modes, models, frames or axis values): each runs once",
            omitted.duplicates
        );
    }
    for s in &omitted.skipped {
        println!("  left out: {} {}: {}", s.dataset, s.mode, s.reason);
    }
    if tally.raised > 0 {
        println!(
            "  {} runs with occupancy.sram_bits raised (map larger than the default SRAM)",
            tally.raised
        );
    }
    // An axis that changes nothing reads as a design insensitive to it: say which runs do
    // not read it, and why (the notes `sim` and `render` print for a --set).
    for (path, (runs, reasons)) in &tally.idle_axes {
        for (why, idle) in reasons {
            println!(
                "  note: {path} is without effect in {} ({why}): their figures do not change \
                 along it",
                if idle == runs {
                    format!("every one of its {runs} runs")
                } else {
                    format!("{idle} of its {runs} runs")
                }
            );
        }
    }
    let (Some(expansion), Some(lock)) = (expansion, lock) else {
        return Ok(());
    };
    let progress = !quiet && std::io::stderr().is_terminal();
    let model = model
        .map(vizsim::run::Model::parse)
        .transpose()
        .map_err(anyhow::Error::msg)?;
    let summary = experiment::sweep_locked(&expansion, out, lock, shard, model, progress)?;
    println!(
        "ran {} runs in {:.1} s ({} were already done) -> {}",
        summary.ran,
        summary.wall_seconds,
        summary.already_done,
        out.join(experiment::store::RESULTS).display()
    );
    if summary.timings_reused > 0 {
        println!(
            "  {} cycle runs took the timing of a run that times alike (another transfer \
             function or dataset of the same size where nothing reads it, or a leaping \
             structure that never leaps: docs/experiments.md)",
            summary.timings_reused
        );
    }
    Ok(())
}

/// What the sweep's first line reports: the runs of this shard and model, those still to run
/// per model (step, cycle) with their estimated seconds on one core, how many had their
/// SRAM raised, and the axes some runs do not read.
#[derive(Default)]
struct Tally {
    mine: usize,
    /// Runs of the model `--model` names (every run without it), in any shard.
    of_model: usize,
    pending: [usize; 2],
    seconds: [f64; 2],
    raised: usize,
    /// Per axis: its runs, and those of them that do not read it, by reason.
    idle_axes:
        std::collections::BTreeMap<String, (usize, std::collections::BTreeMap<String, usize>)>,
}

/// A duration as a person reads it: seconds under a minute, minutes under two hours, else hours.
fn duration_text(seconds: f64) -> String {
    if seconds < 1.0 {
        "under 1 s".into()
    } else if seconds < 60.0 {
        format!("{seconds:.0} s")
    } else if seconds < 7200.0 {
        format!("{:.1} min", seconds / 60.0)
    } else {
        format!("{:.1} h", seconds / 3600.0)
    }
}

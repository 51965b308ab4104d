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
    #[arg(long)]
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
    let mut expansion = spec::load(experiment, dir.as_deref())?;
    if let Some(model) = model {
        anyhow::ensure!(
            model == "step" || model == "cycle",
            "--model {model}: expected `step` or `cycle`"
        );
        expansion.runs.retain(|r| r.run.model.name() == model);
    }
    let mine: Vec<&spec::RunSpec> = expansion
        .runs
        .iter()
        .filter(|r| shard.is_none_or(|s| s.contains(r)))
        .collect();
    experiment::store::ResultStore::check_same_experiment(out, &expansion.experiment.name)?;
    let done = experiment::store::read_lines(&out.join(experiment::store::RESULTS))?
        .into_iter()
        .filter_map(|(v, _)| v.get("key").and_then(|k| k.as_str()).map(str::to_string))
        .collect::<std::collections::HashSet<_>>();
    let pending: Vec<&spec::RunSpec> = mine
        .iter()
        .copied()
        .filter(|r| !done.contains(&r.key))
        .collect();
    let count = |model| pending.iter().filter(|r| r.run.model == model).count();
    let threads = rayon::current_num_threads();
    let estimate = |model| {
        let of: Vec<&spec::RunSpec> = pending
            .iter()
            .copied()
            .filter(|r| r.run.model == model)
            .collect();
        experiment::estimate_seconds(&expansion, &of, threads)
    };
    println!(
        "{}: {} runs{} ({} step model, {} cycle model to run; {} already done in {}); \
         estimate {} + {} on {threads} threads (step + cycle model; rough)",
        expansion.experiment.name,
        mine.len(),
        shard
            .map(|s| format!(" in shard {}/{}", s.index, s.count))
            .unwrap_or_default(),
        count(spec::Model::Step),
        count(spec::Model::Cycle),
        mine.len() - pending.len(),
        out.display(),
        duration_text(estimate(spec::Model::Step)),
        duration_text(estimate(spec::Model::Cycle)),
    );
    if expansion.duplicates > 0 {
        println!(
            "  {} runs are listed more than once (repeated datasets, frames or axis values): each runs once",
            expansion.duplicates
        );
    }
    for s in &expansion.skipped {
        println!("  left out: {} {}: {}", s.dataset, s.mode, s.reason);
    }
    let raised = mine.iter().filter(|r| !r.fits_default_sram).count();
    if raised > 0 {
        println!(
            "  {raised} runs with occupancy.sram_bits raised (map larger than the default SRAM)"
        );
    }
    if dry_run {
        return Ok(());
    }
    let progress = !quiet && std::io::stderr().is_terminal();
    let summary = experiment::sweep(&expansion, out, shard, progress)?;
    println!(
        "ran {} runs in {:.1} s ({} were already done) -> {}",
        summary.ran,
        summary.wall_seconds,
        summary.already_done,
        out.join(experiment::store::RESULTS).display()
    );
    Ok(())
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

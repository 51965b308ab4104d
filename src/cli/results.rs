//! `vizsim merge`, `table` and `plot`: what a sweep's results folder turns into.

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::Args;
use vizsim::tables::Metric;

#[derive(Args)]
pub struct MergeArgs {
    /// Sweep folders (shards) of one experiment.
    #[arg(required = true)]
    inputs: Vec<PathBuf>,
    /// Output folder. Results it already holds are merged in, never dropped (merge into a new
    /// folder to replace them); a folder a sweep is writing into is refused.
    #[arg(long)]
    out: PathBuf,
}

pub fn merge(args: MergeArgs) -> Result<()> {
    let inputs: Vec<&Path> = args.inputs.iter().map(PathBuf::as_path).collect();
    let merged = vizsim::experiment::merge(&inputs, &args.out)?;
    for path in &merged.torn {
        vizsim::note!("{}", vizsim::experiment::store::torn_note(path));
    }
    println!(
        "{} runs -> {}",
        merged.runs,
        args.out.join("results.jsonl").display()
    );
    Ok(())
}

#[derive(Args)]
pub struct TableArgs {
    #[command(flatten)]
    results: ResultsArgs,
    /// Metrics (one table each per model; default fps, cycles, steps, page-hits).
    #[arg(long, value_enum, value_delimiter = ',')]
    metric: Vec<vizsim::tables::Metric>,
    /// Row fields, comma-separated: dataset, tf, mode, frame or a swept field path (not model:
    /// each model has its own tables).
    #[arg(long, default_value = "dataset,tf", value_delimiter = ',')]
    rows: Vec<String>,
    /// Column field.
    #[arg(long, default_value = "mode")]
    columns: String,
    /// Output folder (default DIR/tables).
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(Args)]
pub struct PlotArgs {
    #[command(flatten)]
    results: ResultsArgs,
    /// Output folder (default DIR/plots).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Only these kinds of chart, comma-separated (default: every kind the results support).
    #[arg(long, value_enum, value_delimiter = ',')]
    only: Vec<vizsim::figures::ChartKind>,
}

pub fn plot(args: PlotArgs) -> Result<()> {
    let out = args.out.unwrap_or_else(|| args.results.dir.join("plots"));
    vizsim::experiment::store::must_be_a_folder(&out)?;
    let lines = args.results.read()?;
    anyhow::ensure!(
        !lines.is_empty(),
        "{}: no results",
        args.results.dir.display()
    );
    let kinds = if args.only.is_empty() {
        &vizsim::figures::ChartKind::ALL[..]
    } else {
        &args.only[..]
    };
    // Every chart or none: a failure halfway leaves no partial set that looks complete.
    let written = vizsim::output::removing_new_folder_on_error(&out, || {
        vizsim::output::all_or_none(|| vizsim::figures::write_all(&lines, &out, kinds))
    })?;
    if written == 0 {
        // Said, not "0 charts -> DIR" for a folder that was never made.
        let which = if args.only.is_empty() {
            ""
        } else {
            " of the kinds --only names"
        };
        vizsim::note!(
            "no chart{which} to draw: a per-frame chart needs two frames or more, the frame \
             rate by mode two modes, the sub-cube and skippable charts leaping modes, a \
             vs-field chart a field swept over two values or more; nothing written"
        );
    } else {
        println!(
            "{} -> {}",
            vizsim::text::count(written, "chart", "charts"),
            out.display()
        );
    }
    Ok(())
}

/// The sweep results a `table` or `plot` reads: a sweep folder's results, keeping frames that
/// are multiples of `frame_step` (and one model's when given).
#[derive(Args)]
pub struct ResultsArgs {
    /// Sweep folder (holding results.jsonl).
    pub dir: PathBuf,
    /// Use only frames that are multiples of this (e.g. 2: every other frame).
    #[arg(
        long,
        default_value_t = 1,
        allow_negative_numbers = true,
        value_parser = super::unsigned::<u64>
    )]
    pub frame_step: u64,
    /// Only this model's results (`step` or `cycle`).
    #[arg(long)]
    pub model: Option<String>,
    /// Only these datasets' results (comma-separated names as in the experiment file, or an
    /// alias naming the same dataset: `vessel` for `aneurism`).
    #[arg(long, value_delimiter = ',')]
    pub dataset: Vec<String>,
}

impl ResultsArgs {
    pub fn read(&self) -> Result<Vec<serde_json::Value>> {
        anyhow::ensure!(self.frame_step >= 1, "--frame-step must be at least 1");
        if let Some(m) = &self.model {
            anyhow::ensure!(
                m == "step" || m == "cycle",
                "--model {m}: expected `step` or `cycle`"
            );
        }
        // A misspelt folder is named as such, not as a file the system cannot find in it.
        anyhow::ensure!(
            self.dir.is_dir(),
            "{}: no such sweep folder",
            self.dir.display()
        );
        let path = self.dir.join("results.jsonl");
        anyhow::ensure!(
            path.exists(),
            "{}: no results.jsonl here: not a sweep folder",
            self.dir.display()
        );
        let (mut lines, torn) = vizsim::tables::read_results(&path)?;
        if torn {
            vizsim::note!("{}", vizsim::experiment::store::torn_note(&path));
        }
        // A requested dataset the results do not hold (a typo) is named, not ignored; an alias
        // (`vessel`) picks the results of the dataset it names, as on `sim`.
        let of = |l: &serde_json::Value, d: &str| {
            l.get("dataset")
                .and_then(|v| v.as_str())
                .is_some_and(|held| vizsim::volume::dataset::same_dataset(held, d))
        };
        if let Some(absent) = self
            .dataset
            .iter()
            .find(|d| !lines.iter().any(|l| of(l, d)))
        {
            let held: std::collections::BTreeSet<&str> = lines
                .iter()
                .filter_map(|l| l.get("dataset").and_then(|v| v.as_str()))
                .collect();
            anyhow::bail!(
                "{}: no results of --dataset {absent}; the results hold {}",
                self.dir.display(),
                held.into_iter().collect::<Vec<_>>().join(", ")
            );
        }
        lines.retain(|l| {
            let frame_kept = l
                .get("frame")
                .and_then(|f| f.as_u64())
                .is_none_or(|f| f % self.frame_step == 0);
            let model_kept = self
                .model
                .as_deref()
                .is_none_or(|m| l.get("model").and_then(|v| v.as_str()) == Some(m));
            let dataset_kept = self.dataset.is_empty() || self.dataset.iter().any(|d| of(l, d));
            frame_kept && model_kept && dataset_kept
        });
        anyhow::ensure!(
            !lines.is_empty() || self.dataset.is_empty(),
            "{}: no results of --dataset {}",
            self.dir.display(),
            self.dataset.join(",")
        );
        // Results filtered away by --model are named so (the folder has results, of the other
        // model).
        if let Some(m) = self.model.as_deref().filter(|_| lines.is_empty()) {
            anyhow::bail!(
                "{}: no {m}-model results{}",
                self.dir.display(),
                if self.frame_step > 1 {
                    " of the frames --frame-step keeps"
                } else {
                    ""
                }
            );
        }
        // Key order, not completion order: tables and charts sum in this order.
        lines.sort_by(|a, b| a["key"].as_str().cmp(&b["key"].as_str()));
        Ok(lines)
    }
}

pub fn table(args: TableArgs) -> Result<()> {
    write_tables(
        &args.results,
        &args.metric,
        &args.rows,
        &args.columns,
        args.out.as_deref(),
    )
}

/// The metrics of `metrics` that no table was made for.
fn missing(metrics: &[vizsim::tables::Metric], tabulated: &[bool]) -> Vec<&'static str> {
    metrics
        .iter()
        .zip(tabulated)
        .filter(|(_, t)| !**t)
        .map(|(m, _)| m.file_name())
        .collect()
}

/// What to add when metrics no result carries include the float reference's: where they come
/// from.
fn missing_hint(missing: &[&str]) -> &'static str {
    let image = [Metric::ImageError, Metric::Psnr, Metric::PixelsOff].map(Metric::file_name);
    if missing.iter().any(|m| image.contains(m)) {
        " (image-error, psnr and pixels-off come from experiments with float_reference = true, \
         docs/experiments.md)"
    } else if missing.contains(&Metric::TotalCycles.file_name()) {
        " (total-cycles comes from experiments with [sequence], docs/experiments.md)"
    } else {
        ""
    }
}

/// Writes the tables of `results` (one per model and metric) and prints the fps tables.
pub fn write_tables(
    results: &ResultsArgs,
    metrics: &[vizsim::tables::Metric],
    rows: &[String],
    columns: &str,
    out: Option<&Path>,
) -> Result<()> {
    use vizsim::tables::{self, Metric};
    let dir = &results.dir;
    // Each model gets its own tables (their cells are different clocks), so in one of them a
    // model row or column would hold one value: refused rather than dropped or shown empty.
    if let Some(option) = [
        ("--rows", rows.iter().any(|r| r == "model")),
        ("--columns", columns == "model"),
    ]
    .iter()
    .find_map(|&(option, asked)| asked.then_some(option))
    {
        anyhow::bail!(
            "{option}: `model` cannot be a row or the column: vizsim table writes one table per \
             model (step-METRIC and cycle-METRIC); --model step|cycle keeps one model's tables"
        );
    }
    let lines = results.read()?;
    anyhow::ensure!(!lines.is_empty(), "{}: no results", dir.display());
    let out = out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| dir.join("tables"));
    vizsim::experiment::store::must_be_a_folder(&out)?;
    let asked = !metrics.is_empty();
    let metrics = if asked {
        metrics.to_vec()
    } else {
        vec![Metric::Fps, Metric::Cycles, Metric::Steps, Metric::PageHits]
    };
    // Which asked metrics no result carries: said, rather than left out without a word.
    let mut tabulated = vec![false; metrics.len()];
    let made_by = super::invocation();
    let of_model = results
        .model
        .as_deref()
        .map_or(String::new(), |m| format!(" of the {m} model"));
    // Every table or none: a failure halfway (a folder where a file goes, a full disk) leaves
    // no tables that look like the whole set. They are printed once all are in place.
    let all_markdown = vizsim::output::removing_new_folder_on_error(&out, || {
        vizsim::output::all_or_none(|| -> Result<String> {
            let mut all_markdown = String::new();
            for model in ["step", "cycle"] {
                let of_model: Vec<&serde_json::Value> = lines
                    .iter()
                    .filter(|l| l.get("model").and_then(|m| m.as_str()) == Some(model))
                    .collect();
                if of_model.is_empty() {
                    continue;
                }
                for (m, &metric) in metrics.iter().enumerate() {
                    if !of_model.iter().any(|l| metric.value(l).is_some()) {
                        continue;
                    }
                    tabulated[m] = true;
                    let clock = tables::measured_by(metric, model, &of_model);
                    let subject = format!("{} ({clock})", metric.label());
                    let mut table = tables::build(&of_model, metric, rows, columns, &subject)?;
                    table.made_by = Some(made_by.clone());
                    let stem = out.join(format!("{model}-{}", metric.file_name()));
                    let md = table.markdown();
                    vizsim::output::write_atomically(&stem.with_extension("md"), |w| {
                        std::io::Write::write_all(w, md.as_bytes())
                    })?;
                    let csv = table.csv();
                    vizsim::output::write_atomically(&stem.with_extension("csv"), |w| {
                        std::io::Write::write_all(w, csv.as_bytes())
                    })?;
                    all_markdown += &md;
                    all_markdown += "\n";
                }
            }
            anyhow::ensure!(
                tabulated.iter().any(|&t| t),
                "{}: no result{of_model} carries --metric {}{}",
                dir.display(),
                missing(&metrics, &tabulated).join(","),
                missing_hint(&missing(&metrics, &tabulated))
            );
            let summary = match &results.model {
                Some(m) => format!("tables-{m}.md"),
                None => "tables.md".to_string(),
            };
            vizsim::output::write_atomically(&out.join(summary), |w| {
                std::io::Write::write_all(w, all_markdown.as_bytes())
            })?;
            Ok(all_markdown)
        })
    })?;
    print!("{all_markdown}");
    let missing = missing(&metrics, &tabulated);
    if asked && !missing.is_empty() {
        vizsim::note!(
            "note: no result{of_model} carries --metric {}: no table for it{}",
            missing.join(","),
            missing_hint(&missing)
        );
    }
    println!("tables -> {}", out.display());
    Ok(())
}

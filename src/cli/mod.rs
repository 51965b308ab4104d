//! The `vizsim` command line: one file per command. Commands only parse their arguments into
//! the library's descriptions (a run is a `vizsim::run::RunDescription`) and print; library
//! errors carry what and where, and here get the option they came from.

mod advise;
mod compare;
mod demo;
mod info;
mod occupancy;
mod precision;
mod render;
mod results;
mod sequence;
mod sim;
mod sweep;
mod update;
mod verify_skip;

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use vizsim::camera::{parse_image_size, Projection};
use vizsim::config::HardwareConfig;
use vizsim::run::{Model, RunDescription};
use vizsim::text::{count, percent};
use vizsim::volume::{dataset, Volume};

#[derive(Parser)]
#[command(
    name = "vizsim",
    version,
    about = "Cycle-accurate simulator of hardware volume ray casting architectures"
)]
pub struct Cli {
    /// Worker threads (default: all cores). The results do not depend on the count.
    #[arg(long, global = true, allow_negative_numbers = true, value_parser = parse_threads)]
    threads: Option<usize>,
    /// Memory budget, e.g. 8G or 512M: requests known to need more (a volume from its header,
    /// a frame from its size, an experiment from its run count) are refused up front. Default:
    /// env VIZSIM_MEMORY_BUDGET, else the machine's memory.
    #[arg(
        long,
        global = true,
        allow_hyphen_values = true,
        value_parser = vizsim::budget::parse
    )]
    memory_budget: Option<u64>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render one frame: float reference ray caster, or the fixed-point model (--model fixed).
    Render(render::RenderArgs),
    /// Simulate one frame clock by clock on the cycle-accurate pipeline.
    Sim(sim::SimArgs),
    /// Print a dataset's dimensions, spacing, value histogram and occupied percentage.
    Info(info::InfoArgs),
    /// Occupancy maps per sub-cube size: storage bits, SRAM fit, skippable sub-cubes ('0', class).
    #[command(
        mut_arg("subcube", not_listed),
        mut_arg("hierarchy", not_listed),
        mut_arg("occupancy", not_listed),
        mut_arg("bricks", not_listed)
    )]
    Occupancy(occupancy::OccupancyArgs),
    /// Compare two images: max error per channel, PSNR, pixels differing by more than 1 LSB.
    Compare(compare::CompareArgs),
    /// Exhaustively verify the skip calculator: every (position within a sub-cube, increment)
    /// pair at these widths; reports overshoots (must be 0) and the worst wasted steps.
    VerifySkip(verify_skip::VerifySkipArgs),
    /// Sweep fixed-point widths one at a time against the float reference (image error) and the
    /// skip widths against the step count; writes tables and plots.
    #[command(
        mut_arg("subcube", not_listed),
        mut_arg("hierarchy", not_listed),
        mut_arg("occupancy", not_listed),
        mut_arg("bricks", not_listed)
    )]
    Precision(precision::PrecisionArgs),
    /// Run an experiment file (configs/experiments/): every run in parallel, results appended
    /// to OUT/results.jsonl as they finish; re-running resumes. Any --threads writes the same
    /// lines, in the order the runs finished (merge sorts them by key).
    Sweep(sweep::SweepArgs),
    /// Merge sweep folders (shards) into one, results sorted by key.
    Merge(results::MergeArgs),
    /// Tables of a sweep's results (Markdown and CSV): rows dataset x classification, columns
    /// the acceleration modes, cells averaged over the frames.
    Table(results::TableArgs),
    /// Charts of a sweep's results (PNG + SVG): cycles or steps per frame against the frame,
    /// frame rate by mode (the fastest marked), skippable sub-cubes and frame rate against the
    /// sub-cube size, swept fields.
    Plot(results::PlotArgs),
    /// Predict the frame rate of every leaping configuration (map sizes, hierarchy, distance
    /// volume, leap values) from the functional model and a cost model, and recommend the
    /// fastest that fits the SRAM; --validate compares the advice with a sweep's results.
    Advise(advise::AdviseArgs),
    /// Render orbits and a gallery of the phantoms and the datasets present into reports/demo/.
    Demo(demo::DemoArgs),
    /// Volume updates: a download over the host link with the maps built on the way, a scan
    /// pass, a transfer-function change and a partial update, in cycles (docs/dynamic.md).
    #[command(
        mut_arg("subcube", |arg| arg
            .help("Edge of the occupancy maps' sub-cubes (2, 4, 8, 16, 32 or 64), required (here, or occupancy.subcube by --set or --config): the maps whose costs are measured")),
        mut_arg("hierarchy", not_listed),
        mut_arg("occupancy", not_listed),
        mut_arg("bricks", not_listed)
    )]
    Update(update::UpdateArgs),
    /// The frame loop of a dynamic sequence (metaballs, TSDF fusion, a folder of time steps):
    /// per step update, map and render cycles, and the frames per second (docs/dynamic.md).
    #[command(
        mut_arg("subcube", |arg| arg.help(
            "Edge of the occupancy map's sub-cubes (2, 4, 8, 16, 32 or 64), required (here, or occupancy.subcube by --set or --config) unless --map none"
        )),
        mut_arg("bricks", |arg| arg.help(
            "Bounding bricks of this edge (at least the sub-cube's; the same as --set bricks.size=N): each ray starts at its first active brick and ends after its last; their flags are rebuilt each step from the map's min/max table"
        ))
    )]
    Sequence(sequence::SequenceArgs),
}

/// Hides a leaping flag of the shared `HardwareArgs` from a command's help where it does not
/// apply: the command refuses it (with why) when given, so listing it would only mislead.
fn not_listed(arg: clap::Arg) -> clap::Arg {
    arg.hide(true)
}

/// Most worker threads `--threads` takes: a huge count made the thread pool try to start
/// billions of threads (it hung).
const MAX_THREADS: usize = 1024;

/// The value of an unsigned numeric option. Such options also take `allow_negative_numbers`,
/// so that `--brick -1` reaches here, and is refused as negative, rather than taken for a flag
/// (clap's "unexpected argument '-1' found"); a value in its type is checked against the
/// option's range where the option is used. Floating-point options take
/// `allow_negative_numbers` alone: their range check sees the negative value.
pub fn unsigned<T>(text: &str) -> std::result::Result<T, String>
where
    T: std::str::FromStr,
    T::Err: std::fmt::Display,
{
    text.parse::<T>().map_err(|e| {
        let negative = text
            .strip_prefix('-')
            .is_some_and(|digits| digits.parse::<u128>().is_ok());
        if negative {
            "must not be negative".to_string()
        } else {
            e.to_string()
        }
    })
}

fn parse_threads(text: &str) -> std::result::Result<usize, String> {
    match text.trim().parse::<usize>() {
        Ok(n) if (1..=MAX_THREADS).contains(&n) => Ok(n),
        _ => Err(format!("`{text}`: expected 1..={MAX_THREADS} threads")),
    }
}

pub fn run(cli: Cli) -> Result<()> {
    if let Some(bytes) = cli.memory_budget {
        vizsim::budget::set(bytes);
    }
    if let Some(n) = cli.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .context("setting the thread count")?;
    }
    match cli.command {
        Command::Render(args) => render::run(args),
        Command::Sim(args) => sim::run(args),
        Command::Info(args) => info::run(args),
        Command::Occupancy(args) => occupancy::run(args),
        Command::Compare(args) => compare::run(args),
        Command::VerifySkip(args) => verify_skip::run(args),
        Command::Precision(args) => precision::run(args),
        Command::Sweep(args) => sweep::run(args),
        Command::Merge(args) => results::merge(args),
        Command::Table(args) => results::table(args),
        Command::Plot(args) => results::plot(args),
        Command::Advise(args) => advise::run(args),
        Command::Demo(args) => demo::run(args),
        Command::Update(args) => update::run(args),
        Command::Sequence(args) => sequence::run(args),
    }
}

#[derive(Args, Clone)]
pub struct DataArgs {
    /// Folder holding the real datasets (env VIZSIM_DATA; default ../shared/data, relative to
    /// the folder vizsim runs in, when present).
    #[arg(long)]
    pub data_dir: Option<PathBuf>,
}

impl DataArgs {
    /// The data folder: `--data-dir` (which must exist), else `VIZSIM_DATA`, else
    /// `../shared/data` when present.
    pub fn dir(&self) -> Result<Option<PathBuf>> {
        if let Some(dir) = &self.data_dir {
            anyhow::ensure!(
                dir.is_dir(),
                "--data-dir {}: {}",
                dir.display(),
                if dir.exists() {
                    "not a folder"
                } else {
                    "no such folder"
                }
            );
        }
        Ok(dataset::data_dir(self.data_dir.as_deref()))
    }

    pub fn load(&self, spec: &str) -> Result<Volume> {
        note_stand_in(spec);
        Ok(dataset::load(spec, self.dir()?.as_deref())?)
    }
}

/// Says so when a published dataset name resolves to its stand-in.
pub fn note_stand_in(spec: &str) {
    if let Some(stand_in) = dataset::stand_in_for(spec) {
        // On standard error: standard output may be JSON (`--json`).
        vizsim::note!(
            "{spec}: the published dataset is not available; its stand-in {stand_in} is used"
        );
    }
}

/// The dataset of `info`, `occupancy` and `update`: positional (`vizsim info fuel`), or as
/// `--dataset` as `render`, `sim` and `advise` take it.
#[derive(Args)]
pub struct DatasetName {
    /// Dataset: a name in the data folder (fuel, neghip, aneurism, skull and foot for their
    /// stand-ins...; a wrong name lists them), phantom:KIND[:SIZE] (sphere, shells, jet,
    /// metaballs, cast, tsdf, tube), or a raw, NRRD or descriptor file; or give it as --dataset.
    #[arg(
        value_name = "DATASET",
        required_unless_present = "dataset",
        conflicts_with = "dataset"
    )]
    positional: Option<String>,
    /// The dataset, as render and sim take it (instead of the positional DATASET).
    #[arg(long = "dataset", id = "dataset", value_name = "DATASET")]
    option: Option<String>,
}

impl DatasetName {
    pub fn spec(&self) -> &str {
        self.positional
            .as_deref()
            .or(self.option.as_deref())
            .unwrap_or_default()
    }
}

/// What defines a frame: dataset, transfer function, view and sampling.
#[derive(Args)]
pub struct FrameArgs {
    /// Dataset: a name in the data folder (fuel, neghip, aneurism...), phantom:KIND[:SIZE], or a file.
    #[arg(long)]
    pub dataset: String,
    #[command(flatten)]
    pub data: DataArgs,
    /// Transfer function: `zero`, `class` (the dataset's own), a preset name, or a TOML file.
    #[arg(long, default_value = "class")]
    pub tf: String,
    /// `front`, `orbit:K/N` (frame K of an N-frame orbit about the vertical axis) or
    /// `path:FILE:K/N` (frame K of N along a camera path file, e.g. configs/paths/tube.toml).
    #[arg(long, default_value = "front")]
    pub view: String,
    /// Projection; also for a camera path, whose `fov_y_deg` only perspective uses
    /// (orthographic uses its `view_width`).
    #[arg(long, value_enum, default_value = "ortho")]
    pub projection: ProjectionArg,
    /// Image size WxH.
    #[arg(long, default_value = "256x256", allow_hyphen_values = true)]
    pub size: String,
    /// Sample spacing along the ray, in voxels.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub spacing: f32,
    /// Disable early ray termination (the same as --set compositing.ert=false).
    #[arg(long)]
    pub no_ert: bool,
    /// Phong shading from per-voxel gradients.
    #[arg(long)]
    pub shading: bool,
}

impl FrameArgs {
    /// Files the frame may read (the dataset, the transfer function, the camera path, the
    /// hardware configuration), for `output::check_distinct`: names that are no file are left
    /// to it.
    /// `run` is the run they describe (its geometry's depth file).
    pub fn inputs(&self, hardware: &HardwareArgs, run: &RunDescription) -> Vec<PathBuf> {
        let camera_path = self
            .view
            .strip_prefix("path:")
            .and_then(|rest| rest.rsplit_once(':'))
            .map(|(file, _)| PathBuf::from(file));
        // A dataset given by name is a file in the data folder.
        let dataset_file = self
            .data
            .dir()
            .ok()
            .flatten()
            .and_then(|dir| dataset::file_of(&self.dataset, &dir));
        // With the data file a descriptor or detached NRRD header names (a probe overwrote
        // it with --json while the header was protected).
        let dataset_files = std::iter::once(PathBuf::from(&self.dataset))
            .chain(dataset_file)
            .flat_map(|file| dataset::files_read(&file));
        dataset_files
            .chain(Some(PathBuf::from(&self.tf)))
            .chain(camera_path)
            .chain(hardware.config.clone())
            .chain(Some(PathBuf::from(&run.hardware.geometry.file)))
            .collect()
    }

    /// The run these arguments and `hardware` describe, for `model`.
    pub fn describe(&self, model: Model, hardware: &HardwareArgs) -> Result<RunDescription> {
        let mut extra = Vec::new();
        if self.no_ert {
            extra.push(("compositing.ert=false".to_string(), "--no-ert".to_string()));
        }
        let config = hardware.load(&extra)?;
        let run = RunDescription {
            view: self.view.clone(),
            projection: self.projection.into(),
            size: parse_image_size(&self.size).context("--size")?,
            sample_spacing: self.spacing,
            shading: self.shading,
            ..RunDescription::new(&self.dataset, &self.tf, model, config)
        };
        run.validate()?;
        note_stand_in(&self.dataset);
        Ok(run)
    }
}

#[derive(Args, Clone)]
pub struct HardwareArgs {
    /// Hardware configuration TOML (default: the embedded, calibrated configs/hardware/vizard2.toml).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Override a configuration field, validated like the file: --set skip.reciprocal_bits=6.
    /// Every field (iso.*, clip.*, geometry.*, ray.interleave, blocking.*...) is listed with
    /// its range in docs/config.md.
    #[arg(long = "set", value_name = "FIELD=VALUE")]
    pub overrides: Vec<String>,
    /// Space leaping with sub-cubes of this edge (2, 4, 8, 16, 32 or 64); without it, no leaping.
    #[arg(long, allow_negative_numbers = true, value_parser = unsigned::<usize>)]
    pub subcube: Option<usize>,
    /// Two-level occupancy hierarchy (2x2x2 sub-cubes per byte).
    #[arg(long)]
    pub hierarchy: bool,
    /// Which occupancy map: '0' (`zero`) or `class`.
    #[arg(long, value_enum)]
    pub occupancy: Option<OccupancyArg>,
    /// Bounding bricks of this edge (4, 8, 16 or 32): each ray starts at its first active brick and ends
    /// after its last (the same as --set bricks.size=N; all three models).
    #[arg(long, allow_negative_numbers = true, value_parser = unsigned::<usize>)]
    pub bricks: Option<usize>,
}

impl HardwareArgs {
    /// The configuration file with --set, then the leaping flags and `extra` applied as
    /// overrides too, so every value goes through the same validation.
    /// `extra` are flags of the frame as (override, the flag as typed): `--no-ert`.
    pub fn load(&self, extra: &[(String, String)]) -> Result<HardwareConfig> {
        let mut flags: Vec<(String, String)> = Vec::new();
        if let Some(s) = self.subcube {
            flags.push((format!("occupancy.subcube={s}"), format!("--subcube {s}")));
        }
        if self.hierarchy {
            flags.push(("occupancy.hierarchy=true".into(), "--hierarchy".into()));
        }
        if let Some(kind) = self.occupancy {
            flags.push((
                format!("occupancy.kind={}", kind.toml_name()),
                format!("--occupancy {}", kind.cli_name()),
            ));
        }
        if let Some(b) = self.bricks {
            flags.push((format!("bricks.size={b}"), format!("--bricks {b}")));
        }
        flags.extend(extra.iter().cloned());
        // A flag and a --set of the same field: which one wins would be a silent choice.
        for (assignment, flag) in &flags {
            let field = vizsim::config::override_path(assignment);
            if let Some(set) = self
                .overrides
                .iter()
                .find(|o| vizsim::config::override_path(o) == field)
            {
                anyhow::bail!("{flag} and --set {set} both set `{field}`; give one of them");
            }
        }
        let mut overrides = self.overrides.clone();
        let mut shown: Vec<String> = overrides.iter().map(|o| format!("--set {o}")).collect();
        for (assignment, flag) in flags {
            overrides.push(assignment);
            shown.push(flag);
        }
        let config = HardwareConfig::load_shown(self.config.as_deref(), &overrides, &shown);
        let config = match &self.config {
            Some(path) => config.with_context(|| format!("--config {}", path.display()))?,
            None => config?,
        };
        let occupancy = &config.occupancy;
        anyhow::ensure!(
            !self.hierarchy
                || occupancy.subcube > 0
                || occupancy.structure != vizsim::config::LeapStructure::Map,
            "--hierarchy: there is no occupancy map to build it on (give --subcube N, or \
             occupancy.subcube in the configuration)"
        );
        // The kind chooses the map's test, another structure's, or the bricks' (`bricks.size`).
        anyhow::ensure!(
            self.occupancy.is_none()
                || occupancy.subcube > 0
                || occupancy.structure != vizsim::config::LeapStructure::Map
                || config.bricks.size > 0,
            "--occupancy: there is no occupancy map, other leaping structure or bricks for it \
             to choose the test of (give --subcube N or --bricks N); without one it does nothing"
        );
        Ok(config)
    }

    /// Whether any leaping flag was given.
    pub fn asks_for_leaping(&self) -> bool {
        self.subcube.is_some() || self.hierarchy || self.occupancy.is_some()
    }

    /// One line saying what the configuration resolved to: the preset and every field that
    /// differs from the calibrated default; under it the fields set but without effect in this
    /// run. `not_leaping`: why the run does not leap whatever its configuration asks (the
    /// float model, `--map none`), which leaves the leaping structure's fields without effect.
    pub fn resolved_line(
        &self,
        config: &HardwareConfig,
        used: vizsim::config::ConfigUse,
    ) -> String {
        let source = match &self.config {
            Some(p) => p.display().to_string(),
            None => format!("{} (embedded, calibrated)", vizsim::config::DEFAULT_NAME),
        };
        let changed = config.differences_from_default();
        let line = if changed.is_empty() {
            format!("hardware: {source}, no field changed")
        } else {
            format!(
                "hardware: {source}; differs from the default in {}",
                changed.join(", ")
            )
        };
        let mut idle = config.settings_without_effect(used);
        // A --set the configuration does not even write out while its feature is off
        // (`bricks.setup` with no bricks, `geometry.radius` with no shape) is named too.
        for assignment in &self.overrides {
            let path = vizsim::config::override_path(assignment);
            if idle.iter().any(|i| i.starts_with(&format!("{path} ="))) {
                continue;
            }
            if let Some(why) = config.why_without_effect(path, used) {
                idle.push(format!("--set {} ({why})", assignment.trim()));
            }
        }
        if idle.is_empty() {
            line
        } else {
            format!("{line}\nnote: without effect here: {}", idle.join(", "))
        }
    }
}

#[derive(clap::ValueEnum, Clone, Copy)]
pub enum OccupancyArg {
    // The '0' map (any non-zero voxel): `0` is accepted too. (A `///` comment here would make
    // clap list the values with their help, and lay out every option's help differently.)
    #[value(alias = "0")]
    Zero,
    Class,
}

impl OccupancyArg {
    fn toml_name(self) -> &'static str {
        match self {
            OccupancyArg::Zero => "\"zero\"",
            OccupancyArg::Class => "\"class\"",
        }
    }

    fn cli_name(self) -> &'static str {
        match self {
            OccupancyArg::Zero => "zero",
            OccupancyArg::Class => "class",
        }
    }
}

#[derive(clap::ValueEnum, Clone, Copy)]
pub enum ProjectionArg {
    Ortho,
    Persp,
}

impl From<ProjectionArg> for Projection {
    fn from(p: ProjectionArg) -> Self {
        match p {
            ProjectionArg::Ortho => Projection::Ortho,
            ProjectionArg::Persp => Projection::Persp,
        }
    }
}

/// Leaping as a user reads it: `none`, or `8³ class map`, `8³ '0' map + hierarchy`.
pub fn leaping_text(leaping: &vizsim::functional::renderer::Leaping) -> String {
    use vizsim::functional::renderer::Leaping;
    use vizsim::occupancy::OccupancyKind;
    match leaping {
        Leaping::None => "no leaping".into(),
        Leaping::Occupancy {
            subcube,
            hierarchy,
            kind,
        } => format!(
            "leaping {subcube}³ {} map{}",
            match kind {
                OccupancyKind::Zero => "'0'",
                OccupancyKind::Class => "class",
            },
            if *hierarchy { " + hierarchy" } else { "" }
        ),
        Leaping::Distance { bits, kind } => format!(
            "leaping with a {bits}-bit {} distance volume",
            match kind {
                OccupancyKind::Zero => "'0'",
                OccupancyKind::Class => "class",
            }
        ),
        Leaping::LeapValues { regions, kind } => format!(
            "leap values in the volume ({} regions, {} test)",
            match regions {
                vizsim::config::LeapRegions::Empty => "empty",
                vizsim::config::LeapRegions::Homogeneous => "homogeneous",
            },
            match kind {
                OccupancyKind::Zero => "'0'",
                OccupancyKind::Class => "class",
            }
        ),
    }
}

/// Prints a command's text: to standard output, or to standard error when standard output
/// carries the command's JSON (`--json -`), so that the JSON can be piped.
pub fn say(json: Option<&std::path::Path>, text: &str) {
    use std::io::Write;
    if json.is_some_and(vizsim::output::is_standard_output) {
        let _ = write!(std::io::stderr(), "{text}");
    } else {
        print!("{text}");
    }
}

/// Refuses `-` for file outputs other than the JSON (`--vcd -`, `--rays -`): only `--json -`
/// goes to standard output, and `-` must not become a file of that name.
pub fn refuse_standard_output(outputs: &[(&str, Option<&std::path::Path>)]) -> Result<()> {
    for (option, path) in outputs {
        if path.is_some_and(vizsim::output::is_standard_output) {
            anyhow::bail!("{option} -: only `--json -` writes to standard output; name a file");
        }
    }
    Ok(())
}

/// `--check-bound` (render, sim): refused before anything runs when the run is outside the
/// predicted bound.
pub fn refuse_unbounded(desc: &vizsim::run::RunDescription) -> Result<()> {
    if let Some(reason) = vizsim::bound::unsupported(&desc.hardware) {
        anyhow::bail!("--check-bound: {reason} (docs/precision.md, \"The predicted bound\")");
    }
    Ok(())
}

/// `--check-bound` after the run: the line to print for its check of invariant (c), or the
/// error of a broken invariant; None when the run was not asked to check.
pub fn bound_line(report: &vizsim::run::RunReport) -> Result<Option<String>> {
    let Some(check) = &report.error_bound else {
        return Ok(None);
    };
    anyhow::ensure!(check.holds(), "invariant (c) broken: {}", check.describe());
    Ok(Some(format!("invariant (c): {}", check.describe())))
}

/// The fixed-point frame against the float reference (`Probes::compare_float`), unless the
/// bound's line says it already; None for a float run.
pub fn reference_line(report: &vizsim::run::RunReport) -> Option<String> {
    let c = report
        .float_reference
        .as_ref()
        .filter(|_| report.error_bound.is_none())?;
    let bounded = vizsim::bound::unsupported(&report.run.hardware).is_none();
    Some(reference_text(c, bounded))
}

/// `bounded`: whether `--check-bound` takes this run (it refuses some, e.g. lossy leap values).
fn reference_text(c: &vizsim::compare::Comparison, bounded: bool) -> String {
    let e = c.max_abs_error;
    if c.identical {
        "fixed vs float reference: identical images".to_string()
    } else {
        format!(
            "fixed vs float reference: max error (R, G, B, A) {} {} {} {} levels, mean (R, G, B, A) {:.3}, \
             PSNR {}, {} of {} pixels more than 1 level off{}",
            e[0],
            e[1],
            e[2],
            e[3],
            c.mean_abs_error,
            c.psnr_text(1),
            c.pixels_over_1_lsb,
            c.width as u64 * c.height as u64,
            if bounded {
                " (--check-bound: each pixel against the bound its bit widths predict)"
            } else {
                ""
            }
        )
    }
}

/// What the run's configuration asks that its volume leaves without effect, as notes.
pub fn note_lines(report: &vizsim::run::RunReport) -> Vec<String> {
    report.notes.iter().map(|n| format!("note: {n}")).collect()
}

/// The lines `render` and `sim` print under their summary for the features a run has on (ray
/// start and end, iso-surface mode, a leaping structure's memory, blocking), in that order.
pub fn feature_lines(config: &HardwareConfig, m: &vizsim::run::Measurements) -> Vec<String> {
    [
        ray_range_text(m),
        iso_text(config, m),
        structure_memory_text(m),
        blocking_text(m),
        blocking_cost_note(config, m),
        blocking_sram_note(config, m),
    ]
    .into_iter()
    .flatten()
    .collect()
}

/// The ray start and end figures as a user reads them (None when the feature is off).
fn ray_range_text(m: &vizsim::run::Measurements) -> Option<String> {
    let r = m.ray_range.as_ref()?;
    let mut text = format!(
        "ray start/end: {} of {} positions in the box cut ({} %)",
        r.positions_cut,
        r.positions_in_box,
        percent(
            100.0 * r.positions_cut as f64 / r.positions_in_box.max(1) as f64,
            1
        )
    );
    if let (Some(cycles), Some(bricks)) = (r.setup_cycles, r.bricks_visited) {
        text += &format!("; traversal setup {cycles} cycles over {bricks} bricks visited");
    }
    if let (Some(bytes), Some(cycles)) = (r.table_bytes, r.table_load_cycles) {
        text += &format!("; start/end table {bytes} bytes loaded in {cycles} cycles");
    }
    if r.positions_in_box > 0 && r.positions_cut == r.positions_in_box {
        // A clip region outside the volume, say: the frame's figures are those of no sample.
        text += "; every position is cut, so no ray samples anything (check the clip region, \
                 the geometry, or the bricks' transfer function)";
    }
    Some(text)
}

/// Iso-surface mode as a user reads it (None when it is off): the summary line says nothing
/// of it, and the image is a surface, not a composite.
fn iso_text(config: &HardwareConfig, m: &vizsim::run::Measurements) -> Option<String> {
    let iso = &config.iso;
    iso.enabled.then(|| {
        format!(
            "iso-surface: value {}, {} refinement steps; {} refinement samples",
            if iso.value == 0.0 {
                "half the dataset's largest density".to_string()
            } else {
                format!("{:?}", iso.value)
            },
            iso.refinement_steps,
            m.refinement_samples
        )
    })
}

/// What the leaping structure and bricks store, as a user reads it (None without them).
fn structure_memory_text(m: &vizsim::run::Measurements) -> Option<String> {
    let s = m.structure_memory.as_ref()?;
    let mut parts = Vec::new();
    if s.map_sram_bits > 0 {
        parts.push(format!(
            "{} of map SRAM",
            count(s.map_sram_bits, "bit", "bits")
        ));
    }
    if s.brick_flag_bits > 0 {
        parts.push(format!(
            "{} in ray setup",
            count(s.brick_flag_bits, "brick flag", "brick flags")
        ));
    }
    if s.extra_sdram_rows_per_bank > 0 {
        parts.push(format!(
            "{} more SDRAM {} per bank (the distance array)",
            s.extra_sdram_rows_per_bank,
            if s.extra_sdram_rows_per_bank == 1 {
                "row"
            } else {
                "rows"
            }
        ));
    }
    if s.voxel_word_bits > 0 {
        parts.push(format!(
            "{} of every voxel word (leap values; no extra memory)",
            count(s.voxel_word_bits, "bit", "bits")
        ));
    }
    Some(format!("structure memory: {}", parts.join("; ")))
}

/// The blocking figures as a user reads them (None when blocking is off).
fn blocking_text(m: &vizsim::run::Measurements) -> Option<String> {
    let b = m.blocking.as_ref()?;
    let mut text = format!(
        "blocking: {} of {} blocks of {}³ active; memory {} rows per bank = {} words ({} without \
         blocking: {} words, {}); table {} bits on chip, lookup {} cycles",
        b.active_blocks,
        b.blocks,
        b.block_size,
        b.rows_blocked,
        b.memory_words_blocked,
        b.rows_unblocked,
        b.memory_words_unblocked,
        memory_change_text(b.memory_words_blocked, b.memory_words_unblocked),
        b.table_sram_bits,
        b.lookup_latency
    );
    if let Some(zero) = b.zero_samples {
        text += &format!("; {zero} samples in inactive blocks read as zero (no memory read)");
    }
    Some(text)
}

/// When the occupancy map and the block table together exceed the on-chip SRAM the
/// configuration names (both live in the chip's block RAM; a map alone over it is refused when
/// the run is prepared). None when they fit or blocking is off.
fn blocking_sram_note(config: &HardwareConfig, m: &vizsim::run::Measurements) -> Option<String> {
    let table = m.blocking.as_ref()?.table_sram_bits;
    let map = m.structure_memory.as_ref().map_or(0, |s| s.map_sram_bits);
    let sram = config.occupancy.sram_bits;
    (map + table > sram).then(|| {
        format!(
            "note: the occupancy map ({}) and the block table ({}) need {} on chip, more than \
             occupancy.sram_bits ({sram}): a chip for this design needs that much block RAM \
             (--set occupancy.sram_bits={} to model one), or larger blocks (fewer table entries)",
            count(map, "bit", "bits"),
            count(table, "bit", "bits"),
            count(map + table, "bit", "bits"),
            (map + table).next_power_of_two()
        )
    })
}

/// When blocking takes more memory than the unblocked volume, why: a slot of (B + 2)³ voxels
/// takes whole row units, so it costs several times its block's data (4³ blocks: 54 words of a
/// 512-word row per module), and blocking saves only while few enough blocks are active. None
/// otherwise.
fn blocking_cost_note(config: &HardwareConfig, m: &vizsim::run::Measurements) -> Option<String> {
    let b = m.blocking.as_ref()?;
    if b.memory_words_blocked <= b.memory_words_unblocked {
        return None;
    }
    let memory = &config.memory;
    let layout = vizsim::blocking::SlotLayout::new(memory, b.block_size);
    let unit_words = layout.units * memory.columns as usize;
    let fill = layout.words() as f64 / unit_words.max(1) as f64;
    // The most active blocks whose slots still fit in the unblocked volume's rows.
    let break_even = b.rows_unblocked * memory.banks as u64 / layout.units.max(1) as u64;
    let advice = if fill < 0.5 {
        "a larger blocking.block_size fills its row units better"
    } else {
        "most blocks hold visible data, so blocking cannot save memory on this volume"
    };
    Some(format!(
        "note: blocking costs more memory than it saves here: each {bs}³ block takes a slot of \
         {edge}³ voxels, {used} words per module in {units} row unit(s) of {unit_words} ({fill} % \
         used), so blocking saves memory only with at most {break_even} of the {blocks} blocks \
         active, and {active} are; {advice} (docs/model.md, \"Blocking\")",
        bs = b.block_size,
        edge = b.block_size + 2,
        used = layout.words(),
        units = layout.units,
        fill = percent(100.0 * fill, 1),
        blocks = b.blocks,
        active = b.active_blocks,
    ))
}

/// 1234567 -> "1,234,567".
pub fn thousands(n: u128) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// What blocking does to the memory, as a positive percentage of the unblocked words: "x % saved",
/// or "x % more" when the blocks' borders cost more than the inactive blocks save (most blocks
/// active; a negative saving read as a misprint).
fn memory_change_text(words_blocked: u64, words_unblocked: u64) -> String {
    let ratio = words_blocked as f64 / words_unblocked.max(1) as f64;
    if words_blocked > words_unblocked {
        format!("{:.1} % more", 100.0 * (ratio - 1.0))
    } else {
        format!("{:.1} % saved", 100.0 * (1.0 - ratio))
    }
}

/// The command line as typed, for the provenance line of generated reports: `vizsim` and the
/// arguments, quoted where a shell would need it. Relative paths stay relative, so the same
/// command run from another folder records the same line. An argument that is not UTF-8 (a
/// file name in another encoding) is recorded lossily rather than panicking.
pub fn invocation() -> String {
    std::iter::once("vizsim".to_string())
        .chain(
            std::env::args_os()
                .skip(1)
                .map(|a| vizsim::output::shell_word(&a.to_string_lossy())),
        )
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod tests {
    use vizsim::compare::compare;

    #[test]
    fn a_frame_differing_in_alpha_only_says_why_its_psnr_is_infinite() {
        let line = super::reference_text(
            &compare(&[[1, 2, 3, 4]], &[[1, 2, 3, 9]], 1, 1).unwrap(),
            true,
        );
        assert!(line.contains("A) 0 0 0 5 levels"), "{line}");
        assert!(line.contains("PSNR inf dB (R, G, B identical)"), "{line}");
        let line = super::reference_text(
            &compare(&[[1, 2, 3, 4]], &[[1, 2, 9, 4]], 1, 1).unwrap(),
            true,
        );
        assert!(line.contains("PSNR 37.3 dB"), "{line}");
        let same = super::reference_text(
            &compare(&[[1, 2, 3, 4]], &[[1, 2, 3, 4]], 1, 1).unwrap(),
            true,
        );
        assert_eq!(same, "fixed vs float reference: identical images");
    }
}

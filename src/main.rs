//! The `vizsim` command line. Library errors carry what and where; here they get context and
//! become a message on stderr with a non-zero exit status.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use vizsim::camera::{parse_image_size, Camera, Projection, View};
use vizsim::config::HardwareConfig;
use vizsim::functional::renderer::{FixedRenderer, Leaping};
use vizsim::render::float::FloatRenderer;
use vizsim::render::{Frame, FrameStats, RenderSettings};
use vizsim::transfer;
use vizsim::volume::{dataset, Volume};

#[derive(Parser)]
#[command(
    name = "vizsim",
    version,
    about = "Cycle-accurate simulator of hardware volume ray casting architectures"
)]
struct Cli {
    /// Worker threads (default: all cores). Results are identical for any count.
    #[arg(long, global = true)]
    threads: Option<usize>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render one frame: float reference ray caster, or fixed-point model (--model fixed).
    Render(RenderArgs),
    /// Simulate one frame clock by clock on the cycle-accurate pipeline.
    Sim(SimArgs),
    /// Print a dataset's dimensions, spacing, value histogram and occupied percentage.
    Info {
        /// Dataset name, phantom spec or file (see `vizsim info --help`).
        dataset: String,
        #[command(flatten)]
        data: DataArgs,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Occupancy maps per sub-cube size: storage bits, SRAM fit, skippable sub-cubes ('0', class).
    Occupancy {
        /// Dataset name, phantom spec or file.
        dataset: String,
        #[command(flatten)]
        data: DataArgs,
        /// Transfer function for the class map: `class`, `zero`, a preset or a file.
        #[arg(long, default_value = "class")]
        tf: String,
        #[command(flatten)]
        hardware: HardwareArgs,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Compare two images: max error per channel, PSNR, pixels differing by more than 1 LSB.
    Compare {
        a: PathBuf,
        b: PathBuf,
        /// Write the comparison as JSON.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Write a difference image (|A - B| x 16).
        #[arg(long)]
        diff: Option<PathBuf>,
    },
    /// Exhaustively verify the skip calculator: every (position within a sub-cube, increment)
    /// pair at these widths; reports overshoots (must be 0) and the worst wasted steps.
    VerifySkip {
        /// Fraction bits of the increment V.
        #[arg(long, default_value_t = 8)]
        increment_bits: u32,
        /// Fraction bits of positions (default: = increment bits).
        #[arg(long)]
        position_bits: Option<u32>,
        /// Significant bits of the reciprocal 1/|V|.
        #[arg(long, default_value_t = 8)]
        reciprocal_bits: u32,
        /// Fraction bits kept of the boundary distance (default: = position bits).
        #[arg(long)]
        distance_bits: Option<u32>,
        /// Sub-cube edge in voxels (2..64); several allowed.
        #[arg(long, default_values_t = [16])]
        subcube: Vec<usize>,
        /// Reciprocal rounding: `down` (shipped, safe) or `nearest` (unsafe, shows the checker works).
        #[arg(long, value_enum, default_value = "down")]
        rounding: RoundingArg,
        /// Largest increment enumerated, in voxels (default 1: one sample per voxel or finer).
        #[arg(long, default_value_t = 1)]
        max_increment_voxels: u64,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// Sweep fixed-point widths one at a time against the float reference (image error) and the
    /// skip widths against the step count; writes tables and plots.
    Precision {
        #[arg(long)]
        dataset: String,
        #[command(flatten)]
        data: DataArgs,
        #[arg(long, default_value = "class")]
        tf: String,
        /// An oblique view by default: axis-aligned views, and angles whose direction happens to
        /// be exact in few bits (25° is within 0.1 % of 27/64, 58/64), hide increment errors.
        #[arg(long, default_value = "orbit:7/72")]
        view: String,
        #[arg(long, default_value = "128x128")]
        size: String,
        #[arg(long, default_value = "reports/precision")]
        out: PathBuf,
        #[command(flatten)]
        hardware: HardwareArgs,
    },
    /// Run an experiment file (configs/experiments/): every run in parallel, results appended
    /// to OUT/results.jsonl as they finish; re-running resumes.
    Sweep {
        /// The experiment TOML.
        experiment: PathBuf,
        /// Output folder (results.jsonl, timing.jsonl, experiment.resolved.json).
        #[arg(long)]
        out: PathBuf,
        /// Print the runs, what is already done and a time estimate; run nothing.
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
    },
    /// Merge sweep folders (shards) into one, results sorted by key.
    Merge {
        /// Sweep folders.
        #[arg(required = true)]
        inputs: Vec<PathBuf>,
        #[arg(long)]
        out: PathBuf,
    },
    /// Tables of a sweep's results (Markdown and CSV): rows dataset x classification, columns
    /// the acceleration modes, cells averaged over the frames.
    Table {
        #[command(flatten)]
        results: ResultsArgs,
        /// Metrics (one table each per model; default fps, cycles, steps, page-hits).
        #[arg(long, value_enum, value_delimiter = ',')]
        metric: Vec<vizsim::tables::Metric>,
        /// Row fields, comma-separated: dataset, tf, mode, model, frame or a swept field path.
        #[arg(long, default_value = "dataset,tf", value_delimiter = ',')]
        rows: Vec<String>,
        /// Column field.
        #[arg(long, default_value = "mode")]
        columns: String,
        /// Output folder (default DIR/tables).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Charts of a sweep's results (PNG + SVG): cycles or steps per frame against the frame,
    /// skippable sub-cubes and frame rate against the sub-cube size, swept fields.
    Plot {
        #[command(flatten)]
        results: ResultsArgs,
        /// Output folder (default DIR/plots).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Render orbits and a gallery of the phantoms and the datasets present into reports/demo/.
    Demo {
        #[command(flatten)]
        data: DataArgs,
        /// Output folder.
        #[arg(long, default_value = "reports/demo")]
        out: PathBuf,
        /// Frames of the orbit (the published animation has 72, 5 degrees each).
        #[arg(long, default_value_t = 72)]
        frames: u32,
    },
}

#[derive(Args, Clone)]
struct DataArgs {
    /// Folder holding the real datasets (env VIZSIM_DATA; default ../shared/data when present).
    #[arg(long)]
    data_dir: Option<PathBuf>,
}

/// What defines a frame: dataset, transfer function, view and sampling.
#[derive(Args)]
struct FrameArgs {
    /// Dataset: a name in the data folder (fuel, neghip, aneurism...), phantom:KIND[:SIZE], or a file.
    #[arg(long)]
    dataset: String,
    #[command(flatten)]
    data: DataArgs,
    /// Transfer function: `zero`, `class` (the dataset's own), a preset name, or a TOML file.
    #[arg(long, default_value = "class")]
    tf: String,
    /// `front` or `orbit:K/N` (frame K of an N-frame orbit about the vertical axis).
    #[arg(long, default_value = "front")]
    view: String,
    #[arg(long, value_enum, default_value = "ortho")]
    projection: ProjectionArg,
    /// Image size WxH.
    #[arg(long, default_value = "256x256")]
    size: String,
    /// Sample spacing along the ray, in voxels.
    #[arg(long, default_value_t = 1.0)]
    spacing: f32,
    /// Disable early ray termination.
    #[arg(long)]
    no_ert: bool,
    /// Phong shading from per-voxel gradients.
    #[arg(long)]
    shading: bool,
}

impl FrameArgs {
    fn image_size(&self) -> Result<(u32, u32)> {
        Ok(parse_image_size(&self.size)?)
    }

    /// Render settings with the given ERT threshold (None when --no-ert).
    fn settings(&self, ert_threshold: f32) -> Result<RenderSettings> {
        let settings = RenderSettings {
            sample_spacing: self.spacing,
            ert_threshold: (!self.no_ert).then_some(ert_threshold),
            shading: self.shading,
            ..RenderSettings::default()
        };
        settings.validate()?;
        Ok(settings)
    }

    /// Loads the volume and transfer function and places the camera.
    fn load(&self) -> Result<(Volume, vizsim::transfer::TransferFunction, Camera)> {
        let (width, height) = self.image_size()?;
        let view = View::parse(&self.view)?;
        let volume = load_volume(&self.dataset, &self.data)?;
        let tf = transfer::resolve(&self.tf, &volume.name)?;
        let camera = Camera::for_volume(
            volume_extent(&volume),
            view,
            self.projection.into(),
            width,
            height,
        )?;
        Ok((volume, tf, camera))
    }
}

#[derive(Args)]
struct RenderArgs {
    #[command(flatten)]
    frame: FrameArgs,
    /// Early ray termination threshold (float model; the fixed model takes the configuration's).
    #[arg(long, default_value_t = 0.95)]
    ert_threshold: f32,
    /// Output PNG.
    #[arg(short, long)]
    output: PathBuf,
    /// Also write statistics as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Also write one CSV row per ray: samples, leaps, where it entered and left, ERT.
    #[arg(long)]
    rays: Option<PathBuf>,
    /// `float`: the reference ray caster; `fixed`: the functional fixed-point model.
    #[arg(long, value_enum, default_value = "float")]
    model: ModelArg,
    #[command(flatten)]
    hardware: HardwareArgs,
}

#[derive(Args)]
struct SimArgs {
    #[command(flatten)]
    frame: FrameArgs,
    /// Voxel memory model: `sdram` (modules, banks, FIFOs, overtaking) or `ideal` (fixed
    /// latency, unlimited bandwidth: the bound with free memory).
    #[arg(long, value_enum, default_value = "sdram")]
    memory: MemoryArg,
    /// Write a VCD waveform (GTKWave, Surfer) of the cycles given by --vcd-cycles.
    #[arg(long)]
    vcd: Option<PathBuf>,
    /// Cycle window of the waveform, A..B.
    #[arg(long, default_value = "0..10000")]
    vcd_cycles: String,
    /// Latency of the ideal memory, in cycles.
    #[arg(long, default_value_t = 6)]
    ideal_latency: u64,
    #[command(flatten)]
    hardware: HardwareArgs,
    /// Output PNG.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Statistics as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug, serde::Serialize)]
#[serde(rename_all = "lowercase")]
enum MemoryArg {
    Sdram,
    Ideal,
}

#[derive(Args, Clone)]
struct HardwareArgs {
    /// Hardware configuration TOML (default: the embedded configs/hardware/vizard2.toml).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Override a configuration field, validated like the file: --set skip.reciprocal_bits=6.
    #[arg(long = "set", value_name = "FIELD=VALUE")]
    overrides: Vec<String>,
    /// Space leaping with sub-cubes of this edge (2..64); without it, no leaping.
    #[arg(long)]
    subcube: Option<usize>,
    /// Two-level occupancy hierarchy (2x2x2 sub-cubes per byte).
    #[arg(long)]
    hierarchy: bool,
    /// Which occupancy map: '0' (`zero`) or `class`.
    #[arg(long, value_enum)]
    occupancy: Option<OccupancyArg>,
}

impl HardwareArgs {
    /// The configuration file with --set, then the leaping flags applied as overrides too, so
    /// every value goes through the same validation.
    fn load(&self) -> Result<HardwareConfig> {
        let mut overrides = self.overrides.clone();
        if let Some(s) = self.subcube {
            overrides.push(format!("occupancy.subcube={s}"));
        }
        if self.hierarchy {
            overrides.push("occupancy.hierarchy=true".into());
        }
        if let Some(kind) = self.occupancy {
            overrides.push(format!("occupancy.kind={}", kind.toml_name()));
        }
        Ok(HardwareConfig::load(self.config.as_deref(), &overrides)?)
    }
}

#[derive(clap::ValueEnum, Clone, Copy, PartialEq, Eq)]
enum ModelArg {
    Float,
    Fixed,
}

#[derive(clap::ValueEnum, Clone, Copy)]
enum RoundingArg {
    Down,
    Nearest,
}

#[derive(clap::ValueEnum, Clone, Copy)]
enum OccupancyArg {
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
}

#[derive(clap::ValueEnum, Clone, Copy)]
enum ProjectionArg {
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

fn main() {
    let cli = Cli::parse();
    if let Err(err) = run(cli) {
        eprintln!("error: {err:#}");
        std::process::exit(1);
    }
}

fn run(cli: Cli) -> Result<()> {
    if let Some(n) = cli.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .context("setting the thread count")?;
    }
    match cli.command {
        Command::Render(args) => render(args),
        Command::Sim(args) => sim(args),
        Command::Info {
            dataset,
            data,
            json,
        } => info(&dataset, &data, json),
        Command::Demo { data, out, frames } => demo(&data, &out, frames),
        Command::Occupancy {
            dataset,
            data,
            tf,
            hardware,
            json,
        } => occupancy(&dataset, &data, &tf, &hardware, json),
        Command::VerifySkip {
            increment_bits,
            position_bits,
            reciprocal_bits,
            distance_bits,
            subcube,
            rounding,
            max_increment_voxels,
            json,
        } => {
            let position_bits = position_bits.unwrap_or(increment_bits);
            verify_skip(
                vizsim::skip::SkipWidths::new(
                    position_bits,
                    increment_bits,
                    reciprocal_bits,
                    distance_bits.unwrap_or(position_bits),
                )
                .map_err(|e| anyhow::anyhow!("verify-skip: {e}"))?,
                &subcube,
                rounding,
                max_increment_voxels,
                json,
            )
        }
        Command::Precision {
            dataset,
            data,
            tf,
            view,
            size,
            out,
            hardware,
        } => precision(&dataset, &data, &tf, &view, &size, &out, &hardware),
        Command::Compare { a, b, json, diff } => compare(&a, &b, json.as_deref(), diff.as_deref()),
        Command::Sweep {
            experiment,
            out,
            dry_run,
            shard,
            quiet,
            model,
            data,
        } => sweep(
            &experiment,
            &out,
            dry_run,
            shard.as_deref(),
            model.as_deref(),
            quiet,
            &data,
        ),
        Command::Merge { inputs, out } => {
            let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
            let n = vizsim::experiment::merge(&inputs, &out)?;
            println!("{n} runs -> {}", out.join("results.jsonl").display());
            Ok(())
        }
        Command::Table {
            results,
            metric,
            rows,
            columns,
            out,
        } => table(&results, &metric, &rows, &columns, out.as_deref()),
        Command::Plot { results, out } => {
            let out = out.unwrap_or_else(|| results.dir.join("plots"));
            let lines = results.read()?;
            let written = vizsim::figures::write_all(&lines, &out)?;
            println!("{written} charts -> {}", out.display());
            Ok(())
        }
    }
}

fn load_volume(spec: &str, data: &DataArgs) -> Result<Volume> {
    let dir = dataset::data_dir(data.data_dir.as_deref());
    Ok(dataset::load(spec, dir.as_deref())?)
}

fn volume_extent(volume: &Volume) -> glam::Vec3 {
    glam::Vec3::from(volume.extent())
}

#[derive(serde::Serialize)]
struct RenderReport<'a> {
    dataset: &'a str,
    transfer_function: &'a str,
    model: &'a str,
    view: &'a str,
    projection: Projection,
    width: u32,
    height: u32,
    settings: &'a RenderSettings,
    stats: &'a FrameStats,
    /// Fixed-point model: samples + leaps, the published cost unit.
    steps: u64,
    samples: u64,
    leaps: u64,
    /// Fixed-point model: steps x clock.step_time_ns (the published cost method).
    frame_time_ns: Option<f64>,
    /// Frames per second at that frame time.
    fps: Option<f64>,
    /// The resolved hardware configuration (fixed-point model).
    hardware: Option<&'a HardwareConfig>,
    leaping: Option<Leaping>,
    wall_seconds: f64,
    samples_per_second: f64,
}

fn render(args: RenderArgs) -> Result<()> {
    let hardware = if args.model == ModelArg::Fixed {
        Some(args.hardware.load()?)
    } else {
        anyhow::ensure!(
            args.hardware.config.is_none()
                && args.hardware.overrides.is_empty()
                && args.hardware.subcube.is_none()
                && !args.hardware.hierarchy
                && args.hardware.occupancy.is_none(),
            "--config, --set, --subcube, --hierarchy and --occupancy apply to --model fixed"
        );
        None
    };
    let mut settings = args.frame.settings(match &hardware {
        Some(h) => h.compositing.ert_threshold as f32,
        None => args.ert_threshold,
    })?;
    if hardware.as_ref().is_some_and(|h| !h.compositing.ert) {
        settings.ert_threshold = None;
    }
    let (volume, tf, camera) = args.frame.load()?;
    let (width, height) = (camera.width, camera.height);
    let start = Instant::now();
    let (frame, leaping) = match &hardware {
        None => (
            FloatRenderer::new(&volume, &tf, &settings)?.render(&camera),
            None,
        ),
        Some(h) => {
            let leaping = Leaping::from_config(h);
            let renderer = FixedRenderer::new(&volume, &tf, &settings, h, leaping)?;
            (renderer.render(&camera), Some(leaping))
        }
    };
    let wall = start.elapsed().as_secs_f64();
    frame.write_png(&args.output)?;
    if let Some(path) = &args.rays {
        frame.write_rays_csv(path)?;
    }
    let stats = frame.stats();
    let frame_time_ns = hardware
        .as_ref()
        .map(|h| stats.steps() as f64 * h.clock.step_time_ns);
    println!(
        "{}: {} rays, {} hit, {} samples, {} leaps, {} terminated early{}, {:.3} s ({:.1} M samples/s) -> {}",
        volume.name,
        stats.rays,
        stats.rays_hit,
        stats.samples,
        stats.leaps,
        stats.rays_terminated_early,
        frame_time_ns
            .map(|t| format!(", {} steps = {:.3} ms/frame = {:.1} fps", stats.steps(), t / 1e6, 1e9 / t))
            .unwrap_or_default(),
        wall,
        stats.samples as f64 / wall / 1e6,
        args.output.display()
    );
    if let Some(json) = &args.json {
        let report = RenderReport {
            dataset: &volume.name,
            transfer_function: &tf.name,
            model: if hardware.is_some() { "fixed" } else { "float" },
            view: &args.frame.view,
            projection: args.frame.projection.into(),
            width,
            height,
            settings: &settings,
            stats: &stats,
            steps: stats.steps(),
            samples: stats.samples,
            leaps: stats.leaps,
            frame_time_ns,
            fps: frame_time_ns.map(|t| 1e9 / t),
            hardware: hardware.as_ref(),
            leaping,
            wall_seconds: wall,
            samples_per_second: stats.samples as f64 / wall,
        };
        vizsim::output::write_json(json, &report)?;
    }
    Ok(())
}

#[derive(serde::Serialize)]
struct SimReport<'a> {
    dataset: &'a str,
    transfer_function: &'a str,
    view: &'a str,
    projection: Projection,
    width: u32,
    height: u32,
    memory: MemoryArg,
    /// Clock cycles for the frame.
    cycles: u64,
    /// Frames per second at clock.frequency_mhz.
    fps: f64,
    /// Frame time in ns at clock.frequency_mhz.
    frame_time_ns: f64,
    steps: u64,
    samples: u64,
    leaps: u64,
    discarded_after_ert: u64,
    /// Everything the pipeline counted (stall cycles by cause, occupancy histograms...).
    pipeline: &'a vizsim::arch::pipeline::CycleStats,
    memory_stats: serde_json::Value,
    /// Simulated cycles per wall-clock second of this run.
    sim_cycles_per_second: f64,
    wall_seconds: f64,
    /// The resolved hardware configuration.
    hardware: &'a HardwareConfig,
    leaping: Leaping,
}

fn sim(args: SimArgs) -> Result<()> {
    use vizsim::arch::pipeline::simulate;
    use vizsim::arch::sdram_module::SdramMemory;
    use vizsim::arch::voxel_memory::{IdealMemory, VoxelMemory};
    let config = args.hardware.load()?;
    let mut settings = args
        .frame
        .settings(config.compositing.ert_threshold as f32)?;
    if !config.compositing.ert {
        settings.ert_threshold = None;
    }
    let (volume, tf, camera) = args.frame.load()?;
    let (width, height) = (camera.width, camera.height);
    let leaping = Leaping::from_config(&config);
    let renderer = FixedRenderer::new(&volume, &tf, &settings, &config, leaping)?;
    config
        .memory
        .check_covers(volume.dims, "hardware configuration")?;
    let mut memory: Box<dyn VoxelMemory> = match args.memory {
        MemoryArg::Sdram => Box::new(SdramMemory::new(
            &config.memory,
            &config.sdram,
            volume.dims,
            config.clock.frequency_mhz,
        )),
        MemoryArg::Ideal => Box::new(IdealMemory::new(args.ideal_latency)),
    };
    let mut waveform = match &args.vcd {
        Some(path) => Some(vizsim::arch::trace::Waveform::create(
            path,
            config.memory.modules(),
            vizsim::arch::trace::parse_window(&args.vcd_cycles)?,
        )?),
        None => None,
    };
    let start = Instant::now();
    let result = simulate(
        &renderer,
        &camera,
        &renderer.skipper(),
        &mut memory,
        &config,
        true,
        waveform.as_mut(),
    )?;
    if let Some(w) = waveform {
        w.finish()?;
    }
    let wall = start.elapsed().as_secs_f64();
    let s = &result.stats;
    let frame_time_ns = s.cycles as f64 * 1e3 / config.clock.frequency_mhz;
    println!(
        "{}: {} cycles = {:.3} ms/frame = {:.1} fps at {} MHz; {} steps ({} samples, {} leaps), {} discarded after ERT; \
         stalls: queue empty {}, skip busy {}, memory {}, buffer full {}; {:.1} M cycles/s simulated",
        volume.name,
        s.cycles,
        frame_time_ns / 1e6,
        1e9 / frame_time_ns,
        config.clock.frequency_mhz,
        s.steps,
        s.samples,
        s.leaps,
        s.discarded_after_ert,
        s.stall_cycles.ray_queue_empty,
        s.stall_cycles.skip_unit_busy,
        s.stall_cycles.memory,
        s.stall_cycles.compositing_buffer_full,
        s.cycles as f64 / wall / 1e6
    );
    if let Some(path) = &args.output {
        result.frame.write_png(path)?;
    }
    if let Some(path) = &args.json {
        let report = SimReport {
            dataset: &volume.name,
            transfer_function: &tf.name,
            view: &args.frame.view,
            projection: args.frame.projection.into(),
            width,
            height,
            memory: args.memory,
            cycles: s.cycles,
            fps: 1e9 / frame_time_ns,
            frame_time_ns,
            steps: s.steps,
            samples: s.samples,
            leaps: s.leaps,
            discarded_after_ert: s.discarded_after_ert,
            pipeline: s,
            memory_stats: memory.stats_json(),
            sim_cycles_per_second: s.cycles as f64 / wall,
            wall_seconds: wall,
            hardware: &config,
            leaping,
        };
        vizsim::output::write_json(path, &report)?;
    }
    Ok(())
}

fn info(spec: &str, data: &DataArgs, json: bool) -> Result<()> {
    let volume = load_volume(spec, data)?;
    let info = volume.info();
    if json {
        println!("{}", serde_json::to_string_pretty(&info)?);
    } else {
        println!("dataset   {}", info.name);
        println!(
            "dims      {} x {} x {} ({} voxels, {} bit)",
            info.dims[0], info.dims[1], info.dims[2], info.voxels, info.bits
        );
        println!(
            "spacing   {} {} {}",
            info.spacing[0], info.spacing[1], info.spacing[2]
        );
        println!(
            "values    min {} max {} mean {:.2}",
            info.min, info.max, info.mean
        );
        println!("occupied  {:.2} % of voxels > 0", info.occupied_percent);
        let total = info.voxels.max(1) as f64;
        let bin = (volume.max_value() as usize + 1) / 16;
        for (i, count) in info.histogram16.iter().enumerate() {
            let pct = 100.0 * *count as f64 / total;
            println!(
                "  {:>5}..{:<5} {:>7.3} % {}",
                i * bin,
                (i + 1) * bin - 1,
                pct,
                "#".repeat((pct / 2.0).ceil() as usize)
            );
        }
    }
    Ok(())
}

#[derive(serde::Serialize)]
struct OccupancyRow {
    subcube: usize,
    /// Map bits: one per sub-cube.
    bits: u64,
    /// Map bits with the two-level hierarchy (padded to whole bytes of 2x2x2 sub-cubes).
    bits_with_hierarchy: u64,
    fits_sram: bool,
    fits_sram_with_hierarchy: bool,
    /// Percentage of sub-cubes that are empty, '0' map.
    skippable_zero_percent: f64,
    /// Percentage of sub-cubes that are empty, class map.
    skippable_class_percent: f64,
    /// Percentage of 2x2x2 groups that are empty (whole-group leaps), '0' and class maps.
    empty_groups_zero_percent: f64,
    empty_groups_class_percent: f64,
}

fn occupancy(
    spec: &str,
    data: &DataArgs,
    tf_arg: &str,
    hardware: &HardwareArgs,
    json: bool,
) -> Result<()> {
    use vizsim::functional::arith::ClassificationTable;
    use vizsim::occupancy::{OccupancyKind, OccupancyMap, SUBCUBE_SIZES};
    let config = hardware.load()?;
    let volume = load_volume(spec, data)?;
    let tf = transfer::resolve(tf_arg, &volume.name)?;
    let table = ClassificationTable::build(
        &tf,
        volume.max_value() as usize + 1,
        config.classification.lut_bits,
        1.0,
    );
    let sram = config.occupancy.sram_bits;
    let largest = *volume.dims.iter().max().unwrap_or(&0);
    let pct = |part: usize, whole: usize| 100.0 * part as f64 / whole.max(1) as f64;
    let rows: Vec<OccupancyRow> = SUBCUBE_SIZES
        .iter()
        .filter(|&&s| s <= largest)
        .map(|&s| {
            let log2 = s.trailing_zeros();
            let zero = OccupancyMap::build(&volume, OccupancyKind::Zero, log2, 0, |_, _| true);
            let class = OccupancyMap::build(&volume, OccupancyKind::Class, log2, 0, |lo, hi| {
                table.any_visible(lo, hi)
            });
            let groups = zero.group_dims.iter().product::<usize>();
            OccupancyRow {
                subcube: s,
                bits: zero.storage_bits(false),
                bits_with_hierarchy: zero.storage_bits(true),
                fits_sram: zero.storage_bits(false) <= sram,
                fits_sram_with_hierarchy: zero.storage_bits(true) <= sram,
                skippable_zero_percent: pct(zero.empty_subcubes(), zero.subcubes()),
                skippable_class_percent: pct(class.empty_subcubes(), class.subcubes()),
                empty_groups_zero_percent: pct(zero.empty_groups(), groups),
                empty_groups_class_percent: pct(class.empty_groups(), groups),
            }
        })
        .collect();
    if json {
        #[derive(serde::Serialize)]
        struct Report<'a> {
            dataset: &'a str,
            transfer_function: &'a str,
            sram_bits: u64,
            sizes: &'a [OccupancyRow],
        }
        let report = Report {
            dataset: &volume.name,
            transfer_function: &tf.name,
            sram_bits: sram,
            sizes: &rows,
        };
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "{}: occupancy maps, transfer function {} (class), SRAM {sram} bit",
        volume.name, tf.name
    );
    println!("| sub-cube | map bits | fits SRAM | skippable '0' | skippable class | empty groups '0' | empty groups class |");
    println!("|---:|---:|:---:|---:|---:|---:|---:|");
    for r in &rows {
        println!(
            "| {}³ | {} | {} | {:.2} % | {:.2} % | {:.2} % | {:.2} % |",
            r.subcube,
            r.bits,
            if r.fits_sram { "yes" } else { "no" },
            r.skippable_zero_percent,
            r.skippable_class_percent,
            r.empty_groups_zero_percent,
            r.empty_groups_class_percent
        );
    }
    Ok(())
}

fn precision(
    spec: &str,
    data: &DataArgs,
    tf_arg: &str,
    view: &str,
    size: &str,
    out: &Path,
    hardware: &HardwareArgs,
) -> Result<()> {
    let config = hardware.load()?;
    let (width, height) = parse_image_size(size)?;
    let view = View::parse(view)?;
    let volume = load_volume(spec, data)?;
    let tf = transfer::resolve(tf_arg, &volume.name)?;
    let camera = Camera::for_volume(
        volume_extent(&volume),
        view,
        Projection::Ortho,
        width,
        height,
    )?;
    let settings = RenderSettings {
        ert_threshold: config.ert_threshold(),
        ..RenderSettings::default()
    };
    let start = Instant::now();
    let report = vizsim::precision::sweep(&volume, &tf, &config, &camera, &settings)?;
    for path in vizsim::precision::write_report(&report, out)? {
        println!("wrote {}", path.display());
    }
    println!("{} in {:.1} s", volume.name, start.elapsed().as_secs_f64());
    Ok(())
}

fn verify_skip(
    widths: vizsim::skip::SkipWidths,
    subcubes: &[usize],
    rounding: RoundingArg,
    max_increment_voxels: u64,
    json: bool,
) -> Result<()> {
    use vizsim::skip::{verify_exhaustive, ReciprocalRounding, VerifyParams};
    let rounding = match rounding {
        RoundingArg::Down => ReciprocalRounding::Down,
        RoundingArg::Nearest => ReciprocalRounding::Nearest,
    };
    let mut reports = Vec::new();
    for &s in subcubes {
        anyhow::ensure!(
            vizsim::occupancy::SUBCUBE_SIZES.contains(&s),
            "--subcube {s}: allowed {:?}",
            vizsim::occupancy::SUBCUBE_SIZES
        );
        let mut params = VerifyParams::new(widths, s.trailing_zeros(), rounding);
        params.max_increment = max_increment_voxels
            .checked_shl(widths.inc_frac_bits)
            .filter(|m| (1..=1 << 24).contains(m))
            .ok_or_else(|| anyhow::anyhow!("--max-increment-voxels {max_increment_voxels}: too many increments to enumerate"))?;
        let report = verify_exhaustive(&params).map_err(|e| anyhow::anyhow!("verify-skip: {e}"))?;
        if !json {
            println!(
                "sub-cube {s}³: {} cases, {} violations, worst wasted steps {}, mean {:.4}{}",
                report.cases,
                report.violations,
                report.worst_wasted_steps,
                report.mean_wasted_steps,
                report
                    .first_violation
                    .map(|v| format!(
                        "; first violation: offset {} LSB, increment {} LSB: {} steps computed, {} exact",
                        v.offset, v.increment, v.computed_steps, v.exact_steps
                    ))
                    .unwrap_or_default()
            );
        }
        reports.push(report);
    }
    if json {
        let value = if reports.len() == 1 {
            serde_json::to_value(&reports[0])?
        } else {
            serde_json::to_value(&reports)?
        };
        println!("{}", serde_json::to_string_pretty(&value)?);
    }
    Ok(())
}

fn compare(a: &Path, b: &Path, json: Option<&Path>, diff: Option<&Path>) -> Result<()> {
    use vizsim::compare;
    let (wa, ha, pa) = compare::load_rgba(a)?;
    let (wb, hb, pb) = compare::load_rgba(b)?;
    anyhow::ensure!(
        (wa, ha) == (wb, hb),
        "{} is {wa}x{ha} but {} is {wb}x{hb}",
        a.display(),
        b.display()
    );
    let result = compare::compare(&pa, &pb, wa, ha)?;
    println!(
        "max |error| R {} G {} B {} A {}, mean {:.4}, PSNR {:.2} dB, {} pixels differ by more than 1 LSB{}",
        result.max_abs_error[0],
        result.max_abs_error[1],
        result.max_abs_error[2],
        result.max_abs_error[3],
        result.mean_abs_error,
        result.psnr_db,
        result.pixels_over_1_lsb,
        if result.identical { " (identical)" } else { "" }
    );
    if let Some(path) = json {
        vizsim::output::write_json(path, &result)?;
    }
    if let Some(path) = diff {
        let frame = Frame {
            width: wa,
            height: ha,
            pixels: compare::difference_image(&pa, &pb, 16),
            rays: Vec::new(),
        };
        frame.write_png(path)?;
    }
    Ok(())
}

/// The main job on the embedded default: orbits of a phantom (and of fuel when the data folder
/// is there) as contact sheets, and a front-view gallery of every dataset with both of its
/// transfer functions.
fn demo(data: &DataArgs, out: &Path, frames: u32) -> Result<()> {
    anyhow::ensure!(frames >= 1, "--frames must be at least 1");
    let dir = dataset::data_dir(data.data_dir.as_deref());
    let mut orbit_sets = vec!["phantom:metaballs:64".to_string()];
    let mut gallery: Vec<String> = vizsim::volume::phantom::PhantomKind::ALL
        .iter()
        .map(|k| format!("phantom:{}:64", k.name()))
        .collect();
    match &dir {
        Some(d) if d.is_dir() => {
            orbit_sets.push("fuel".into());
            gallery.extend(dataset::scan(d)?.into_iter().map(|e| e.name));
        }
        _ => {
            println!("no data directory (--data-dir / VIZSIM_DATA / ../shared/data): phantoms only")
        }
    }
    let settings = RenderSettings::default();
    for spec in &orbit_sets {
        let volume = dataset::load(spec, dir.as_deref())?;
        let tf = transfer::resolve("class", &volume.name)?;
        let renderer = FloatRenderer::new(&volume, &tf, &settings)?;
        let start = Instant::now();
        let mut images = Vec::new();
        for k in 0..frames {
            let camera = Camera::for_volume(
                volume_extent(&volume),
                View::Orbit { k, n: frames },
                Projection::Ortho,
                128,
                128,
            )?;
            images.push(renderer.render(&camera));
        }
        let step = (frames / 12).max(1) as usize;
        let picked: Vec<&Frame> = images.iter().step_by(step).take(12).collect();
        let path = out.join(format!("orbit-{}.png", file_safe(&volume.name)));
        write_contact_sheet(&picked, 6, &path)?;
        println!(
            "{}: {frames}-frame orbit in {:.2} s -> {}",
            volume.name,
            start.elapsed().as_secs_f64(),
            path.display()
        );
    }
    for spec in &gallery {
        let volume = dataset::load(spec, dir.as_deref())?;
        let mut row = Vec::new();
        for kind in ["zero", "class"] {
            let tf = transfer::resolve(kind, &volume.name)?;
            let renderer = FloatRenderer::new(&volume, &tf, &settings)?;
            for view in [View::Front, View::Orbit { k: 1, n: 4 }] {
                let camera =
                    Camera::for_volume(volume_extent(&volume), view, Projection::Ortho, 256, 256)?;
                row.push(renderer.render(&camera));
            }
        }
        let path = out.join(format!("gallery-{}.png", file_safe(&volume.name)));
        write_contact_sheet(&row.iter().collect::<Vec<_>>(), 4, &path)?;
        println!(
            "{}: zero | class, front and side -> {}",
            volume.name,
            path.display()
        );
    }
    quick_experiment(dir.as_deref(), &out.join("quick"))
}

/// The quick experiment (configs/experiments/quick.toml, embedded): sweep, tables and charts.
/// Without the data folder its real datasets are left out.
fn quick_experiment(data_dir: Option<&Path>, out: &Path) -> Result<()> {
    use vizsim::experiment::{self, spec};
    const QUICK: &str = include_str!("../configs/experiments/quick.toml");
    let mut file: spec::ExperimentFile = toml::from_str(QUICK)?;
    file.datasets.retain(|d| {
        let present = dataset::load(d, data_dir).is_ok();
        if !present {
            println!("quick experiment: {d} is not there, left out");
        }
        present
    });
    let expansion = spec::expand(
        &toml::to_string(&file)?,
        "configs/experiments/quick.toml",
        data_dir,
    )?;
    let summary = experiment::sweep(&expansion, out, None, false)?;
    println!(
        "quick experiment: {} runs in {:.1} s -> {}",
        summary.total,
        summary.wall_seconds,
        out.display()
    );
    let results = ResultsArgs {
        dir: out.to_path_buf(),
        frame_step: 1,
        model: None,
    };
    table(
        &results,
        &[],
        &["dataset".to_string(), "tf".to_string()],
        "mode",
        None,
    )?;
    let lines = results.read()?;
    let charts = vizsim::figures::write_all(&lines, &out.join("plots"))?;
    println!("{charts} charts -> {}", out.join("plots").display());
    Ok(())
}

fn file_safe(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '-'
            }
        })
        .collect()
}

/// Tiles frames of equal size into one PNG, `columns` per row.
fn write_contact_sheet(frames: &[&Frame], columns: usize, path: &Path) -> Result<()> {
    let Some(first) = frames.first() else {
        return Ok(());
    };
    let (w, h) = (first.width, first.height);
    let rows = frames.len().div_ceil(columns) as u32;
    let cols = columns.min(frames.len()) as u32;
    let sheet = Frame {
        width: w * cols,
        height: h * rows,
        pixels: {
            let mut pixels = vec![[0u8, 0, 0, 255]; (w * cols * h * rows) as usize];
            for (i, f) in frames.iter().enumerate() {
                let (ox, oy) = ((i as u32 % cols) * w, (i as u32 / cols) * h);
                for y in 0..h {
                    for x in 0..w {
                        pixels[((oy + y) * w * cols + ox + x) as usize] =
                            f.pixels[(y * w + x) as usize];
                    }
                }
            }
            pixels
        },
        rays: Vec::new(),
    };
    sheet.write_png(path)?;
    Ok(())
}

fn sweep(
    experiment: &Path,
    out: &Path,
    dry_run: bool,
    shard: Option<&str>,
    model: Option<&str>,
    quiet: bool,
    data: &DataArgs,
) -> Result<()> {
    use std::io::IsTerminal;
    use vizsim::experiment::{self, spec, Shard};
    let shard = shard.map(Shard::parse).transpose()?;
    let dir = dataset::data_dir(data.data_dir.as_deref());
    let mut expansion = spec::load(experiment, dir.as_deref())?;
    if let Some(model) = model {
        anyhow::ensure!(
            model == "step" || model == "cycle",
            "--model {model}: expected `step` or `cycle`"
        );
        expansion.runs.retain(|r| r.model.name() == model);
    }
    let mine: Vec<&spec::RunSpec> = expansion
        .runs
        .iter()
        .filter(|r| shard.is_none_or(|s| s.contains(r)))
        .collect();
    let done = experiment::store::read_lines(&out.join(experiment::store::RESULTS))?
        .into_iter()
        .filter_map(|(v, _)| v.get("key").and_then(|k| k.as_str()).map(str::to_string))
        .collect::<std::collections::HashSet<_>>();
    let pending: Vec<&spec::RunSpec> = mine
        .iter()
        .copied()
        .filter(|r| !done.contains(&r.key))
        .collect();
    let count = |model| pending.iter().filter(|r| r.model == model).count();
    let threads = rayon::current_num_threads();
    let estimate = |model| {
        let of: Vec<&spec::RunSpec> = pending
            .iter()
            .copied()
            .filter(|r| r.model == model)
            .collect();
        experiment::estimate_seconds(&expansion, &of, threads) / 60.0
    };
    println!(
        "{}: {} runs{} ({} step model, {} cycle model to run; {} already done in {}); \
         estimate {:.0} + {:.0} min on {threads} threads (step + cycle model; rough)",
        expansion.experiment.name,
        mine.len(),
        shard
            .map(|s| format!(" in shard {}/{}", s.index, s.count))
            .unwrap_or_default(),
        count(spec::Model::Step),
        count(spec::Model::Cycle),
        mine.len() - pending.len(),
        out.display(),
        estimate(spec::Model::Step),
        estimate(spec::Model::Cycle),
    );
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

/// The sweep results a `table` or `plot` reads: a sweep folder's results, keeping frames that
/// are multiples of `frame_step` (and one model's when given).
#[derive(Args)]
struct ResultsArgs {
    /// Sweep folder (holding results.jsonl).
    dir: PathBuf,
    /// Use only frames that are multiples of this (e.g. 2: every other frame).
    #[arg(long, default_value_t = 1)]
    frame_step: u64,
    /// Only this model's results (`step` or `cycle`).
    #[arg(long)]
    model: Option<String>,
}

impl ResultsArgs {
    fn read(&self) -> Result<Vec<serde_json::Value>> {
        anyhow::ensure!(self.frame_step >= 1, "--frame-step must be at least 1");
        if let Some(m) = &self.model {
            anyhow::ensure!(
                m == "step" || m == "cycle",
                "--model {m}: expected `step` or `cycle`"
            );
        }
        let mut lines = vizsim::tables::read_results(&self.dir.join("results.jsonl"))?;
        lines.retain(|l| {
            let frame_kept = l
                .get("frame")
                .and_then(|f| f.as_u64())
                .is_none_or(|f| f % self.frame_step == 0);
            let model_kept = self
                .model
                .as_deref()
                .is_none_or(|m| l.get("model").and_then(|v| v.as_str()) == Some(m));
            frame_kept && model_kept
        });
        Ok(lines)
    }
}

fn table(
    results: &ResultsArgs,
    metrics: &[vizsim::tables::Metric],
    rows: &[String],
    columns: &str,
    out: Option<&Path>,
) -> Result<()> {
    use vizsim::tables::{self, Metric};
    let dir = &results.dir;
    let lines = results.read()?;
    anyhow::ensure!(!lines.is_empty(), "{}: no results", dir.display());
    let out = out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| dir.join("tables"));
    let metrics = if metrics.is_empty() {
        vec![Metric::Fps, Metric::Cycles, Metric::Steps, Metric::PageHits]
    } else {
        metrics.to_vec()
    };
    let mut all_markdown = String::new();
    for model in ["step", "cycle"] {
        let of_model: Vec<&serde_json::Value> = lines
            .iter()
            .filter(|l| l.get("model").and_then(|m| m.as_str()) == Some(model))
            .collect();
        if of_model.is_empty() {
            continue;
        }
        for &metric in &metrics {
            if !of_model.iter().any(|l| metric.value(l).is_some()) {
                continue;
            }
            let clock = match model {
                "step" => "step model, published cost 12.5 ns per step",
                _ => "cycle-accurate model at its clock",
            };
            let frames: std::collections::BTreeSet<u64> = of_model
                .iter()
                .filter_map(|l| l.get("frame").and_then(|f| f.as_u64()))
                .collect();
            let title = format!(
                "{} ({clock}), mean over {} frame{}",
                metric.label(),
                frames.len(),
                if frames.len() == 1 { "" } else { "s" }
            );
            let rows_here: Vec<String> = rows.iter().filter(|r| *r != "model").cloned().collect();
            let table = tables::build(&of_model, metric, &rows_here, columns, title)?;
            let stem = out.join(format!("{model}-{}", metric.file_name()));
            let md = table.markdown();
            vizsim::output::write_atomically(&stem.with_extension("md"), |w| {
                std::io::Write::write_all(w, md.as_bytes())
            })?;
            let csv = table.csv();
            vizsim::output::write_atomically(&stem.with_extension("csv"), |w| {
                std::io::Write::write_all(w, csv.as_bytes())
            })?;
            if metric == Metric::Fps {
                println!("{md}");
            }
            all_markdown += &md;
            all_markdown += "\n";
        }
    }
    let summary = match &results.model {
        Some(m) => format!("tables-{m}.md"),
        None => "tables.md".to_string(),
    };
    vizsim::output::write_atomically(&out.join(summary), |w| {
        std::io::Write::write_all(w, all_markdown.as_bytes())
    })?;
    println!("tables -> {}", out.display());
    Ok(())
}

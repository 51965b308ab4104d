//! What an SDRAM command trace costs, and a way to write one before the CLI has the flag.
//!
//! ```text
//! cargo run --release --example command_trace -- [--dataset aneurism] [--data-dir DIR]
//!     [--view front] [--size 256] [--set section.field=value]...
//!     [--trace FILE[.gz]] [--trace-cycles A..B] [--check]
//!     [--vcd FILE] [--vcd-cycles A..B]
//! ```
//!
//! Simulates one frame as `vizsim sim` does (default hardware, the dataset's transfer function,
//! orthographic projection, ERT as configured) and prints the simulation's wall time; with
//! `--trace` it writes the command trace, with `--check` it then re-checks it and prints the
//! checker's report. Run it under `/usr/bin/time -v` for the peak memory (docs/waveforms.md).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use vizsim::arch::command_trace::{self, CommandTrace};
use vizsim::arch::pipeline::{simulate_with, SimOptions};
use vizsim::arch::sdram_module::SdramMemory;
use vizsim::arch::trace::{parse_cycle_window, Waveform};
use vizsim::camera::{Camera, Projection, View};
use vizsim::config::HardwareConfig;
use vizsim::functional::renderer::{FixedRenderer, Leaping};
use vizsim::render::RenderSettings;
use vizsim::transfer;
use vizsim::volume::dataset;

fn main() -> Result<()> {
    let mut dataset_name = "aneurism".to_string();
    let mut data_dir: Option<PathBuf> = None;
    let mut view = "front".to_string();
    let mut size = 256u32;
    let mut overrides = Vec::new();
    let mut trace: Option<PathBuf> = None;
    let mut trace_cycles = None;
    let mut check = false;
    let mut vcd: Option<PathBuf> = None;
    let mut vcd_cycles = 0..10_000;
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = || args.next().with_context(|| format!("{arg} needs a value"));
        match arg.as_str() {
            "--dataset" => dataset_name = value()?,
            "--data-dir" => data_dir = Some(value()?.into()),
            "--view" => view = value()?,
            "--size" => size = value()?.parse().context("--size")?,
            "--set" => overrides.push(value()?),
            "--trace" => trace = Some(value()?.into()),
            "--trace-cycles" => {
                trace_cycles = Some(parse_cycle_window("--trace-cycles", &value()?)?)
            }
            "--check" => check = true,
            "--vcd" => vcd = Some(value()?.into()),
            "--vcd-cycles" => vcd_cycles = parse_cycle_window("--vcd-cycles", &value()?)?,
            other => bail!("unknown argument `{other}` (see the file's doc comment)"),
        }
    }

    let config = HardwareConfig::load(None, &overrides)?;
    let dir = dataset::data_dir(data_dir.as_deref());
    let volume = dataset::load(&dataset_name, dir.as_deref())?;
    let tf = transfer::resolve("class", &volume.name)?;
    let settings = RenderSettings {
        ert_threshold: config
            .compositing
            .ert
            .then_some(config.compositing.ert_threshold as f32),
        ..RenderSettings::default()
    };
    let camera = Camera::for_volume(
        glam::Vec3::from(volume.extent()),
        View::parse(&view)?,
        Projection::Ortho,
        size,
        size,
    )?;
    let renderer = FixedRenderer::new(
        &volume,
        &tf,
        &settings,
        &config,
        Leaping::from_config(&config),
    )?;
    config
        .memory
        .check_covers(volume.dims, "hardware configuration")?;
    let mut memory = SdramMemory::new(
        &config.memory,
        &config.sdram,
        volume.dims,
        config.clock.frequency_mhz,
    );
    let mut command_trace = match &trace {
        Some(path) => {
            let mut t = CommandTrace::create(path, &config, trace_cycles.clone())?;
            t.note(&format!(
                "{} {view} {size}x{size}, transfer function class (cargo run --release --example command_trace)",
                volume.name
            ))?;
            Some(t)
        }
        None => None,
    };
    let mut waveform = match &vcd {
        Some(path) => Some(Waveform::for_config(path, &config, vcd_cycles)?),
        None => None,
    };

    let start = Instant::now();
    let result = simulate_with(
        &renderer,
        &camera,
        &renderer.skipper(),
        &mut memory,
        &config,
        SimOptions {
            waveform: waveform.as_mut(),
            command_trace: command_trace.as_mut(),
            ..SimOptions::default()
        },
    )?;
    let threads = thread_cpu_seconds();
    let lines = match command_trace {
        Some(t) => Some(t.finish()?),
        None => None,
    };
    if let Some(w) = waveform {
        w.finish()?;
    }
    let wall = start.elapsed().as_secs_f64();
    let s = &result.stats;
    let reads: u64 = memory.module_stats().iter().map(|m| m.reads).sum();
    println!(
        "{} {view} {size}x{size}: {} cycles, {} samples, {reads} READs; simulation {wall:.2} s \
         ({:.2} M cycles/s)",
        volume.name,
        s.cycles,
        s.samples,
        s.cycles as f64 / wall / 1e6
    );
    // CPU time by thread (the writer thread exists until `finish`): on a machine with a free
    // core for the writer, the main thread's time is the simulation's.
    let cpu: Vec<String> = threads
        .iter()
        .map(|(name, seconds)| format!("{name} {seconds:.2} s"))
        .collect();
    println!("CPU time by thread: {}", cpu.join(", "));
    if let (Some(path), Some(lines)) = (&trace, lines) {
        let bytes = std::fs::metadata(path)?.len();
        println!(
            "trace {}: {lines} commands, {:.1} MB ({:.1} bytes per command)",
            path.display(),
            bytes as f64 / 1e6,
            bytes as f64 / lines.max(1) as f64
        );
        if check {
            let start = Instant::now();
            let report = command_trace::check(path)?;
            println!("check: {:.2} s\n{report}", start.elapsed().as_secs_f64());
            if trace_cycles.is_none() && report.reads() != reads {
                bail!("{} READ lines but {reads} reads counted", report.reads());
            }
        }
    }
    Ok(())
}

/// (thread name, user + system CPU seconds) of this process's threads, from /proc (Linux).
fn thread_cpu_seconds() -> Vec<(String, f64)> {
    let Ok(tasks) = std::fs::read_dir("/proc/self/task") else {
        return Vec::new();
    };
    let ticks = 100.0; // USER_HZ
    let mut threads = Vec::new();
    for task in tasks.flatten() {
        let Ok(stat) = std::fs::read_to_string(task.path().join("stat")) else {
            continue;
        };
        let (Some(open), Some(close)) = (stat.find('('), stat.rfind(')')) else {
            continue;
        };
        let name = stat[open + 1..close].to_string();
        let fields: Vec<&str> = stat[close + 2..].split_whitespace().collect();
        // After the name: state is field 3, utime field 14, stime field 15.
        let time = |i: usize| fields.get(i - 3).and_then(|f| f.parse::<f64>().ok());
        if let (Some(user), Some(system)) = (time(14), time(15)) {
            threads.push((name, (user + system) / ticks));
        }
    }
    threads
}

//! `vizsim sim`: one frame clock by clock on the cycle-accurate pipeline.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use vizsim::run::{self, Memory, Model, Probes};

use super::{leaping_text, FrameArgs, HardwareArgs};

#[derive(Args)]
pub struct SimArgs {
    #[command(flatten)]
    frame: FrameArgs,
    /// Voxel memory model: `sdram` (modules, banks, FIFOs, overtaking) or `ideal` (fixed
    /// latency, unlimited bandwidth: the bound with free memory).
    #[arg(long, value_enum, default_value = "sdram")]
    memory: MemoryArg,
    /// Write a VCD waveform (GTKWave, Surfer) of the cycles given by --vcd-cycles.
    #[arg(long)]
    vcd: Option<PathBuf>,
    /// Cycle window of the waveform, A..B (default 0..10000).
    #[arg(long, requires = "vcd")]
    vcd_cycles: Option<String>,
    /// Write every SDRAM command to this CSV file (gzip when it ends in .gz): cycle, module,
    /// command, bank, row, column, tag; the timing parameters in its header (docs/waveforms.md).
    #[arg(long)]
    command_trace: Option<PathBuf>,
    /// Cycle window of the command trace, A..B (default: the whole frame).
    #[arg(long, requires = "command_trace")]
    trace_cycles: Option<String>,
    /// Sampled simulation: simulate this share of the frame's ray units in detail, in (0, 1]
    /// (e.g. 0.05), and estimate the cycles with a 95 % interval; the image stays exact
    /// (docs/sampling.md). Default: every cycle simulated.
    #[arg(long, value_name = "RATE", allow_negative_numbers = true)]
    sample: Option<f64>,
    /// Latency of the ideal memory (--memory ideal), in cycles (1..=1048576; default 6).
    #[arg(long, allow_negative_numbers = true, value_parser = super::unsigned::<u64>)]
    ideal_latency: Option<u64>,
    #[command(flatten)]
    hardware: HardwareArgs,
    /// Output PNG.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// The run and its statistics as JSON (`-`: to standard output, the text then to
    /// standard error).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Also check invariant (c): render the float reference and check every pixel of the
    /// frame (the cycle model's image, equal to the fixed-point model's) within the error
    /// bound the bit widths predict (docs/precision.md); exits non-zero, writing nothing, when
    /// a pixel is over its bound.
    #[arg(long)]
    check_bound: bool,
}

#[derive(clap::ValueEnum, Clone, Copy)]
enum MemoryArg {
    Sdram,
    Ideal,
}

pub fn run(args: SimArgs) -> Result<()> {
    let mut desc = args.frame.describe(Model::Cycle, &args.hardware)?;
    let ideal_latency = args.ideal_latency.unwrap_or(6);
    desc.memory = match args.memory {
        MemoryArg::Sdram => {
            anyhow::ensure!(
                args.ideal_latency.is_none(),
                "--ideal-latency applies to --memory ideal (the SDRAM model times every access)"
            );
            Memory::Sdram
        }
        MemoryArg::Ideal => Memory::Ideal {
            latency: ideal_latency,
        },
    };
    desc.sample = args
        .sample
        .map(|rate| vizsim::arch::sampling::Sampling::new(rate, "--sample"))
        .transpose()?;
    anyhow::ensure!(
        desc.sample.is_none() || (args.vcd.is_none() && args.command_trace.is_none()),
        "--sample cannot record a waveform or command trace (--vcd, --command-trace): they \
         need every cycle"
    );
    desc.validate()?;
    if args.check_bound {
        super::refuse_unbounded(&desc)?;
    }
    // Output paths are checked before the simulation, not after it.
    let outputs: Vec<(&str, &std::path::Path)> = [
        ("--output", &args.output),
        ("--json", &args.json),
        ("--vcd", &args.vcd),
        ("--command-trace", &args.command_trace),
    ]
    .into_iter()
    .filter_map(|(option, path)| Some((option, path.as_deref()?)))
    .collect();
    let inputs = args.frame.inputs(&args.hardware, &desc);
    let inputs: Vec<&std::path::Path> = inputs.iter().map(PathBuf::as_path).collect();
    vizsim::output::check_distinct(&inputs, &outputs)?;
    if let Some(path) = &args.output {
        vizsim::output::check_png_name("--output", path)?;
    }
    super::refuse_standard_output(&[
        ("--vcd", args.vcd.as_deref()),
        ("--command-trace", args.command_trace.as_deref()),
    ])?;
    for path in [&args.output, &args.json].into_iter().flatten() {
        vizsim::output::check_writable(path)?;
    }
    let config = &desc.hardware;
    let json = args.json.as_deref();
    super::say(
        json,
        &format!(
            "{}\n",
            args.hardware.resolved_line(config, desc.config_use())
        ),
    );
    // The ideal memory reads no SDRAM or memory field: a changed one would go unnoticed.
    if desc.memory != Memory::Sdram {
        let memory_fields: Vec<String> = config
            .differences_from_default()
            .into_iter()
            .filter(|d| d.starts_with("sdram.") || d.starts_with("memory."))
            .collect();
        if !memory_fields.is_empty() {
            super::say(
                json,
                &format!(
                    "note: without effect with --memory ideal: {}\n",
                    memory_fields.join(", ")
                ),
            );
        }
    }
    use vizsim::arch::command_trace::CommandTrace;
    use vizsim::arch::trace::{parse_cycle_window, parse_window, Waveform};
    anyhow::ensure!(
        args.command_trace.is_none() || desc.memory == Memory::Sdram,
        "--command-trace needs --memory sdram (the ideal memory issues no commands)"
    );
    // The outputs appear together or not at all (a JSON that cannot be written leaves no PNG,
    // trace or waveform); what the run says is printed after them (a failed print must not
    // leave the outputs' temporaries behind).
    use std::fmt::Write as _;
    let (said, warned) = vizsim::output::all_or_none(|| -> Result<(String, String)> {
        let (mut said, mut warned) = (String::new(), String::new());
        let mut command_trace = match &args.command_trace {
            Some(path) => {
                let window = args
                    .trace_cycles
                    .as_deref()
                    .map(|t| parse_cycle_window("--trace-cycles", t))
                    .transpose()?;
                let mut trace = CommandTrace::create(path, config, window)?;
                trace.note(&super::invocation())?;
                Some(trace)
            }
            None => None,
        };
        // The timescale follows the configured clock.
        let vcd_window = parse_window(args.vcd_cycles.as_deref().unwrap_or("0..10000"))?;
        let mut waveform = match &args.vcd {
            Some(path) => Some(Waveform::for_config(path, config, vcd_window.clone())?),
            None => None,
        };
        let probes = Probes {
            waveform: waveform.as_mut(),
            command_trace: command_trace.as_mut(),
            check_bound: args.check_bound,
            compare_float: true,
        };
        let report = run::run(&desc, args.frame.data.dir()?.as_deref(), probes)?;
        let bound_line = super::bound_line(&report)?;
        if let Some(t) = command_trace {
            let commands = t.finish()?;
            writeln!(
                said,
                "{commands} SDRAM commands -> {}",
                args.command_trace
                    .as_ref()
                    .map(|p| p.display().to_string())
                    .unwrap_or_default()
            )?;
        }
        let m = &report.measurements;
        if let Some(w) = waveform {
            w.finish()?;
            let last = m.cycles.unwrap_or_default();
            if vcd_window.start >= last {
                writeln!(
                    warned,
                    "warning: --vcd-cycles {}..{} begins after the frame's last cycle ({}): the \
                 waveform holds no cycle",
                    vcd_window.start,
                    vcd_window.end,
                    last.saturating_sub(1)
                )?;
            }
        }
        let stalls = m.stall_cycles.unwrap_or_default();
        let cycles = m.cycles.unwrap_or_default();
        let frame_time_ns = m.frame_time_ns.unwrap_or_default();
        let memory_line = match (desc.memory, m.page_hit_rate, m.avg_ns_per_voxel_access) {
            (Memory::Ideal { latency }, ..) => format!("; ideal memory, {latency} cycles latency"),
            (_, Some(hits), Some(ns)) => format!(
                "; SDRAM {} % row hits, {:.2} ns per voxel access",
                vizsim::text::percent(100.0 * hits, 1),
                ns
            ),
            _ => "; SDRAM: no voxel read".to_string(),
        };
        writeln!(
            said,
        "{}: {} cycles = {:.3} ms/frame = {} at {} MHz; {}, {} ray selection, ERT {}; \
         {} steps ({} samples of which {} leap samples, {} leaps), {} discarded after ERT{memory_line}; \
         stalls: queue empty {}, skip busy {}, memory {}, buffer full {}{}; {}",
        report.volume,
        cycles,
        frame_time_ns / 1e6,
        m.fps.map_or("no frame rate".to_string(), |fps| format!("{fps:.1} fps")),
        config.clock.frequency_mhz,
        leaping_text(&report.leaping),
        serde_json::to_value(report.ray_selection)?.as_str().unwrap_or("?"),
        if config.compositing.ert { "on" } else { "off" },
        m.steps,
        m.samples,
        m.leap_samples,
        m.leaps,
        m.discarded_after_ert.unwrap_or_default(),
        stalls.ray_queue_empty,
        stalls.skip_unit_busy,
        stalls.memory,
        stalls.compositing_buffer_full,
        volume_word_stalls(&stalls),
        simulation_rate(&report)
    )?;
        let unit_rays = report.run.sample.map_or(0, |s| s.unit_rays);
        if let (Some(e), Some(ci)) = (&report.sampling, m.cycles_ci95) {
            if e.measured_units == e.units {
                writeln!(
                    said,
                    "sampled (rate {:?}): every one of the {} units of {unit_rays} rays simulated, \
                     so the timing figures above are exact; the steps and samples are the \
                     functional model's, as in every sampled run (an exact run also counts those \
                     issued after ERT; docs/sampling.md){}",
                    m.sample_rate.unwrap_or_default(),
                    e.units,
                    if e.units < vizsim::arch::sampling::MIN_SAMPLED_UNITS {
                        format!(
                            " (a frame of fewer than {} units is simulated whole: sampling is \
                             validated from 256×256; docs/sampling.md)",
                            vizsim::arch::sampling::MIN_SAMPLED_UNITS
                        )
                    } else {
                        String::new()
                    }
                )?;
            } else {
                writeln!(
                    said,
                    "sampled (rate {:?}): the timing figures above are estimates; cycles {} ± \
                     {:.0} (95 % interval, ± {:.2} %); {} of {} units of {unit_rays} rays \
                     simulated in {} segments ({} rays, {} cycles with warm-ups of {} rays)",
                    m.sample_rate.unwrap_or_default(),
                    cycles,
                    ci,
                    100.0 * ci / cycles.max(1) as f64,
                    e.measured_units,
                    e.units,
                    e.segments,
                    e.simulated_rays,
                    e.simulated_cycles,
                    e.warmup_rays
                )?;
            }
        }
        for line in super::feature_lines(&report.run.hardware, &report.measurements)
            .into_iter()
            .chain(super::note_lines(&report))
        {
            writeln!(said, "{line}")?;
        }
        for line in super::reference_line(&report).into_iter().chain(bound_line) {
            writeln!(said, "{line}")?;
        }
        if let Some(path) = &args.output {
            report.frame.write_png(path)?;
        }
        if let Some(path) = &args.json {
            vizsim::output::write_json(path, &report)?;
        }
        Ok((said, warned))
    })?;
    super::say(json, &said);
    {
        use std::io::Write;
        // A standard error that cannot be written is no reason to fail a finished run.
        let _ = write!(std::io::stderr(), "{warned}");
    }
    Ok(())
}

/// How fast the frame was simulated. A sampled frame simulates only part of its cycles: its
/// rate of frame cycles timed per second (`sim_cycles_per_second`) is not a simulation speed,
/// so the cycles it did simulate are given too.
fn simulation_rate(report: &vizsim::run::RunReport) -> String {
    let rate = report.sim_cycles_per_second.unwrap_or_default() / 1e6;
    match &report.sampling {
        Some(e) => format!(
            "{rate:.1} M frame cycles/s timed ({:.1} M cycles/s simulated)",
            e.simulated_cycles as f64 / report.wall_seconds.max(1e-12) / 1e6
        ),
        None => format!("{rate:.1} M cycles/s simulated"),
    }
}

/// Stalls on words from volume memory, shown only for the structures that have them.
fn volume_word_stalls(stalls: &vizsim::arch::pipeline::StallCycles) -> String {
    let mut text = String::new();
    if stalls.distance_word > 0 {
        text += &format!(", distance word {}", stalls.distance_word);
    }
    if stalls.leap_word > 0 {
        text += &format!(", leap word {}", stalls.leap_word);
    }
    text
}

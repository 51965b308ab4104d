//! SDRAM command traces (written by the pipeline, re-checked from the file alone) and VCD
//! waveforms (clock, timescale, command and bank signals against the command trace).

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use vizsim::arch::address_map::RowPolicy;
use vizsim::arch::command_trace::{self, CommandTrace, Report};
use vizsim::arch::pipeline::{simulate_with, CycleResult, SimOptions};
use vizsim::arch::sdram_module::{ModuleStats, SdramMemory};
use vizsim::arch::trace::{VcdTime, Waveform};
use vizsim::camera::{Camera, Projection, View};
use vizsim::config::HardwareConfig;
use vizsim::functional::renderer::{FixedRenderer, Leaping};
use vizsim::render::RenderSettings;
use vizsim::transfer::TransferFunction;
use vizsim::volume::Volume;

struct Scene {
    volume: Volume,
    tf: TransferFunction,
    camera: Camera,
}

/// A small frame with a few refresh intervals, row conflicts and a busy memory.
fn scene() -> Scene {
    let volume = common::ball(32);
    let tf = common::tf(&[
        (0.0, [0.0; 4]),
        (60.0, [0.0; 4]),
        (200.0, [1.0, 0.8, 0.2, 0.8]),
    ]);
    let camera = common::camera(&volume, View::Orbit { k: 3, n: 72 }, Projection::Ortho, 32);
    Scene { volume, tf, camera }
}

impl Scene {
    fn run(&self, config: &HardwareConfig, options: SimOptions) -> (CycleResult, Vec<ModuleStats>) {
        let renderer = FixedRenderer::new(
            &self.volume,
            &self.tf,
            &RenderSettings::default(),
            config,
            Leaping::None,
        )
        .unwrap();
        let mut memory = SdramMemory::new(
            &config.memory,
            &config.sdram,
            self.volume.dims,
            config.clock.frequency_mhz,
        );
        let result = simulate_with(
            &renderer,
            &self.camera,
            &renderer.skipper(),
            &mut memory,
            config,
            options,
        )
        .unwrap();
        (result, memory.module_stats())
    }

    /// Runs with a command trace (and optionally a waveform) and returns the run.
    fn traced(
        &self,
        config: &HardwareConfig,
        path: &Path,
        window: Option<std::ops::Range<u64>>,
        waveform: Option<&mut Waveform>,
    ) -> (CycleResult, Vec<ModuleStats>, u64) {
        let mut trace = CommandTrace::create(path, config, window).unwrap();
        let run = self.run(
            config,
            SimOptions {
                waveform,
                command_trace: Some(&mut trace),
                ..SimOptions::default()
            },
        );
        let lines = trace.finish().unwrap();
        (run.0, run.1, lines)
    }
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn configs() -> Vec<(&'static str, HardwareConfig)> {
    let open = HardwareConfig::default_config();
    let mut close = open.clone();
    close.memory.row_policy = RowPolicy::Close;
    close.memory.overtaking = false;
    vec![("open", open), ("close", close)]
}

fn sum(stats: &[ModuleStats], f: fn(&ModuleStats) -> u64) -> u64 {
    stats.iter().map(f).sum()
}

#[test]
fn trace_of_a_small_frame_passes_the_check_and_counts_every_command() {
    let scene = scene();
    let dir = temp_dir("trace-pass");
    for (name, config) in configs() {
        let path = dir.join(format!("{name}.csv"));
        let (traced, stats, lines) = scene.traced(&config, &path, None, None);
        let (plain, plain_stats) = scene.run(&config, SimOptions::default());
        assert!(traced.frame.pixels == plain.frame.pixels, "{name}");
        assert_eq!(traced.stats, plain.stats, "{name}: tracing changes nothing");
        assert_eq!(stats, plain_stats, "{name}");
        assert!(
            traced.stats.cycles > 3 * 1562,
            "{name}: the frame must span refreshes ({} cycles)",
            traced.stats.cycles
        );

        let report = command_trace::check(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        eprintln!("{name}: {report}");
        assert_eq!(
            report.reads(),
            sum(&stats, |s| s.reads),
            "{name}: READ lines"
        );
        assert_eq!(report.reads(), traced.stats.samples * 4, "{name}");
        assert_eq!(report.commands[0], sum(&stats, |s| s.activates), "{name}");
        assert_eq!(report.commands[2], sum(&stats, |s| s.precharges), "{name}");
        assert_eq!(report.commands[3], sum(&stats, |s| s.refreshes), "{name}");
        assert_eq!(report.total(), lines);
        for (m, s) in stats.iter().enumerate() {
            assert_eq!(
                report.per_module[m],
                [s.activates, s.reads, s.precharges, s.refreshes],
                "{name} module {m}"
            );
        }
        assert_eq!(report.end_cycle, Some(traced.stats.cycles));
        assert!(report.refresh_intervals_checked >= 4 * 3, "{name}");
        // Every rule was exercised.
        for r in &report.rules {
            assert!(r.checked > 0, "{name}: {r:?} never checked");
            assert!(r.min_gap.unwrap() >= r.rule.latency as u64, "{name}: {r:?}");
        }
    }
}

/// Reads a trace's lines; `None` for comment lines.
fn read_lines(path: &Path) -> Vec<String> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(str::to_string)
        .collect()
}

/// Moves the command of line `line` (1-based) one cycle earlier, keeps the lines in cycle order
/// and writes the result to `out`.
fn move_one_cycle_early(lines: &[String], line: u64, out: &Path) -> u64 {
    let index = line as usize - 1;
    let header = lines
        .iter()
        .position(|l| l == command_trace::COLUMNS)
        .unwrap();
    let mut commands: Vec<(u64, String)> = lines[header + 1..]
        .iter()
        .filter(|l| !l.starts_with('#'))
        .map(|l| (l.split(',').next().unwrap().parse().unwrap(), l.clone()))
        .collect();
    let (cycle, rest) = lines[index].split_once(',').unwrap();
    let moved: u64 = cycle.parse::<u64>().unwrap() - 1;
    let position = commands
        .iter()
        .position(|(_, l)| *l == lines[index])
        .unwrap();
    commands[position] = (moved, format!("{moved},{rest}"));
    commands.sort_by_key(|&(c, _)| c); // stable: the moved line stays after its cycle's others
    let mut text: Vec<String> = lines[..=header].to_vec();
    text.extend(commands.into_iter().map(|(_, l)| l));
    text.extend(lines.iter().filter(|l| l.starts_with("# end:")).cloned());
    std::fs::write(out, text.join("\n") + "\n").unwrap();
    moved
}

#[test]
fn a_command_moved_one_cycle_early_is_rejected_by_its_rule() {
    let scene = scene();
    let dir = temp_dir("trace-early");
    let mut rejected: BTreeMap<&'static str, usize> = BTreeMap::new();
    for (name, config) in configs() {
        let path = dir.join(format!("{name}.csv"));
        scene.traced(&config, &path, None, None);
        let report = command_trace::check(&path).unwrap();
        let lines = read_lines(&path);
        for r in &report.rules {
            let Some(line) = r.first_at_limit else {
                continue;
            };
            let bad = dir.join(format!("{name}-{}-{}.csv", r.rule.parameter, line));
            let moved = move_one_cycle_early(&lines, line, &bad);
            let mutated = command_trace::analyze(&bad).unwrap();
            assert!(
                mutated
                    .violations
                    .iter()
                    .any(|v| v.rule == r.rule.parameter && v.cycle == moved),
                "{name}: moving line {line} ({}) one cycle early is not caught by {}: {:?}",
                lines[line as usize - 1],
                r.rule.parameter,
                mutated.violations
            );
            assert!(command_trace::check(&bad).is_err());
            *rejected.entry(r.rule.parameter).or_default() += 1;
            std::fs::remove_file(&bad).unwrap();
        }
    }
    eprintln!("rules caught one cycle early: {rejected:?}");
    // tRRD is never at its limit in these traces (the controller's next ACT waits at least
    // for the READ of the previous one: min gap 3 > 2), nor REF -> REF (an interval apart);
    // `every_rule_is_tight_in_a_handwritten_trace` covers them.
    for rule in [
        "t_rcd",
        "t_rp",
        "t_ras",
        "t_rc",
        "t_ccd",
        "t_rfc",
        "read_to_pre",
    ] {
        assert!(rejected.contains_key(rule), "no tight {rule} in the traces");
    }
}

/// Each rule of the table on its own: legal at its limit, rejected one cycle early.
#[test]
fn every_rule_is_tight_in_a_handwritten_trace() {
    let dir = temp_dir("trace-tight");
    let t = HardwareConfig::default_config().sdram;
    let cases: [(&str, &str, &str, u64); 10] = [
        ("t_rcd", "0,0,ACT,0,5,,\n", "0,READ,0,5,0,0", t.t_rcd as u64),
        ("t_ras", "0,0,ACT,0,5,,\n", "0,PRE,0,5,,", t.t_ras as u64),
        (
            "t_rc",
            "0,0,ACT,0,5,,\n5,0,PRE,0,5,,\n",
            "0,ACT,0,6,,",
            t.t_rc as u64,
        ),
        ("t_rrd", "0,0,ACT,0,5,,\n", "0,ACT,1,5,,", t.t_rrd as u64),
        (
            "t_rp",
            "0,0,ACT,0,5,,\n10,0,PRE,0,5,,\n",
            "0,ACT,0,6,,",
            10 + t.t_rp as u64,
        ),
        (
            "t_rp",
            "0,0,ACT,0,5,,\n1600,0,PRE,0,5,,\n",
            "0,REF,,,,",
            1600 + t.t_rp as u64,
        ),
        (
            "t_ccd",
            "0,0,ACT,0,5,,\n2,0,READ,0,5,0,0\n",
            "0,READ,0,5,1,1",
            2 + t.t_ccd as u64,
        ),
        (
            "read_to_pre",
            "0,0,ACT,0,5,,\n8,0,READ,0,5,0,0\n",
            "0,PRE,0,5,,",
            9,
        ),
        (
            "t_rfc",
            "1562,0,REF,,,,\n",
            "0,ACT,0,5,,",
            1562 + t.t_rfc as u64,
        ),
        (
            "t_rfc",
            "1562,0,REF,,,,\n",
            "0,REF,,,,",
            1562 + t.t_rfc as u64,
        ),
    ];
    for (i, (rule, before, command, at)) in cases.into_iter().enumerate() {
        let trace = |cycle: u64| {
            let path = handwritten(
                &dir,
                &format!("{i}-{cycle}"),
                None,
                &format!("{before}{cycle},{command}\n"),
            );
            violations(&path)
        };
        let on_time = trace(at);
        assert!(
            !on_time
                .iter()
                .any(|v| v == rule || v == "state" || v == "bus"),
            "case {i}: {rule} on time: {on_time:?}"
        );
        let early = trace(at - 1);
        assert!(
            early.iter().any(|v| v == rule),
            "case {i}: {rule} one cycle early: {early:?}"
        );
    }
}

/// A hand-written trace with the default header.
fn handwritten(
    dir: &Path,
    name: &str,
    window: Option<std::ops::Range<u64>>,
    body: &str,
) -> PathBuf {
    let path = dir.join(format!("{name}.csv"));
    let trace = CommandTrace::create(&path, &HardwareConfig::default_config(), window).unwrap();
    trace.finish().unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let header: String = text
        .lines()
        .take_while(|l| !l.starts_with("# end:"))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&path, header + body).unwrap();
    path
}

fn violations(path: &Path) -> Vec<String> {
    let report: Report = command_trace::analyze(path).unwrap();
    report.violations.iter().map(|v| v.rule.clone()).collect()
}

#[test]
fn state_bus_and_refresh_rules_are_checked() {
    let dir = temp_dir("trace-rules");
    let case = |name: &str, body: &str| violations(&handwritten(&dir, name, None, body));
    // Legal: ACT, READ at tRCD, READ, PRE at tRAS, ACT at tRC; a REF after PRE + tRP.
    assert_eq!(
        case(
            "legal",
            "0,0,ACT,1,7,,\n2,0,READ,1,7,3,0\n3,0,READ,1,7,4,1\n5,0,PRE,1,7,,\n7,0,ACT,1,8,,\n\
             12,0,PRE,1,8,,\n1562,0,REF,,,,\n# end: cycle 1600, 7 commands\n"
        ),
        Vec::<String>::new()
    );
    assert_eq!(case("read-closed", "5,0,READ,1,7,3,0\n"), ["state"]);
    assert_eq!(
        case("read-other-row", "0,0,ACT,1,7,,\n3,0,READ,1,8,3,0\n"),
        ["state"]
    );
    assert_eq!(
        case("act-open", "0,0,ACT,1,7,,\n9,0,ACT,1,8,,\n"),
        ["state"]
    );
    assert_eq!(case("pre-closed", "5,0,PRE,1,7,,\n"), ["state"]);
    assert_eq!(
        case("ref-open", "0,0,ACT,1,7,,\n1562,0,REF,,,,\n"),
        ["state"]
    );
    assert_eq!(
        case("bus", "0,0,ACT,1,7,,\n0,0,ACT,2,7,,\n"),
        ["bus", "t_rrd"]
    );
    assert_eq!(
        case("other-module-same-cycle", "0,0,ACT,1,7,,\n0,1,ACT,1,7,,\n"),
        Vec::<String>::new()
    );
    assert_eq!(case("order", "5,0,ACT,1,7,,\n4,1,ACT,1,7,,\n"), ["order"]);
    assert_eq!(case("early-refresh", "1000,0,REF,,,,\n"), ["refresh"]);
    assert_eq!(
        case("double-refresh", "1562,0,REF,,,,\n1600,0,REF,,,,\n"),
        ["refresh"]
    );
    // Module 0 refreshed in both intervals, module 1 in none: two missing.
    assert_eq!(
        case(
            "missing-refresh",
            "1562,0,REF,,,,\n3124,0,REF,,,,\n# end: cycle 4700, 2 commands\n"
        ),
        ["refresh", "refresh", "refresh", "refresh", "refresh", "refresh"]
    );
    // A window that starts late: the banks' first commands define their state.
    let path = handwritten(
        &dir,
        "window",
        Some(1000..2000),
        "1000,0,READ,1,7,3,0\n1001,0,PRE,2,9,,\n1005,0,PRE,1,7,,\n1007,0,ACT,1,8,,\n",
    );
    assert_eq!(violations(&path), Vec::<String>::new());
    let path = handwritten(&dir, "outside", Some(1000..2000), "999,0,ACT,1,7,,\n");
    assert_eq!(violations(&path), ["window"]);
    // Malformed lines are errors that name the file and line.
    let path = handwritten(&dir, "malformed", None, "0,0,ACT,1,,,\n");
    let err = command_trace::analyze(&path).unwrap_err().to_string();
    assert!(
        err.contains("malformed.csv") && err.contains("ACT has fields"),
        "{err}"
    );
    let path = handwritten(&dir, "bad-bank", None, "0,0,ACT,4,7,,\n");
    let err = command_trace::analyze(&path).unwrap_err().to_string();
    assert!(err.contains("bank 4 is out of range"), "{err}");
    std::fs::write(dir.join("empty.csv"), "").unwrap();
    assert!(command_trace::analyze(&dir.join("empty.csv")).is_err());
}

#[test]
fn window_and_gzip_write_the_same_commands() {
    let scene = scene();
    let dir = temp_dir("trace-window");
    let config = HardwareConfig::default_config();
    let full = dir.join("full.csv");
    let (run, _, _) = scene.traced(&config, &full, None, None);
    let gz = dir.join("full.csv.gz");
    scene.traced(&config, &gz, None, None);
    let mut text = String::new();
    use std::io::Read;
    flate2::read::GzDecoder::new(std::fs::File::open(&gz).unwrap())
        .read_to_string(&mut text)
        .unwrap();
    assert_eq!(text, std::fs::read_to_string(&full).unwrap());
    let gz_report = command_trace::check(&gz).unwrap();
    assert_eq!(gz_report.reads(), run.stats.samples * 4);

    let window = 2000..5000;
    let part = dir.join("part.csv");
    scene.traced(&config, &part, Some(window.clone()), None);
    let commands = |path: &Path| -> Vec<String> {
        read_lines(path)
            .into_iter()
            .filter(|l| l.chars().next().is_some_and(|c| c.is_ascii_digit()))
            .collect()
    };
    let expected: Vec<String> = commands(&full)
        .into_iter()
        .filter(|l| window.contains(&l.split(',').next().unwrap().parse().unwrap()))
        .collect();
    assert!(!expected.is_empty());
    assert_eq!(commands(&part), expected);
    let report = command_trace::check(&part).unwrap();
    assert_eq!(report.header.window, window);
    assert!(report.refresh_intervals_checked > 0);
    // No temporary files left behind.
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["full.csv", "full.csv.gz", "part.csv"]);
}

#[test]
fn a_failed_or_abandoned_trace_leaves_no_file_and_errors_name_the_path() {
    let dir = temp_dir("trace-fail");
    let config = HardwareConfig::default_config();
    let path = dir.join("abandoned.csv.gz");
    let trace = CommandTrace::create(&path, &config, None).unwrap();
    drop(trace);
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
    // A folder that cannot be created (a file is in the way).
    std::fs::write(dir.join("file"), "").unwrap();
    let bad = dir.join("file").join("t.csv");
    let err = CommandTrace::create(&bad, &config, None)
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains(&dir.join("file").display().to_string()),
        "{err}"
    );
    let err = command_trace::check(&dir.join("missing.csv"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("missing.csv"), "{err}");
    // An abandoned waveform leaves nothing either.
    let vcd = Waveform::for_config(&dir.join("w.vcd"), &config, 0..10).unwrap();
    drop(vcd);
    assert!(!dir.join("w.vcd").exists());
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1, "only `file`");
}

// ---------------------------------------------------------------------------------------------
// Waveforms

/// A VCD file's value changes: per signal (scope path joined by '.'), (time, value) in order.
struct Vcd {
    timescale: (u32, vcd::TimescaleUnit),
    changes: BTreeMap<String, Vec<(u64, String)>>,
}

fn read_vcd(path: &Path) -> Vcd {
    use vcd::{Command, ScopeItem};
    let mut parser = vcd::Parser::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let header = parser.parse_header().unwrap();
    let mut names = BTreeMap::new();
    fn walk(items: &[ScopeItem], prefix: &str, names: &mut BTreeMap<vcd::IdCode, String>) {
        for item in items {
            match item {
                ScopeItem::Scope(s) => walk(&s.items, &format!("{prefix}{}.", s.identifier), names),
                ScopeItem::Var(v) => {
                    names.insert(v.code, format!("{prefix}{}", v.reference));
                }
                _ => {}
            }
        }
    }
    walk(&header.items, "", &mut names);
    let mut changes: BTreeMap<String, Vec<(u64, String)>> = BTreeMap::new();
    let mut time = 0;
    for command in parser {
        let (id, value) = match command.unwrap() {
            Command::Timestamp(t) => {
                time = t;
                continue;
            }
            Command::ChangeScalar(id, v) => (id, v.to_string()),
            Command::ChangeVector(id, v) => (id, v.to_string()),
            Command::ChangeString(id, v) => (id, v),
            _ => continue,
        };
        changes
            .entry(names[&id].clone())
            .or_default()
            .push((time, value));
    }
    Vcd {
        timescale: header.timescale.unwrap(),
        changes,
    }
}

impl Vcd {
    /// The signal's value at every rising edge of `cycles`.
    fn at_cycles(&self, signal: &str, time: &VcdTime, cycles: std::ops::Range<u64>) -> Vec<String> {
        let changes = &self.changes[signal];
        cycles
            .map(|c| {
                let t = time.edge(c, false);
                let i = changes.partition_point(|&(ct, _)| ct <= t);
                changes[i - 1].1.clone()
            })
            .collect()
    }
}

#[test]
fn waveform_clock_follows_the_frequency() {
    let dir = temp_dir("vcd-clock");
    use vcd::TimescaleUnit::{NS, PS};
    // (clock, timescale, period in timescale units)
    for (mhz, timescale, period) in [
        (100.0, (1, NS), 10.0),
        (133.0, (1, PS), 1e6 / 133.0),
        (125.0, (1, NS), 8.0),
        (250.0, (1, NS), 4.0),
        // 2.5 ns: half a period is 1.25 ns = 12.5 × 100 ps, a whole 125 × 10 ps.
        (400.0, (10, PS), 250.0),
    ] {
        let time = VcdTime::for_frequency(mhz);
        let path = dir.join(format!("{mhz}.vcd"));
        let mut w = Waveform::create_at(&path, 4, 10..20, mhz).unwrap();
        for cycle in 0..30 {
            w.sample(cycle, &Default::default()).unwrap();
        }
        w.finish().unwrap();
        let vcd = read_vcd(&path);
        assert_eq!(vcd.timescale, timescale, "{mhz} MHz");
        assert_eq!(time.unit_ps() * period, 1e6 / mhz, "{mhz} MHz");
        for c in [10u64, 11, 19, 20, 123_456_789] {
            let want = c as f64 * period;
            assert!(
                (time.edge(c, false) as f64 - want).abs() <= 0.5,
                "{mhz} MHz cycle {c}: {} vs {want}",
                time.edge(c, false)
            );
        }
        // The clock: high at each cycle's start, low half a period later, for every cycle of
        // the window, and a last rising edge ending the window.
        let clk = &vcd.changes["pipeline.clk"];
        let mut want = Vec::new();
        for c in 10..20 {
            want.push((time.edge(c, false), "1".to_string()));
            want.push((time.edge(c, true), "0".to_string()));
        }
        want.push((time.edge(20, false), "1".to_string()));
        assert_eq!(clk, &want, "{mhz} MHz");
        let cycles = vcd.at_cycles("pipeline.cycle", &time, 10..20);
        let numbers: Vec<u64> = cycles
            .iter()
            .map(|b| u64::from_str_radix(b, 2).unwrap())
            .collect();
        assert_eq!(numbers, (10..20).collect::<Vec<_>>());
    }
    // 133 MHz in picoseconds, rounded per edge from the cycle number.
    let t = VcdTime::for_frequency(133.0);
    assert_eq!(t.edge(1, false), 7519);
    assert_eq!(t.edge(3, false), 22556);
    assert_eq!(t.edge(1_000_000, false), 7_518_796_992);
}

#[test]
fn waveform_commands_and_banks_match_the_command_trace() {
    let scene = scene();
    let dir = temp_dir("vcd-commands");
    for mhz in [100.0, 133.0] {
        let mut config = HardwareConfig::default_config();
        config.clock.frequency_mhz = mhz;
        let window = 1000..3500;
        let vcd_path = dir.join(format!("w{mhz}.vcd"));
        let csv_path = dir.join(format!("t{mhz}.csv"));
        let mut waveform = Waveform::for_config(&vcd_path, &config, window.clone()).unwrap();
        let (traced, _, lines) = scene.traced(
            &config,
            &csv_path,
            Some(window.clone()),
            Some(&mut waveform),
        );
        waveform.finish().unwrap();
        let (plain, _) = scene.run(&config, SimOptions::default());
        assert!(traced.frame.pixels == plain.frame.pixels);
        assert_eq!(traced.stats.cycles, plain.stats.cycles);
        assert!(lines > 1000, "{lines} commands in the window");

        let time = VcdTime::for_frequency(mhz);
        let vcd = read_vcd(&vcd_path);
        for signal in [
            "pipeline.ray_queue_occupancy",
            "pipeline.issue_valid",
            "pipeline.compositing_buffer",
            "pipeline.ert_event",
            "pipeline.module3.address_fifo",
            "pipeline.module3.command",
        ] {
            assert!(vcd.changes.contains_key(signal), "missing {signal}");
        }
        // (cycle, module, command, bank) from the waveform...
        let mut from_vcd = Vec::new();
        for m in 0..4 {
            let scope = format!("pipeline.module{m}");
            let cmd = vcd.at_cycles(&format!("{scope}.cmd"), &time, window.clone());
            let bank = vcd.at_cycles(&format!("{scope}.bank"), &time, window.clone());
            let code = vcd.at_cycles(&format!("{scope}.command"), &time, window.clone());
            let column = vcd.at_cycles(&format!("{scope}.column"), &time, window.clone());
            let bits: Vec<Vec<String>> = ["act", "read", "pre", "ref"]
                .iter()
                .map(|k| vcd.at_cycles(&format!("{scope}.{k}"), &time, window.clone()))
                .collect();
            for (i, c) in window.clone().enumerate() {
                let names = ["ACT", "READ", "PRE", "REF"];
                let on: Vec<&str> = (0..4)
                    .filter(|&k| bits[k][i] == "1")
                    .map(|k| names[k])
                    .collect();
                let code = u64::from_str_radix(&code[i], 2).unwrap();
                if cmd[i] == "NOP" {
                    assert!(on.is_empty() && code == 0 && bank[i] == "zzzz", "cycle {c}");
                    assert_eq!(column[i], "z".repeat(16));
                    continue;
                }
                assert_eq!(on, [cmd[i].as_str()], "cycle {c} module {m}");
                assert_eq!(names[code as usize - 1], cmd[i]);
                let bank = if cmd[i] == "REF" {
                    assert_eq!(bank[i], "zzzz");
                    String::new()
                } else {
                    u64::from_str_radix(&bank[i], 2).unwrap().to_string()
                };
                let column = if cmd[i] == "READ" {
                    u64::from_str_radix(&column[i], 2).unwrap().to_string()
                } else {
                    assert_eq!(column[i], "z".repeat(16));
                    String::new()
                };
                from_vcd.push((c, m, cmd[i].clone(), bank, column));
            }
        }
        from_vcd.sort();
        // ...equals the command trace's.
        let mut from_trace: Vec<(u64, usize, String, String, String)> = read_lines(&csv_path)
            .into_iter()
            .filter(|l| l.chars().next().is_some_and(|c| c.is_ascii_digit()))
            .map(|l| {
                let f: Vec<&str> = l.split(',').collect();
                (
                    f[0].parse().unwrap(),
                    f[1].parse().unwrap(),
                    f[2].to_string(),
                    f[3].to_string(),
                    f[5].to_string(),
                )
            })
            .collect();
        from_trace.sort();
        assert_eq!(from_vcd.len() as u64, lines);
        assert_eq!(from_vcd, from_trace, "{mhz} MHz");
        let names = ["ACT", "READ", "PRE", "REF"];
        for name in names {
            assert!(
                from_trace.iter().any(|e| e.2 == name),
                "{mhz} MHz: no {name} in the window"
            );
        }
    }
}

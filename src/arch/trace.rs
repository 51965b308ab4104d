//! Waveforms: a VCD file (GTKWave, Surfer) of the pipeline's signals over a window of cycles.
//! The pipeline builds a `Probe` only when a waveform is being recorded, so a run without
//! `--vcd` pays one `Option` check per cycle. Signals and how to view them: docs/waveforms.md.
//!
//! Time: `clk` rises at the start of each cycle and falls half a period later; the timescale
//! follows the clock (`VcdTime`), so the viewer's time axis is real time and cycle c starts at
//! c × period. Every other signal changes only on rising edges.

use std::io::Write;
use std::ops::Range;
use std::path::{Path, PathBuf};

use vcd::{IdCode, TimescaleUnit, Value, VarType};

use crate::config::HardwareConfig;
use crate::error::{Error, Result};
use crate::output::PendingFile;

/// Per-module signals. `command`: 0 none, 1 ACT, 2 READ, 3 PRE, 4 REF (issued this cycle).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ModuleProbe {
    pub command: u64,
    /// Bank of this cycle's command (None: no command, or REF, which has no bank).
    pub bank: Option<u64>,
    /// Column of this cycle's READ (None: no READ).
    pub column: Option<u64>,
    /// Row of the most recent ACT.
    pub open_row: u64,
    pub address_fifo: u64,
    pub voxel_fifo: u64,
}

/// Names of the `command` codes: the string signal `cmd` shows these.
pub const COMMAND_NAMES: [&str; 5] = ["NOP", "ACT", "READ", "PRE", "REF"];

/// The signals of one cycle.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Probe {
    pub ray_queue_occupancy: u64,
    pub issue_valid: bool,
    /// Ray id (pixel index) of the issued step.
    pub issue_ray: u64,
    /// The issued step was a leap (no sample).
    pub leap: bool,
    /// The occupancy lookup said the position's sub-cube is occupied.
    pub occupied: bool,
    pub compositing_buffer: u64,
    pub ert_event: bool,
    pub retire_event: bool,
    pub modules: Vec<ModuleProbe>,
}

/// Reads one pipeline signal from a probe.
type Signal = dyn Fn(&Probe) -> u64;

/// The VCD time of clock edges. The timescale is the coarsest of 1 ns, 100 ps, 10 ps and 1 ps in
/// which half a clock period is a whole number (100 MHz: 1 ns, a cycle is 10 units); when none
/// is (133 MHz: 3759.398... ps), 1 ps, and each edge's time is rounded to the nearest ps from
/// its cycle number (the error stays below 0.5 ps and never accumulates).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VcdTime {
    /// The timescale: `magnitude` × `unit`.
    pub magnitude: u32,
    pub unit: TimescaleUnit,
    /// Half a clock period in timescale units (may be fractional: then edges are rounded).
    pub half_period: f64,
}

impl VcdTime {
    pub fn for_frequency(frequency_mhz: f64) -> VcdTime {
        let half_ps = 5e5 / frequency_mhz;
        for (magnitude, unit, ps) in [
            (1, TimescaleUnit::NS, 1000.0),
            (100, TimescaleUnit::PS, 100.0),
            (10, TimescaleUnit::PS, 10.0),
        ] {
            let units = half_ps / ps;
            if units >= 1.0 && (units - units.round()).abs() < 1e-9 * units.max(1.0) {
                return VcdTime {
                    magnitude,
                    unit,
                    half_period: units.round(),
                };
            }
        }
        VcdTime {
            magnitude: 1,
            unit: TimescaleUnit::PS,
            half_period: half_ps,
        }
    }

    /// The time of cycle `cycle`'s rising edge (`falling`: its falling edge), in timescale units.
    pub fn edge(&self, cycle: u64, falling: bool) -> u64 {
        ((2 * cycle + falling as u64) as f64 * self.half_period).round() as u64
    }

    /// The timescale in picoseconds.
    pub fn unit_ps(&self) -> f64 {
        let unit = match self.unit {
            TimescaleUnit::S => 1e12,
            TimescaleUnit::MS => 1e9,
            TimescaleUnit::US => 1e6,
            TimescaleUnit::NS => 1e3,
            TimescaleUnit::PS => 1.0,
            TimescaleUnit::FS => 1e-3,
        };
        self.magnitude as f64 * unit
    }
}

struct ModuleIds {
    command: IdCode,
    name: IdCode,
    kinds: [IdCode; 4],
    bank: IdCode,
    column: IdCode,
    open_row: IdCode,
    address_fifo: IdCode,
    voxel_fifo: IdCode,
}

/// Width of the `column` signal (columns <= 65536).
const COLUMN_BITS: u32 = 16;

/// Width of the `cycle` signal.
const CYCLE_BITS: u32 = 40;

pub struct Waveform {
    writer: vcd::Writer<PendingFile>,
    path: PathBuf,
    window: Range<u64>,
    time: VcdTime,
    clk: IdCode,
    cycle: IdCode,
    ids: [IdCode; 8],
    modules: Vec<ModuleIds>,
    last: Option<Probe>,
    last_cycle: Option<u64>,
}

impl Waveform {
    /// Starts a VCD file for `config`'s memory modules at its clock frequency, recording cycles
    /// in `window`. The file is written under a temporary name and renamed by `finish`; a
    /// waveform dropped without `finish` leaves no file.
    pub fn for_config(
        path: &Path,
        config: &HardwareConfig,
        window: Range<u64>,
    ) -> Result<Waveform> {
        Waveform::create_at(
            path,
            config.memory.modules(),
            window,
            config.clock.frequency_mhz,
        )
    }

    /// `create_at` at 100 MHz (the default clock). Prefer `for_config`.
    pub fn create(path: &Path, modules: usize, window: Range<u64>) -> Result<Waveform> {
        Waveform::create_at(path, modules, window, 100.0)
    }

    /// Starts a VCD file for `modules` memory modules clocked at `frequency_mhz`, recording
    /// cycles in `window`.
    pub fn create_at(
        path: &Path,
        modules: usize,
        window: Range<u64>,
        frequency_mhz: f64,
    ) -> Result<Waveform> {
        if !(frequency_mhz > 0.0 && frequency_mhz <= 1e5) {
            return Err(Error::Invalid(format!(
                "{}: clock frequency {frequency_mhz:?} MHz is out of range (0, 1e5]",
                path.display()
            )));
        }
        let file = PendingFile::create(path)?;
        let time = VcdTime::for_frequency(frequency_mhz);
        let mut w = vcd::Writer::new(file);
        let e = io(path);
        let period_ns = 1e3 / frequency_mhz;
        w.comment(&format!(
            "vizsim pipeline waveform: clock {frequency_mhz} MHz (period {period_ns} ns), cycles {}..{}; \
             signals: docs/waveforms.md",
            window.start, window.end
        ))
        .map_err(&e)?;
        w.timescale(time.magnitude, time.unit).map_err(&e)?;
        w.add_module("pipeline").map_err(&e)?;
        let clk = w.add_wire(1, "clk").map_err(&e)?;
        let cycle = w.add_wire(CYCLE_BITS, "cycle").map_err(&e)?;
        let ids = [
            w.add_wire(16, "ray_queue_occupancy").map_err(&e)?,
            w.add_wire(1, "issue_valid").map_err(&e)?,
            w.add_wire(32, "issue_ray").map_err(&e)?,
            w.add_wire(1, "leap").map_err(&e)?,
            w.add_wire(1, "occupancy_lookup_occupied").map_err(&e)?,
            w.add_wire(16, "compositing_buffer").map_err(&e)?,
            w.add_wire(1, "ert_event").map_err(&e)?,
            w.add_wire(1, "retire_event").map_err(&e)?,
        ];
        let mut module_ids = Vec::new();
        for m in 0..modules {
            w.add_module(&format!("module{m}")).map_err(&e)?;
            module_ids.push(ModuleIds {
                command: w.add_wire(3, "command").map_err(&e)?,
                name: w.add_var(VarType::String, 1, "cmd", None).map_err(&e)?,
                kinds: [
                    w.add_wire(1, "act").map_err(&e)?,
                    w.add_wire(1, "read").map_err(&e)?,
                    w.add_wire(1, "pre").map_err(&e)?,
                    w.add_wire(1, "ref").map_err(&e)?,
                ],
                bank: w.add_wire(4, "bank").map_err(&e)?,
                column: w.add_wire(COLUMN_BITS, "column").map_err(&e)?,
                open_row: w.add_wire(24, "open_row").map_err(&e)?,
                address_fifo: w.add_wire(12, "address_fifo").map_err(&e)?,
                voxel_fifo: w.add_wire(12, "voxel_fifo").map_err(&e)?,
            });
            w.upscope().map_err(&e)?;
        }
        w.upscope().map_err(&e)?;
        w.enddefinitions().map_err(&e)?;
        drop(e);
        Ok(Waveform {
            writer: w,
            path: path.to_path_buf(),
            window,
            time,
            clk,
            cycle,
            ids,
            modules: module_ids,
            last: None,
            last_cycle: None,
        })
    }

    pub fn wants(&self, cycle: u64) -> bool {
        self.window.contains(&cycle)
    }

    /// The waveform's time base.
    pub fn time(&self) -> VcdTime {
        self.time
    }

    /// Records the cycle's signals (only those that changed) at its rising clock edge, and the
    /// falling edge half a period later.
    pub fn sample(&mut self, cycle: u64, p: &Probe) -> Result<()> {
        if !self.wants(cycle) {
            return Ok(());
        }
        let e = io(&self.path);
        let prev = self.last.take();
        let changed = |f: &Signal| prev.as_ref().is_none_or(|q| f(q) != f(p));
        let w = &mut self.writer;
        w.timestamp(self.time.edge(cycle, false)).map_err(&e)?;
        w.change_scalar(self.clk, Value::V1).map_err(&e)?;
        write_value(w, self.cycle, cycle, CYCLE_BITS).map_err(&e)?;
        let scalars: [(usize, &Signal, u32); 8] = [
            (0, &|p| p.ray_queue_occupancy, 16),
            (1, &|p| p.issue_valid as u64, 1),
            (2, &|p| p.issue_ray, 32),
            (3, &|p| p.leap as u64, 1),
            (4, &|p| p.occupied as u64, 1),
            (5, &|p| p.compositing_buffer, 16),
            (6, &|p| p.ert_event as u64, 1),
            (7, &|p| p.retire_event as u64, 1),
        ];
        for (i, f, width) in scalars {
            if changed(f) {
                write_value(w, self.ids[i], f(p), width).map_err(&e)?;
            }
        }
        for (m, ids) in self.modules.iter().enumerate() {
            let now = p.modules.get(m).copied().unwrap_or_default();
            let before = prev.as_ref().and_then(|q| q.modules.get(m).copied());
            let first = before.is_none();
            let before = before.unwrap_or_default();
            if first || now.command != before.command {
                write_value(w, ids.command, now.command, 3).map_err(&e)?;
                let name = COMMAND_NAMES
                    .get(now.command as usize)
                    .copied()
                    .unwrap_or("?");
                w.change_string(ids.name, name).map_err(&e)?;
                for (k, &id) in ids.kinds.iter().enumerate() {
                    let on = now.command == k as u64 + 1;
                    if first || on != (before.command == k as u64 + 1) {
                        write_value(w, id, on as u64, 1).map_err(&e)?;
                    }
                }
            }
            if first || now.bank != before.bank {
                match now.bank {
                    Some(bank) => write_value(w, ids.bank, bank, 4),
                    None => w.change_vector(ids.bank, [Value::Z; 4]),
                }
                .map_err(&e)?;
            }
            if first || now.column != before.column {
                match now.column {
                    Some(column) => write_value(w, ids.column, column, COLUMN_BITS),
                    None => w.change_vector(ids.column, [Value::Z; COLUMN_BITS as usize]),
                }
                .map_err(&e)?;
            }
            for (id, value, old, width) in [
                (ids.open_row, now.open_row, before.open_row, 24),
                (ids.address_fifo, now.address_fifo, before.address_fifo, 12),
                (ids.voxel_fifo, now.voxel_fifo, before.voxel_fifo, 12),
            ] {
                if first || old != value {
                    write_value(w, id, value, width).map_err(&e)?;
                }
            }
        }
        w.timestamp(self.time.edge(cycle, true)).map_err(&e)?;
        w.change_scalar(self.clk, Value::V0).map_err(&e)?;
        self.last = Some(p.clone());
        self.last_cycle = Some(cycle);
        Ok(())
    }

    /// Ends the last cycle recorded (the next rising edge), flushes and moves the file to its
    /// name.
    pub fn finish(mut self) -> Result<()> {
        let e = io(&self.path);
        if let Some(cycle) = self.last_cycle {
            let w = &mut self.writer;
            w.timestamp(self.time.edge(cycle + 1, false)).map_err(&e)?;
            w.change_scalar(self.clk, Value::V1).map_err(&e)?;
        }
        self.writer.writer().commit()
    }
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> Error + '_ {
    move |e| Error::io(path, e)
}

fn write_value<W: Write>(
    w: &mut vcd::Writer<W>,
    id: IdCode,
    value: u64,
    width: u32,
) -> std::io::Result<()> {
    if width == 1 {
        w.change_scalar(id, if value != 0 { Value::V1 } else { Value::V0 })
    } else {
        w.change_vector(
            id,
            (0..width).rev().map(|b| {
                if value >> b & 1 == 1 {
                    Value::V1
                } else {
                    Value::V0
                }
            }),
        )
    }
}

/// Parses `A..B` (cycles A up to B, B excluded) given to `--vcd-cycles`.
pub fn parse_window(text: &str) -> Result<Range<u64>> {
    parse_cycle_window("--vcd-cycles", text)
}

/// Parses `A..B` (cycles A up to B, B excluded); `flag` names the option in errors.
pub fn parse_cycle_window(flag: &str, text: &str) -> Result<Range<u64>> {
    let bad = || {
        Error::Invalid(format!(
            "{flag} `{text}`: expected A..B with A < B, e.g. 0..5000"
        ))
    };
    let (a, b) = text.split_once("..").ok_or_else(bad)?;
    let (a, b): (u64, u64) = (
        a.trim().parse().map_err(|_| bad())?,
        b.trim().parse().map_err(|_| bad())?,
    );
    if a >= b {
        return Err(bad());
    }
    Ok(a..b)
}

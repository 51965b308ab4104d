//! Waveforms: a VCD file (GTKWave, Surfer) of the pipeline's signals over a window of cycles.
//! The pipeline builds a `Probe` only when a waveform is being recorded, so a run without
//! `--vcd` pays one `Option` check per cycle.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};

use vcd::{IdCode, TimescaleUnit, Value};

use crate::error::{Error, Result};

/// Per-module signals. `command`: 0 none, 1 ACT, 2 READ, 3 PRE, 4 REF (issued this cycle).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ModuleProbe {
    pub command: u64,
    /// Row of the most recent ACT.
    pub open_row: u64,
    pub address_fifo: u64,
    pub voxel_fifo: u64,
}

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

struct ModuleIds {
    command: IdCode,
    open_row: IdCode,
    address_fifo: IdCode,
    voxel_fifo: IdCode,
}

pub struct Waveform {
    writer: vcd::Writer<BufWriter<File>>,
    path: PathBuf,
    tmp: PathBuf,
    window: Range<u64>,
    ids: [IdCode; 8],
    modules: Vec<ModuleIds>,
    last: Option<Probe>,
}

fn io(path: &Path) -> impl Fn(std::io::Error) -> Error + '_ {
    move |e| Error::io(path, e)
}

impl Waveform {
    /// Starts a VCD file for `modules` memory modules, recording cycles in `window`. The file is
    /// written under a temporary name and renamed by `finish`.
    pub fn create(path: &Path, modules: usize, window: Range<u64>) -> Result<Waveform> {
        let tmp = path.with_extension("vcd.tmp");
        let file = File::create(&tmp).map_err(io(&tmp))?;
        let mut w = vcd::Writer::new(BufWriter::new(file));
        let e = io(&tmp);
        w.timescale(10, TimescaleUnit::NS).map_err(&e)?;
        w.add_module("pipeline").map_err(&e)?;
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
            tmp: tmp.clone(),
            window,
            ids,
            modules: module_ids,
            last: None,
        })
    }

    pub fn wants(&self, cycle: u64) -> bool {
        self.window.contains(&cycle)
    }

    /// Records the cycle's signals (only those that changed).
    pub fn sample(&mut self, cycle: u64, p: &Probe) -> Result<()> {
        if !self.wants(cycle) {
            return Ok(());
        }
        let e = io(&self.tmp);
        let prev = self.last.take();
        let changed = |f: &Signal| prev.as_ref().is_none_or(|q| f(q) != f(p));
        self.writer.timestamp(cycle).map_err(&e)?;
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
                write_value(&mut self.writer, self.ids[i], f(p), width).map_err(&e)?;
            }
        }
        for (m, ids) in self.modules.iter().enumerate() {
            let now = p.modules.get(m).copied().unwrap_or_default();
            let before = prev.as_ref().and_then(|q| q.modules.get(m).copied());
            for (id, value, old, width) in [
                (ids.command, now.command, before.map(|b| b.command), 3),
                (ids.open_row, now.open_row, before.map(|b| b.open_row), 24),
                (
                    ids.address_fifo,
                    now.address_fifo,
                    before.map(|b| b.address_fifo),
                    12,
                ),
                (
                    ids.voxel_fifo,
                    now.voxel_fifo,
                    before.map(|b| b.voxel_fifo),
                    12,
                ),
            ] {
                if old != Some(value) {
                    write_value(&mut self.writer, id, value, width).map_err(&e)?;
                }
            }
        }
        self.last = Some(p.clone());
        Ok(())
    }

    /// Flushes and moves the file to its name.
    pub fn finish(mut self) -> Result<()> {
        self.writer.writer().flush().map_err(io(&self.tmp))?;
        std::fs::rename(&self.tmp, &self.path).map_err(io(&self.path))
    }
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

/// Parses `A..B` (cycles A up to B, B excluded).
pub fn parse_window(text: &str) -> Result<Range<u64>> {
    let bad = || {
        Error::Invalid(format!(
            "--vcd-cycles `{text}`: expected A..B with A < B, e.g. 0..5000"
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

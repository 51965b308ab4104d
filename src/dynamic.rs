//! Dynamic volumes: what a download, a scan, a transfer-function change and a partial update
//! cost on the update engine (`arch::update`), each in clock cycles, with the maps each way
//! checked against `OccupancyMap::build` on the volume in memory (docs/dynamic.md).

use crate::arch::address_map::MemoryConfig;
use crate::arch::update::{
    PartialMapPolicy, ScanReport, TfChangeReport, UpdateEngine, UpdateReport, VolumeUpdate,
};
use crate::config::HardwareConfig;
use crate::error::{Error, Result};
use crate::functional::arith::ClassificationTable;
use crate::functional::renderer::Leaping;
use crate::occupancy::{check_subcube_size, OccupancyKind, OccupancyMap};
use crate::render::Frame;
use crate::run::{self, Model, RunDescription};
use crate::volume::phantom::{self, PhantomKind, PhantomSpec, TsdfFusion};
use crate::volume::Volume;
use std::path::{Path, PathBuf};

/// The regions of `after` that differ from `before`: one region per `brick`³ brick (clipped to
/// the volume) holding any changed voxel, in brick order: a partial update of one time step.
/// A partial update's brick edge: at least 1, at most the volume's longest edge (a larger brick
/// is the same one brick, and a figure no update sends).
pub fn check_brick(brick: usize, dims: [usize; 3]) -> Result<()> {
    let longest = dims.into_iter().max().unwrap_or(1);
    if brick == 0 || brick > longest {
        return Err(Error::Invalid(format!(
            "brick size {brick}: out of range 1..={longest} (the volume is {}×{}×{}; one brick \
             of {longest} covers it)",
            dims[0], dims[1], dims[2]
        )));
    }
    Ok(())
}

pub fn changed_bricks(before: &Volume, after: &Volume, brick: usize) -> Result<VolumeUpdate> {
    if before.dims != after.dims {
        return Err(Error::Invalid(format!(
            "the next volume is {:?}, the current one {:?}: a partial update needs equal extents",
            after.dims, before.dims
        )));
    }
    if before.bits != after.bits {
        return Err(Error::Invalid(format!(
            "the next volume has {}-bit voxels, the current one {}-bit: a partial update needs \
             equal bit depths",
            after.bits, before.bits
        )));
    }
    check_brick(brick, after.dims)?;
    let d = after.dims;
    let mut regions = Vec::new();
    for bz in (0..d[2]).step_by(brick) {
        for by in (0..d[1]).step_by(brick) {
            for bx in (0..d[0]).step_by(brick) {
                let o = [bx, by, bz];
                let e = [0, 1, 2].map(|a| brick.min(d[a] - o[a]));
                let changed = (bz..bz + e[2]).any(|z| {
                    (by..by + e[1]).any(|y| {
                        let row = after.index(bx, y, z);
                        before.data[row..row + e[0]] != after.data[row..row + e[0]]
                    })
                });
                if changed {
                    regions.push(VolumeUpdate::region_of(after, o, e));
                }
            }
        }
    }
    Ok(VolumeUpdate {
        regions,
        ..VolumeUpdate::default()
    })
}

/// A partial update measured with both map policies.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PartialReport {
    pub next: String,
    pub brick: usize,
    pub widen: UpdateReport,
    pub rescan: UpdateReport,
    /// Sub-cubes the widened map keeps set although the new volume's are empty (class map).
    pub widen_stale_subcubes: usize,
}

/// Every cost of keeping the maps of one volume, at one sub-cube size.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DynamicReport {
    pub volume: String,
    pub dims: [usize; 3],
    pub clock_mhz: f64,
    pub host_link_mb_per_s: f64,
    pub mapping: String,
    pub subcube: usize,
    /// Full download in volume order (x fastest), the maps built on the way (exact).
    pub download: UpdateReport,
    /// The download with its map: `download.total_cycles` (writes + map bits), in ms. The text
    /// gives the writes' ms and the map's cycles apart, and this sum as "in all".
    pub download_ms: f64,
    /// Full download in the layout's tiles (`VolumeUpdate::full_tiled`: whole voxel-pair words).
    pub download_tiled: UpdateReport,
    /// The same for the tiled download.
    pub download_tiled_ms: f64,
    /// A separate scan pass through the read path (the brief's ~20 ms for 256³).
    pub scan: ScanReport,
    pub tf_change: TfChangeReport,
    pub tf_change_table_us: f64,
    /// The map bits ('0' or class, one per sub-cube).
    pub map_bits: u64,
    /// The map with the min/max table and the prefix table beside it
    /// (`UpdateEngine::table_on_chip_bits`): what the maps built during updates and the
    /// table-based transfer-function change keep on chip.
    pub table_on_chip_bits: u64,
    /// What the maps were checked against: both maps equal `OccupancyMap::build` after the
    /// download and after the scan.
    pub maps_exact: bool,
    pub partial: Option<PartialReport>,
}

/// A note when the map with its min/max and prefix tables (`table_on_chip_bits`) exceeds the
/// SRAM the configuration names; None when it fits. `needs` says which work keeps the tables,
/// `instead` what needs only the map.
pub fn table_sram_note(
    table_on_chip_bits: u64,
    map_bits: u64,
    sram_bits: u64,
    needs: &str,
    instead: &str,
) -> Option<String> {
    (table_on_chip_bits > sram_bits).then(|| {
        // A map over the SRAM on its own fits no way of building it.
        let map_alone = if map_bits > sram_bits {
            format!(
                "the map alone ({map_bits} bits) exceeds it too, so no chip of that SRAM holds \
                 this sub-cube size"
            )
        } else {
            format!("{instead} needs only the map")
        };
        format!(
            "note: the map, the min/max table and the prefix table need {table_on_chip_bits} bits \
             on chip, more than occupancy.sram_bits ({sram_bits}): {needs} need a chip with that \
             much SRAM (--set occupancy.sram_bits={} to model one); {map_alone}",
            table_on_chip_bits.next_power_of_two()
        )
    })
}

/// Who asks the update model: `vizsim update` measures the map alone (its bits, at the
/// sub-cube size); a sequence also renders every step with it, its map kept as `map` says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UpdateUse {
    Measure,
    Sequence { map: MapMode },
}

/// Refuses a configuration the update model does not model (docs/dynamic.md, "Not modelled
/// during updates"): every structure other than the occupancy map that a run builds from the
/// volume when it is prepared. The update engine keeps only the map's min/max table, so with
/// any of them a step would render with a structure rebuilt for free and charge no cycles for
/// it. The one list of such refusals, for `measure`, `run_sequence` and the experiments.
pub fn check_modelled(hw: &HardwareConfig, used: UpdateUse) -> Result<()> {
    let refuse = |setting: String, why: &str| {
        Err(Error::Invalid(format!(
            "{setting}: {why}; not modelled during updates (docs/dynamic.md, \"Not modelled \
             during updates\")"
        )))
    };
    if !hw.occupancy.structure.is_map() {
        return refuse(
            format!(
                "occupancy.structure = {}",
                serde_json::to_string(&hw.occupancy.structure).unwrap_or_default()
            ),
            "the update engine keeps an occupancy map, not a distance volume or leap values in \
             the voxel words, which would have to be recomputed around every changed voxel",
        );
    }
    if hw.bricks.size > 0 {
        // A sequence rebuilds the brick flags from the map's min/max table (`run_sequence`).
        match used {
            UpdateUse::Measure => {
                return refuse(
                    format!("bricks.size = {}", hw.bricks.size),
                    "update measures the map; the brick flags that start and end each ray are \
                     rebuilt from its table in `vizsim sequence`",
                )
            }
            UpdateUse::Sequence { map: MapMode::None } => {
                return refuse(
                    format!("bricks.size = {} with --map none", hw.bricks.size),
                    "the brick flags are rebuilt from the map's min/max table, which the chip \
                     keeps only with a map",
                )
            }
            UpdateUse::Sequence { .. } if hw.bricks.size < hw.occupancy.subcube => {
                return refuse(
                    format!(
                        "bricks.size = {} below occupancy.subcube = {}",
                        hw.bricks.size, hw.occupancy.subcube
                    ),
                    "the brick flags are rebuilt from the map's min/max table, one range per \
                     sub-cube: a brick must hold whole sub-cubes",
                )
            }
            UpdateUse::Sequence { .. } => {}
        }
    }
    if hw.blocking.enabled {
        return refuse(
            "blocking.enabled = true".into(),
            "the blocking table is not kept up to date (a block that becomes active needs a \
             free slot and its voxels written, one that empties frees its slot)",
        );
    }
    if used == UpdateUse::Measure && hw.occupancy.hierarchy {
        return refuse(
            "occupancy.hierarchy = true (--hierarchy)".into(),
            "update measures the map's bits without the hierarchy's byte layout",
        );
    }
    Ok(())
}

/// The configuration fields (paths or prefixes) `vizsim update` reads: the clock, the memory
/// and SDRAM (its writes and scans), the map's sub-cube and SRAM, the classification table's
/// size (the class map). The others shape a frame, which `update` does not render.
const READ_BY_UPDATE: [&str; 6] = [
    "clock.frequency_mhz",
    "memory.",
    "sdram.",
    "occupancy.subcube",
    "occupancy.sram_bits",
    "classification.lut_bits",
];

/// The changed fields of `hw` (as `HardwareConfig::differences_from_default` writes them,
/// `field = value`) that `measure` does not read: `vizsim update` names them, as `sim` names
/// the fields without effect in its run.
pub fn unread_by_update(hw: &HardwareConfig) -> Vec<String> {
    hw.differences_from_default()
        .into_iter()
        .filter(|d| {
            let path = d.split(" = ").next().unwrap_or_default();
            !READ_BY_UPDATE
                .iter()
                .any(|read| path == *read || (read.ends_with('.') && path.starts_with(read)))
        })
        .collect()
}

/// Measures a download of `volume`, a scan, the costs of a transfer-function change, and with
/// `next` a partial update to it (changed `brick`³ bricks) under both map policies. The maps are
/// checked against `OccupancyMap::build`; an error if one is not exact (or, widened, not
/// conservative), or for a configuration the update model does not model (`check_modelled`).
pub fn measure(
    hw: &HardwareConfig,
    volume: &Volume,
    table: &ClassificationTable,
    subcube: usize,
    next: Option<(&Volume, usize)>,
) -> Result<DynamicReport> {
    check_modelled(hw, UpdateUse::Measure)?;
    let log2 = check_subcube_size(subcube, volume.dims)?;
    let visible = |lo: u16, hi: u16| table.any_visible(lo, hi);
    let mut engine = UpdateEngine::new(hw, volume.dims, volume.bits, log2, 0)?;
    let download = engine.update(&VolumeUpdate::full(volume), PartialMapPolicy::Widen)?;
    check_maps(&engine, volume, log2, &visible, true, "after the download")?;
    let download_tiled = {
        let mut engine = UpdateEngine::new(hw, volume.dims, volume.bits, log2, 0)?;
        let tiled = VolumeUpdate::full_tiled(volume, &hw.memory);
        let report = engine.update(&tiled, PartialMapPolicy::Widen)?;
        check_maps(
            &engine,
            volume,
            log2,
            &visible,
            true,
            "after the tiled download",
        )?;
        if engine.memory_volume("memory")?.data != volume.data {
            return Err(Error::Invalid(
                "the tiled download left another volume in memory".into(),
            ));
        }
        report
    };
    let scan = engine.scan();
    check_maps(&engine, volume, log2, &visible, true, "after the scan")?;
    let tf_change = engine.tf_change_costs(scan.cycles);
    let us = |cycles: u64| cycles as f64 / hw.clock.frequency_mhz;
    let partial = match next {
        None => None,
        Some((after, brick)) => {
            let update = changed_bricks(volume, after, brick)?;
            let mut reports = Vec::new();
            let mut stale = 0;
            for policy in [PartialMapPolicy::Widen, PartialMapPolicy::Rescan] {
                let mut engine = UpdateEngine::new(hw, volume.dims, volume.bits, log2, 0)?;
                engine.update(&VolumeUpdate::full(volume), policy)?;
                reports.push(engine.update(&update, policy)?);
                let exact = policy == PartialMapPolicy::Rescan;
                let extra = check_maps(
                    &engine,
                    after,
                    log2,
                    &visible,
                    exact,
                    "after the partial update",
                )?;
                if !exact {
                    stale = extra;
                }
            }
            let rescan = reports.pop().expect("two policies");
            Some(PartialReport {
                next: after.name.clone(),
                brick,
                widen: reports.pop().expect("two policies"),
                rescan,
                widen_stale_subcubes: stale,
            })
        }
    };
    Ok(DynamicReport {
        volume: volume.name.clone(),
        dims: volume.dims,
        clock_mhz: hw.clock.frequency_mhz,
        host_link_mb_per_s: hw.memory.host_link_bytes_per_second() / 1e6,
        mapping: hw.memory.mapping.name().to_string(),
        subcube,
        download_ms: us(download.total_cycles) / 1e3,
        download,
        download_tiled_ms: us(download_tiled.total_cycles) / 1e3,
        download_tiled,
        scan,
        tf_change_table_us: us(tf_change.prefix_cycles + tf_change.table_pass_cycles),
        tf_change,
        map_bits: engine.table().subcubes() as u64,
        table_on_chip_bits: engine.table_on_chip_bits(),
        maps_exact: true,
        partial,
    })
}

/// Compares the engine's '0' and class maps with `OccupancyMap::build` on `volume`: equal
/// (`exact`) or a superset; returns the class map's extra bits.
fn check_maps(
    engine: &UpdateEngine,
    volume: &Volume,
    log2: u32,
    visible: &impl Fn(u16, u16) -> bool,
    exact: bool,
    when: &str,
) -> Result<usize> {
    let mut extra = 0;
    for kind in [OccupancyKind::Zero, OccupancyKind::Class] {
        let built = OccupancyMap::build(volume, kind, log2, 0, visible);
        let ours = engine.map(kind, visible);
        for z in 0..built.dims[2] {
            for y in 0..built.dims[1] {
                for x in 0..built.dims[0] {
                    let (a, b) = (ours.occupied([x, y, z]), built.occupied([x, y, z]));
                    if (b && !a) || (exact && a != b) {
                        return Err(Error::Invalid(format!(
                            "{when}: the {} map's sub-cube {x},{y},{z} is {} but the volume's is {}",
                            kind.label(),
                            if a { "occupied" } else { "empty" },
                            if b { "occupied" } else { "empty" },
                        )));
                    }
                    extra += (a && !b && kind == OccupancyKind::Class) as usize;
                }
            }
        }
    }
    Ok(extra)
}

// ---------------------------------------------------------------------------------------------
// Volume sequences and the frame loop of a dynamic sequence (issue 16, parts 1 and 4).

/// Largest number of time steps of a sequence.
pub const MAX_STEPS: usize = 10_000;

/// The metaballs' time between steps and a partial update's brick edge, when not given
/// (`vizsim sequence`, `vizsim update` and an experiment's `[sequence]` alike).
pub const DEFAULT_DT: f32 = 0.05;
pub const DEFAULT_BRICK: usize = 8;

/// Where the time steps come from.
enum Source {
    /// `phantom:metaballs…` at t0, t0 + dt, t0 + 2·dt, …
    Metaballs { spec: PhantomSpec, dt: f32 },
    /// `phantom:tsdf…`: one depth image integrated per step, at t0 + 1, t0 + 2, … after the
    /// reconstruction at t0.
    Tsdf {
        spec: PhantomSpec,
        fusion: TsdfFusion,
    },
    /// A folder of raw/NRRD files, one time step each, in file-name order.
    Folder { files: Vec<PathBuf> },
}

/// A sequence of volumes of one extent, read step by step.
pub struct Sequence {
    source: Source,
    /// The source as given.
    pub name: String,
    pub steps: usize,
    brick: usize,
    next: usize,
    current: Option<Volume>,
}

/// One time step: the volume and what the host sends to bring the previous one up to it.
pub struct SequenceStep {
    pub index: usize,
    pub volume: Volume,
    /// Step 0: the whole volume in the layout's tiles (a download); later steps: the changed
    /// (metaballs, folder) or touched (TSDF) `brick`³ bricks.
    pub update: VolumeUpdate,
    /// TSDF: the voxels the integration touched (all within μ of the observed surface).
    pub touched_voxels: Option<Vec<usize>>,
}

impl Sequence {
    /// Opens `source`: `phantom:metaballs[:SIZE][:seed=N][:t=T0]` (time steps `dt` apart),
    /// `phantom:tsdf[:SIZE][:seed=N][:t=T0]` (one depth image per step) or a folder of
    /// `.raw`/`.nrrd`/`.nhdr` files (one per step, file-name order, all of one size). Errors:
    /// zero steps, more steps than the folder holds or the TSDF allows, a phantom that does not
    /// move, a brick of 0.
    pub fn open(source: &str, steps: usize, dt: f32, brick: usize) -> Result<Sequence> {
        if steps == 0 {
            return Err(Error::Invalid(
                "zero time steps: a sequence needs at least one".into(),
            ));
        }
        if steps > MAX_STEPS {
            return Err(Error::Invalid(format!(
                "{steps} time steps: at most {MAX_STEPS}"
            )));
        }
        if brick == 0 {
            return Err(Error::Invalid("brick size 0: must be at least 1".into()));
        }
        let source_kind = if let Some(rest) = source.strip_prefix("phantom:") {
            let spec = phantom::parse_spec(rest)?;
            match spec.kind {
                PhantomKind::Metaballs => {
                    if !dt.is_finite() || dt <= 0.0 {
                        return Err(Error::Invalid(format!(
                            "time step dt = {dt}: must be a finite number above 0"
                        )));
                    }
                    // The last step's time must be finite too (dt = 3e38 overflowed at step 1
                    // and the phantom generator panicked on t = inf).
                    let last = spec.time + (steps - 1) as f32 * dt;
                    if !last.is_finite() {
                        return Err(Error::Invalid(format!(
                            "time step dt = {dt:e}: the time of step {} overflows ({last}); give a \
                             smaller dt or fewer steps",
                            steps - 1
                        )));
                    }
                    Source::Metaballs { spec, dt }
                }
                PhantomKind::Tsdf => {
                    let last = spec.time as f64 + (steps - 1) as f64;
                    if last > phantom::TSDF_MAX_TIME as f64 {
                        return Err(Error::Invalid(format!(
                            "time step {} (t = {last}) out of range: the TSDF phantom goes up to \
                             t = {}",
                            steps - 1,
                            phantom::TSDF_MAX_TIME
                        )));
                    }
                    let fusion = TsdfFusion::new(spec.size, spec.seed);
                    Source::Tsdf { spec, fusion }
                }
                other => {
                    return Err(Error::Invalid(format!(
                        "{source}: the {} phantom does not change with time; sequences: \
                         phantom:metaballs, phantom:tsdf or a folder of time steps",
                        other.name()
                    )))
                }
            }
        } else {
            let dir = Path::new(source);
            if !dir.is_dir() {
                return Err(Error::Invalid(format!(
                    "{source}: not a sequence (phantom:metaballs…, phantom:tsdf… or a folder \
                     of raw/NRRD time steps)"
                )));
            }
            let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
                .map_err(|e| Error::Invalid(format!("{source}: {e}")))?
                .filter_map(|entry| entry.ok().map(|e| e.path()))
                .filter(|p| {
                    p.is_file()
                        && [".raw", ".nrrd", ".nhdr"]
                            .iter()
                            .any(|ext| p.to_string_lossy().ends_with(ext))
                })
                .collect();
            files.sort();
            if files.is_empty() {
                return Err(Error::Invalid(format!(
                    "{source}: no .raw, .nrrd or .nhdr time steps in the folder"
                )));
            }
            if steps > files.len() {
                return Err(Error::Invalid(format!(
                    "{steps} time steps asked for, but the folder {source} holds {}: ask for at \
                     most {} (`vizsim sequence --steps`, or the experiment's steps)",
                    files.len(),
                    files.len()
                )));
            }
            // Every time step the sequence will read has the first one's size, checked from the
            // names and headers before any step runs (a mismatch stopped it after the steps
            // before).
            let mut first: Option<(&std::path::Path, ([usize; 3], u8))> = None;
            for file in &files[..steps] {
                let Some(described) = crate::volume::dataset::describe_file(file)? else {
                    continue;
                };
                match first {
                    None => first = Some((file, described)),
                    Some((at, expected)) if expected != described => {
                        return Err(Error::Invalid(format!(
                            "{}: {:?} voxels of {} bits, but {} is {:?} of {} bits: every time \
                             step must have the same size",
                            file.display(),
                            described.0,
                            described.1,
                            at.display(),
                            expected.0,
                            expected.1
                        )));
                    }
                    _ => {}
                }
            }
            Source::Folder { files }
        };
        Ok(Sequence {
            source: source_kind,
            name: source.to_string(),
            steps,
            brick,
            next: 0,
            current: None,
        })
    }

    /// The next time step, or None after the last. `memory` sets the tiles of the first
    /// step's download.
    pub fn next_step(&mut self, memory: &MemoryConfig) -> Result<Option<SequenceStep>> {
        if self.next >= self.steps {
            return Ok(None);
        }
        let k = self.next;
        let mut touched = None;
        let volume = match &mut self.source {
            Source::Metaballs { spec, dt } => phantom::generate(&PhantomSpec {
                time: spec.time + k as f32 * *dt,
                ..spec.clone()
            }),
            Source::Tsdf { spec, fusion } => {
                let time = spec.time as f64 + k as f64;
                if k == 0 {
                    *fusion = TsdfFusion::at(spec.size, spec.seed, time);
                } else {
                    touched = Some(fusion.integrate(time));
                }
                let step = PhantomSpec {
                    time: time as f32,
                    ..spec.clone()
                };
                Volume::new(step.name(), [spec.size; 3], [1.0; 3], 8, fusion.values())?
            }
            Source::Folder { files } => {
                let file = &files[k];
                let volume = crate::volume::dataset::load_file(file)?;
                if let Some(first) = &self.current {
                    if volume.dims != first.dims || volume.bits != first.bits {
                        return Err(Error::Invalid(format!(
                            "{}: {:?} voxels of {} bits, but the sequence's earlier time steps \
                             are {:?} of {} bits: every time step must have the same size",
                            file.display(),
                            volume.dims,
                            volume.bits,
                            first.dims,
                            first.bits
                        )));
                    }
                }
                volume
            }
        };
        let update = match (&self.current, &touched) {
            (None, _) => {
                // Checked at the first step, where the extent is known (the experiment's
                // validation takes it), not after a step has run.
                check_brick(self.brick, volume.dims)?;
                VolumeUpdate::full_tiled(&volume, memory)
            }
            (Some(_), Some(voxels)) => touched_bricks(&volume, voxels, self.brick),
            (Some(before), None) => changed_bricks(before, &volume, self.brick)?,
        };
        self.current = Some(volume.clone());
        self.next += 1;
        Ok(Some(SequenceStep {
            index: k,
            volume,
            update,
            touched_voxels: touched,
        }))
    }
}

/// The `brick`³ bricks holding any of `voxels` (indices, x fastest), each as one region of
/// `volume`, in brick order: the partial update of a TSDF integration.
pub fn touched_bricks(volume: &Volume, voxels: &[usize], brick: usize) -> VolumeUpdate {
    let d = volume.dims;
    let bd = d.map(|v| v.div_ceil(brick));
    let mut marked = vec![false; bd[0] * bd[1] * bd[2]];
    for &i in voxels {
        let (x, y, z) = (i % d[0], (i / d[0]) % d[1], i / (d[0] * d[1]));
        marked[x / brick + bd[0] * (y / brick + bd[1] * (z / brick))] = true;
    }
    let mut regions = Vec::new();
    for (b, _) in marked.iter().enumerate().filter(|(_, m)| **m) {
        let c = [b % bd[0], (b / bd[0]) % bd[1], b / (bd[0] * bd[1])];
        let o = c.map(|v| v * brick);
        let e = [0, 1, 2].map(|a| brick.min(d[a] - o[a]));
        regions.push(VolumeUpdate::region_of(volume, o, e));
    }
    VolumeUpdate {
        regions,
        ..VolumeUpdate::default()
    }
}

/// How the occupancy map follows the volume in a sequence.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum MapMode {
    /// Built during the update from the min/max table (`PartialMapPolicy::Widen`):
    /// conservative after partial updates.
    DuringUpdate,
    /// During the update, the partly written sub-cubes read back (`PartialMapPolicy::Rescan`):
    /// exact.
    Rescan,
    /// A separate scan pass after every update (exact), then every map bit written.
    Scan,
    /// No leaping: no map.
    None,
}

impl MapMode {
    pub fn parse(text: &str) -> std::result::Result<MapMode, String> {
        match text {
            "during-update" => Ok(MapMode::DuringUpdate),
            "rescan" => Ok(MapMode::Rescan),
            "scan" => Ok(MapMode::Scan),
            "none" => Ok(MapMode::None),
            other => Err(format!(
                "`{other}`: expected `during-update`, `rescan`, `scan` or `none`"
            )),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            MapMode::DuringUpdate => "during-update",
            MapMode::Rescan => "rescan",
            MapMode::Scan => "scan",
            MapMode::None => "none",
        }
    }
}

/// What a sequence run does besides the run description.
#[derive(Clone, Debug)]
pub struct SequenceOptions {
    pub steps: usize,
    /// Metaballs: time between steps.
    pub dt: f32,
    /// Edge of the bricks a partial update sends.
    pub brick: usize,
    pub map: MapMode,
    /// Render every frame a second time without leaping and require the same image.
    pub verify: bool,
}

/// One time step of the frame loop, in pipeline clock cycles. Ordering: a fence (docs/dynamic.md):
/// update, then map, then render, one after the other on the same SDRAM.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StepReport {
    pub step: usize,
    pub volume: String,
    pub regions: u64,
    pub voxels_written: u64,
    /// TSDF: voxels the depth image's integration touched.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub voxels_touched: Option<u64>,
    /// From the first byte on the host link to the last WRITE.
    pub update_cycles: u64,
    /// After the last WRITE until the map is ready: map bits from the table (during-update),
    /// plus the rescan of partly written sub-cubes (rescan), or the scan pass and every bit
    /// (scan); 0 without leaping.
    pub map_cycles: u64,
    /// The frame on the cycle model (`run::execute`), with the map as the chip holds it.
    pub render_cycles: u64,
    pub total_cycles: u64,
    /// Map bits set whose sub-cubes are empty in the volume in memory (conservative, stale).
    pub stale_subcubes: u64,
    /// Empty sub-cubes of the map rendered with, percent.
    pub empty_subcubes_percent: f64,
    /// With `verify`: the image equals the non-leaping image bit for bit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub equals_non_leaping: Option<bool>,
}

/// A sequence's frame loop.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SequenceReport {
    pub source: String,
    pub dims: [usize; 3],
    pub map: MapMode,
    /// The map's sub-cube edge; None (null) with `map = none` (no map kept).
    pub subcube: Option<usize>,
    pub brick: usize,
    pub clock_mhz: f64,
    /// How update and render are ordered: `fence` (update, map, render in turn).
    pub ordering: &'static str,
    pub steps: Vec<StepReport>,
    /// Frames per second over every step, the download of step 0 included.
    pub fps: f64,
    /// Frames per second of the steps after the first (partial updates): the sequence's rate.
    /// None (null) with a single step: there is no step after the first.
    pub steady_fps: Option<f64>,
    /// SRAM bits of the map with its min/max table and prefix table, which the modes that
    /// build the map from the table (during-update, rescan) keep on chip; None (null) with
    /// `scan` and `none`, which need at most the map.
    pub table_on_chip_bits: Option<u64>,
    /// Mean cycles per step after the first: update, map, render (None with a single step).
    pub mean_update_cycles: Option<f64>,
    pub mean_map_cycles: Option<f64>,
    pub mean_render_cycles: Option<f64>,
}

/// What the frame loop shows an observer after each step.
pub struct StepView<'a> {
    pub report: &'a StepReport,
    /// The volume the step describes.
    pub volume: &'a Volume,
    /// The volume as the SDRAM holds it after the update (what the frame read).
    pub memory: &'a Volume,
    /// The map the frame leapt with (None without leaping).
    pub map: Option<&'a OccupancyMap>,
    pub frame: &'a Frame,
    /// The frame's measurements (`run::execute`): its cycles are the step's render cycles.
    pub measurements: &'a run::Measurements,
    /// The transfer function's name.
    pub transfer_function: &'a str,
    /// `SequenceReport::table_on_chip_bits`: the map with the tables the map mode keeps on chip.
    pub table_on_chip_bits: Option<u64>,
}

/// The first cell `exact` marks occupied that `ours` leaves empty (same grid): where `ours`
/// is not conservative.
fn first_uncovered(ours: &OccupancyMap, exact: &OccupancyMap) -> Option<[usize; 3]> {
    let d = exact.dims;
    (0..d[2])
        .flat_map(|z| (0..d[1]).flat_map(move |y| (0..d[0]).map(move |x| [x, y, z])))
        .find(|&c| exact.occupied(c) && !ours.occupied(c))
}

/// Runs the frame loop of `source` with `run` (cycle model; its dataset is ignored; its
/// `occupancy.subcube` is the map's sub-cube size): per step the update engine writes what
/// changed, the map follows as `options.map` says, and the frame is rendered through
/// `run::prepare`/`run::execute` from the volume in the SDRAM with the map the chip holds.
/// Errors: a configuration the update model does not model (`check_modelled`), the memory
/// image differs from the step's volume, the map is not conservative, or (`verify`) a frame
/// differs from the non-leaping frame.
pub fn run_sequence(
    run: &RunDescription,
    source: &str,
    options: &SequenceOptions,
    mut observe: impl FnMut(&StepView) -> Result<()>,
) -> Result<SequenceReport> {
    if run.model != Model::Cycle {
        return Err(Error::Invalid(format!(
            "a sequence runs on the cycle model, not the {} model",
            run.model.name()
        )));
    }
    let hw = &run.hardware;
    check_modelled(hw, UpdateUse::Sequence { map: options.map })?;
    let leaping_run = || {
        let mut r = run.clone();
        if options.map == MapMode::None {
            r.hardware.occupancy.subcube = 0;
        }
        r
    };
    let render_run = leaping_run();
    if options.map != MapMode::None && !matches!(render_run.leaping(), Leaping::Occupancy { .. }) {
        return Err(Error::Invalid(format!(
            "--map {}: the run must leap with an occupancy map (give its sub-cube size); or \
             --map none",
            options.map.name()
        )));
    }
    let plain_run = {
        let mut r = run.clone();
        r.hardware.occupancy.subcube = 0;
        r
    };
    let mut sequence = Sequence::open(source, options.steps, options.dt, options.brick)?;
    let kind = hw.occupancy.kind;
    let policy = if options.map == MapMode::Rescan {
        PartialMapPolicy::Rescan
    } else {
        PartialMapPolicy::Widen
    };
    let mut engine: Option<UpdateEngine> = None;
    let mut table_on_chip_bits = None;
    let mut steps = Vec::new();
    let mut subcube = 0;
    let mut dims = [0; 3];
    while let Some(step) = sequence.next_step(&hw.memory)? {
        let volume = &step.volume;
        if engine.is_none() {
            dims = volume.dims;
            subcube = if hw.occupancy.subcube > 0 {
                hw.occupancy.subcube
            } else {
                8.min(*volume.dims.iter().min().expect("three axes"))
                    .next_power_of_two()
                    .max(2)
            };
            let log2 = check_subcube_size(subcube, volume.dims)?;
            let created = UpdateEngine::new(hw, volume.dims, volume.bits, log2, 0)?;
            table_on_chip_bits = matches!(options.map, MapMode::DuringUpdate | MapMode::Rescan)
                .then(|| created.table_on_chip_bits());
            engine = Some(created);
        }
        let engine = engine.as_mut().expect("created above");
        let update = engine.update(&step.update, policy)?;
        let mut map_cycles = match options.map {
            MapMode::DuringUpdate | MapMode::Rescan => update.rescan_cycles + update.map_cycles,
            MapMode::Scan => engine.scan().cycles + engine.table().subcubes() as u64,
            MapMode::None => 0,
        };
        let memory = engine.memory_volume(&volume.name)?;
        if memory.data != volume.data {
            let i = (0..volume.data.len())
                .find(|&i| memory.data[i] != volume.data[i])
                .expect("the volumes differ");
            return Err(Error::Invalid(format!(
                "step {}: after the update voxel {i} holds {} in SDRAM but the volume has {}",
                step.index, memory.data[i], volume.data[i]
            )));
        }
        let mut prepared = run::prepare(&render_run, &memory)?;
        let mut map = None;
        let mut stale = 0;
        if options.map != MapMode::None {
            let table = &prepared.fixed().expect("cycle model").table;
            let visible = |lo: u16, hi: u16| table.any_visible(lo, hi);
            let ours = engine.map(kind, visible);
            let log2 = ours.cube_log2;
            let exact = OccupancyMap::build(&memory, kind, log2, 0, visible);
            for z in 0..exact.dims[2] {
                for y in 0..exact.dims[1] {
                    for x in 0..exact.dims[0] {
                        let (a, b) = (ours.occupied([x, y, z]), exact.occupied([x, y, z]));
                        if b && !a {
                            return Err(Error::Invalid(format!(
                                "step {}: the {} map leaves sub-cube {x},{y},{z} empty but the \
                                 volume in memory has visible voxels there: not conservative",
                                step.index,
                                kind.label()
                            )));
                        }
                        stale += (a && !b) as u64;
                    }
                }
            }
            // Bounding bricks: their flags from the same table, a brick's range the hull of
            // its sub-cubes' (a pass over the table after the map's, one entry per cycle),
            // conservative as the map is.
            let bricks = if hw.bricks.size > 0 {
                let log2 = crate::bricks::check_brick_size(hw.bricks.size, memory.dims)?;
                let ours = engine
                    .table()
                    .coarse_map(kind, log2, visible)
                    .ok_or_else(|| {
                        Error::Invalid(format!(
                            "bricks.size = {} below the map's sub-cube size {subcube}",
                            hw.bricks.size
                        ))
                    })?;
                let exact = crate::bricks::build_brick_map(&memory, kind, hw.bricks.size, visible)?;
                if let Some(c) = first_uncovered(&ours, &exact) {
                    return Err(Error::Invalid(format!(
                        "step {}: the brick flags leave brick {c:?} inactive but the volume in \
                         memory has visible voxels there: not conservative",
                        step.index
                    )));
                }
                map_cycles += engine.table().subcubes() as u64;
                Some(ours)
            } else {
                None
            };
            if let Some(bricks) = bricks {
                prepared.set_brick_map(bricks)?;
            }
            prepared.set_occupancy_map(ours.clone())?;
            map = Some(ours);
        }
        let report = run::execute(&render_run, &prepared, run::Probes::default())?;
        let render_cycles = report.measurements.cycles.expect("cycle model");
        let equals_non_leaping = if options.verify && options.map != MapMode::None {
            let plain = run::prepare(&plain_run, &memory)?;
            let reference = run::execute(&plain_run, &plain, run::Probes::default())?;
            let same = reference.frame.pixels == report.frame.pixels;
            if !same {
                return Err(Error::Invalid(format!(
                    "step {}: the leaping image differs from the non-leaping image",
                    step.index
                )));
            }
            Some(same)
        } else {
            None
        };
        let total_cycles = update.write_cycles + map_cycles + render_cycles;
        let step_report = StepReport {
            step: step.index,
            volume: volume.name.clone(),
            regions: update.regions,
            voxels_written: update.voxels_written,
            voxels_touched: step.touched_voxels.as_ref().map(|t| t.len() as u64),
            update_cycles: update.write_cycles,
            map_cycles,
            render_cycles,
            total_cycles,
            stale_subcubes: stale,
            empty_subcubes_percent: report
                .measurements
                .skippable_subcubes_percent
                .unwrap_or(0.0),
            equals_non_leaping,
        };
        observe(&StepView {
            report: &step_report,
            volume,
            memory: &memory,
            map: map.as_ref(),
            frame: &report.frame,
            measurements: &report.measurements,
            transfer_function: &report.transfer_function,
            table_on_chip_bits,
        })?;
        steps.push(step_report);
    }
    let fps_of = |reports: &[StepReport]| {
        let cycles: u64 = reports.iter().map(|s| s.total_cycles).sum();
        reports.len() as f64 * hw.clock.frequency_mhz * 1e6 / (cycles.max(1) as f64)
    };
    let later = steps.get(1..).filter(|later| !later.is_empty());
    let mean = |f: fn(&StepReport) -> u64| {
        later.map(|later| later.iter().map(f).sum::<u64>() as f64 / later.len() as f64)
    };
    Ok(SequenceReport {
        source: sequence.name.clone(),
        dims,
        map: options.map,
        subcube: (options.map != MapMode::None).then_some(subcube),
        brick: options.brick,
        clock_mhz: hw.clock.frequency_mhz,
        ordering: "fence",
        fps: fps_of(&steps),
        steady_fps: later.map(fps_of),
        table_on_chip_bits,
        mean_update_cycles: mean(|s| s.update_cycles),
        mean_map_cycles: mean(|s| s.map_cycles),
        mean_render_cycles: mean(|s| s.render_cycles),
        steps,
    })
}

//! Dynamic volumes: what a download, a scan, a transfer-function change and a partial update
//! cost on the update engine (`arch::update`), each in clock cycles, with the maps each way
//! checked against `OccupancyMap::build` on the volume in memory (docs/dynamic.md).

use crate::arch::update::{
    PartialMapPolicy, ScanReport, TfChangeReport, UpdateEngine, UpdateReport, VolumeUpdate,
};
use crate::config::HardwareConfig;
use crate::error::{Error, Result};
use crate::functional::arith::ClassificationTable;
use crate::occupancy::{check_subcube_size, OccupancyKind, OccupancyMap};
use crate::volume::Volume;

/// The regions of `after` that differ from `before`: one region per `brick`³ brick (clipped to
/// the volume) holding any changed voxel, in brick order: a partial update of one time step.
pub fn changed_bricks(before: &Volume, after: &Volume, brick: usize) -> Result<VolumeUpdate> {
    if before.dims != after.dims {
        return Err(Error::Invalid(format!(
            "the next volume is {:?}, the current one {:?}: a partial update needs equal extents",
            after.dims, before.dims
        )));
    }
    if brick == 0 {
        return Err(Error::Invalid("brick size 0: must be at least 1".into()));
    }
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
    pub download_ms: f64,
    /// Full download in the layout's tiles (`VolumeUpdate::full_tiled`: whole voxel-pair words).
    pub download_tiled: UpdateReport,
    pub download_tiled_ms: f64,
    /// A separate scan pass through the read path (the brief's ~20 ms for 256³).
    pub scan: ScanReport,
    pub tf_change: TfChangeReport,
    pub tf_change_table_us: f64,
    /// The map bits ('0' or class, one per sub-cube) and the min/max table beside them.
    pub map_bits: u64,
    /// What the maps were checked against: both maps equal `OccupancyMap::build` after the
    /// download and after the scan.
    pub maps_exact: bool,
    pub partial: Option<PartialReport>,
}

/// Measures a download of `volume`, a scan, the costs of a transfer-function change, and with
/// `next` a partial update to it (changed `brick`³ bricks) under both map policies. The maps are
/// checked against `OccupancyMap::build`; an error if one is not exact (or, widened, not
/// conservative).
pub fn measure(
    hw: &HardwareConfig,
    volume: &Volume,
    table: &ClassificationTable,
    subcube: usize,
    next: Option<(&Volume, usize)>,
) -> Result<DynamicReport> {
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
        mapping: format!("{:?}", hw.memory.mapping).to_lowercase(),
        subcube,
        download_ms: us(download.total_cycles) / 1e3,
        download,
        download_tiled_ms: us(download_tiled.total_cycles) / 1e3,
        download_tiled,
        scan,
        tf_change_table_us: us(tf_change.prefix_cycles + tf_change.table_pass_cycles),
        tf_change,
        map_bits: engine.table().subcubes() as u64,
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

//! The volume update / download engine: the FPGA unit that takes voxels from the host link,
//! writes them into the SDRAM modules (every copy the layout stores) and keeps the occupancy
//! maps up to date on the way, clock by clock; and the two other ways to get a map: a scan of
//! the volume through the read path, and a transfer-function change from the on-chip
//! per-sub-cube min/max table (docs/dynamic.md).
//!
//! **Host link.** `memory.host_link_bits` × `memory.host_link_mhz` bytes per second (default
//! 32-bit 33 MHz PCI, 132 MB/s peak), converted to bytes per pipeline clock; the link buffers
//! at most `HOST_BUFFER_BYTES` ahead of the FPGA (a stalled FPGA stalls the link). An update
//! is a list of regions (boxes of voxels, x fastest); each costs `REGION_HEADER_BYTES` of
//! header (origin and extent) plus its voxels at 1 byte (8-bit data) or 2 (16-bit).
//!
//! **Input stage.** Per cycle up to `INPUT_VOXELS_PER_CYCLE` voxels (one host word of 8-bit
//! voxels) whose bytes have arrived, in order, each only when the write FIFO of its module has
//! room for all its copies (`AddressMap::voxel_copies`: 2 with the voxel-pair layouts, written
//! with byte masks; 1 with `interleaved8`).
//!
//! **Map unit (during the update).** Per sub-cube the table keeps the min and max over the
//! sub-cube's dilated block (`occupancy::dilated_range`, the same block `OccupancyMap::build`
//! tests); the '0' bit is max > 0 and the class bit `visible(min, max)`. Each voxel taken widens
//! the entries of every sub-cube whose block holds it. When a region starts, the entries of the
//! sub-cubes whose whole block lies inside the region are reset (the region overwrites all of
//! their voxels), so they end exact. A sub-cube only partly written is *dirty*: with
//! `PartialMapPolicy::Widen` its entry is only widened (min/max of old and new values: the map
//! is **conservative**, a bit may stay set after its voxels became empty); with `Rescan` its
//! block is read back through the read path after the writes and its entry recomputed (the map
//! is **exact**). After a full download every entry is exact.

use super::address_map::{AddressMap, Mapping, MemoryConfig};
use super::sdram::SdramTiming;
use super::sdram_module::{PendingWrite, SdramModule};
use crate::config::HardwareConfig;
use crate::error::{Error, Result};
use crate::occupancy::{dilated_range, OccupancyKind, OccupancyMap};
use crate::volume::Volume;

/// Header bytes of one region on the host link: origin and extent, 3 × 2 × 16 bits.
pub const REGION_HEADER_BYTES: u64 = 12;
/// The most cycles an update's host-link transfer may take (2^36: 11 minutes at 100 MHz).
pub const MAX_LINK_CYCLES: u64 = 1 << 36;
/// Bytes the host link may run ahead of the FPGA (its FIFO).
pub const HOST_BUFFER_BYTES: u64 = 64;
/// Voxels the input stage takes per cycle at most (one 32-bit host word of 8-bit voxels).
pub const INPUT_VOXELS_PER_CYCLE: usize = 4;
/// Voxels of the word-pair slice buffer (one slice of a region: 16×16 for the default tiles;
/// 4096 × 16 bits = 64 Kbit of block RAM at most).
pub const SLICE_BUFFER_VOXELS: usize = 4096;

const UNTOUCHED: u32 = 0;
const DIRTY: u32 = 1;
/// Reset by a whole-volume download: exact.
const WHOLE: u32 = u32::MAX;

/// A box of voxels written by an update: `values` x fastest, `dims` product long.
#[derive(Clone, Debug, PartialEq)]
pub struct Region {
    pub origin: [usize; 3],
    pub dims: [usize; 3],
    pub values: Vec<u16>,
}

/// What the host sends: regions written in order (a later region overwrites an earlier one
/// where they overlap; a voxel written twice ends with its last value).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VolumeUpdate {
    pub regions: Vec<Region>,
    /// The host announces a download of the whole volume: the map unit resets every table
    /// entry first, and every entry ends exact. `check` verifies that the regions cover every
    /// voxel and that a voxel sent twice (a tile border) carries the same value both times.
    pub whole_volume: bool,
    /// Voxel-pair words (`replicated4`, `linear4`): the host sends each region slice by slice
    /// including the slice above it (the border), and the FPGA writes each word (z, z + 1) once,
    /// whole, when voxel z + 1 arrives, from a buffer of the region's previous slice (at most
    /// `SLICE_BUFFER_VOXELS`); a region's top slice is written only at the volume's top. Without
    /// it every voxel is written into both its words with byte masks.
    pub word_pairs: bool,
}

impl VolumeUpdate {
    /// The whole volume as one region in volume order, x fastest (a download).
    pub fn full(volume: &Volume) -> VolumeUpdate {
        VolumeUpdate {
            regions: vec![Region {
                origin: [0; 3],
                dims: volume.dims,
                values: volume.data.clone(),
            }],
            whole_volume: true,
            word_pairs: false,
        }
    }

    /// The whole volume in the layout's tiles (the voxels of one row of every module: the
    /// block of `memory.block` words), tile after tile, x fastest: a download whose writes stay
    /// in one row per module for a tile. With the voxel-pair layouts each tile carries the
    /// slice above it and the words are written whole (`word_pairs`).
    pub fn full_tiled(volume: &Volume, config: &MemoryConfig) -> VolumeUpdate {
        let b = config.block.map(|b| b as usize);
        let pairs = config.mapping != Mapping::Interleaved8;
        let tile = if pairs {
            [2 * b[0], 2 * b[1], b[2]]
        } else {
            [2 * b[0], 2 * b[1], 2 * b[2]]
        };
        let d = volume.dims;
        let mut regions = Vec::new();
        for z in (0..d[2]).step_by(tile[2]) {
            for y in (0..d[1]).step_by(tile[1]) {
                for x in (0..d[0]).step_by(tile[0]) {
                    let o = [x, y, z];
                    let mut e = [0, 1, 2].map(|a| tile[a].min(d[a] - o[a]));
                    if pairs && z + e[2] < d[2] {
                        e[2] += 1; // the border slice
                    }
                    regions.push(Self::region_of(volume, o, e));
                }
            }
        }
        VolumeUpdate {
            regions,
            whole_volume: true,
            word_pairs: pairs,
        }
    }

    /// Single voxels, each its own region, in order.
    pub fn voxels(writes: &[([usize; 3], u16)]) -> VolumeUpdate {
        VolumeUpdate {
            regions: writes
                .iter()
                .map(|&(p, v)| Region {
                    origin: p,
                    dims: [1; 3],
                    values: vec![v],
                })
                .collect(),
            ..VolumeUpdate::default()
        }
    }

    /// The box `origin..origin + dims` of `volume` as one region.
    pub fn region_of(volume: &Volume, origin: [usize; 3], dims: [usize; 3]) -> Region {
        let mut values = Vec::with_capacity(dims.iter().product());
        for z in origin[2]..origin[2] + dims[2] {
            for y in origin[1]..origin[1] + dims[1] {
                let row = volume.index(0, y, z);
                values.extend_from_slice(&volume.data[row + origin[0]..row + origin[0] + dims[0]]);
            }
        }
        Region {
            origin,
            dims,
            values,
        }
    }

    /// An error naming the region when it leaves the volume, is empty, has the wrong number of
    /// values or a value above the volume's bit depth.
    pub fn check(&self, dims: [usize; 3], bits: u8) -> Result<()> {
        let max = if bits == 8 { 255 } else { u16::MAX };
        for (i, r) in self.regions.iter().enumerate() {
            let bad = |msg: String| Err(Error::Invalid(format!("update region {i}: {msg}")));
            if r.dims.contains(&0) {
                return bad(format!("extent {:?} is empty", r.dims));
            }
            if (0..3).any(|a| r.origin[a] + r.dims[a] > dims[a]) {
                return bad(format!(
                    "origin {:?} + extent {:?} leaves the {dims:?} volume",
                    r.origin, r.dims
                ));
            }
            let n = r.dims.iter().product::<usize>();
            if r.values.len() != n {
                return bad(format!(
                    "{} values for an extent of {n} voxels",
                    r.values.len()
                ));
            }
            if let Some(v) = r.values.iter().find(|&&v| v > max) {
                return bad(format!("value {v} exceeds the {bits}-bit volume's {max}"));
            }
            if self.word_pairs && r.dims[0] * r.dims[1] > SLICE_BUFFER_VOXELS {
                return bad(format!(
                    "a slice of {}×{} voxels exceeds the word-pair slice buffer of {SLICE_BUFFER_VOXELS}",
                    r.dims[0], r.dims[1]
                ));
            }
        }
        if self.word_pairs && !self.whole_volume {
            return Err(Error::Invalid(
                "word-pair updates are whole-volume downloads (a partial region would leave the \
                 copy of its bottom slice in the word below stale)"
                    .into(),
            ));
        }
        if self.whole_volume {
            // Every voxel sent, and sent with one value; with word pairs every voxel above the
            // bottom sent together with the one below it (so both its words are written).
            let mut seen: Vec<Option<u16>> = vec![None; dims.iter().product()];
            let mut paired = vec![false; if self.word_pairs { seen.len() } else { 0 }];
            for (i, r) in self.regions.iter().enumerate() {
                let mut values = r.values.iter();
                for z in r.origin[2]..r.origin[2] + r.dims[2] {
                    for y in r.origin[1]..r.origin[1] + r.dims[1] {
                        for x in r.origin[0]..r.origin[0] + r.dims[0] {
                            let v = *values.next().expect("checked length");
                            let slot = &mut seen[x + dims[0] * (y + dims[1] * z)];
                            if slot.is_some_and(|old| old != v) {
                                return Err(Error::Invalid(format!(
                                    "update region {i}: a whole-volume download sends voxel \
                                     {x},{y},{z} twice with different values"
                                )));
                            }
                            *slot = Some(v);
                            if self.word_pairs && z > r.origin[2] {
                                paired[x + dims[0] * (y + dims[1] * z)] = true;
                            }
                        }
                    }
                }
            }
            if let Some(i) = seen.iter().position(Option::is_none) {
                let (x, y, z) = (i % dims[0], i / dims[0] % dims[1], i / (dims[0] * dims[1]));
                return Err(Error::Invalid(format!(
                    "a whole-volume download must send every voxel; {x},{y},{z} is missing"
                )));
            }
            let plane = dims[0] * dims[1];
            if let Some(i) = (plane..paired.len()).find(|&i| !paired[i]) {
                let (x, y, z) = (i % dims[0], i / dims[0] % dims[1], i / plane);
                return Err(Error::Invalid(format!(
                    "a word-pair download must send voxel {x},{y},{z} in a region with the voxel \
                     below it (regions overlap by one slice in z)"
                )));
            }
        }
        Ok(())
    }

    /// Applies the update to a volume in memory (the reference the SDRAM image must equal).
    pub fn apply_to(&self, volume: &mut Volume) {
        for r in &self.regions {
            let mut values = r.values.iter();
            for z in r.origin[2]..r.origin[2] + r.dims[2] {
                for y in r.origin[1]..r.origin[1] + r.dims[1] {
                    for x in r.origin[0]..r.origin[0] + r.dims[0] {
                        let i = volume.index(x, y, z);
                        volume.data[i] = *values.next().expect("checked length");
                    }
                }
            }
        }
    }

    pub fn voxels_written(&self) -> u64 {
        self.regions.iter().map(|r| r.values.len() as u64).sum()
    }

    /// Bytes on the host link: headers and voxels.
    pub fn host_bytes(&self, voxel_bytes: u64) -> u64 {
        self.regions.len() as u64 * REGION_HEADER_BYTES + self.voxels_written() * voxel_bytes
    }
}

/// How the map unit treats sub-cubes an update writes only partly.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PartialMapPolicy {
    /// Widen their min/max by the new values: no extra memory traffic, the map stays
    /// conservative (a bit is never cleared until a rescan or a full download).
    Widen,
    /// Read their blocks back through the read path after the writes: the map is exact.
    Rescan,
}

/// Per sub-cube, the min and max voxel value over its dilated block: the on-chip table the map
/// bits come from (an entry with min > max has seen no voxel).
#[derive(Clone, Debug, PartialEq)]
pub struct MinMaxTable {
    pub cube_log2: u32,
    pub stencil_reach: usize,
    pub volume_dims: [usize; 3],
    /// Sub-cubes per axis.
    pub dims: [usize; 3],
    min: Vec<u16>,
    max: Vec<u16>,
    /// Per axis and voxel coordinate: the first and last sub-cube whose block holds it.
    holders: [Vec<(u32, u32)>; 3],
}

impl MinMaxTable {
    /// The table of a volume of zeros (every entry min = max = 0: exact for zeroed memory).
    pub fn zeros(volume_dims: [usize; 3], cube_log2: u32, stencil_reach: usize) -> MinMaxTable {
        let s = 1usize << cube_log2;
        let dims = volume_dims.map(|d| d.div_ceil(s));
        let holders = [0, 1, 2].map(|a| {
            (0..volume_dims[a])
                .map(|v| {
                    let cells: Vec<usize> = (0..dims[a])
                        .filter(|&c| {
                            let (lo, hi) =
                                dilated_range(c, cube_log2, stencil_reach, volume_dims[a]);
                            lo <= v && v <= hi
                        })
                        .collect();
                    (cells[0] as u32, *cells.last().unwrap() as u32)
                })
                .collect()
        });
        let n = dims.iter().product();
        MinMaxTable {
            cube_log2,
            stencil_reach,
            volume_dims,
            dims,
            min: vec![0; n],
            max: vec![0; n],
            holders,
        }
    }

    pub fn subcubes(&self) -> usize {
        self.min.len()
    }

    /// SRAM bits: a min and a max of `voxel_bits` each per sub-cube.
    pub fn storage_bits(&self, voxel_bits: u8) -> u64 {
        self.subcubes() as u64 * 2 * voxel_bits as u64
    }

    fn index(&self, c: [usize; 3]) -> usize {
        c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2])
    }

    fn reset(&mut self, i: usize) {
        self.min[i] = u16::MAX;
        self.max[i] = 0;
    }

    /// (min, max) of sub-cube `c`.
    pub fn entry(&self, c: [usize; 3]) -> (u16, u16) {
        let i = self.index(c);
        (self.min[i], self.max[i])
    }

    /// The voxel range of sub-cube c's block per axis.
    fn block(&self, c: [usize; 3]) -> [(usize, usize); 3] {
        [0, 1, 2].map(|a| {
            dilated_range(
                c[a],
                self.cube_log2,
                self.stencil_reach,
                self.volume_dims[a],
            )
        })
    }

    /// Calls `f` with the index of every sub-cube whose block holds voxel `p`.
    #[inline]
    fn for_each_holder(&self, p: [usize; 3], mut f: impl FnMut(usize)) {
        let [hx, hy, hz] = [0, 1, 2].map(|a| self.holders[a][p[a]]);
        for cz in hz.0..=hz.1 {
            for cy in hy.0..=hy.1 {
                for cx in hx.0..=hx.1 {
                    f(self.index([cx as usize, cy as usize, cz as usize]));
                }
            }
        }
    }

    /// Widens every entry whose block holds `p` by `value`.
    #[inline]
    fn widen(&mut self, p: [usize; 3], value: u16) {
        let [hx, hy, hz] = [0, 1, 2].map(|a| self.holders[a][p[a]]);
        for cz in hz.0..=hz.1 {
            for cy in hy.0..=hy.1 {
                for cx in hx.0..=hx.1 {
                    let i = self.index([cx as usize, cy as usize, cz as usize]);
                    self.min[i] = self.min[i].min(value);
                    self.max[i] = self.max[i].max(value);
                }
            }
        }
    }

    /// The map of `kind` over cubes of edge 2^`log2` ≥ the table's sub-cubes (bounding bricks'
    /// flags): a cube's range is its sub-cubes' hull (the least min, the greatest max), which
    /// is the range of its own dilated block, since those of its sub-cubes tile it. So it is
    /// `OccupancyMap::build`'s at that edge when the table is exact, and conservative when the
    /// table is widened. None when `log2` is below the table's.
    pub fn coarse_map(
        &self,
        kind: OccupancyKind,
        log2: u32,
        visible: impl Fn(u16, u16) -> bool,
    ) -> Option<OccupancyMap> {
        let shift = log2.checked_sub(self.cube_log2)?;
        let dims = self.volume_dims.map(|d| d.div_ceil(1 << log2));
        let mut lo = vec![u16::MAX; dims.iter().product()];
        let mut hi = vec![0u16; lo.len()];
        for z in 0..self.dims[2] {
            for y in 0..self.dims[1] {
                for x in 0..self.dims[0] {
                    let [cx, cy, cz] = [x, y, z].map(|c| c >> shift);
                    let coarse = cx + dims[0] * (cy + dims[1] * cz);
                    let (min, max) = self.entry([x, y, z]);
                    lo[coarse] = lo[coarse].min(min);
                    hi[coarse] = hi[coarse].max(max);
                }
            }
        }
        let cells = lo
            .iter()
            .zip(&hi)
            .map(|(&lo, &hi)| match kind {
                OccupancyKind::Zero => (hi > 0) as u8,
                OccupancyKind::Class => (lo <= hi && visible(lo, hi)) as u8,
            })
            .collect();
        Some(OccupancyMap::from_cells(log2, dims, cells))
    }

    /// The occupancy map of `kind` from the table: '0' occupied when max > 0, class when
    /// `visible(min, max)` (`OccupancyMap::build`'s tests on the same blocks).
    pub fn map(&self, kind: OccupancyKind, visible: impl Fn(u16, u16) -> bool) -> OccupancyMap {
        let cells = self
            .min
            .iter()
            .zip(&self.max)
            .map(|(&lo, &hi)| match kind {
                OccupancyKind::Zero => (hi > 0) as u8,
                OccupancyKind::Class => (lo <= hi && visible(lo, hi)) as u8,
            })
            .collect();
        OccupancyMap::from_cells(self.cube_log2, self.dims, cells)
    }
}

/// What an update cost, in pipeline clock cycles.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct UpdateReport {
    pub regions: u64,
    pub voxels_written: u64,
    pub host_bytes: u64,
    /// Cycles the host link needs for the bytes at its peak rate: the link's bound.
    pub host_link_cycles: u64,
    /// From the first cycle to the last WRITE (every copy in SDRAM).
    pub write_cycles: u64,
    /// Cycles the input stage waited for a write-FIFO place with bytes available (the SDRAM
    /// could not keep up with the link).
    pub write_stall_cycles: u64,
    pub writes: u64,
    /// WRITEs per voxel written (2 with the voxel-pair layouts except z = 0, 1 otherwise).
    pub writes_per_voxel: f64,
    pub write_row_misses: u64,
    pub refreshes: u64,
    /// Sub-cubes whose block the update wrote wholly (entry reset: exact).
    pub subcubes_reset: u64,
    /// Sub-cubes written only partly (dirty: widened, or rescanned under `Rescan`).
    pub subcubes_partial: u64,
    /// Cycles of the rescan of the partial sub-cubes (0 with `Widen`).
    pub rescan_cycles: u64,
    /// Cycles to write the touched sub-cubes' map bits from the table after the last voxel
    /// (one per cycle): the map-generation cost of the update beyond the writes.
    pub map_cycles: u64,
    /// write_cycles + rescan_cycles + map_cycles.
    pub total_cycles: u64,
    /// Whether the map is exact after the update (else conservative).
    pub map_exact: bool,
}

/// What a scan of the volume through the read path cost.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ScanReport {
    /// Sample requests (2×2×2 neighbourhoods at even coordinates: every voxel once).
    pub requests: u64,
    pub words_read: u64,
    pub cycles: u64,
    pub row_hit_rate: f64,
    pub refreshes: u64,
    /// cycles at the configured clock, in ms.
    pub ms: f64,
}

/// What a transfer-function change costs, both ways.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct TfChangeReport {
    /// Rebuilding the class map by scanning the volume (`ScanReport::cycles`).
    pub scan_cycles: u64,
    /// From the min/max table: the visibility prefix table of the new classification (one
    /// entry per density, built as the classification table is loaded) ...
    pub prefix_cycles: u64,
    /// ... then one pass over the table, one entry (two prefix lookups, one map bit) per cycle.
    pub table_pass_cycles: u64,
    /// SRAM bits of the min/max table.
    pub table_bits: u64,
    /// SRAM bits of the visibility prefix table (2^bits entries of bits + 1 bits).
    pub prefix_bits: u64,
}

/// Where the input stage is in the update's stream.
struct Feed<'a> {
    update: &'a VolumeUpdate,
    region: usize,
    voxel: usize,
    /// Header bytes of the current region still to arrive.
    header_left: u64,
}

/// One request of a scan: its base and the sub-cube it rescans (None: a full scan).
#[derive(Clone, Copy)]
struct ScanRequest {
    base: [usize; 3],
    cell: Option<usize>,
}

/// The update engine: the SDRAM modules with their contents, the host link and the min/max
/// table, with a clock that runs across operations (rows stay open, refresh stays due).
pub struct UpdateEngine {
    config: MemoryConfig,
    map: AddressMap,
    modules: Vec<SdramModule>,
    table: MinMaxTable,
    dims: [usize; 3],
    bits: u8,
    clock_mhz: f64,
    /// Host-link bytes per clock, 32.32 fixed point.
    link_per_cycle: u64,
    now: u64,
    /// The word-pair slice buffer (the region's previous slice).
    slice: Vec<u16>,
}

impl UpdateEngine {
    /// An engine for a `dims` volume of `bits`-bit voxels, zeroed memory and the zero table for
    /// `cube_log2` sub-cubes. Errors: the volume does not fit the memory.
    pub fn new(
        hw: &HardwareConfig,
        dims: [usize; 3],
        bits: u8,
        cube_log2: u32,
        stencil_reach: usize,
    ) -> Result<UpdateEngine> {
        let config = &hw.memory;
        config.validate("hardware configuration")?;
        config.check_covers(dims, "hardware configuration")?;
        if dims.contains(&0) {
            return Err(Error::Invalid(format!("volume extent {dims:?} is empty")));
        }
        // A voxel's copies enter one module's write FIFO together: a smaller FIFO could never
        // take them, and the engine would wait forever.
        if config.address_fifo_depth < config.replicas() {
            return Err(Error::config(
                "hardware configuration",
                "memory.address_fifo_depth",
                format!(
                    "{} is too small for a volume update: the {} layout writes each voxel as {} \
                     copies into one module's write FIFO at once; at least {}",
                    config.address_fifo_depth,
                    config.mapping.name(),
                    config.replicas(),
                    config.replicas()
                ),
            ));
        }
        let timing: &SdramTiming = &hw.sdram;
        let rows = config.rows_needed(dims) as u32;
        let link_per_cycle = hw.host_link_per_cycle_q32();
        if link_per_cycle == 0 {
            return Err(Error::config(
                "hardware configuration",
                "memory.host_link_mhz",
                "the host link delivers no bytes per pipeline clock (bandwidth 0)".to_string(),
            ));
        }
        Ok(UpdateEngine {
            map: AddressMap::new(config, dims),
            modules: (0..config.modules())
                .map(|_| {
                    // Nothing here reads the modules' last commands.
                    SdramModule::new(config, timing)
                        .with_image(config.banks, rows, config.columns)
                        .without_command_record()
                })
                .collect(),
            table: MinMaxTable::zeros(dims, cube_log2, stencil_reach),
            config: config.clone(),
            dims,
            bits,
            clock_mhz: hw.clock.frequency_mhz,
            link_per_cycle,
            now: 0,
            slice: Vec::new(),
        })
    }

    /// Module controllers that run every cycle instead of sleeping until their next possible
    /// command: the reference that sleeping must equal (tests).
    pub fn without_sleeping(mut self) -> UpdateEngine {
        self.modules = self
            .modules
            .into_iter()
            .map(SdramModule::without_sleeping)
            .collect();
        self
    }

    /// Per-module statistics (reads, writes, row misses, refreshes, ...).
    pub fn module_stats(&self) -> Vec<super::sdram_module::ModuleStats> {
        self.modules.iter().map(SdramModule::final_stats).collect()
    }

    pub fn now(&self) -> u64 {
        self.now
    }

    pub fn table(&self) -> &MinMaxTable {
        &self.table
    }

    /// SRAM bits the chip keeps beside the map when it builds maps from the min/max table
    /// (during updates, and for a transfer-function change): the map (one bit per sub-cube),
    /// the table and the visibility prefix table. A scan pass needs only the map.
    pub fn table_on_chip_bits(&self) -> u64 {
        let costs = self.tf_change_costs(0);
        self.table.subcubes() as u64 + costs.table_bits + costs.prefix_bits
    }

    /// The map of `kind` as the map unit holds it now.
    pub fn map(&self, kind: OccupancyKind, visible: impl Fn(u16, u16) -> bool) -> OccupancyMap {
        self.table.map(kind, visible)
    }

    fn voxel_bytes(&self) -> u64 {
        if self.bits == 8 {
            1
        } else {
            2
        }
    }

    /// Bytes per second over the clock: host-link bytes per pipeline cycle.
    pub fn host_bytes_per_cycle(&self) -> f64 {
        self.link_per_cycle as f64 / (1u64 << 32) as f64
    }

    fn step_modules(&mut self) {
        for m in &mut self.modules {
            m.step_with_writes(self.now);
        }
    }

    fn writes_pending(&self) -> bool {
        self.modules.iter().any(|m| m.writes_pending() > 0)
    }

    fn stats_sum(&self, f: fn(&super::sdram_module::ModuleStats) -> u64) -> u64 {
        self.modules.iter().map(|m| f(&m.stats)).sum()
    }

    /// Streams `update` from the host link into SDRAM, maintaining the table; returns what it
    /// cost. Errors: a region outside the volume or malformed (nothing is written then).
    pub fn update(
        &mut self,
        update: &VolumeUpdate,
        policy: PartialMapPolicy,
    ) -> Result<UpdateReport> {
        update.check(self.dims, self.bits)?;
        if update.word_pairs && self.config.mapping == Mapping::Interleaved8 {
            return Err(Error::Invalid(
                "word-pair updates need a voxel-pair layout (replicated4 or linear4); \
                 interleaved8 stores one voxel per word"
                    .into(),
            ));
        }
        // The link's own bound, known before simulating: a link so slow that the update would
        // take more cycles than a simulation can step through (a refresh every few thousand
        // cycles keeps the controllers busy) is refused, not simulated for days.
        let voxel_bytes = self.voxel_bytes();
        let link_bound =
            ((update.host_bytes(voxel_bytes) as u128) << 32).div_ceil(self.link_per_cycle as u128);
        if link_bound > MAX_LINK_CYCLES as u128 {
            return Err(Error::config(
                "hardware configuration",
                "memory.host_link_mhz",
                format!(
                    "the host link ({:.3e} bytes per cycle) needs {link_bound} cycles for this \
                     update, more than the 2^36 ({MAX_LINK_CYCLES}) the update engine \
                     simulates: raise memory.host_link_bits or memory.host_link_mhz, or lower \
                     clock.frequency_mhz",
                    self.host_bytes_per_cycle()
                ),
            ));
        }
        let start = self.now;
        let (writes0, misses0, refreshes0) = (
            self.stats_sum(|s| s.writes),
            self.stats_sum(|s| s.write_row_misses),
            self.stats_sum(|s| s.refreshes),
        );
        let mut feed = Feed {
            update,
            region: 0,
            voxel: 0,
            header_left: REGION_HEADER_BYTES,
        };
        // Per sub-cube: UNTOUCHED, DIRTY (partly written), or r + 2 when region r covers its
        // block wholly (entry reset when r began: exact unless a later region writes part).
        let mut touched = vec![UNTOUCHED; self.table.subcubes()];
        if update.whole_volume {
            for i in 0..self.table.subcubes() {
                self.table.reset(i);
            }
            touched.fill(WHOLE);
        }
        self.slice.clear();
        self.begin_region(update, 0, &mut touched);
        let mut credit = 0u64; // host bytes arrived, 32.32
        let cap = HOST_BUFFER_BYTES << 32;
        let mut stalls = 0u64;
        let mut last_write = start;
        loop {
            let input_done = feed.region >= update.regions.len();
            if input_done && !self.writes_pending() {
                break;
            }
            if !input_done && !self.writes_pending() {
                // Nothing to write, the input waiting for the link's next byte or voxel: jump
                // over the cycles in which only the credit grows, up to the first a controller
                // wakes in (a refresh). Exact (tests/dynamic.rs compares ticking controllers,
                // which never skip); a slow link otherwise costs a loop turn per cycle, over a
                // billion for a 1-bit link at 1 kHz.
                let need = if feed.header_left > 0 { 1 } else { voxel_bytes } << 32;
                let waiting = (need.saturating_sub(credit) as u128)
                    .div_ceil(self.link_per_cycle as u128)
                    .saturating_sub(1);
                let wake = self.modules.iter().map(SdramModule::wakes_at).min();
                let skip = (waiting as u64).min(wake.unwrap_or(u64::MAX).saturating_sub(self.now));
                credit += skip * self.link_per_cycle;
                self.now += skip;
            }
            // Saturating: the fastest validated link brings 2^32 bytes per cycle and more.
            credit = credit.saturating_add(self.link_per_cycle).min(cap);
            if !input_done {
                stalls +=
                    self.input_cycle(&mut feed, &mut credit, voxel_bytes, &mut touched) as u64;
            }
            let before = self.stats_sum(|s| s.writes);
            self.step_modules();
            if self.stats_sum(|s| s.writes) != before {
                last_write = self.now;
            }
            self.now += 1;
        }
        let write_cycles = last_write + 1 - start;
        let reset = touched.iter().filter(|&&t| t >= 2 || t == WHOLE).count() as u64;
        let partial = touched.iter().filter(|&&t| t == DIRTY).count() as u64;
        let rescan_cycles = match policy {
            PartialMapPolicy::Widen => 0,
            PartialMapPolicy::Rescan => {
                let cells: Vec<usize> = (0..touched.len())
                    .filter(|&i| touched[i] == DIRTY)
                    .collect();
                self.rescan(&cells)
            }
        };
        let map_cycles = reset + partial;
        let writes = self.stats_sum(|s| s.writes) - writes0;
        let voxels = update.voxels_written();
        let host_bytes = update.host_bytes(voxel_bytes);
        Ok(UpdateReport {
            regions: update.regions.len() as u64,
            voxels_written: voxels,
            host_bytes,
            host_link_cycles: ((host_bytes as u128) << 32).div_ceil(self.link_per_cycle as u128)
                as u64,
            write_cycles,
            write_stall_cycles: stalls,
            writes,
            writes_per_voxel: writes as f64 / voxels.max(1) as f64,
            write_row_misses: self.stats_sum(|s| s.write_row_misses) - misses0,
            refreshes: self.stats_sum(|s| s.refreshes) - refreshes0,
            subcubes_reset: reset,
            subcubes_partial: partial,
            rescan_cycles,
            map_cycles,
            total_cycles: write_cycles + rescan_cycles + map_cycles,
            map_exact: partial == 0 || policy == PartialMapPolicy::Rescan,
        })
    }

    /// A region starts: reset the entries of the sub-cubes whose block it covers wholly.
    fn begin_region(&mut self, update: &VolumeUpdate, region: usize, touched: &mut [u32]) {
        let Some(r) = update.regions.get(region) else {
            return;
        };
        if update.whole_volume {
            return; // every entry was reset at the start
        }
        let s = 1usize << self.table.cube_log2;
        let lo = [0, 1, 2].map(|a| r.origin[a].saturating_sub(s + self.table.stencil_reach) / s);
        let hi = [0, 1, 2].map(|a| ((r.origin[a] + r.dims[a]) / s).min(self.table.dims[a] - 1));
        for cz in lo[2]..=hi[2] {
            for cy in lo[1]..=hi[1] {
                for cx in lo[0]..=hi[0] {
                    let c = [cx, cy, cz];
                    let block = self.table.block(c);
                    let inside = (0..3)
                        .all(|a| r.origin[a] <= block[a].0 && block[a].1 < r.origin[a] + r.dims[a]);
                    if inside {
                        let i = self.table.index(c);
                        self.table.reset(i);
                        touched[i] = region as u32 + 2;
                    }
                }
            }
        }
    }

    /// One cycle of the input stage; returns whether it stalled on a full write FIFO.
    fn input_cycle(
        &mut self,
        feed: &mut Feed,
        credit: &mut u64,
        voxel_bytes: u64,
        touched: &mut [u32],
    ) -> bool {
        let one = 1u64 << 32;
        // Header bytes first (the region's origin and extent).
        if feed.header_left > 0 {
            let arrived = (*credit >> 32).min(feed.header_left);
            feed.header_left -= arrived;
            *credit -= arrived * one;
            if feed.header_left > 0 {
                return false;
            }
        }
        for _ in 0..INPUT_VOXELS_PER_CYCLE {
            if *credit < voxel_bytes * one {
                return false;
            }
            let r = &feed.update.regions[feed.region];
            let i = feed.voxel;
            let p = [
                r.origin[0] + i % r.dims[0],
                r.origin[1] + (i / r.dims[0]) % r.dims[1],
                r.origin[2] + i / (r.dims[0] * r.dims[1]),
            ];
            let value = r.values[i];
            if feed.update.word_pairs {
                if !self.write_pair(r, p, value) {
                    return true;
                }
            } else {
                let (copies, n) = self.map.voxel_copies(p);
                let module = &mut self.modules[copies[0].0.module as usize];
                if module.writes_pending() + n > self.config.address_fifo_depth {
                    return true;
                }
                for &(addr, half) in &copies[..n] {
                    module.push_write(
                        PendingWrite {
                            addr,
                            data: (value as u32) << (16 * half as u32),
                            mask: 1 << half,
                        },
                        self.now,
                    );
                }
            }
            *credit -= voxel_bytes * one;
            // The map unit: widen every holder; a holder not reset by this region is dirty.
            let table = &mut self.table;
            let this = feed.region as u32 + 2;
            if !feed.update.whole_volume {
                table.for_each_holder(p, |c| {
                    if touched[c] != this {
                        touched[c] = DIRTY;
                    }
                });
            }
            table.widen(p, value);
            feed.voxel += 1;
            if feed.voxel == r.values.len() {
                feed.region += 1;
                feed.voxel = 0;
                feed.header_left = REGION_HEADER_BYTES;
                let update = feed.update;
                self.begin_region(update, feed.region, touched);
                if feed.region >= update.regions.len() {
                    return false;
                }
                // The next region's header must arrive before its voxels.
                let arrived = (*credit >> 32).min(feed.header_left);
                feed.header_left -= arrived;
                *credit -= arrived * one;
                if feed.header_left > 0 {
                    return false;
                }
            }
        }
        false
    }

    /// Word-pair mode: voxel `p` of region `r` completes the word (z − 1, z) from the slice
    /// buffer (above the region's first slice), and at the volume's top starts and ends its
    /// own word (low half). False, nothing done, if the module's write FIFO lacks room.
    fn write_pair(&mut self, r: &Region, p: [usize; 3], value: u16) -> bool {
        let at = (p[0] - r.origin[0]) + r.dims[0] * (p[1] - r.origin[1]);
        if self.slice.len() < r.dims[0] * r.dims[1] {
            self.slice.resize(r.dims[0] * r.dims[1], 0);
        }
        let below = p[2] > r.origin[2];
        let top = p[2] == self.dims[2] - 1;
        let n = below as usize + top as usize;
        let (own, _) = self.map.voxel_copies(p);
        let module = &mut self.modules[own[0].0.module as usize];
        if module.writes_pending() + n > self.config.address_fifo_depth {
            return false;
        }
        if below {
            let (word, _) = self.map.voxel_copies([p[0], p[1], p[2] - 1]);
            module.push_write(
                PendingWrite {
                    addr: word[0].0,
                    data: self.slice[at] as u32 | (value as u32) << 16,
                    mask: 3,
                },
                self.now,
            );
        }
        if top {
            module.push_write(
                PendingWrite {
                    addr: own[0].0,
                    data: value as u32,
                    mask: 1,
                },
                self.now,
            );
        }
        self.slice[at] = value;
        true
    }

    /// Reads the whole volume through the read path and rebuilds every table entry exactly:
    /// the separate scan pass.
    pub fn scan(&mut self) -> ScanReport {
        for i in 0..self.table.subcubes() {
            self.table.reset(i);
        }
        let mut requests = Vec::new();
        self.scan_bases(
            [
                (0, self.dims[0] - 1),
                (0, self.dims[1] - 1),
                (0, self.dims[2] - 1),
            ],
            |base| requests.push(ScanRequest { base, cell: None }),
        );
        self.run_scan(&requests)
    }

    /// Recomputes the entries of `cells` from their blocks read through the read path; the
    /// cycles it took.
    fn rescan(&mut self, cells: &[usize]) -> u64 {
        let mut requests = Vec::new();
        for &i in cells {
            self.table.reset(i);
            let d = self.table.dims;
            let c = [i % d[0], (i / d[0]) % d[1], i / (d[0] * d[1])];
            let block = self.table.block(c);
            self.scan_bases(block, |base| {
                requests.push(ScanRequest {
                    base,
                    cell: Some(i),
                })
            });
        }
        self.run_scan(&requests).cycles
    }

    /// The even-coordinate bases whose neighbourhoods cover the voxel box `range`, in the
    /// layout's block order (one row per module for a block's requests).
    fn scan_bases(&self, range: [(usize, usize); 3], mut f: impl FnMut([usize; 3])) {
        let b = self.config.block;
        let tile = match self.config.mapping {
            Mapping::Interleaved8 => [2 * b[0], 2 * b[1], 2 * b[2]],
            _ => [2 * b[0], 2 * b[1], b[2]],
        }
        .map(|t| t as usize);
        let lo = range.map(|(l, _)| l & !1);
        let hi = range.map(|(_, h)| h);
        let first_tile = [0, 1, 2].map(|a| lo[a] / tile[a]);
        let last_tile = [0, 1, 2].map(|a| hi[a] / tile[a]);
        for tz in first_tile[2]..=last_tile[2] {
            for ty in first_tile[1]..=last_tile[1] {
                for tx in first_tile[0]..=last_tile[0] {
                    let t = [tx, ty, tz];
                    let from = [0, 1, 2].map(|a| lo[a].max(t[a] * tile[a]));
                    let to = [0, 1, 2].map(|a| hi[a].min(t[a] * tile[a] + tile[a] - 1));
                    for z in (from[2]..=to[2]).step_by(2) {
                        for y in (from[1]..=to[1]).step_by(2) {
                            for x in (from[0]..=to[0]).step_by(2) {
                                f([x, y, z]);
                            }
                        }
                    }
                }
            }
        }
    }

    /// Issues the requests through the modules' read path (one per cycle when every module
    /// has room), assembles each from its words and widens the table with the voxels read.
    fn run_scan(&mut self, requests: &[ScanRequest]) -> ScanReport {
        let start = self.now;
        let (reads0, hits0, refreshes0) = (
            self.stats_sum(|s| s.reads),
            self.stats_sum(|s| s.row_hits),
            self.stats_sum(|s| s.refreshes),
        );
        // Tags: slots of a small reassembly buffer, reused when free.
        let slots = 64usize;
        let mut missing = vec![0u8; slots];
        let mut free: Vec<usize> = (0..slots).rev().collect();
        let mut slot_request = vec![0usize; slots];
        let mut next = 0usize;
        let mut done = 0usize;
        let words_per_request = self.modules.len() as u8;
        while done < requests.len() {
            if next < requests.len()
                && !free.is_empty()
                && self.modules.iter().all(SdramModule::can_accept)
            {
                let slot = free.pop().expect("checked");
                slot_request[slot] = next;
                missing[slot] = words_per_request;
                let modules = &mut self.modules;
                let now = self.now;
                self.map.for_each_sample_word(requests[next].base, |w| {
                    modules[w.module as usize].push(slot as u32, w, now)
                });
                next += 1;
            }
            for m in 0..self.modules.len() {
                self.modules[m].step_with_writes(self.now);
                if let Some(tag) = self.modules[m].pop_word(self.now) {
                    let slot = tag as usize;
                    missing[slot] -= 1;
                    if missing[slot] == 0 {
                        let request = requests[slot_request[slot]];
                        self.absorb(request);
                        free.push(slot);
                        done += 1;
                    }
                }
            }
            self.now += 1;
        }
        let cycles = self.now - start;
        let reads = self.stats_sum(|s| s.reads) - reads0;
        ScanReport {
            requests: requests.len() as u64,
            words_read: reads,
            cycles,
            row_hit_rate: (self.stats_sum(|s| s.row_hits) - hits0) as f64 / reads.max(1) as f64,
            refreshes: self.stats_sum(|s| s.refreshes) - refreshes0,
            ms: cycles as f64 / (self.clock_mhz * 1e3),
        }
    }

    /// The voxels a completed scan request read, from the words it read (for the voxel-pair
    /// layouts the upper z voxel is the high half of the lower one's word), into the table.
    fn absorb(&mut self, request: ScanRequest) {
        let b = request.base;
        let pair = self.config.mapping != Mapping::Interleaved8;
        for dz in 0..2 {
            for dy in 0..2 {
                for dx in 0..2 {
                    let p = [b[0] + dx, b[1] + dy, b[2] + dz];
                    if (0..3).any(|a| p[a] >= self.dims[a]) {
                        continue;
                    }
                    let value = if pair && dz == 1 {
                        // High half of the word at z − 1 (= the base's z): the word read.
                        self.copy_value(p, 1)
                    } else {
                        self.copy_value(p, 0)
                    };
                    match request.cell {
                        None => self.table.widen(p, value),
                        Some(i) => {
                            let d = self.table.dims;
                            let c = [i % d[0], (i / d[0]) % d[1], i / (d[0] * d[1])];
                            let block = self.table.block(c);
                            if (0..3).all(|a| block[a].0 <= p[a] && p[a] <= block[a].1) {
                                self.table.min[i] = self.table.min[i].min(value);
                                self.table.max[i] = self.table.max[i].max(value);
                            }
                        }
                    }
                }
            }
        }
    }

    /// Voxel `p` as stored in its copy `copy` (0: own word, 1: the word of z − 1).
    fn copy_value(&self, p: [usize; 3], copy: usize) -> u16 {
        let (copies, n) = self.map.voxel_copies(p);
        let (addr, half) = copies[copy.min(n - 1)];
        let image = self.modules[addr.module as usize]
            .image()
            .expect("the engine's modules hold images");
        (image.word(addr) >> (16 * half as u32)) as u16
    }

    /// The volume as the SDRAM holds it (each voxel from its own word), or an error naming the
    /// first voxel whose copies disagree.
    pub fn memory_volume(&self, name: &str) -> Result<Volume> {
        let mut data = Vec::with_capacity(self.dims.iter().product());
        for z in 0..self.dims[2] {
            for y in 0..self.dims[1] {
                for x in 0..self.dims[0] {
                    let p = [x, y, z];
                    let v = self.copy_value(p, 0);
                    let (_, n) = self.map.voxel_copies(p);
                    if n == 2 && self.copy_value(p, 1) != v {
                        return Err(Error::Invalid(format!(
                            "voxel {p:?}: its copies in SDRAM differ ({v} and {})",
                            self.copy_value(p, 1)
                        )));
                    }
                    data.push(v);
                }
            }
        }
        Volume::new(name, self.dims, [1.0; 3], self.bits, data)
    }

    /// A transfer-function change: the class map rebuilt by a scan (`scan_cycles`, measured
    /// with `scan`) against one pass over the min/max table.
    pub fn tf_change_costs(&self, scan_cycles: u64) -> TfChangeReport {
        let densities = 1u64 << self.bits;
        TfChangeReport {
            scan_cycles,
            prefix_cycles: densities,
            table_pass_cycles: self.table.subcubes() as u64,
            table_bits: self.table.storage_bits(self.bits),
            prefix_bits: densities * (self.bits as u64 + 1),
        }
    }
}

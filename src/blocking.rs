//! 2-way blocking (brief, section 7): the volume memory holds only the *active* blocks of B³
//! voxels, each stored with a one-voxel border in a slot of (B + 2)³ voxels, and an on-chip
//! indirection table maps a block index to its slot. Small bricks or the occupancy map still do
//! the skipping; blocking saves memory. docs/model.md, "Blocking".
//!
//! **Which blocks are active.** A sample whose lower corner (the voxel its memory request is
//! addressed by, `FixedRenderer::base_voxel`) lies in block b reads voxels up to one further
//! along each axis, so b decides by the dilated block [B·b, B·b + B] (clamped): the same
//! conservative test as the occupancy map (`OccupancyMap::build` with the block as sub-cube;
//! kind '0': any non-zero voxel, class: the classification table's min/max test). A sample in
//! an inactive block is not read: its 8 voxels (and gradients) read as zero. For the image to
//! stay the same bit for bit, zero must then be invisible too: with a class test and a transfer
//! function that gives density 0 non-zero opacity, every block is active (reading zero would
//! show). With kind '0' an inactive block's voxels are all zero anyway.
//!
//! **Why the border.** A sample in an active block reads its upper neighbours from the block's
//! own slot (the border holds copies of the neighbouring blocks' voxels), so it never needs a
//! second table lookup or another slot, and it reads the true values even when the neighbour
//! block is inactive. The lower border layer is stored as the brief describes ((B + 2)³) but not
//! read: gradients are stored per voxel (`shading`), so no stencil reaches below the sample's
//! lower corner.

use crate::arch::address_map::{Mapping, MemoryConfig};
use crate::error::{Error, Result};
use crate::occupancy::{OccupancyKind, OccupancyMap};
use crate::volume::Volume;

/// Slot index of an inactive block in the table.
const INACTIVE: u32 = u32::MAX;

/// The indirection table: per block (x fastest) its slot, slots numbered in block order.
#[derive(Clone, Debug, PartialEq)]
pub struct BlockTable {
    pub block_log2: u32,
    /// Blocks per axis (the volume's dimensions / B).
    pub grid: [usize; 3],
    slots: Vec<u32>,
    pub active: usize,
}

/// Checks a block size against the volume: it must divide every dimension.
pub fn check_block_size(size: usize, dims: [usize; 3]) -> Result<u32> {
    if let Some(a) = (0..3).find(|&a| !dims[a].is_multiple_of(size)) {
        // The largest power of two (blocks are 4..=256, powers of two) dividing every dimension.
        let largest = dims
            .iter()
            .map(|&d| 1usize << d.trailing_zeros().min(8))
            .min()
            .unwrap_or(1);
        let advice = if largest >= 4 {
            format!("use a block size that divides every dimension (at most {largest})")
        } else {
            format!(
                "no block size does (4 to 256, powers of two; the largest power of two dividing \
                 every dimension is {largest}): blocking cannot store this volume, whose edge \
                 blocks are not padded"
            )
        };
        return Err(Error::config(
            "hardware configuration",
            "blocking.block_size",
            format!(
                "{size} does not divide the volume's {} dimension ({}, volume {dims:?}); {advice}",
                ["x", "y", "z"][a],
                dims[a]
            ),
        ));
    }
    Ok(size.trailing_zeros())
}

impl BlockTable {
    /// The table for `volume` with blocks of 2^`block_log2`: active by `kind` (class:
    /// `visible(min, max)`), and every block when density 0 is visible (`zero_visible`) under a
    /// class test.
    pub fn build(
        volume: &Volume,
        kind: OccupancyKind,
        block_log2: u32,
        zero_visible: bool,
        visible: impl Fn(u16, u16) -> bool,
    ) -> BlockTable {
        let map = OccupancyMap::build(volume, kind, block_log2, 0, visible);
        let all = kind == OccupancyKind::Class && zero_visible;
        let mut slots = Vec::with_capacity(map.subcubes());
        let mut active = 0u32;
        for z in 0..map.dims[2] {
            for y in 0..map.dims[1] {
                for x in 0..map.dims[0] {
                    if all || map.occupied([x, y, z]) {
                        slots.push(active);
                        active += 1;
                    } else {
                        slots.push(INACTIVE);
                    }
                }
            }
        }
        BlockTable {
            block_log2,
            grid: map.dims,
            slots,
            active: active as usize,
        }
    }

    pub fn block_size(&self) -> usize {
        1 << self.block_log2
    }

    pub fn blocks(&self) -> usize {
        self.slots.len()
    }

    /// The block holding voxel `v`.
    #[inline(always)]
    pub fn block_of(&self, v: [usize; 3]) -> [usize; 3] {
        v.map(|c| c >> self.block_log2)
    }

    /// The slot of block `b`, None when inactive.
    #[inline(always)]
    pub fn slot(&self, b: [usize; 3]) -> Option<u32> {
        let s = self.slots[b[0] + self.grid[0] * (b[1] + self.grid[1] * b[2])];
        (s != INACTIVE).then_some(s)
    }

    /// The slot of the block holding voxel `v` (a sample's lower corner), None when inactive.
    #[inline(always)]
    pub fn slot_at(&self, v: [usize; 3]) -> Option<u32> {
        self.slot(self.block_of(v))
    }

    /// Bits of the on-chip table: per block a slot index wide enough for every slot the memory
    /// holds, plus a valid bit.
    pub fn sram_bits(&self, memory: &MemoryConfig) -> u64 {
        let slots = max_slots(memory, self.block_size()).max(2);
        let index_bits = 64 - (slots - 1).leading_zeros() as u64;
        self.blocks() as u64 * (index_bits + 1)
    }
}

/// How a slot is laid out in one module: the module-local word extent of a (B + 2)³ voxel
/// block, cut into the `memory.block` word blocks of the unblocked layout (the last one along
/// an axis partial: the border makes the extent B/2 + 1 words), the word blocks packed into the
/// slot's rows largest first so each lies inside one row (whole word blocks take a row each, in
/// x-fastest order; the thin border pieces share rows), and how many row units (one bank's row)
/// that takes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SlotLayout {
    /// Module-local words per axis of a slot.
    pub local: [usize; 3],
    /// Word blocks (`memory.block`) per axis of a slot (cubic layouts).
    pub word_blocks: [usize; 3],
    /// Per axis and word-block coordinate: the word block's extent in words.
    pub extents: [Vec<usize>; 3],
    /// Per word block (x fastest): its first word in the slot.
    pub starts: Vec<usize>,
    /// Row units per slot: each a (bank, row); slot s takes units s·units .. (s + 1)·units, unit
    /// G in bank G mod banks, row G / banks.
    pub units: usize,
}

impl SlotLayout {
    pub fn new(memory: &MemoryConfig, block_size: usize) -> SlotLayout {
        let e = block_size + 2;
        let local = match memory.mapping {
            Mapping::Replicated4 | Mapping::Linear4 => [e / 2, e / 2, e],
            Mapping::Interleaved8 => [e / 2; 3],
        };
        let columns = memory.columns as usize;
        let word_blocks = [0, 1, 2].map(|a| local[a].div_ceil(memory.block[a] as usize));
        let extents = [0, 1, 2].map(|a| {
            let b = memory.block[a] as usize;
            (0..word_blocks[a])
                .map(|k| b.min(local[a] - k * b))
                .collect::<Vec<_>>()
        });
        let mut starts = Vec::new();
        let units = match memory.mapping {
            Mapping::Linear4 => (local.iter().product::<usize>()).div_ceil(columns),
            _ => {
                let g = word_blocks;
                let size = |k: usize| {
                    extents[0][k % g[0]]
                        * extents[1][(k / g[0]) % g[1]]
                        * extents[2][k / (g[0] * g[1])]
                };
                let mut order: Vec<usize> = (0..g.iter().product()).collect();
                order.sort_by_key(|&k| std::cmp::Reverse(size(k)));
                starts = vec![0; order.len()];
                let mut next = 0;
                for k in order {
                    let n = size(k);
                    if next % columns + n > columns {
                        next = next.div_ceil(columns) * columns;
                    }
                    starts[k] = next;
                    next += n;
                }
                next.div_ceil(columns)
            }
        };
        SlotLayout {
            local,
            word_blocks,
            extents,
            starts,
            units,
        }
    }

    /// Words of a slot that hold data, per module.
    pub fn words(&self) -> usize {
        self.local.iter().product()
    }
}

/// Slots the configured memory holds for blocks of `block_size`.
pub fn max_slots(memory: &MemoryConfig, block_size: usize) -> u64 {
    let units = SlotLayout::new(memory, block_size).units as u64;
    memory.rows as u64 * memory.banks as u64 / units
}

/// Rows per bank that `slots` slots take.
pub fn rows_needed(memory: &MemoryConfig, block_size: usize, slots: usize) -> u64 {
    let units = SlotLayout::new(memory, block_size).units as u64;
    (slots as u64 * units).div_ceil(memory.banks as u64)
}

/// What blocking saves and costs, for the run's measurements.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct BlockingStats {
    pub block_size: usize,
    pub blocks: usize,
    pub active_blocks: usize,
    /// Rows per bank the volume takes without blocking and with it (active slots only).
    pub rows_unblocked: u64,
    pub rows_blocked: u64,
    /// Memory words (64-bit, all modules) of those rows.
    pub memory_words_unblocked: u64,
    pub memory_words_blocked: u64,
    /// Slots the configured memory holds.
    pub slots_available: u64,
    /// Bits of the on-chip indirection table.
    pub table_sram_bits: u64,
    /// Cycles the table lookup adds to address generation.
    pub lookup_latency: u32,
    /// Cycle model: sample requests that looked up an inactive block (read as zero, no memory
    /// read).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub zero_samples: Option<u64>,
}

impl BlockingStats {
    pub fn new(
        table: &BlockTable,
        memory: &MemoryConfig,
        dims: [usize; 3],
        lookup_latency: u32,
    ) -> BlockingStats {
        let b = table.block_size();
        let row_words = memory.banks as u64 * memory.columns as u64 * memory.modules() as u64;
        let rows_unblocked = memory.rows_needed(dims);
        let rows_blocked = rows_needed(memory, b, table.active);
        BlockingStats {
            block_size: b,
            blocks: table.blocks(),
            active_blocks: table.active,
            rows_unblocked,
            rows_blocked,
            memory_words_unblocked: rows_unblocked * row_words,
            memory_words_blocked: rows_blocked * row_words,
            slots_available: max_slots(memory, b),
            table_sram_bits: table.sram_bits(memory),
            lookup_latency,
            zero_samples: None,
        }
    }

    /// Whether the active blocks fit the configured rows.
    pub fn fits(&self, memory: &MemoryConfig) -> bool {
        self.rows_blocked <= memory.rows as u64
    }

    /// "with blocking (block B) it needs N active blocks of M slots ..." for error messages.
    pub fn describe(&self) -> String {
        format!(
            "with blocking (block {}) it needs {} active blocks of {} ({} rows per bank), the \
             memory holds {} slots",
            self.block_size,
            self.active_blocks,
            self.blocks,
            self.rows_blocked,
            self.slots_available
        )
    }
}

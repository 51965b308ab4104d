//! Address mapping: which memory module, bank, row and column hold each word a sample needs.
//! A policy chosen by configuration (`memory.mapping`):
//!
//! - `replicated4` (published): 4 modules, module = (x mod 2) + 2·(y mod 2); each 64-bit word
//!   holds the voxel pair (z, z+1) and every z starts a pair (2× storage), so a sample's
//!   2×2×2 neighbourhood is one word from each module. Module-local word coordinates
//!   (x/2, y/2, z) are grouped in cubic blocks of `block` words, one block per row.
//! - `interleaved8`: 8 modules, module = (x mod 2) + 2·(y mod 2) + 4·(z mod 2), one voxel per
//!   word, no replication; local coordinates (x/2, y/2, z/2) in cubic blocks likewise.
//! - `linear4`: the 4-module interleave of `replicated4` with a plain linear address inside the
//!   module (x/2 fastest, then y/2, then z): the layout without locality, for comparison.
//!
//! Cubic layouts: block B = local / block, offset o = local mod block; column = o_x + b_x·(o_y +
//! b_y·o_z). The bank takes the low bits of the block coordinates, interleaved x, y, z (4 banks:
//! bank = (B_x mod 2) + 2·(B_y mod 2), so blocks next along x or y lie in another bank); the row
//! is the linear index of the remaining block bits. Every block has its own (bank, row).
//! Linear: address a, global row r = a / columns, column = a mod columns, bank = r mod banks,
//! row = r / banks.

use serde::{Deserialize, Serialize};

use crate::blocking::{BlockTable, SlotLayout};
use crate::error::{Error, Result};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mapping {
    Replicated4,
    Interleaved8,
    Linear4,
}

impl Mapping {
    /// The mapping as `memory.mapping` spells it in TOML (what messages show, not `Replicated4`).
    pub fn name(self) -> &'static str {
        match self {
            Mapping::Replicated4 => "replicated4",
            Mapping::Interleaved8 => "interleaved8",
            Mapping::Linear4 => "linear4",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RowPolicy {
    /// Leave a row open after a read (hits are cheap, conflicts pay tRP).
    Open,
    /// Precharge a bank after a read unless a queued request hits its row.
    Close,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MemoryConfig {
    pub mapping: Mapping,
    /// Cubic block of module-local words stored in one row.
    pub block: [u32; 3],
    /// Banks per module (power of two).
    pub banks: u32,
    /// Rows per bank.
    pub rows: u32,
    /// Words per row (power of two).
    pub columns: u32,
    /// Address FIFO depth per module (the overtaking FIFO's storage).
    pub address_fifo_depth: usize,
    /// Voxel FIFO depth per module (returned words).
    pub voxel_fifo_depth: usize,
    /// Let a request to an open row overtake older requests to other rows.
    pub overtaking: bool,
    /// How many of the oldest requests the overtaking FIFO searches.
    pub overtaking_window: usize,
    /// How often the oldest request may be overtaken before it must be served.
    pub max_bypass: u32,
    pub row_policy: RowPolicy,
    /// Where the distance volume's words lie (`occupancy.structure = "distance"`): in the rows
    /// after the volume's, in the bank of the voxel's own word ("same-bank") or in the bank
    /// with every bank bit flipped ("other-bank"). Written out only when not the default.
    #[serde(default, skip_serializing_if = "DistancePlacement::is_same_bank")]
    pub distance_placement: DistancePlacement,
    /// Host link that feeds volume updates (`arch::update`): data width in bits. Default the
    /// 32-bit PCI bus of the VIZARD II card. Optional in files, written only when not default.
    #[serde(
        default = "default_host_link_bits",
        skip_serializing_if = "is_default_host_link_bits"
    )]
    pub host_link_bits: u32,
    /// Host link transfer clock in MHz (default 33 MHz PCI: 32 bit × 33 MHz = 132 MB/s peak).
    #[serde(
        default = "default_host_link_mhz",
        skip_serializing_if = "is_default_host_link_mhz"
    )]
    pub host_link_mhz: f64,
}

fn default_host_link_bits() -> u32 {
    32
}
fn is_default_host_link_bits(v: &u32) -> bool {
    *v == default_host_link_bits()
}
fn default_host_link_mhz() -> f64 {
    33.0
}
fn is_default_host_link_mhz(v: &f64) -> bool {
    *v == default_host_link_mhz()
}

/// The bank of a distance word relative to its voxel's word (`AddressMap::distance_word`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DistancePlacement {
    /// The voxel word's bank: a step's distance read and its sample's read share a bank (and
    /// conflict in its row buffer).
    #[default]
    SameBank,
    /// The voxel word's bank XOR (banks − 1): the bank of the diagonal neighbour block.
    OtherBank,
}

impl DistancePlacement {
    pub fn is_same_bank(&self) -> bool {
        *self == DistancePlacement::SameBank
    }
}

impl MemoryConfig {
    pub fn validate(&self, source: &str) -> Result<()> {
        let err = |field: &str, msg: String| Err(Error::config(source, field, msg));
        for (i, b) in self.block.iter().enumerate() {
            if !b.is_power_of_two() || *b > 64 {
                return err(
                    &format!("memory.block[{i}]"),
                    format!("{b} is not allowed; allowed a power of two 1..=64"),
                );
            }
        }
        if !self.banks.is_power_of_two() || self.banks > 16 {
            return err(
                "memory.banks",
                format!("{} is not allowed; allowed 1, 2, 4, 8, 16", self.banks),
            );
        }
        if !self.columns.is_power_of_two() || !(8..=1 << 16).contains(&self.columns) {
            return err(
                "memory.columns",
                format!(
                    "{} is not allowed; allowed a power of two 8..=65536",
                    self.columns
                ),
            );
        }
        let words = self.block.iter().product::<u32>();
        if words > self.columns {
            return err(
                "memory.block",
                format!(
                    "{:?} holds {words} words, more than a row's {} columns",
                    self.block, self.columns
                ),
            );
        }
        if !(1..=1 << 24).contains(&self.rows) {
            return err(
                "memory.rows",
                format!("{} is out of range; allowed 1..=16777216", self.rows),
            );
        }
        if !(1..=4096).contains(&self.address_fifo_depth) {
            return err(
                "memory.address_fifo_depth",
                format!(
                    "{} is out of range; allowed 1..=4096",
                    self.address_fifo_depth
                ),
            );
        }
        if !(1..=4096).contains(&self.voxel_fifo_depth) {
            return err(
                "memory.voxel_fifo_depth",
                format!(
                    "{} is out of range; allowed 1..=4096",
                    self.voxel_fifo_depth
                ),
            );
        }
        if !(1..=1024).contains(&self.host_link_bits) {
            return err(
                "memory.host_link_bits",
                format!(
                    "{} is out of range; allowed 1..=1024 bits (a host link of zero bandwidth \
                     could never deliver an update)",
                    self.host_link_bits
                ),
            );
        }
        let mhz = self.host_link_mhz;
        if !(mhz.is_finite() && (1e-3..=1e5).contains(&mhz)) {
            return err(
                "memory.host_link_mhz",
                format!(
                    "{mhz:?} is out of range; allowed 0.001..=100000 MHz (a host link of zero \
                     bandwidth could never deliver an update)"
                ),
            );
        }
        if !(1..=self.address_fifo_depth).contains(&self.overtaking_window) {
            return err(
                "memory.overtaking_window",
                format!(
                    "{} is out of range; allowed 1..=memory.address_fifo_depth ({}): the window \
                     searches the FIFO's entries (a shallower FIFO needs the window lowered too)",
                    self.overtaking_window, self.address_fifo_depth
                ),
            );
        }
        Ok(())
    }

    /// Peak host-link bandwidth in bytes per second (bits / 8 × clock).
    pub fn host_link_bytes_per_second(&self) -> f64 {
        self.host_link_bits as f64 / 8.0 * self.host_link_mhz * 1e6
    }

    /// Copies of each voxel the layout stores: 2 for the voxel-pair layouts (`replicated4`,
    /// `linear4`: voxel z is the low half of word z and the high half of word z − 1), 1 for
    /// `interleaved8`. Every copy costs an SDRAM WRITE when the voxel is written.
    pub fn replicas(&self) -> usize {
        match self.mapping {
            Mapping::Replicated4 | Mapping::Linear4 => 2,
            Mapping::Interleaved8 => 1,
        }
    }

    pub fn modules(&self) -> usize {
        match self.mapping {
            Mapping::Replicated4 | Mapping::Linear4 => 4,
            Mapping::Interleaved8 => 8,
        }
    }

    /// Module-local word extent for a volume.
    fn local_dims(&self, dims: [usize; 3]) -> [usize; 3] {
        match self.mapping {
            Mapping::Replicated4 | Mapping::Linear4 => {
                [dims[0].div_ceil(2), dims[1].div_ceil(2), dims[2]]
            }
            Mapping::Interleaved8 => dims.map(|d| d.div_ceil(2)),
        }
    }

    /// Rows per bank the volume occupies (rows 0..this in every bank and module).
    pub fn rows_needed(&self, dims: [usize; 3]) -> u64 {
        let local = self.local_dims(dims);
        match self.mapping {
            Mapping::Linear4 => {
                let words = local.iter().product::<usize>() as u64;
                words
                    .div_ceil(self.columns as u64)
                    .div_ceil(self.banks as u64)
            }
            _ => {
                let blocks = [0, 1, 2].map(|a| local[a].div_ceil(self.block[a] as usize));
                bank_split(blocks, self.banks)
                    .1
                    .iter()
                    .map(|&d| d as u64)
                    .product()
            }
        }
    }

    /// An error when the volume does not fit the modules' rows × banks × columns.
    pub fn check_covers(&self, dims: [usize; 3], source: &str) -> Result<()> {
        self.check_covers_with(dims, false, source)
    }

    /// `check_covers`, with `distance`: the volume and its distance array after it (the same
    /// layout again, in the rows after the volume's: `AddressMap::distance_word`).
    pub fn check_covers_with(&self, dims: [usize; 3], distance: bool, source: &str) -> Result<()> {
        let rows_needed = self.rows_needed(dims) * if distance { 2 } else { 1 };
        if rows_needed > self.rows as u64 {
            return Err(Error::config(
                source,
                "memory.rows",
                format!(
                    "a {dims:?} volume{} needs {rows_needed} rows per bank with mapping {}, the modules have {}",
                    if distance { " and its distance array" } else { "" },
                    self.mapping.name(), self.rows
                ),
            ));
        }
        Ok(())
    }
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct WordAddress {
    pub module: u32,
    pub bank: u32,
    pub row: u32,
    pub column: u32,
}

/// Maps sample neighbourhoods to word addresses for one volume.
#[derive(Clone, Debug)]
pub struct AddressMap {
    config: MemoryConfig,
    local: [usize; 3],
    /// log2 of the block edge per axis (blocks are powers of two).
    block_log2: [u32; 3],
    /// Low block-coordinate bits per axis that form the bank, and the rest's grid for rows.
    bank_shifts: [u32; 3],
    row_grid: [usize; 3],
    /// Block layouts: bank, row and column are sums of independent per-axis parts (bank bits
    /// are disjoint, row and column are linear in the block coordinates), tabulated per local
    /// coordinate so a word costs three lookups. Empty for the linear layout.
    parts: [Vec<AxisPart>; 3],
    /// Rows the volume occupies per bank: the distance array starts at this row.
    distance_row: u32,
    /// XOR applied to a distance word's bank (`memory.distance_placement`).
    distance_bank_xor: u32,
    /// 2-way blocking: the indirection table and the slot layout (`AddressMap::blocked`).
    blocked: Option<Blocked>,
}

/// The blocked layout: a sample's words lie in its block's slot.
#[derive(Clone, Debug)]
struct Blocked {
    table: std::sync::Arc<BlockTable>,
    layout: SlotLayout,
}

#[derive(Clone, Copy, Debug, Default)]
struct AxisPart {
    bank: u32,
    row: u32,
    column: u32,
}

impl AddressMap {
    pub fn new(config: &MemoryConfig, dims: [usize; 3]) -> AddressMap {
        let local = config.local_dims(dims);
        let blocks = [0, 1, 2].map(|a| local[a].div_ceil(config.block[a] as usize));
        let (bank_shifts, row_grid) = bank_split(blocks, config.banks);
        let mut map = AddressMap {
            config: config.clone(),
            local,
            block_log2: config.block.map(|b| b.trailing_zeros()),
            bank_shifts,
            row_grid,
            parts: Default::default(),
            distance_row: config.rows_needed(dims) as u32,
            distance_bank_xor: match config.distance_placement {
                DistancePlacement::SameBank => 0,
                DistancePlacement::OtherBank => config.banks - 1,
            },
            blocked: None,
        };
        if config.mapping != Mapping::Linear4 {
            // One past the local extent: a neighbourhood's upper corner may lie there.
            map.parts = [0, 1, 2].map(|axis| {
                (0..=local[axis] + 1)
                    .map(|l| {
                        let mut coords = [0; 3];
                        coords[axis] = l;
                        let w = map.block_word(0, coords);
                        AxisPart {
                            bank: w.bank,
                            row: w.row,
                            column: w.column,
                        }
                    })
                    .collect()
            });
        }
        map
    }

    /// The blocked layout (2-way blocking, `crate::blocking`): only the table's active blocks
    /// are stored, block b in slot `table.slot(b)`. A slot holds the block with a one-voxel
    /// border, (B + 2)³ voxels from B·b − 1, in the mapping's modules (module by the voxel's
    /// own parities, as unblocked) and module-local words (slot-local voxel / 2 per axis; z
    /// whole for the voxel-pair layouts). Inside a slot the words are grouped in the
    /// `memory.block` word blocks as unblocked, packed largest first (`SlotLayout`): a whole
    /// word block is one row unit, as unblocked, and the partial ones of the border share
    /// units. Word w of the slot is in unit j = w / columns at column w mod columns; global
    /// unit G = slot · units + j, bank = G mod banks, row = G / banks. Whole word blocks come
    /// in x-fastest order, so with 4 banks those next along x or y lie in another bank and
    /// those next along z in the same one, as unblocked. `linear4`: the slot's words in linear
    /// order. Samples of inactive blocks are not read (`arch::block_lookup`); `sample_words` of
    /// one is empty. Only sample reads are blocked: `distance_word` and `voxel_copies` keep the
    /// unblocked layout (blocking needs `occupancy.structure = "map"`, and the update engine
    /// writes unblocked volumes).
    pub fn blocked(
        config: &MemoryConfig,
        dims: [usize; 3],
        table: std::sync::Arc<BlockTable>,
    ) -> AddressMap {
        let mut map = AddressMap::new(config, dims);
        map.blocked = Some(Blocked {
            layout: SlotLayout::new(config, table.block_size()),
            table,
        });
        map
    }

    /// The word of voxel `v` in slot `slot` of the block whose first voxel is `origin`.
    #[inline]
    fn slot_word(&self, b: &Blocked, slot: u32, origin: [usize; 3], v: [usize; 3]) -> WordAddress {
        let c = &self.config;
        let (x, y, z) = (
            v[0] - origin[0] + 1,
            v[1] - origin[1] + 1,
            v[2] - origin[2] + 1,
        );
        let (module, l) = match c.mapping {
            Mapping::Interleaved8 => (
                (v[0] & 1) + 2 * (v[1] & 1) + 4 * (v[2] & 1),
                [x >> 1, y >> 1, z >> 1],
            ),
            _ => ((v[0] & 1) + 2 * (v[1] & 1), [x >> 1, y >> 1, z]),
        };
        let layout = &b.layout;
        let word = match c.mapping {
            Mapping::Linear4 => l[0] + layout.local[0] * (l[1] + layout.local[1] * l[2]),
            _ => {
                let lg = self.block_log2;
                let wb = [0, 1, 2].map(|a| l[a] >> lg[a]);
                let o = [0, 1, 2].map(|a| l[a] & ((1 << lg[a]) - 1));
                let g = layout.word_blocks;
                let (sx, sy) = (layout.extents[0][wb[0]], layout.extents[1][wb[1]]);
                layout.starts[wb[0] + g[0] * (wb[1] + g[1] * wb[2])]
                    + o[0]
                    + sx * (o[1] + sy * o[2])
            }
        };
        let (unit, column) = (word / c.columns as usize, word % c.columns as usize);
        let global = slot as usize * layout.units + unit;
        let banks = c.banks as usize;
        WordAddress {
            module: module as u32,
            bank: (global % banks) as u32,
            row: (global / banks) as u32,
            column: column as u32,
        }
    }

    /// Blocked layout: the slot of the block holding voxel `base` (None: inactive, or not
    /// blocked).
    pub fn slot_at(&self, base: [usize; 3]) -> Option<u32> {
        self.blocked.as_ref().and_then(|b| b.table.slot_at(base))
    }

    /// The words a sample with lower corner `base` reads, one per module it touches: the first
    /// `n` entries of the returned array.
    pub fn sample_words(&self, base: [usize; 3]) -> ([WordAddress; 8], usize) {
        let mut out = [WordAddress {
            module: 0,
            bank: 0,
            row: 0,
            column: 0,
        }; 8];
        let mut n = 0;
        self.for_each_sample_word(base, |word| {
            out[n] = word;
            n += 1;
        });
        (out, n)
    }

    /// Calls `f` with each word of the sample's neighbourhood, one per module (every mapping
    /// puts the 2×2×2 neighbourhood on distinct modules; tests/sdram.rs checks it).
    #[inline]
    pub fn for_each_sample_word(&self, base: [usize; 3], mut f: impl FnMut(WordAddress)) {
        if let Some(b) = &self.blocked {
            let block = b.table.block_of(base);
            let Some(slot) = b.table.slot(block) else {
                return;
            };
            let origin = block.map(|c| c << b.table.block_log2);
            let dz_range = match self.config.mapping {
                Mapping::Interleaved8 => 0..2,
                _ => 0..1,
            };
            for dz in dz_range {
                for dy in 0..2 {
                    for dx in 0..2 {
                        let v = [base[0] + dx, base[1] + dy, base[2] + dz];
                        f(self.slot_word(b, slot, origin, v));
                    }
                }
            }
            return;
        }
        if self.config.mapping == Mapping::Replicated4 {
            // The four words share the z part; x and y take two parts each (`word` by axis).
            let z = self.parts[2][base[2]];
            let xs = [base[0], base[0] + 1];
            let ys = [base[1], base[1] + 1];
            let px = xs.map(|x| self.parts[0][x >> 1]);
            let py = ys.map(|y| self.parts[1][y >> 1]);
            for dy in 0..2 {
                for dx in 0..2 {
                    let (x, y) = (px[dx], py[dy]);
                    f(WordAddress {
                        module: ((xs[dx] & 1) + 2 * (ys[dy] & 1)) as u32,
                        bank: x.bank | y.bank | z.bank,
                        row: x.row + y.row + z.row,
                        column: x.column + y.column + z.column,
                    });
                }
            }
            return;
        }
        let dz_range = match self.config.mapping {
            Mapping::Interleaved8 => 0..2,
            _ => 0..1, // the word at z holds the pair (z, z+1)
        };
        for dz in dz_range {
            for dy in 0..2 {
                for dx in 0..2 {
                    let (x, y, z) = (base[0] + dx, base[1] + dy, base[2] + dz);
                    let module = match self.config.mapping {
                        Mapping::Interleaved8 => (x & 1) + 2 * (y & 1) + 4 * (z & 1),
                        _ => (x & 1) + 2 * (y & 1),
                    } as u32;
                    let local = match self.config.mapping {
                        Mapping::Interleaved8 => [x >> 1, y >> 1, z >> 1],
                        _ => [x >> 1, y >> 1, z],
                    };
                    f(self.word(module, local));
                }
            }
        }
    }

    /// The word holding the distance of voxel `voxel`. The distance array mirrors the volume's
    /// layout (one distance per word, on the module and at the bank and column of the voxel's
    /// own word, the word the sample's lower corner reads) in the rows after the volume's:
    /// row = the voxel word's row + `rows_needed`; bank = the voxel word's bank, or with
    /// `distance_placement = "other-bank"` that bank XOR (banks − 1). Simple, not dense: 8 bits
    /// of each word used.
    #[inline]
    pub fn distance_word(&self, voxel: [usize; 3]) -> WordAddress {
        let (x, y, z) = (voxel[0], voxel[1], voxel[2]);
        let (module, local) = match self.config.mapping {
            Mapping::Interleaved8 => (
                (x & 1) + 2 * (y & 1) + 4 * (z & 1),
                [x >> 1, y >> 1, z >> 1],
            ),
            _ => ((x & 1) + 2 * (y & 1), [x >> 1, y >> 1, z]),
        };
        let mut word = self.word(module as u32, local);
        word.row += self.distance_row;
        word.bank ^= self.distance_bank_xor;
        word
    }

    /// The words that hold voxel `p`, with the half of each it occupies (0: low, 1: high): the
    /// voxel's own word (low half) first, then with the voxel-pair layouts and z > 0 the word
    /// of z − 1, whose high half repeats it. Writing a voxel writes every copy; the first `n`
    /// entries are valid.
    #[inline]
    pub fn voxel_copies(&self, p: [usize; 3]) -> ([(WordAddress, u8); 2], usize) {
        let (x, y, z) = (p[0], p[1], p[2]);
        match self.config.mapping {
            Mapping::Interleaved8 => {
                let module = ((x & 1) + 2 * (y & 1) + 4 * (z & 1)) as u32;
                let w = self.word(module, [x >> 1, y >> 1, z >> 1]);
                ([(w, 0), (w, 0)], 1)
            }
            _ => {
                let module = ((x & 1) + 2 * (y & 1)) as u32;
                let own = self.word(module, [x >> 1, y >> 1, z]);
                if z == 0 {
                    ([(own, 0), (own, 0)], 1)
                } else {
                    (
                        [(own, 0), (self.word(module, [x >> 1, y >> 1, z - 1]), 1)],
                        2,
                    )
                }
            }
        }
    }

    #[inline]
    fn word(&self, module: u32, l: [usize; 3]) -> WordAddress {
        if self.config.mapping == Mapping::Linear4 {
            return self.linear_word(module, l);
        }
        let (x, y, z) = (
            self.parts[0][l[0]],
            self.parts[1][l[1]],
            self.parts[2][l[2]],
        );
        WordAddress {
            module,
            bank: x.bank | y.bank | z.bank,
            row: x.row + y.row + z.row,
            column: x.column + y.column + z.column,
        }
    }

    /// The word by the layout's definition (the per-axis tables are built from it).
    fn block_word(&self, module: u32, l: [usize; 3]) -> WordAddress {
        let c = &self.config;
        match c.mapping {
            Mapping::Linear4 => self.linear_word(module, l),
            _ => {
                let lg = self.block_log2;
                let block = [l[0] >> lg[0], l[1] >> lg[1], l[2] >> lg[2]];
                let o = [0, 1, 2].map(|a| l[a] & ((1 << lg[a]) - 1));
                let mut bank = 0usize;
                let mut used = [0u32; 3];
                for bit in 0..c.banks.trailing_zeros() {
                    let axis = bit as usize % 3;
                    bank |= ((block[axis] >> used[axis]) & 1) << bit;
                    used[axis] += 1;
                }
                let r = [0, 1, 2].map(|a| block[a] >> self.bank_shifts[a]);
                let rest = self.row_grid;
                WordAddress {
                    module,
                    bank: bank as u32,
                    row: (r[0] + rest[0] * (r[1] + rest[1] * r[2])) as u32,
                    column: (o[0] + ((o[1] + (o[2] << lg[1])) << lg[0])) as u32,
                }
            }
        }
    }
}

impl AddressMap {
    fn linear_word(&self, module: u32, l: [usize; 3]) -> WordAddress {
        let c = &self.config;
        let a = l[0] + self.local[0] * (l[1] + self.local[1] * l[2]);
        let global_row = a / c.columns as usize;
        let banks = c.banks as usize;
        WordAddress {
            module,
            bank: (global_row % banks) as u32,
            row: (global_row / banks) as u32,
            column: (a % c.columns as usize) as u32,
        }
    }
}

/// How the bank bits split a block grid: per axis, how many low coordinate bits go to the bank
/// (interleaved x, y, z), and the block grid that remains for rows.
fn bank_split(blocks: [usize; 3], banks: u32) -> ([u32; 3], [usize; 3]) {
    let mut shifts = [0u32; 3];
    for bit in 0..banks.trailing_zeros() {
        shifts[bit as usize % 3] += 1;
    }
    let rest = [0, 1, 2].map(|a| blocks[a].div_ceil(1 << shifts[a]));
    (shifts, rest)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `replicated4` sample's words (computed by axis parts) are the layout's definition:
    /// the voxel pair word of each (x, y) of the neighbourhood, on the module of its parities.
    #[test]
    fn replicated4_sample_words_are_the_definition() {
        let base = crate::config::HardwareConfig::default_config().memory;
        for (block, banks, dims) in [
            ([8, 8, 8], 4, [40, 36, 20]),
            ([4, 8, 16], 16, [27, 19, 33]),
            ([2, 2, 2], 2, [9, 12, 7]),
        ] {
            let config = MemoryConfig {
                mapping: Mapping::Replicated4,
                block,
                banks,
                ..base.clone()
            };
            let map = AddressMap::new(&config, dims);
            for z in 0..dims[2] - 1 {
                for y in 0..dims[1] - 1 {
                    for x in 0..dims[0] - 1 {
                        let (words, n) = map.sample_words([x, y, z]);
                        assert_eq!(n, 4);
                        for (i, word) in words[..n].iter().enumerate() {
                            let (vx, vy) = (x + i % 2, y + i / 2);
                            let module = ((vx & 1) + 2 * (vy & 1)) as u32;
                            let expected = map.block_word(module, [vx >> 1, vy >> 1, z]);
                            assert_eq!(*word, expected, "sample at {:?}", [x, y, z]);
                        }
                    }
                }
            }
        }
    }

    /// The per-axis tables give the layout's definition at every coordinate.
    #[test]
    fn tabulated_words_equal_the_definition() {
        let base = crate::config::HardwareConfig::default_config().memory;
        for (mapping, block, banks, dims) in [
            (Mapping::Replicated4, [8, 8, 8], 4, [64, 64, 64]),
            (Mapping::Replicated4, [16, 16, 2], 8, [256, 256, 178]),
            (Mapping::Replicated4, [4, 8, 16], 16, [103, 94, 161]),
            (Mapping::Interleaved8, [8, 8, 8], 4, [140, 120, 161]),
            (Mapping::Interleaved8, [2, 4, 8], 2, [64, 64, 64]),
        ] {
            let config = MemoryConfig {
                mapping,
                block,
                banks,
                ..base.clone()
            };
            let map = AddressMap::new(&config, dims);
            let local = config.local_dims(dims);
            let mut checked = 0;
            for z in 0..=local[2] {
                for y in 0..=local[1] {
                    for x in 0..=local[0] {
                        assert_eq!(
                            map.word(3, [x, y, z]),
                            map.block_word(3, [x, y, z]),
                            "{mapping:?} {block:?} {banks} banks at {x},{y},{z}"
                        );
                        checked += 1;
                    }
                }
            }
            assert!(checked > 1000);
        }
    }
}

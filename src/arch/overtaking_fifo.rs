//! The overtaking FIFO (Doggett 2000): a module's queue of word requests in which a request to
//! the currently open row may overtake older requests to other rows, within a window of the
//! oldest entries. Every request a younger one overtakes counts one bypass; once a request has
//! been bypassed `max_bypass` times it is served next, whatever it costs (no starvation).
//! Disabled, it is a plain in-order FIFO.
//!
//! **Row-hit mask.** The FIFO keeps its own copy of the module's open rows (the controller
//! reports every ACT and PRE: `row_opened`, `row_closed`) and, per queue position, a bit that
//! says whether that request targets its bank's open row. The bit is set when a request enters
//! and changes only when its bank opens or closes a row, which is rare next to the reads, so
//! the selection is a bit scan instead of a row compare per queued request. Positions from 64
//! on (deep FIFOs with wide windows only) have no bit and are compared when the window reaches
//! them.

use super::address_map::WordAddress;

/// A queued word request, 24 bytes: the FIFO moves entries when one overtakes, so they are
/// kept small. The bank and row are one `page` key (a row hit is one compare).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PendingWord {
    pub tag: u32,
    /// `page(bank, row)`.
    pub page: u32,
    /// Cycle the request entered the FIFO.
    pub entered: u64,
    pub bypassed: u32,
    /// Columns are < 2^16 (validated: `memory.columns` <= 65536).
    pub column: u16,
    /// An ACT was issued for this request's row (a row miss).
    pub activated: bool,
    /// Another row had to be closed first (a row conflict).
    pub precharged: bool,
}

impl PendingWord {
    /// A request for `addr` (its module is the FIFO's own) that entered at `entered`.
    pub fn new(tag: u32, addr: WordAddress, entered: u64) -> PendingWord {
        debug_assert!(addr.bank < 16 && addr.row < 1 << 24 && addr.column < 1 << 16);
        PendingWord {
            tag,
            page: page(addr.bank, addr.row),
            entered,
            bypassed: 0,
            column: addr.column as u16,
            activated: false,
            precharged: false,
        }
    }

    pub fn bank(&self) -> u32 {
        self.page & 15
    }

    pub fn row(&self) -> u32 {
        self.page >> 4
    }
}

/// A (bank, row) pair as one key: banks <= 16, rows < 2^24 (validated).
#[inline(always)]
pub fn page(bank: u32, row: u32) -> u32 {
    bank | row << 4
}

/// No row open: no page has all bits set (rows are < 2^24, so `page` < 2^28).
const CLOSED: u32 = u32::MAX;

/// Queue positions with a row-hit bit.
const MASKED: usize = 64;

pub struct OvertakingFifo {
    /// A ring of a power-of-two capacity >= `depth`; position i of the queue (0 = oldest) is
    /// `ring[(head + i) & (ring.len() - 1)]` (the mask is taken from the length: no second
    /// field to keep in step with it).
    ring: Box<[PendingWord]>,
    head: usize,
    len: usize,
    depth: usize,
    enabled: bool,
    window: usize,
    /// The window's positions that have a row-hit bit.
    window_bits: u64,
    max_bypass: u32,
    /// Bit i: the request at position i (< 64) targets the open row of its bank.
    hits: u64,
    /// The open page per bank (`CLOSED` if none), as the device has it (banks <= 16).
    open_pages: [u32; 16],
    /// Requests served ahead of an older one.
    pub overtakes: u64,
    /// Selections forced by the bypass bound.
    pub forced: u64,
    pub peak: usize,
}

impl OvertakingFifo {
    pub fn new(depth: usize, enabled: bool, window: usize, max_bypass: u32) -> Self {
        let capacity = depth.max(1).next_power_of_two();
        OvertakingFifo {
            ring: vec![PendingWord::default(); capacity].into_boxed_slice(),
            head: 0,
            len: 0,
            depth,
            enabled,
            window,
            window_bits: low_bits(window),
            max_bypass,
            hits: 0,
            open_pages: [CLOSED; 16],
            overtakes: 0,
            forced: 0,
            peak: 0,
        }
    }

    pub fn can_accept(&self) -> bool {
        self.len < self.depth
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    #[inline(always)]
    fn at(&self, position: usize) -> &PendingWord {
        &self.ring[(self.head + position) & (self.ring.len() - 1)]
    }

    #[inline(always)]
    fn at_mut(&mut self, position: usize) -> &mut PendingWord {
        let mask = self.ring.len() - 1;
        &mut self.ring[(self.head + position) & mask]
    }

    #[inline(always)]
    fn is_open(&self, word: &PendingWord) -> bool {
        self.open_pages[word.page as usize & 15] == word.page
    }

    #[inline]
    pub fn push(&mut self, word: PendingWord) {
        debug_assert!(self.can_accept());
        let position = self.len;
        // Branch-free: whether a new request hits follows the data.
        let hit = (position < MASKED) & self.is_open(&word);
        self.hits |= (hit as u64) << (position & (MASKED - 1));
        *self.at_mut(position) = word;
        self.len += 1;
        self.peak = self.peak.max(self.len);
    }

    pub fn get(&self, index: usize) -> &PendingWord {
        debug_assert!(index < self.len);
        self.at(index)
    }

    pub fn get_mut(&mut self, index: usize) -> &mut PendingWord {
        debug_assert!(index < self.len);
        self.at_mut(index)
    }

    /// Whether the request at `index` targets its bank's open row.
    #[inline(always)]
    pub fn is_hit(&self, index: usize) -> bool {
        if index < MASKED {
            self.hits >> index & 1 != 0
        } else {
            self.is_open(self.at(index))
        }
    }

    /// The device opened `row` in `bank` (an ACT): its queued requests become row hits.
    pub fn row_opened(&mut self, bank: u32, row: u32) {
        let opened = page(bank, row);
        self.open_pages[bank as usize & 15] = opened;
        for position in 0..self.len.min(MASKED) {
            // Branch-free: which requests hit follows the data.
            self.hits |= ((self.at(position).page == opened) as u64) << position;
        }
    }

    /// The device closed `bank`'s row (a PRE): its queued requests are no longer row hits.
    pub fn row_closed(&mut self, bank: u32) {
        self.open_pages[bank as usize & 15] = CLOSED;
        let mut bits = self.hits;
        while bits != 0 {
            let position = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            if self.at(position).bank() == bank {
                self.hits &= !(1 << position);
            }
        }
    }

    /// Whether any request in the window targets `row` of `bank`.
    pub fn window_hits(&self, bank: u32, row: u32) -> bool {
        let wanted = page(bank, row);
        (0..self.window.min(self.len)).any(|i| self.at(i).page == wanted)
    }

    /// The request to serve: the oldest one bypassed `max_bypass` times; else the oldest row
    /// hit within the window; else the oldest.
    #[inline]
    pub fn select(&self) -> Option<usize> {
        if self.len == 0 {
            return None;
        }
        // Every take bypasses all requests older than the one taken, so bypass counts never
        // rise along the queue: if any request in the window reached the bound, the oldest did.
        debug_assert!((1..self.len).all(|i| self.at(i - 1).bypassed >= self.at(i).bypassed));
        // The oldest request is served if overtaking is off, if it is a row hit itself (the
        // common case), or if it reached the bypass bound; else the oldest hit in the window,
        // if any. Chosen without a branch on which case holds (it follows the data).
        let oldest =
            !self.enabled | (self.hits & 1 != 0) | (self.at(0).bypassed >= self.max_bypass);
        let in_window = self.hits & self.window_bits;
        let candidates = if oldest {
            1
        } else {
            in_window | (in_window == 0) as u64
        };
        let choice = candidates.trailing_zeros() as usize;
        if choice != 0 || oldest || self.window <= MASKED {
            return Some(choice);
        }
        // Only windows wider than the mask look further, comparing rows.
        let hit = (MASKED..self.window.min(self.len)).find(|&i| self.is_open(self.at(i)));
        Some(hit.unwrap_or(0))
    }

    /// Removes the request at `index` to be served; every older request was overtaken.
    #[inline(always)]
    pub fn take(&mut self, index: usize) -> PendingWord {
        debug_assert!(index < self.len);
        let served = *self.at(index);
        // Counted without a branch on whether the oldest was taken (it follows the data).
        let overtook = index != 0;
        self.forced += (!overtook & self.enabled & (served.bypassed >= self.max_bypass)) as u64;
        self.overtakes += overtook as u64;
        // The older requests move one place towards the younger end, each counting one
        // bypass; the younger ones stay where they are. Logical positions below `index`
        // keep their number, those above move down by one.
        for position in (0..index).rev() {
            let mut older = *self.at(position);
            older.bypassed += 1;
            *self.at_mut(position + 1) = older;
        }
        self.head = (self.head + 1) & (self.ring.len() - 1);
        let below = low_bits(index);
        self.hits = (self.hits & below) | ((self.hits >> 1) & !below);
        self.len -= 1;
        // The request now at the last masked position came from beyond the mask.
        if self.len >= MASKED && self.is_open(self.at(MASKED - 1)) {
            self.hits |= 1 << (MASKED - 1);
        }
        served
    }
}

/// A mask of the lowest `n` bits (all 64 for n >= 64), without a branch.
#[inline(always)]
fn low_bits(n: usize) -> u64 {
    ((1u64 << (n & 63)) - 1) | ((n >= 64) as u64).wrapping_neg()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn word(tag: u32, bank: u32, row: u32) -> PendingWord {
        let addr = WordAddress {
            module: 0,
            bank,
            row,
            column: tag & 0xffff,
        };
        PendingWord::new(tag, addr, 0)
    }

    /// The selection the FIFO made before the row-hit mask and the page keys: a bank and row
    /// compare per request against `open_rows`, the test's own record of the open rows.
    fn reference_select(fifo: &OvertakingFifo, open_rows: &[Option<u32>; 16]) -> Option<usize> {
        if fifo.len == 0 {
            return None;
        }
        let open = |i: usize| {
            let w = fifo.at(i);
            open_rows[w.bank() as usize] == Some(w.row())
        };
        if !fifo.enabled || open(0) || fifo.at(0).bypassed >= fifo.max_bypass {
            return Some(0);
        }
        Some(
            (0..fifo.window.min(fifo.len))
                .find(|&i| open(i))
                .unwrap_or(0),
        )
    }

    /// A request's page key gives back its bank, row and column at the extremes the
    /// configuration allows (16 banks, 2^24 rows, 65,536 columns); an entry is 24 bytes.
    #[test]
    fn page_keys_keep_bank_row_and_column() {
        for (bank, row, column) in [(0, 0, 0), (15, (1 << 24) - 1, 65_535), (7, 12_345, 511)] {
            let addr = WordAddress {
                module: 3,
                bank,
                row,
                column,
            };
            let w = PendingWord::new(9, addr, 77);
            assert_eq!((w.bank(), w.row(), w.column as u32), (bank, row, column));
            assert_ne!(w.page, CLOSED);
        }
        assert_eq!(std::mem::size_of::<PendingWord>(), 24);
    }

    /// Random pushes, takes, ACTs and PREs (a small xorshift generator) over banks 0..16 and
    /// rows up to the largest: the mask's selection equals the bank-and-row compares', for
    /// masked and unmasked depths, and the overtake and forced counts are as defined.
    #[test]
    fn hit_mask_selects_as_row_compares_do() {
        let mut exercised = (0u64, 0u64);
        for (depth, window) in [(16, 8), (16, 16), (100, 90), (70, 3)] {
            let mut fifo = OvertakingFifo::new(depth, true, window, 8);
            let mut state = 0x9e37_79b9_7f4a_7c15u64;
            let mut next = |n: u64| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                state % n
            };
            let banks = [0, 5, 15];
            let rows = [0, 1, (1 << 24) - 1];
            let mut open_rows = [None; 16];
            let mut tag = 0;
            let (mut overtakes, mut forced) = (0u64, 0u64);
            for _ in 0..200_000 {
                match next(8) {
                    0..=3 if fifo.can_accept() => {
                        tag += 1;
                        let (bank, row) = (banks[next(3) as usize], rows[next(3) as usize]);
                        fifo.push(word(tag, bank, row));
                    }
                    4 | 5 => {
                        let choice = fifo.select();
                        assert_eq!(choice, reference_select(&fifo, &open_rows));
                        if let Some(i) = choice {
                            // The counters as defined: an overtake when a younger request is
                            // served, a forced selection when the oldest had reached the bound.
                            overtakes += (i != 0) as u64;
                            forced += (i == 0 && fifo.at(0).bypassed >= fifo.max_bypass) as u64;
                            fifo.take(i);
                        }
                    }
                    6 => {
                        let (bank, row) = (banks[next(3) as usize], rows[next(3) as usize]);
                        fifo.row_closed(bank);
                        fifo.row_opened(bank, row);
                        open_rows[bank as usize] = Some(row);
                    }
                    _ => {
                        let bank = banks[next(3) as usize];
                        fifo.row_closed(bank);
                        open_rows[bank as usize] = None;
                    }
                }
                for i in 0..fifo.len.min(MASKED) {
                    let w = fifo.at(i);
                    let hit = open_rows[w.bank() as usize] == Some(w.row());
                    assert_eq!(fifo.hits >> i & 1 == 1, hit);
                }
            }
            assert_eq!((fifo.overtakes, fifo.forced), (overtakes, forced));
            exercised.0 += overtakes;
            exercised.1 += forced;
        }
        assert!(
            exercised.0 > 0 && exercised.1 > 0,
            "the traffic exercises both counters"
        );
    }
}

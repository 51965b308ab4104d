//! The overtaking FIFO (Doggett 2000): a module's queue of word requests in which a request to
//! the currently open row may overtake older requests to other rows, within a window of the
//! oldest entries. Every request a younger one overtakes counts one bypass; once a request has
//! been bypassed `max_bypass` times it is served next, whatever it costs (no starvation).
//! Disabled, it is a plain in-order FIFO.

use std::collections::VecDeque;

use super::address_map::WordAddress;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PendingWord {
    pub tag: u32,
    pub addr: WordAddress,
    /// Cycle the request entered the FIFO.
    pub entered: u64,
    pub bypassed: u32,
    /// An ACT was issued for this request's row (a row miss).
    pub activated: bool,
    /// Another row had to be closed first (a row conflict).
    pub precharged: bool,
}

pub struct OvertakingFifo {
    queue: VecDeque<PendingWord>,
    depth: usize,
    enabled: bool,
    window: usize,
    max_bypass: u32,
    /// Requests served ahead of an older one.
    pub overtakes: u64,
    /// Selections forced by the bypass bound.
    pub forced: u64,
    pub peak: usize,
}

impl OvertakingFifo {
    pub fn new(depth: usize, enabled: bool, window: usize, max_bypass: u32) -> Self {
        OvertakingFifo {
            queue: VecDeque::with_capacity(depth),
            depth,
            enabled,
            window,
            max_bypass,
            overtakes: 0,
            forced: 0,
            peak: 0,
        }
    }

    pub fn can_accept(&self) -> bool {
        self.queue.len() < self.depth
    }

    pub fn len(&self) -> usize {
        self.queue.len()
    }

    pub fn is_empty(&self) -> bool {
        self.queue.is_empty()
    }

    pub fn push(&mut self, word: PendingWord) {
        debug_assert!(self.can_accept());
        self.queue.push_back(word);
        self.peak = self.peak.max(self.queue.len());
    }

    pub fn get_mut(&mut self, index: usize) -> &mut PendingWord {
        &mut self.queue[index]
    }

    /// Whether any request in the window targets `row` of `bank`.
    pub fn window_hits(&self, bank: u32, row: u32) -> bool {
        self.queue
            .iter()
            .take(self.window)
            .any(|w| w.addr.bank == bank && w.addr.row == row)
    }

    /// The request to serve: the oldest one bypassed `max_bypass` times; else the oldest row
    /// hit (`is_open(addr)`) within the window; else the oldest.
    pub fn select(&self, is_open: impl Fn(&WordAddress) -> bool) -> Option<usize> {
        if self.queue.is_empty() {
            return None;
        }
        // The oldest request is served if overtaking is off, if it is a row hit itself (the
        // common case), or if it reached the bypass bound.
        if !self.enabled || is_open(&self.queue[0].addr) {
            return Some(0);
        }
        // Every take bypasses all requests older than the one taken, so bypass counts never
        // rise along the queue: if any request in the window reached the bound, the oldest did.
        debug_assert!(self
            .queue
            .iter()
            .zip(self.queue.iter().skip(1))
            .all(|(older, younger)| older.bypassed >= younger.bypassed));
        if self.queue[0].bypassed >= self.max_bypass {
            return Some(0);
        }
        let (front, back) = self.queue.as_slices();
        let window = self.window.min(self.queue.len());
        let (front, back) = if window <= front.len() {
            (&front[..window], &back[..0])
        } else {
            (front, &back[..window - front.len()])
        };
        let hit = front
            .iter()
            .chain(back)
            .position(|w| is_open(&w.addr))
            .unwrap_or(0);
        Some(hit)
    }

    /// Removes the request at `index` to be served; every older request was overtaken.
    #[inline(always)]
    pub fn take(&mut self, index: usize) -> PendingWord {
        if index > 0 {
            self.overtakes += 1;
            for older in self.queue.iter_mut().take(index) {
                older.bypassed += 1;
            }
        } else if self.queue[0].bypassed >= self.max_bypass && self.enabled {
            self.forced += 1;
        }
        if index == 0 {
            return self.queue.pop_front().expect("queue not empty");
        }
        self.queue.remove(index).expect("index within the queue")
    }
}

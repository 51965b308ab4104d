//! The compositing buffer: a reorder buffer keyed by (ray, sample index). Memory words return
//! out of order across modules and rays; compositing must see each ray's samples in order. An
//! entry is reserved when the ray queue issues the sample (a full buffer back-pressures issue);
//! its id is the sample's memory tag, so an arrival finds its entry directly. An entry is
//! released to the compositing stages only when it has arrived and is its ray's oldest
//! outstanding sample; rays take turns (round-robin) when several could release.

use std::collections::VecDeque;

use crate::functional::leaping::SampleValue;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BufferedSample {
    pub ray_id: usize,
    pub k: u64,
    pub pos: [i64; 3],
    /// What the sample composites (the strategy's decision at issue).
    pub value: SampleValue,
    pub arrived: bool,
}

pub struct CompositingBuffer {
    entries: Vec<BufferedSample>,
    free: Vec<u32>,
    /// Per ray, its entry ids in issue (= k) order.
    per_ray: Vec<VecDeque<u32>>,
    /// Rays holding entries, in the order they first reserved one.
    active: Vec<usize>,
    /// Round-robin position in `active`.
    next: usize,
    pub peak: usize,
}

impl CompositingBuffer {
    pub fn new(capacity: usize, rays: usize) -> CompositingBuffer {
        CompositingBuffer {
            entries: vec![BufferedSample::default(); capacity],
            free: (0..capacity as u32).rev().collect(),
            per_ray: vec![VecDeque::new(); rays],
            active: Vec::new(),
            next: 0,
            peak: 0,
        }
    }

    pub fn is_full(&self) -> bool {
        self.free.is_empty()
    }

    pub fn len(&self) -> usize {
        self.entries.len() - self.free.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Reserves an entry for a sample just issued; returns its id (the memory tag), or None
    /// when the buffer is full.
    /// The entry id the next `reserve` will return.
    pub fn next_free(&self) -> Option<u32> {
        self.free.last().copied()
    }

    pub fn reserve(
        &mut self,
        ray_id: usize,
        k: u64,
        pos: [i64; 3],
        value: SampleValue,
    ) -> Option<u32> {
        let id = self.free.pop()?;
        self.entries[id as usize] = BufferedSample {
            ray_id,
            k,
            pos,
            value,
            arrived: false,
        };
        let queue = &mut self.per_ray[ray_id];
        if queue.is_empty() {
            self.active.push(ray_id);
        }
        queue.push_back(id);
        self.peak = self.peak.max(self.len());
        Some(id)
    }

    /// All words of the sample with this entry id have arrived.
    pub fn arrive(&mut self, id: u32) {
        self.entries[id as usize].arrived = true;
    }

    /// Releases one sample that has arrived and is its ray's oldest outstanding one.
    pub fn release(&mut self) -> Option<BufferedSample> {
        let n = self.active.len();
        let next = self.next.min(n);
        let at = (next..n).chain(0..next).find(|&i| {
            let ray = self.active[i];
            self.per_ray[ray]
                .front()
                .is_some_and(|&id| self.entries[id as usize].arrived)
        })?;
        let ray = self.active[at];
        let id = self.per_ray[ray].pop_front()?;
        self.free.push(id);
        if self.per_ray[ray].is_empty() {
            self.active.remove(at);
            self.next = if self.active.is_empty() {
                0
            } else {
                at % self.active.len()
            };
        } else {
            self.next = (at + 1) % n;
        }
        Some(self.entries[id as usize])
    }
}

//! The compositing buffer: a reorder buffer keyed by (ray, sample index). Memory words return
//! out of order across modules and rays; compositing must see each ray's samples in order. An
//! entry is reserved when the ray queue issues the sample (a full buffer back-pressures issue),
//! marked when its words have all arrived, and released to the compositing stages only when it
//! is its ray's oldest outstanding sample.

use std::collections::{BTreeMap, VecDeque};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BufferedSample {
    pub ray_id: usize,
    pub k: u64,
    pub pos: [i64; 3],
    pub arrived: bool,
}

pub struct CompositingBuffer {
    capacity: usize,
    reserved: usize,
    /// Per ray, its reserved samples in issue (= k) order. BTreeMap: deterministic scans.
    per_ray: BTreeMap<usize, VecDeque<BufferedSample>>,
    /// Where the next release scan starts (round-robin over rays).
    next_ray: usize,
    pub peak: usize,
}

impl CompositingBuffer {
    pub fn new(capacity: usize) -> CompositingBuffer {
        CompositingBuffer {
            capacity,
            reserved: 0,
            per_ray: BTreeMap::new(),
            next_ray: 0,
            peak: 0,
        }
    }

    pub fn is_full(&self) -> bool {
        self.reserved >= self.capacity
    }

    pub fn len(&self) -> usize {
        self.reserved
    }

    pub fn is_empty(&self) -> bool {
        self.reserved == 0
    }

    /// Reserves an entry for a sample just issued (the caller checked `is_full`).
    pub fn reserve(&mut self, ray_id: usize, k: u64, pos: [i64; 3]) {
        debug_assert!(!self.is_full());
        self.per_ray
            .entry(ray_id)
            .or_default()
            .push_back(BufferedSample {
                ray_id,
                k,
                pos,
                arrived: false,
            });
        self.reserved += 1;
        self.peak = self.peak.max(self.reserved);
    }

    /// All words of sample (ray, k) have arrived.
    pub fn arrive(&mut self, ray_id: usize, k: u64) {
        let entry = self
            .per_ray
            .get_mut(&ray_id)
            .and_then(|q| q.iter_mut().find(|s| s.k == k));
        match entry {
            Some(s) => s.arrived = true,
            None => debug_assert!(false, "arrival for unreserved sample ({ray_id}, {k})"),
        }
    }

    /// Releases one sample whose ray has it as the oldest outstanding one and whose words have
    /// arrived, scanning rays round-robin from the last one released.
    pub fn release(&mut self) -> Option<BufferedSample> {
        let ray = self
            .per_ray
            .range(self.next_ray..)
            .chain(self.per_ray.range(..self.next_ray))
            .find(|(_, q)| q.front().is_some_and(|s| s.arrived))
            .map(|(&r, _)| r)?;
        let queue = self.per_ray.get_mut(&ray)?;
        let sample = queue.pop_front()?;
        if queue.is_empty() {
            self.per_ray.remove(&ray);
        }
        self.reserved -= 1;
        self.next_ray = ray + 1;
        Some(sample)
    }
}

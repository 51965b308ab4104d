//! The compositing buffer: a reorder buffer keyed by (ray, sample index). Memory words return
//! out of order across modules and rays; compositing must see each ray's samples in order. An
//! entry is reserved when the ray queue issues the sample (a full buffer back-pressures issue);
//! its id is the sample's memory tag, so an arrival finds its entry directly. An entry is
//! released to the compositing stages only when it has arrived and is its ray's oldest
//! outstanding sample; rays take turns (round-robin) when several could release.

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

/// No entry (end of a ray's list).
const NONE: u32 = u32::MAX;

/// An entry and its place in its ray's list.
#[derive(Clone, Copy, Debug, Default)]
struct Entry {
    sample: BufferedSample,
    /// The ray's next entry in issue order, or `NONE`.
    next: u32,
    /// The entry is its ray's oldest outstanding one.
    head: bool,
}

pub struct CompositingBuffer {
    entries: Vec<Entry>,
    free: Vec<u32>,
    /// Per ray, its oldest and newest entry ids (`NONE` when it holds none): each ray's entries
    /// are a list in issue (= k) order through `Entry::next`.
    per_ray: Vec<(u32, u32)>,
    /// Rays holding entries, in the order they first reserved one.
    active: Vec<usize>,
    /// Round-robin position in `active`.
    next: usize,
    /// Rays whose oldest entry has arrived: when none has, nothing can be released and the
    /// round-robin scan is skipped.
    releasable: usize,
    pub peak: usize,
}

impl CompositingBuffer {
    pub fn new(capacity: usize, rays: usize) -> CompositingBuffer {
        CompositingBuffer {
            entries: vec![Entry::default(); capacity],
            free: (0..capacity as u32).rev().collect(),
            per_ray: vec![(NONE, NONE); rays],
            active: Vec::new(),
            next: 0,
            releasable: 0,
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

    /// The entry id the next `reserve` will return.
    pub fn next_free(&self) -> Option<u32> {
        self.free.last().copied()
    }

    /// Reserves an entry for a sample just issued; returns its id (the memory tag), or None
    /// when the buffer is full.
    pub fn reserve(
        &mut self,
        ray_id: usize,
        k: u64,
        pos: [i64; 3],
        value: SampleValue,
    ) -> Option<u32> {
        let id = self.free.pop()?;
        let (head, tail) = self.per_ray[ray_id];
        let first = head == NONE;
        self.entries[id as usize] = Entry {
            sample: BufferedSample {
                ray_id,
                k,
                pos,
                value,
                arrived: false,
            },
            next: NONE,
            head: first,
        };
        if first {
            self.active.push(ray_id);
            self.per_ray[ray_id] = (id, id);
        } else {
            self.entries[tail as usize].next = id;
            self.per_ray[ray_id].1 = id;
        }
        self.peak = self.peak.max(self.len());
        Some(id)
    }

    /// All words of the sample with this entry id have arrived.
    pub fn arrive(&mut self, id: u32) {
        let entry = &mut self.entries[id as usize];
        entry.sample.arrived = true;
        self.releasable += entry.head as usize;
    }

    /// Releases one sample that has arrived and is its ray's oldest outstanding one.
    pub fn release(&mut self) -> Option<BufferedSample> {
        if self.releasable == 0 {
            return None;
        }
        let n = self.active.len();
        let next = self.next.min(n);
        let at = (next..n).chain(0..next).find(|&i| {
            let head = self.per_ray[self.active[i]].0;
            self.entries[head as usize].sample.arrived
        })?;
        let ray = self.active[at];
        let id = self.per_ray[ray].0;
        let released = self.entries[id as usize];
        self.free.push(id);
        self.releasable -= 1;
        if released.next == NONE {
            self.per_ray[ray] = (NONE, NONE);
            self.active.remove(at);
            self.next = if self.active.is_empty() {
                0
            } else {
                at % self.active.len()
            };
        } else {
            self.per_ray[ray].0 = released.next;
            let head = &mut self.entries[released.next as usize];
            head.head = true;
            self.releasable += head.sample.arrived as usize;
            self.next = (at + 1) % n;
        }
        Some(released.sample)
    }
}

//! The ray queue: R slots of active rays. Each cycle it selects one ready ray (not busy in the
//! skip unit, not terminated) by the configured policy and issues its step. It learns of early
//! ray termination only through the delayed feedback from the compositing stage.

use crate::config::RaySelection;
use crate::functional::leaping::SkipState;
use crate::functional::setup::FixedRay;

#[derive(Clone, Debug)]
pub struct RaySlot {
    /// Pixel index of the ray (row-major).
    pub ray_id: usize,
    pub ray: FixedRay,
    pub pos: [i64; 3],
    pub k: u64,
    /// Its position update is in the skip unit.
    pub busy: bool,
    /// The ERT feedback arrived: issue nothing more.
    pub terminated: bool,
    /// Cycle the ray entered the queue (for oldest-first selection).
    pub admitted: u64,
    /// Samples issued so far (the compositing side needs the total to retire the ray).
    pub samples_issued: u32,
    /// The space-skipping strategy's per-ray state as of the ray's next step.
    pub state: SkipState,
}

impl RaySlot {
    pub fn finished(&self) -> bool {
        self.terminated || self.k >= self.ray.samples as u64
    }
}

pub struct RayQueue {
    slots: Vec<Option<RaySlot>>,
    occupied: usize,
    selection: RaySelection,
    next_round_robin: usize,
}

impl RayQueue {
    pub fn new(rays: usize, selection: RaySelection) -> RayQueue {
        RayQueue {
            slots: vec![None; rays],
            occupied: 0,
            selection,
            next_round_robin: 0,
        }
    }

    pub fn free_slot(&self) -> Option<usize> {
        if self.occupied == self.slots.len() {
            return None;
        }
        self.slots.iter().position(Option::is_none)
    }

    pub fn occupancy(&self) -> usize {
        self.occupied
    }

    pub fn capacity(&self) -> usize {
        self.slots.len()
    }

    pub fn slot(&self, index: usize) -> Option<&RaySlot> {
        self.slots[index].as_ref()
    }

    pub fn slot_mut(&mut self, index: usize) -> Option<&mut RaySlot> {
        self.slots[index].as_mut()
    }

    pub fn slots(&self) -> impl Iterator<Item = &RaySlot> {
        self.slots.iter().flatten()
    }

    /// Puts a ray into a free slot (the caller found it with `free_slot`).
    pub fn admit(&mut self, index: usize, slot: RaySlot) {
        debug_assert!(self.slots[index].is_none());
        self.slots[index] = Some(slot);
        self.occupied += 1;
    }

    /// Takes a ray out of its slot.
    pub fn remove(&mut self, index: usize) -> Option<RaySlot> {
        let slot = self.slots[index].take();
        self.occupied -= slot.is_some() as usize;
        slot
    }

    /// The slot to issue from this cycle among those `eligible` accepts (ready, not busy, not
    /// finished), by the configured policy. Round-robin advances only when a slot issues.
    pub fn select(&self, eligible: impl Fn(&RaySlot) -> bool) -> Option<usize> {
        let n = self.slots.len();
        let ready = |i: usize| {
            self.slots[i]
                .as_ref()
                .is_some_and(|s| !s.busy && !s.finished() && eligible(s))
        };
        // Slots from the round-robin pointer on, wrapping (no division per slot).
        let from_pointer = || (self.next_round_robin..n).chain(0..self.next_round_robin);
        match self.selection {
            RaySelection::RoundRobin => from_pointer().find(|&i| ready(i)),
            RaySelection::LaggingFirst => from_pointer()
                .filter(|&i| ready(i))
                .min_by_key(|&i| self.slots[i].as_ref().map(|s| s.k)),
            RaySelection::OldestFirst => (0..n)
                .filter(|&i| ready(i))
                .min_by_key(|&i| self.slots[i].as_ref().map(|s| (s.admitted, s.ray_id))),
        }
    }

    pub fn issued_from(&mut self, slot: usize) {
        self.next_round_robin = (slot + 1) % self.slots.len();
    }

    /// Marks the ray terminated if it still holds a slot (the feedback may arrive after the
    /// ray has already issued its last position and left).
    /// Marks the ray terminated; returns its slot if it is still in the queue.
    pub fn terminate(&mut self, ray_id: usize) -> Option<usize> {
        let index = self
            .slots
            .iter()
            .position(|s| s.as_ref().is_some_and(|s| s.ray_id == ray_id))?;
        if let Some(s) = self.slots[index].as_mut() {
            s.terminated = true;
        }
        Some(index)
    }
}

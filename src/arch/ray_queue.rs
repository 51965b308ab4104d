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
    /// Per slot, its issue key: the ray's position index k when it may issue (present, not
    /// busy, not finished), else `NOT_READY`. Selection scans this compact array instead of
    /// the slots (a slot is some 1,300 bytes).
    keys: Vec<u64>,
    /// Slots handed out by `slot_mut` since the last selection: their keys are recomputed
    /// before the next one.
    stale: Vec<usize>,
    /// The last selection, while no key and not the round-robin pointer changed since: a cycle
    /// in which nothing issued (the memory or the compositing buffer full) and no key changed
    /// selects the same slot again without a scan.
    last_choice: Option<Option<usize>>,
    occupied: usize,
    selection: RaySelection,
    next_round_robin: usize,
}

/// The key of a slot that cannot issue.
const NOT_READY: u64 = u64::MAX;

fn key_of(slot: &Option<RaySlot>) -> u64 {
    match slot {
        Some(s) if !s.busy && !s.finished() => s.k,
        _ => NOT_READY,
    }
}

impl RayQueue {
    pub fn new(rays: usize, selection: RaySelection) -> RayQueue {
        RayQueue {
            slots: vec![None; rays],
            keys: vec![NOT_READY; rays],
            stale: Vec::new(),
            last_choice: None,
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

    /// The slot to change (its issue key is recomputed before the next selection).
    pub fn slot_mut(&mut self, index: usize) -> Option<&mut RaySlot> {
        self.stale.push(index);
        self.slots[index].as_mut()
    }

    /// Sets slot `index`'s issue key; a different key voids the last selection.
    #[inline]
    fn set_key(&mut self, index: usize, key: u64) {
        if self.keys[index] != key {
            self.keys[index] = key;
            self.last_choice = None;
        }
    }

    pub fn slots(&self) -> impl Iterator<Item = &RaySlot> {
        self.slots.iter().flatten()
    }

    /// Puts a ray into a free slot (the caller found it with `free_slot`).
    pub fn admit(&mut self, index: usize, slot: RaySlot) {
        debug_assert!(self.slots[index].is_none());
        self.slots[index] = Some(slot);
        self.set_key(index, key_of(&self.slots[index]));
        self.occupied += 1;
    }

    /// Takes a ray out of its slot.
    pub fn remove(&mut self, index: usize) -> Option<RaySlot> {
        let slot = self.slots[index].take();
        self.set_key(index, NOT_READY);
        self.occupied -= slot.is_some() as usize;
        slot
    }

    /// The slot to issue from this cycle among the ready ones (present, not busy, not
    /// finished), by the configured policy. Round-robin advances only when a slot issues.
    pub fn select(&mut self) -> Option<usize> {
        while let Some(i) = self.stale.pop() {
            self.set_key(i, key_of(&self.slots[i]));
        }
        if let Some(choice) = self.last_choice {
            return choice;
        }
        let choice = self.scan();
        self.last_choice = Some(choice);
        choice
    }

    /// The selection by the configured policy, from the keys.
    fn scan(&self) -> Option<usize> {
        let n = self.keys.len();
        let start = self.next_round_robin;
        let keys = &self.keys;
        match self.selection {
            RaySelection::RoundRobin => (start..n).chain(0..start).find(|&i| keys[i] != NOT_READY),
            // The least k; among equals, the first from the round-robin pointer on.
            RaySelection::LaggingFirst => {
                let least = |range: std::ops::Range<usize>| {
                    range.fold((NOT_READY, usize::MAX), |best, i| {
                        if keys[i] < best.0 {
                            (keys[i], i)
                        } else {
                            best
                        }
                    })
                };
                let (after, at_after) = least(start..n);
                let (before, at_before) = least(0..start);
                match (after, before) {
                    (NOT_READY, NOT_READY) => None,
                    _ if before < after => Some(at_before),
                    _ => Some(at_after),
                }
            }
            RaySelection::OldestFirst => (0..n)
                .filter(|&i| keys[i] != NOT_READY)
                .min_by_key(|&i| self.slots[i].as_ref().map(|s| (s.admitted, s.ray_id))),
        }
    }

    pub fn issued_from(&mut self, slot: usize) {
        self.next_round_robin = (slot + 1) % self.slots.len();
        self.last_choice = None;
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
        self.set_key(index, NOT_READY);
        Some(index)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Lagging-first as written in the brief: the least k among ready slots; among equals the
    /// first from the round-robin pointer on.
    fn reference(keys: &[u64], start: usize) -> Option<usize> {
        let n = keys.len();
        (start..n)
            .chain(0..start)
            .filter(|&i| keys[i] != NOT_READY)
            .min_by_key(|&i| keys[i])
    }

    fn ray_of(samples: u32) -> FixedRay {
        FixedRay {
            start: [0; 3],
            step: [0; 3],
            reciprocals: [None; 3],
            samples,
            first_k: 0,
            light: [0; 3],
            cut: 0,
            bricks_visited: 0,
            surface: None,
            refinable_start: false,
            t_range: [0.0; 2],
        }
    }

    /// What the pipeline does to the queue, as the property test below drives it.
    #[derive(Clone, Debug)]
    enum Event {
        /// A ray enters the first free slot at position k of `samples` (busy: its first
        /// distance word is being read).
        Admit { k: u64, samples: u32, busy: bool },
        /// The selected ray issues: busy until its update returns.
        Issue,
        /// A slot's update returns (or its word arrives): new k, busy or not.
        Update { slot: usize, k: u64, busy: bool },
        /// ERT feedback for the ray in this slot.
        Terminate { slot: usize },
        /// The ray in this slot leaves.
        Remove { slot: usize },
    }

    fn event() -> impl proptest::strategy::Strategy<Value = Event> {
        use proptest::prelude::*;
        prop_oneof![
            (0u64..4, 0u32..5, any::<bool>()).prop_map(|(k, samples, busy)| Event::Admit {
                k,
                samples,
                busy
            }),
            Just(Event::Issue),
            Just(Event::Issue),
            (0usize..8, 0u64..5, any::<bool>()).prop_map(|(slot, k, busy)| Event::Update {
                slot,
                k,
                busy
            }),
            (0usize..8).prop_map(|slot| Event::Terminate { slot }),
            (0usize..8).prop_map(|slot| Event::Remove { slot }),
        ]
    }

    /// The selection by each policy's definition, from the slots themselves (not the keys).
    fn defined_choice(queue: &RayQueue) -> Option<usize> {
        let n = queue.slots.len();
        let start = queue.next_round_robin;
        let ready = |i: usize| queue.slots[i].as_ref().filter(|s| !s.busy && !s.finished());
        let from_pointer = (start..n).chain(0..start);
        match queue.selection {
            RaySelection::RoundRobin => from_pointer.into_iter().find(|&i| ready(i).is_some()),
            RaySelection::LaggingFirst => from_pointer
                .into_iter()
                .filter_map(|i| Some((i, ready(i)?.k)))
                .min_by_key(|&(_, k)| k)
                .map(|(i, _)| i),
            RaySelection::OldestFirst => (0..n)
                .filter_map(|i| Some((i, ready(i)?)))
                .min_by_key(|(_, s)| (s.admitted, s.ray_id))
                .map(|(i, _)| i),
        }
    }

    proptest::proptest! {
        /// Any key set (small keys: many ties; some slots not ready) and pointer: the
        /// selection picks the slot the definition picks.
        #[test]
        fn lagging_first_picks_the_least_k_first_from_the_pointer(
            keys in proptest::collection::vec(proptest::option::of(0u64..6), 1..20),
            pointer in 0usize..20,
        ) {
            let mut queue = RayQueue::new(keys.len(), RaySelection::LaggingFirst);
            for (slot, key) in queue.keys.iter_mut().zip(&keys) {
                *slot = key.unwrap_or(NOT_READY);
            }
            queue.next_round_robin = pointer % keys.len();
            let expected = reference(&queue.keys, queue.next_round_robin);
            proptest::prop_assert_eq!(queue.select(), expected);
        }

        /// Keys changing one at a time (or not at all) and slots issuing (the pointer moves),
        /// with a selection after each event: the selection kept from one cycle to the next
        /// is always the one the definition picks from the keys as they are.
        #[test]
        fn a_kept_selection_is_the_definitions(
            slots in 1usize..20,
            events in proptest::collection::vec(
                (0usize..20, proptest::option::of(0u64..5), proptest::bool::ANY), 1..200),
        ) {
            for selection in [RaySelection::LaggingFirst, RaySelection::RoundRobin] {
                let mut queue = RayQueue::new(slots, selection);
                for &(slot, key, issues) in &events {
                    if issues {
                        queue.issued_from(slot % slots);
                    } else {
                        queue.set_key(slot % slots, key.unwrap_or(NOT_READY));
                    }
                    let start = queue.next_round_robin;
                    let expected = match selection {
                        RaySelection::RoundRobin => (start..slots)
                            .chain(0..start)
                            .find(|&i| queue.keys[i] != NOT_READY),
                        _ => reference(&queue.keys, start),
                    };
                    proptest::prop_assert_eq!(queue.select(), expected);
                }
            }
        }

        /// The queue as the pipeline drives it (admissions, issues through the selection,
        /// updates through `slot_mut`, ERT, removals), under every policy: after each event
        /// the selection, with its keys and the choice kept between cycles, is the one the
        /// policy defines from the slots as they are.
        #[test]
        fn the_selection_follows_the_slots_through_admit_issue_update_terminate_and_remove(
            slots in 1usize..8,
            events in proptest::collection::vec(event(), 1..120),
        ) {
            for selection in [
                RaySelection::LaggingFirst,
                RaySelection::RoundRobin,
                RaySelection::OldestFirst,
            ] {
                let mut queue = RayQueue::new(slots, selection);
                let mut next_ray = 0usize;
                for (now, event) in events.iter().enumerate() {
                    match *event {
                        Event::Admit { k, samples, busy } => {
                            if let Some(free) = queue.free_slot() {
                                queue.admit(
                                    free,
                                    RaySlot {
                                        ray_id: next_ray,
                                        ray: ray_of(samples),
                                        pos: [0; 3],
                                        k,
                                        busy,
                                        terminated: false,
                                        admitted: now as u64,
                                        samples_issued: 0,
                                        state: SkipState::default(),
                                    },
                                );
                                next_ray += 1;
                            }
                        }
                        Event::Issue => {
                            if let Some(index) = queue.select() {
                                queue.slot_mut(index).expect("a selected slot holds a ray").busy = true;
                                queue.issued_from(index);
                            }
                        }
                        Event::Update { slot, k, busy } => {
                            if let Some(s) = queue.slot_mut(slot % slots) {
                                s.k = k;
                                s.busy = busy;
                            }
                        }
                        Event::Terminate { slot } => {
                            let ray = queue.slot(slot % slots).map(|s| s.ray_id);
                            if let Some(ray) = ray {
                                proptest::prop_assert_eq!(queue.terminate(ray), Some(slot % slots));
                            }
                        }
                        Event::Remove { slot } => {
                            let had = queue.slot(slot % slots).is_some();
                            proptest::prop_assert_eq!(queue.remove(slot % slots).is_some(), had);
                        }
                    }
                    let expected = defined_choice(&queue);
                    proptest::prop_assert_eq!(queue.select(), expected, "after {:?}", event);
                    proptest::prop_assert_eq!(
                        queue.occupancy(),
                        queue.slots.iter().filter(|s| s.is_some()).count()
                    );
                }
            }
        }
    }
}

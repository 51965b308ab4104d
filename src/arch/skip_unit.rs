//! The skip calculator as a timed unit: a pipeline of `latency` stages, one new step per
//! cycle. The arithmetic (occupancy lookup, n_s, P + n_s·V) is the functional model's
//! (`functional::leaping`); this unit only delays its result, so a ray can issue at most one
//! step per `latency` cycles (brief, section 3).

use std::collections::VecDeque;

/// A ray's position update travelling through the skip calculator.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PositionUpdate {
    pub slot: usize,
    pub pos: [i64; 3],
    /// Sample positions of the ray covered so far (the next position's index k).
    pub k: u64,
}

pub struct SkipUnit {
    latency: u64,
    /// (cycle the result is back at the ray queue, update), in issue order.
    in_flight: VecDeque<(u64, PositionUpdate)>,
    pub issued: u64,
}

impl SkipUnit {
    pub fn new(latency: u32) -> SkipUnit {
        SkipUnit {
            latency: latency as u64,
            in_flight: VecDeque::new(),
            issued: 0,
        }
    }

    /// Accepts one update at `now` (throughput one per cycle: the caller issues at most one).
    pub fn push(&mut self, update: PositionUpdate, now: u64) {
        self.in_flight.push_back((now + self.latency, update));
        self.issued += 1;
    }

    /// The update whose result is due at `now`, if any (at most one: one entered per cycle).
    pub fn pop_ready(&mut self, now: u64) -> Option<PositionUpdate> {
        match self.in_flight.front() {
            Some(&(due, update)) if due <= now => {
                self.in_flight.pop_front();
                Some(update)
            }
            _ => None,
        }
    }

    pub fn occupancy(&self) -> usize {
        self.in_flight.len()
    }

    /// The next cycle at which a result comes out.
    pub fn next_event(&self) -> Option<u64> {
        self.in_flight.front().map(|&(due, _)| due)
    }
}

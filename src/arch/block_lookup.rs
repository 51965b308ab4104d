//! 2-way blocking in address generation (`crate::blocking`): every sample request looks up its
//! block in the on-chip indirection table, a pipelined stage of `blocking.lookup_latency`
//! cycles between the ray queue's issue and the memory's address FIFOs. A request leaves the
//! stage in order, `lookup_latency` cycles after it entered, when the memory takes it (else the
//! stage holds it, and when all its `lookup_latency` places are taken the issue stalls as on a
//! full address FIFO). A request whose block is inactive is not sent to memory: it completes as
//! it leaves the stage, its voxels read as zero (the functional model reads zero for it too).
//! With `lookup_latency = 0` active requests go straight to memory (as without blocking) and an
//! inactive one completes the next cycle.
//!
//! The memory behind it addresses the active blocks' slots (`AddressMap::blocked`).

use std::collections::VecDeque;
use std::sync::Arc;

use super::command_trace::IssuedCommand;
use super::trace::ModuleProbe;
use super::voxel_memory::{SampleRequest, VoxelMemory};
use crate::blocking::BlockTable;

pub struct BlockLookup<M> {
    pub inner: M,
    table: Arc<BlockTable>,
    latency: u64,
    /// Requests in the lookup stage: (cycle they may leave, request), in order.
    stage: VecDeque<(u64, SampleRequest)>,
    /// `lookup_latency = 0`: inactive requests completing at the next step.
    zeros: Vec<u64>,
    /// Table lookups (every sample request).
    pub lookups: u64,
    /// Requests of inactive blocks: completed without a memory read.
    pub zero_samples: u64,
}

impl<M: VoxelMemory> BlockLookup<M> {
    pub fn new(inner: M, table: Arc<BlockTable>, latency: u32) -> Self {
        BlockLookup {
            inner,
            table,
            latency: latency as u64,
            stage: VecDeque::new(),
            zeros: Vec::new(),
            lookups: 0,
            zero_samples: 0,
        }
    }
}

impl<M: VoxelMemory> VoxelMemory for BlockLookup<M> {
    fn try_push(&mut self, request: SampleRequest, now: u64) -> bool {
        if self.latency == 0 {
            if self.table.slot_at(request.base).is_none() {
                self.zeros.push(request.tag);
            } else if !self.inner.try_push(request, now) {
                return false;
            }
        } else {
            if self.stage.len() as u64 >= self.latency {
                return false;
            }
            self.stage.push_back((now + self.latency, request));
        }
        self.lookups += 1;
        true
    }

    fn try_push_word(&mut self, tag: u64, voxel: [usize; 3], now: u64) -> bool {
        self.inner.try_push_word(tag, voxel, now)
    }

    fn step(&mut self, now: u64, completed: &mut Vec<u64>) {
        self.inner.step(now, completed);
        self.zero_samples += self.zeros.len() as u64;
        completed.append(&mut self.zeros);
        while let Some(&(due, request)) = self.stage.front() {
            if due > now {
                break;
            }
            if self.table.slot_at(request.base).is_none() {
                completed.push(request.tag);
                self.zero_samples += 1;
            } else if !self.inner.try_push(request, now) {
                break;
            }
            self.stage.pop_front();
        }
    }

    fn is_idle(&self) -> bool {
        self.stage.is_empty() && self.zeros.is_empty() && self.inner.is_idle()
    }

    fn account_cycles(&mut self, cycles: u64) {
        self.inner.account_cycles(cycles)
    }

    fn next_event(&self, now: u64) -> Option<u64> {
        let stage = match self.zeros.is_empty() {
            true => self.stage.front().map(|&(due, _)| due.max(now + 1)),
            false => Some(now + 1),
        };
        match (self.inner.next_event(now), stage) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    fn longest_legal_wait(&self) -> u64 {
        self.inner.longest_legal_wait() + self.latency
    }

    fn stats_json(&self) -> serde_json::Value {
        let mut json = self.inner.stats_json();
        if let Some(object) = json.as_object_mut() {
            object.insert("block_lookups".into(), self.lookups.into());
            object.insert("zero_samples".into(), self.zero_samples.into());
            object.insert("lookup_latency_cycles".into(), self.latency.into());
        }
        json
    }

    fn probe(&self, modules: &mut Vec<ModuleProbe>) {
        self.inner.probe(modules)
    }

    fn issued_commands(&self, now: u64, out: &mut Vec<IssuedCommand>) {
        self.inner.issued_commands(now, out)
    }

    fn record_commands(&mut self, on: bool) {
        self.inner.record_commands(on)
    }
}

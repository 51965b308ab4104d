//! Voxel memory as seen by the pipeline: it takes a sample's neighbourhood request and, some
//! cycles later, reports the sample's words complete. The SDRAM model (modules, banks, FIFOs,
//! overtaking) is one implementation; `IdealMemory` (a fixed latency, unlimited bandwidth) is
//! the other, used for closed-form checks and as the "memory is free" bound.

use super::command_trace::IssuedCommand;
use super::trace::ModuleProbe;

/// A sample's memory request: its tag and the lower corner of its 2×2×2 neighbourhood.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SampleRequest {
    pub tag: u64,
    pub base: [usize; 3],
}

/// Tags of one-word reads (`try_push_word`: the distance volume) carry this bit; sample tags
/// (compositing-buffer entries, below 2^20) never do.
pub const WORD_TAG: u64 = 1 << 31;

pub trait VoxelMemory {
    /// Enters a request at cycle `now` if it can enter (every address FIFO it needs has room);
    /// false, and nothing changed, if not.
    fn try_push(&mut self, request: SampleRequest, now: u64) -> bool;
    /// Enters a one-word read of the distance of voxel `voxel` at cycle `now` (`tag` carries
    /// `WORD_TAG`); false, and nothing changed, if its address FIFO is full. Its tag is
    /// reported by `step` like a sample's.
    fn try_push_word(&mut self, tag: u64, voxel: [usize; 3], now: u64) -> bool;
    /// Advances one cycle and appends the tags of samples whose words are all in by `now`.
    fn step(&mut self, now: u64, completed: &mut Vec<u64>);
    /// Whether nothing is pending.
    fn is_idle(&self) -> bool;
    /// The pipeline's clock moves on by `cycles` from the current state (for occupancy
    /// histograms; nothing changes during those cycles).
    fn account_cycles(&mut self, _cycles: u64) {}
    /// The earliest cycle after `now` at which stepping could change anything (None = never
    /// on its own); the pipeline jumps over the cycles between.
    fn next_event(&self, now: u64) -> Option<u64>;
    /// Statistics as JSON (model-specific fields, documented by each model).
    fn stats_json(&self) -> serde_json::Value;
    /// A bound on how long a request may legally wait with no sample coming back, in cycles:
    /// the pipeline's watchdog allows this much on top of its own setting, so that it never
    /// fires on slow but legal timing.
    fn longest_legal_wait(&self) -> u64;
    /// Per-module waveform signals of the current cycle (none for models without modules).
    fn probe(&self, modules: &mut Vec<ModuleProbe>) {
        modules.clear();
    }
    /// Appends the memory commands issued in cycle `now` (the last cycle stepped), in module
    /// order; none for models without commands. Called only while a command trace records.
    fn issued_commands(&self, _now: u64, _out: &mut Vec<IssuedCommand>) {}
    /// Whether to keep the last issued command (for `issued_commands` and the command fields of
    /// `probe`): models with commands keep it unless told not to; the pipeline turns it off
    /// when it records no trace or waveform.
    fn record_commands(&mut self, _on: bool) {}
}

/// Every request completes exactly `latency` cycles after it entered.
pub struct IdealMemory {
    latency: u64,
    pending: std::collections::VecDeque<(u64, u64)>,
    pub requests: u64,
}

impl IdealMemory {
    pub fn new(latency: u64) -> IdealMemory {
        IdealMemory {
            latency,
            pending: Default::default(),
            requests: 0,
        }
    }
}

impl VoxelMemory for IdealMemory {
    fn try_push(&mut self, request: SampleRequest, now: u64) -> bool {
        self.pending.push_back((now + self.latency, request.tag));
        self.requests += 1;
        true
    }

    fn try_push_word(&mut self, tag: u64, _: [usize; 3], now: u64) -> bool {
        self.pending.push_back((now + self.latency, tag));
        self.requests += 1;
        true
    }

    fn step(&mut self, now: u64, completed: &mut Vec<u64>) {
        while let Some(&(due, tag)) = self.pending.front() {
            if due > now {
                break;
            }
            self.pending.pop_front();
            completed.push(tag);
        }
    }

    fn is_idle(&self) -> bool {
        self.pending.is_empty()
    }

    fn next_event(&self, _: u64) -> Option<u64> {
        self.pending.front().map(|&(due, _)| due)
    }

    fn stats_json(&self) -> serde_json::Value {
        serde_json::json!({ "model": "ideal", "latency_cycles": self.latency, "requests": self.requests })
    }

    fn longest_legal_wait(&self) -> u64 {
        self.latency
    }
}

impl<M: VoxelMemory + ?Sized> VoxelMemory for Box<M> {
    fn try_push(&mut self, request: SampleRequest, now: u64) -> bool {
        (**self).try_push(request, now)
    }
    fn try_push_word(&mut self, tag: u64, voxel: [usize; 3], now: u64) -> bool {
        (**self).try_push_word(tag, voxel, now)
    }
    fn step(&mut self, now: u64, completed: &mut Vec<u64>) {
        (**self).step(now, completed)
    }
    fn is_idle(&self) -> bool {
        (**self).is_idle()
    }
    fn account_cycles(&mut self, cycles: u64) {
        (**self).account_cycles(cycles)
    }
    fn next_event(&self, now: u64) -> Option<u64> {
        (**self).next_event(now)
    }
    fn stats_json(&self) -> serde_json::Value {
        (**self).stats_json()
    }
    fn longest_legal_wait(&self) -> u64 {
        (**self).longest_legal_wait()
    }
    fn probe(&self, modules: &mut Vec<ModuleProbe>) {
        (**self).probe(modules)
    }
    fn issued_commands(&self, now: u64, out: &mut Vec<IssuedCommand>) {
        (**self).issued_commands(now, out)
    }
    fn record_commands(&mut self, on: bool) {
        (**self).record_commands(on)
    }
}

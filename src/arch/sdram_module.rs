//! One SDRAM memory module clock by clock (controller + banks + FIFOs), and `SdramMemory`, the
//! interleaved modules behind the `VoxelMemory` interface with the sample assembly that waits
//! for all of a sample's words.
//!
//! Controller, one command per cycle at most, in this priority:
//! 1. refresh, when due: precharge the open banks (one per cycle), then REF (delayed, never
//!    skipped);
//! 2. close-page policy: precharge a bank whose row was read and that no queued request hits;
//! 3. the request the overtaking FIFO selects: READ if its row is open (and the voxel FIFO has a
//!    free place counting words in flight), else PRE the bank's other row, else ACT its row.
//!
//! A word read at cycle t is in the voxel FIFO at t + CL; the sample assembly takes at most one
//! word per module per cycle. A request pushed at cycle t is seen by the controller at t + 1.
//!
//! Writes (volume updates, `arch::update`) wait in their own in-order write FIFO (depth
//! `memory.address_fifo_depth`) and are served only when no read is queued (reads first: the
//! renderer waits for them): WRITE if the row is open, else PRE, else ACT, under the same timing
//! table. A module given a memory image (`with_image`) stores each WRITE's data in it at the
//! WRITE's cycle, so the image is what the command sequence left in the SDRAM. The write path
//! runs only under `step_with_writes`; the pipeline's `step` compiles without it, so a
//! read-only simulation does the same work as before writes existed.

use std::collections::VecDeque;

use super::address_map::{AddressMap, MemoryConfig, RowPolicy, WordAddress};
use super::command_trace::IssuedCommand;
use super::overtaking_fifo::{OvertakingFifo, PendingWord};
use super::sdram::{Command, CommandKind, SdramDevice, SdramTiming};
use super::trace::ModuleProbe;
use super::voxel_memory::{SampleRequest, VoxelMemory, WORD_TAG};

/// What one module counted. Cycles are clock cycles.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ModuleStats {
    pub reads: u64,
    /// READs whose row was already open when the request was first served.
    pub row_hits: u64,
    /// READs that needed an ACT (including those that needed a PRE first).
    pub row_misses: u64,
    /// Row misses that first had to close another row of the bank.
    pub row_conflicts: u64,
    pub activates: u64,
    pub precharges: u64,
    pub refreshes: u64,
    /// Cycles with a request queued or a refresh pending.
    pub busy_cycles: u64,
    /// Cycles the selected READ waited for a voxel-FIFO place.
    pub voxel_fifo_full_cycles: u64,
    /// Sum over reads of (data in the voxel FIFO) − (request entered the address FIFO).
    pub total_latency_cycles: u64,
    pub overtakes: u64,
    pub forced_by_bypass_bound: u64,
    pub address_fifo_peak: usize,
    /// Cycles spent at each address-FIFO fill level 0..=depth (requests waiting).
    pub address_fifo_occupancy: Vec<u64>,
    /// Cycles spent at each voxel-FIFO fill level 0..=depth (places taken: words waiting for
    /// the sample assembly, and words on their way from a READ).
    pub voxel_fifo_occupancy: Vec<u64>,
    /// WRITE commands (volume updates only; absent from the JSON when zero).
    #[serde(skip_serializing_if = "is_zero")]
    pub writes: u64,
    /// WRITEs that needed an ACT first.
    #[serde(skip_serializing_if = "is_zero")]
    pub write_row_misses: u64,
}

fn is_zero(v: &u64) -> bool {
    *v == 0
}

/// A word waiting in a module's write FIFO: where, the data and which halves to write (the
/// byte masks, DQM: bit 0 the low half, bit 1 the high half of the 2 × 16-bit word).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PendingWrite {
    pub addr: WordAddress,
    pub data: u32,
    pub mask: u8,
}

/// A module's memory contents: one 32-bit word (two 16-bit halves: the voxel pair (z, z+1), or
/// one voxel in the low half) per (bank, row, column) of the rows a volume occupies.
#[derive(Clone, Debug)]
pub struct MemoryImage {
    rows: u32,
    columns: u32,
    words: Vec<u32>,
}

impl MemoryImage {
    pub fn new(banks: u32, rows: u32, columns: u32) -> MemoryImage {
        MemoryImage {
            rows,
            columns,
            words: vec![0; banks as usize * rows as usize * columns as usize],
        }
    }

    fn index(&self, a: WordAddress) -> usize {
        (a.bank as usize * self.rows as usize + a.row as usize) * self.columns as usize
            + a.column as usize
    }

    pub fn word(&self, a: WordAddress) -> u32 {
        self.words[self.index(a)]
    }

    fn write(&mut self, w: &PendingWrite) {
        let i = self.index(w.addr);
        let keep = (if w.mask & 1 == 0 { 0xffff } else { 0 })
            | (if w.mask & 2 == 0 { 0xffff_0000 } else { 0 });
        self.words[i] = (self.words[i] & keep) | (w.data & !keep);
    }
}

/// A module's voxel FIFO: a ring of (cycle the data is there, tag) of a power-of-two capacity
/// at least the depth (the controller never puts more in), without `VecDeque`'s growth checks
/// on the read path.
struct VoxelFifo {
    ring: Box<[(u64, u32)]>,
    head: usize,
    len: usize,
    /// The oldest word's cycle (`u64::MAX` when empty): the per-cycle check is one compare.
    front_ready: u64,
}

impl VoxelFifo {
    fn new(depth: usize) -> VoxelFifo {
        VoxelFifo {
            ring: vec![(0, 0); depth.max(1).next_power_of_two()].into_boxed_slice(),
            head: 0,
            len: 0,
            front_ready: u64::MAX,
        }
    }

    #[inline(always)]
    fn len(&self) -> usize {
        self.len
    }

    #[inline(always)]
    fn is_empty(&self) -> bool {
        self.len == 0
    }

    #[inline(always)]
    fn push_back(&mut self, word: (u64, u32)) {
        let mask = self.ring.len() - 1;
        assert!(self.len <= mask, "voxel FIFO over its capacity");
        self.ring[(self.head + self.len) & mask] = word;
        if self.len == 0 {
            self.front_ready = word.0;
        }
        self.len += 1;
    }

    /// The cycle the oldest word's data is there, `u64::MAX` if there is none.
    #[inline(always)]
    fn front_ready(&self) -> u64 {
        self.front_ready
    }

    /// Takes the oldest word's tag if its data is there by `now`.
    #[inline(always)]
    fn pop_ready(&mut self, now: u64) -> Option<u32> {
        if now < self.front_ready {
            return None;
        }
        let mask = self.ring.len() - 1;
        let tag = self.ring[self.head & mask].1;
        self.head = (self.head + 1) & mask;
        self.len -= 1;
        self.front_ready = if self.len == 0 {
            u64::MAX
        } else {
            self.ring[self.head & mask].0
        };
        Some(tag)
    }
}

pub struct SdramModule {
    device: SdramDevice,
    fifo: OvertakingFifo,
    /// Words read: (cycle the data is there, tag), in read order; its length counts in-flight
    /// reads, so it never exceeds the voxel FIFO depth.
    voxel_fifo: VoxelFifo,
    voxel_depth: usize,
    cl: u64,
    policy: RowPolicy,
    /// Banks read under the close-page policy, to precharge.
    to_close: Vec<bool>,
    refresh_interval: Option<u64>,
    next_refresh: u64,
    refresh_pending: bool,
    /// For waveforms and command traces: the last command issued (cycle `u64::MAX`: none yet;
    /// kept only while `records_commands`), the row of the last ACT.
    last_command: IssuedCommand,
    last_act_row: u32,
    /// Keep `last_command` (on unless turned off: a simulation without trace or waveform does
    /// not read it, and storing it is a tenth of a READ's cost).
    records_commands: bool,
    /// The controller sleeps until this cycle (0 after a push: run next cycle).
    wake_at: u64,
    /// The last cycle the controller ran, and whether it was busy (requests queued or a
    /// refresh pending) when it went to sleep: the cycles slept through count as busy then.
    last_step: u64,
    busy_while_asleep: bool,
    /// Sleeping enabled (off only to check that it changes nothing).
    sleeps: bool,
    pub stats: ModuleStats,
    /// Words to write, in order (volume updates), and their FIFO depth.
    writes: VecDeque<PendingWrite>,
    write_depth: usize,
    /// The module's contents, when modelled (`with_image`).
    image: Option<MemoryImage>,
}

impl SdramModule {
    pub fn new(config: &MemoryConfig, timing: &SdramTiming) -> SdramModule {
        let refresh_interval = timing.refresh.then_some(timing.refresh_interval as u64);
        SdramModule {
            device: SdramDevice::new(config.banks as usize, timing),
            fifo: OvertakingFifo::new(
                config.address_fifo_depth,
                config.overtaking,
                config.overtaking_window,
                config.max_bypass,
            ),
            voxel_fifo: VoxelFifo::new(config.voxel_fifo_depth),
            voxel_depth: config.voxel_fifo_depth,
            cl: timing.cl as u64,
            policy: config.row_policy,
            to_close: vec![false; config.banks as usize],
            refresh_interval,
            next_refresh: refresh_interval.unwrap_or(u64::MAX),
            refresh_pending: false,
            last_command: IssuedCommand {
                cycle: u64::MAX,
                module: 0,
                kind: CommandKind::Ref,
                bank: 0,
                row: 0,
                column: 0,
                tag: 0,
            },
            last_act_row: 0,
            records_commands: true,
            wake_at: 0,
            last_step: 0,
            busy_while_asleep: false,
            sleeps: true,
            stats: ModuleStats {
                address_fifo_occupancy: vec![0; config.address_fifo_depth + 1],
                voxel_fifo_occupancy: vec![0; config.voxel_fifo_depth + 1],
                ..ModuleStats::default()
            },
            writes: VecDeque::new(),
            write_depth: config.address_fifo_depth,
            image: None,
        }
    }

    /// Models the module's contents (the rows `rows` per bank), all zero at the start: WRITEs
    /// store their data there.
    pub fn with_image(mut self, banks: u32, rows: u32, columns: u32) -> SdramModule {
        self.image = Some(MemoryImage::new(banks, rows, columns));
        self
    }

    /// A module that keeps no record of its last command (`issued_at` then answers None): for
    /// users that read none (the update engine), as the pipeline turns it off through
    /// `VoxelMemory::record_commands` when no trace or waveform records.
    pub fn without_command_record(mut self) -> SdramModule {
        self.records_commands = false;
        self
    }

    pub fn image(&self) -> Option<&MemoryImage> {
        self.image.as_ref()
    }

    /// A controller that runs every cycle instead of sleeping: the reference that sleeping
    /// must equal (tests).
    pub fn without_sleeping(mut self) -> SdramModule {
        self.sleeps = false;
        self
    }

    /// Whether the write FIFO has a free place.
    pub fn can_accept_write(&self) -> bool {
        self.writes.len() < self.write_depth
    }

    /// Queues a word write at cycle `now` (seen by the controller at `now + 1`).
    pub fn push_write(&mut self, write: PendingWrite, _now: u64) {
        debug_assert!(self.can_accept_write());
        self.wake_at = 0;
        self.writes.push_back(write);
    }

    /// Writes waiting in the write FIFO.
    pub fn writes_pending(&self) -> usize {
        self.writes.len()
    }

    pub fn can_accept(&self) -> bool {
        self.fifo.can_accept()
    }

    pub fn push(&mut self, tag: u32, addr: WordAddress, now: u64) {
        self.wake_at = 0;
        self.fifo.push(PendingWord::new(tag, addr, now));
    }

    /// Issues `cmd` at `now` if the timing rules allow it, else returns the earliest cycle
    /// they do. `tag`: the request a READ serves. The controller only asks for commands whose
    /// state precondition holds (READ and PRE to an open bank, ACT to a closed one, REF with
    /// every bank closed), so only the timing is checked here.
    #[inline(always)]
    fn try_issue(&mut self, cmd: Command, now: u64, tag: u32) -> Result<(), u64> {
        debug_assert!(
            self.device.state_allows(cmd),
            "{cmd:?} in the wrong bank state"
        );
        let ready = self.device.earliest(cmd);
        if now < ready {
            return Err(ready);
        }
        // The row a READ reads or a PRE closes: the bank's open row before the command.
        let (bank, row, column) = match cmd {
            Command::Act { bank, row } => (bank, row, 0),
            // READ, WRITE and PRE go to an open bank.
            Command::Read { bank, column } | Command::Write { bank, column } => {
                (bank, self.device.open_row_of_open_bank(bank), column)
            }
            Command::Pre { bank } => (bank, self.device.open_row_of_open_bank(bank), 0),
            Command::Ref => (0, 0, 0),
        };
        self.device.issue(cmd, now);
        match cmd {
            Command::Act { bank, row } => {
                self.stats.activates += 1;
                self.last_act_row = row;
                self.fifo.row_opened(bank as u32, row);
            }
            Command::Read { .. } => self.stats.reads += 1,
            Command::Pre { bank } => {
                self.stats.precharges += 1;
                self.fifo.row_closed(bank as u32);
            }
            Command::Ref => self.stats.refreshes += 1,
            Command::Write { .. } => self.stats.writes += 1,
        }
        if self.records_commands {
            self.last_command = IssuedCommand {
                cycle: now,
                module: 0,
                kind: cmd.kind(),
                bank: bank as u32,
                row,
                column,
                tag,
            };
        }
        Ok(())
    }

    /// The command issued in cycle `now`, if any (`module` is left 0: the module does not know
    /// its index).
    pub fn issued_at(&self, now: u64) -> Option<IssuedCommand> {
        (self.last_command.cycle == now).then_some(self.last_command)
    }

    /// One controller cycle. A controller that can do nothing before a known cycle (its
    /// command waits for a timing rule, or it is idle until the next refresh) sleeps until
    /// then; a push wakes it. Sleeping is exact: the cycles slept through are counted as
    /// ticking would count them (tests/sdram.rs compares both).
    ///
    /// The read path's step: the write FIFO is not looked at (the pipeline never writes), so
    /// the controller compiles to the read-only code. `step_with_writes` serves both.
    #[inline]
    pub fn step(&mut self, now: u64) {
        debug_assert!(self.writes.is_empty(), "writes need step_with_writes");
        self.step_generic::<false>(now)
    }

    /// `step` for a module that also writes (volume updates): reads first, then writes.
    pub fn step_with_writes(&mut self, now: u64) {
        self.step_generic::<true>(now)
    }

    #[inline(always)]
    fn step_generic<const WRITES: bool>(&mut self, now: u64) {
        if now < self.wake_at {
            return;
        }
        if self.busy_while_asleep {
            self.stats.busy_cycles += now - self.last_step - 1;
        }
        self.last_step = now;
        let wake = if self.sleeps {
            self.control::<WRITES>(now)
        } else {
            self.control::<WRITES>(now);
            now + 1
        };
        self.wake_at = wake.min(self.next_refresh);
        self.busy_while_asleep =
            !self.fifo.is_empty() || self.refresh_pending || (WRITES && !self.writes.is_empty());
    }

    /// The controller's decision in cycle `now`; returns the next cycle it must run again
    /// (absent pushes). With `WRITES` false (the read path) the write FIFO is not looked at.
    fn control<const WRITES: bool>(&mut self, now: u64) -> u64 {
        if now >= self.next_refresh {
            self.refresh_pending = true;
            self.next_refresh += self.refresh_interval.unwrap_or(u64::MAX);
        }
        if !self.fifo.is_empty() || self.refresh_pending || (WRITES && !self.writes.is_empty()) {
            self.stats.busy_cycles += 1;
        }
        if self.refresh_pending {
            let open = (0..self.device.banks()).find(|&b| self.device.is_open(b));
            let command = match open {
                Some(bank) => Command::Pre { bank },
                None => Command::Ref,
            };
            return match self.try_issue(command, now, 0) {
                Ok(()) => {
                    if command == Command::Ref {
                        self.refresh_pending = false;
                    }
                    now + 1
                }
                Err(ready) => ready,
            };
        }
        if self.policy == RowPolicy::Close {
            for bank in 0..self.to_close.len() {
                if !self.to_close[bank] {
                    continue;
                }
                match self.device.open_row(bank) {
                    Some(row) if !self.fifo.window_hits(bank as u32, row) => {
                        if self.try_issue(Command::Pre { bank }, now, 0).is_ok() {
                            self.to_close[bank] = false;
                            return now + 1;
                        }
                    }
                    _ => self.to_close[bank] = false,
                }
            }
        }
        let pending_close = self.policy == RowPolicy::Close && self.to_close.iter().any(|&c| c);
        let Some(index) = self.fifo.select() else {
            if WRITES && !self.writes.is_empty() {
                return self.control_write_path(now, pending_close);
            }
            return if pending_close { now + 1 } else { u64::MAX };
        };
        let request = *self.fifo.get(index);
        let bank = request.bank() as usize;
        // The FIFO's row-hit bit says whether the request's row is open; a miss needs its bank
        // closed first if another row is open.
        let command = if self.fifo.is_hit(index) {
            if self.voxel_fifo.len() >= self.voxel_depth {
                self.stats.voxel_fifo_full_cycles += 1;
                return now + 1;
            }
            Command::Read {
                bank,
                column: request.column as u32,
            }
        } else if self.device.is_open(bank) {
            Command::Pre { bank }
        } else {
            Command::Act {
                bank,
                row: request.row(),
            }
        };
        if let Err(ready) = self.try_issue(command, now, request.tag) {
            return if pending_close { now + 1 } else { ready };
        }
        match command {
            Command::Read { .. } => {
                let served = self.fifo.take(index);
                let ready = now + self.cl;
                self.voxel_fifo.push_back((ready, served.tag));
                self.stats.total_latency_cycles += ready - served.entered;
                if served.activated {
                    self.stats.row_misses += 1;
                    self.stats.row_conflicts += served.precharged as u64;
                } else {
                    self.stats.row_hits += 1;
                }
                if self.policy == RowPolicy::Close {
                    self.to_close[bank] = true;
                }
            }
            Command::Pre { .. } => self.fifo.get_mut(index).precharged = true,
            Command::Act { .. } => self.fifo.get_mut(index).activated = true,
            Command::Ref | Command::Write { .. } => {
                unreachable!("read requests issue READ, PRE or ACT")
            }
        }
        now + 1
    }

    /// The write path's decision (no read queued). Kept out of line: the read path's `control`
    /// stays as small (and as inlined) as without writes.
    #[cold]
    #[inline(never)]
    fn control_write_path(&mut self, now: u64, pending_close: bool) -> u64 {
        self.control_write(now, pending_close)
    }

    /// The write path's decision (no read queued): the oldest write's WRITE if its row is
    /// open, else PRE the bank's other row, else ACT its row.
    fn control_write(&mut self, now: u64, pending_close: bool) -> u64 {
        let write = self.writes[0];
        let bank = write.addr.bank as usize;
        let command = match self.device.open_row(bank) {
            Some(row) if row == write.addr.row => Command::Write {
                bank,
                column: write.addr.column,
            },
            Some(_) => Command::Pre { bank },
            None => Command::Act {
                bank,
                row: write.addr.row,
            },
        };
        if let Err(ready) = self.try_issue(command, now, 0) {
            return if pending_close { now + 1 } else { ready };
        }
        match command {
            Command::Write { .. } => {
                self.writes.pop_front();
                if let Some(image) = &mut self.image {
                    image.write(&write);
                }
            }
            Command::Act { .. } => self.stats.write_row_misses += 1,
            _ => {}
        }
        now + 1
    }

    /// The oldest word whose data is in the voxel FIFO by `now`.
    pub fn pop_word(&mut self, now: u64) -> Option<u32> {
        self.voxel_fifo.pop_ready(now)
    }

    /// The earliest cycle after `now` at which this module could change anything: its
    /// controller wakes, or a word's data reaches the voxel FIFO.
    pub fn next_event(&self, now: u64) -> Option<u64> {
        let data = self.voxel_fifo.front_ready();
        let next = self.wake_at.min(data);
        (next != u64::MAX).then(|| next.max(now + 1))
    }

    /// The first cycle at which a step can change anything: before it, `step` returns at once
    /// (the controller sleeps). A module that does not sleep says the next cycle.
    pub fn wakes_at(&self) -> u64 {
        self.wake_at
    }

    pub fn is_idle(&self) -> bool {
        self.fifo.is_empty() && self.voxel_fifo.is_empty() && self.writes.is_empty()
    }

    /// Adds `cycles` cycles at the current FIFO levels to the occupancy histograms.
    pub fn account_cycles(&mut self, cycles: u64) {
        self.stats.address_fifo_occupancy[self.fifo.len()] += cycles;
        self.stats.voxel_fifo_occupancy[self.voxel_fifo.len()] += cycles;
    }

    /// Waveform signals at cycle `now`.
    pub fn probe(&self, now: u64) -> ModuleProbe {
        let issued = self.issued_at(now);
        ModuleProbe {
            command: issued.map_or(0, |c| c.kind.index() as u64 + 1),
            bank: issued
                .filter(|c| c.kind != CommandKind::Ref)
                .map(|c| c.bank as u64),
            column: issued
                .filter(|c| c.kind == CommandKind::Read)
                .map(|c| c.column as u64),
            open_row: self.last_act_row as u64,
            address_fifo: self.fifo.len() as u64,
            voxel_fifo: self.voxel_fifo.len() as u64,
        }
    }

    /// Final statistics (folds in the FIFO's counters).
    pub fn final_stats(&self) -> ModuleStats {
        let mut s = self.stats.clone();
        s.overtakes = self.fifo.overtakes;
        s.forced_by_bypass_bound = self.fifo.forced;
        s.address_fifo_peak = self.fifo.peak;
        s
    }
}

/// The interleaved SDRAM modules as the pipeline's voxel memory.
pub struct SdramMemory {
    map: AddressMap,
    /// The cycle of the last `step`, for waveform probes.
    now: u64,
    modules: Vec<SdramModule>,
    /// Words still missing per tag (tags are compositing-buffer entry ids).
    missing: Vec<u8>,
    clock_mhz: f64,
    /// `VoxelMemory::longest_legal_wait`.
    longest_wait: u64,
}

impl SdramMemory {
    pub fn new(
        config: &MemoryConfig,
        timing: &SdramTiming,
        dims: [usize; 3],
        clock_mhz: f64,
    ) -> Self {
        Self::with_map(config, timing, AddressMap::new(config, dims), clock_mhz)
    }

    /// The modules addressed through `map` (e.g. the blocked layout, `AddressMap::blocked`).
    pub fn with_map(
        config: &MemoryConfig,
        timing: &SdramTiming,
        map: AddressMap,
        clock_mhz: f64,
    ) -> Self {
        SdramMemory {
            map,
            now: 0,
            modules: (0..config.modules())
                .map(|_| SdramModule::new(config, timing))
                .collect(),
            missing: Vec::new(),
            clock_mhz,
            longest_wait: longest_legal_wait(config, timing),
        }
    }

    /// Controllers that run every cycle instead of sleeping until their next possible
    /// command: the reference that sleeping must equal (tests).
    pub fn without_sleeping(mut self) -> Self {
        for module in &mut self.modules {
            module.sleeps = false;
        }
        self
    }

    pub fn module_stats(&self) -> Vec<ModuleStats> {
        self.modules.iter().map(SdramModule::final_stats).collect()
    }
}

/// A bound on a request's legal wait: every request ahead of it in its address FIFO, the
/// overtaking window and the voxel FIFO, plus itself, each taking at most every timing
/// parameter in turn (precharge, activate, read, refresh, write turnarounds...). Loose on
/// purpose: it only keeps the watchdog off legal waits.
fn longest_legal_wait(config: &MemoryConfig, timing: &SdramTiming) -> u64 {
    let per_request: u64 = timing
        .parameters()
        .iter()
        .filter(|(name, _)| *name != "refresh_interval")
        .chain(timing.write_parameters().iter())
        .map(|&(_, cycles)| cycles as u64)
        .sum();
    let ahead = config.address_fifo_depth + config.overtaking_window + config.voxel_fifo_depth;
    per_request * (ahead as u64 + 1)
}

impl VoxelMemory for SdramMemory {
    fn try_push(&mut self, request: SampleRequest, now: u64) -> bool {
        // A sample's words go one to each module: it enters only if every module has room
        // (every module asked, without a branch per module).
        if !self
            .modules
            .iter()
            .fold(true, |room, m| room & m.can_accept())
        {
            return false;
        }
        let tag = request.tag as usize;
        if self.missing.len() <= tag {
            self.missing.resize(tag + 1, 0);
        }
        self.missing[tag] = self.modules.len() as u8;
        let modules = &mut self.modules;
        self.map.for_each_sample_word(request.base, |word| {
            modules[word.module as usize].push(request.tag as u32, word, now)
        });
        true
    }

    fn try_push_word(&mut self, tag: u64, voxel: [usize; 3], now: u64) -> bool {
        let word = self.map.distance_word(voxel);
        let module = &mut self.modules[word.module as usize];
        if !module.can_accept() {
            return false;
        }
        module.push(tag as u32, word, now);
        true
    }

    fn step(&mut self, now: u64, completed: &mut Vec<u64>) {
        self.now = now;
        for module in &mut self.modules {
            module.step(now);
            if let Some(tag) = module.pop_word(now) {
                if tag as u64 & WORD_TAG != 0 {
                    completed.push(tag as u64);
                    continue;
                }
                let missing = &mut self.missing[tag as usize];
                *missing -= 1;
                // Without a branch on whether this was the sample's last word (it follows
                // the data): pushed, then kept only if so.
                let kept = completed.len() + (*missing == 0) as usize;
                completed.push(tag as u64);
                completed.truncate(kept);
            }
        }
    }

    fn is_idle(&self) -> bool {
        self.modules.iter().all(SdramModule::is_idle)
    }

    fn account_cycles(&mut self, cycles: u64) {
        for module in &mut self.modules {
            module.account_cycles(cycles);
        }
    }

    fn next_event(&self, now: u64) -> Option<u64> {
        self.modules.iter().filter_map(|m| m.next_event(now)).min()
    }

    fn probe(&self, modules: &mut Vec<ModuleProbe>) {
        modules.clear();
        modules.extend(self.modules.iter().map(|m| m.probe(self.now)));
    }

    fn record_commands(&mut self, on: bool) {
        for module in &mut self.modules {
            module.records_commands = on;
        }
    }

    fn issued_commands(&self, now: u64, out: &mut Vec<IssuedCommand>) {
        for (index, module) in self.modules.iter().enumerate() {
            if let Some(mut command) = module.issued_at(now) {
                command.module = index as u32;
                out.push(command);
            }
        }
    }

    fn stats_json(&self) -> serde_json::Value {
        let modules = self.module_stats();
        let sum = |f: fn(&ModuleStats) -> u64| modules.iter().map(f).sum::<u64>();
        // Rates per read are null without a read (a frame that reads no voxel).
        let reads = sum(|s| s.reads);
        let per_read = |total: u64| (reads > 0).then(|| total as f64 / reads as f64);
        let period_ns = 1e3 / self.clock_mhz;
        serde_json::json!({
            "model": "sdram",
            "reads": reads,
            "row_hits": sum(|s| s.row_hits),
            "row_misses": sum(|s| s.row_misses),
            "row_hit_rate": per_read(sum(|s| s.row_hits)),
            "refreshes": sum(|s| s.refreshes),
            // Module busy time per word read: the published "average memory cost per voxel access".
            "avg_ns_per_voxel_access": per_read(sum(|s| s.busy_cycles)).map(|c| c * period_ns),
            "avg_access_latency_cycles": per_read(sum(|s| s.total_latency_cycles)),
            "modules": modules,
        })
    }

    fn longest_legal_wait(&self) -> u64 {
        self.longest_wait
    }
}

/// Functional warming for sampled simulation (`arch::sampling`): a segment that starts inside
/// the frame starts the memory's refresh counter at a phase of the refresh interval rather than
/// at 0 (the frame's first refresh), so that a measured window does not always meet its
/// refreshes at the same place.
impl SdramMemory {
    /// The first refresh of every module comes `refresh_interval - phase % refresh_interval`
    /// cycles from now (at cycle 0, before the first step), as if the frame had last refreshed
    /// `phase % refresh_interval` cycles ago. No effect without refresh.
    pub fn warm_refresh_phase(&mut self, phase: u64) {
        for module in &mut self.modules {
            if let Some(interval) = module.refresh_interval {
                module.next_refresh = interval - phase % interval;
            }
        }
    }
}

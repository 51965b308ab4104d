//! SDRAM banks and their timing rules, as data (Ramulator / DRAMSim style): every constraint is
//! one row of `timing_rules` — {preceding command, following command, scope, latency} — and
//! issuing a command raises the "earliest legal cycle" of the commands it constrains. One
//! command per cycle per module (the command bus). PC100 2-2-2 defaults (brief, section 4).
//!
//! WRITE (burst length 1, data registered with the command, as in SDR SDRAM) shares the table:
//! ACT -> WRITE tRCD, WRITE -> WRITE tCCD (data bus, one word per cycle), WRITE -> PRE tWR
//! (write recovery), WRITE -> READ tWTR and READ -> WRITE tRTW (data-bus turnaround: the read
//! data is on the bus CL cycles after its READ). The read path never issues a WRITE, so these
//! rules never fire in a read-only simulation (command traces, which record the read path,
//! list only the read rules: `read_path_rules`).

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SdramTiming {
    /// CAS latency: READ to data, cycles.
    pub cl: u32,
    /// ACT to READ, same bank.
    pub t_rcd: u32,
    /// PRE to ACT, same bank.
    pub t_rp: u32,
    /// ACT to PRE, same bank (row active time).
    pub t_ras: u32,
    /// ACT to ACT, same bank (row cycle).
    pub t_rc: u32,
    /// ACT to ACT, different banks of a module.
    pub t_rrd: u32,
    /// READ to READ, any bank.
    pub t_ccd: u32,
    /// REF to any command (refresh cycle).
    pub t_rfc: u32,
    /// Cycles between refreshes (a refresh is due every this many cycles).
    pub refresh_interval: u32,
    /// Model refresh at all.
    pub refresh: bool,
    /// WRITE to PRE, same bank (write recovery, tWR / tDPL): PC100 needs 15 ns, 2 cycles at
    /// 100 MHz. The write fields are optional in configuration files (defaults here) and written
    /// out only when not the default, so read-only configurations and run keys are unchanged.
    #[serde(default = "default_t_wr", skip_serializing_if = "is_default_t_wr")]
    pub t_wr: u32,
    /// WRITE to READ, any bank of the module (write-to-read turnaround, tWTR). SDR SDRAM
    /// registers the write data with the command, so 1 (the next cycle).
    #[serde(default = "default_t_wtr", skip_serializing_if = "is_default_t_wtr")]
    pub t_wtr: u32,
    /// READ to WRITE, any bank of the module (read-to-write turnaround, tRTW): the read's data
    /// occupies the data bus CL cycles after the READ, then one idle cycle before the write
    /// data may drive it: CL + 1 (burst) + 1 = 4 at CL 2. Must exceed `cl`.
    #[serde(default = "default_t_rtw", skip_serializing_if = "is_default_t_rtw")]
    pub t_rtw: u32,
}

fn default_t_wr() -> u32 {
    2
}
fn is_default_t_wr(v: &u32) -> bool {
    *v == default_t_wr()
}
fn default_t_wtr() -> u32 {
    1
}
fn is_default_t_wtr(v: &u32) -> bool {
    *v == default_t_wtr()
}
fn default_t_rtw() -> u32 {
    4
}
fn is_default_t_rtw(v: &u32) -> bool {
    *v == default_t_rtw()
}

/// The largest value of every SDRAM timing field, in cycles.
const MAX_TIMING_CYCLES: u32 = 64;

impl SdramTiming {
    /// The write-timing parameters in cycles, by configuration name (`sdram.<name>`).
    pub fn write_parameters(&self) -> [(&'static str, u32); 3] {
        [
            ("t_wr", self.t_wr),
            ("t_wtr", self.t_wtr),
            ("t_rtw", self.t_rtw),
        ]
    }

    /// Every read-path timing parameter in cycles, by its configuration name (`sdram.<name>`).
    pub fn parameters(&self) -> [(&'static str, u32); 9] {
        [
            ("cl", self.cl),
            ("t_rcd", self.t_rcd),
            ("t_rp", self.t_rp),
            ("t_ras", self.t_ras),
            ("t_rc", self.t_rc),
            ("t_rrd", self.t_rrd),
            ("t_ccd", self.t_ccd),
            ("t_rfc", self.t_rfc),
            ("refresh_interval", self.refresh_interval),
        ]
    }

    /// The longest a READ can wait behind a refresh, in cycles from the cycle before the refresh
    /// falls due (when the last ACT can have issued): the REF waits `t_ras` for that row, then
    /// precharges the `banks` banks one per cycle and waits `t_rp`; the next ACT waits `t_rfc`
    /// (or `t_rc` / `t_rrd` from the last ACT, were those longer) and its READ `t_rcd`. A
    /// refresh interval at least this long lets every interval serve a READ; a shorter one can
    /// refresh forever without reading (the pipeline's watchdog then stops the run).
    pub fn longest_refresh_wait(&self, banks: u32) -> u32 {
        (self.t_ras + banks.saturating_sub(1) + self.t_rp + self.t_rfc)
            .max(self.t_rc)
            .max(self.t_rrd)
            + self.t_rcd
    }

    /// Checks every field's range and the rules between them; `banks` (`memory.banks`) bounds
    /// the refresh interval (`longest_refresh_wait`).
    pub fn validate(&self, source: &str, banks: u32) -> Result<()> {
        for (field, value) in [
            ("sdram.cl", self.cl),
            ("sdram.t_rcd", self.t_rcd),
            ("sdram.t_rp", self.t_rp),
            ("sdram.t_ras", self.t_ras),
            ("sdram.t_rc", self.t_rc),
            ("sdram.t_rrd", self.t_rrd),
            ("sdram.t_ccd", self.t_ccd),
            ("sdram.t_rfc", self.t_rfc),
            ("sdram.t_wr", self.t_wr),
            ("sdram.t_wtr", self.t_wtr),
            ("sdram.t_rtw", self.t_rtw),
        ] {
            if !(1..=MAX_TIMING_CYCLES).contains(&value) {
                return Err(Error::config(
                    source,
                    field,
                    format!("{value} is out of range; allowed 1..={MAX_TIMING_CYCLES} cycles"),
                ));
            }
        }
        // t_rtw must exceed cl and is at most MAX_TIMING_CYCLES: a cl at that bound leaves t_rtw
        // no value, and the error then belongs to cl (not to t_rtw with an empty range).
        if self.cl >= MAX_TIMING_CYCLES {
            return Err(Error::config(
                source,
                "sdram.cl",
                format!(
                    "{} leaves no room for the READ-to-WRITE turnaround sdram.t_rtw, which must \
                     exceed cl and is at most {MAX_TIMING_CYCLES} cycles; allowed 1..={}",
                    self.cl,
                    MAX_TIMING_CYCLES - 1
                ),
            ));
        }
        if self.t_rtw <= self.cl {
            return Err(Error::config(
                source,
                "sdram.t_rtw",
                format!(
                    "{} would drive write data while the READ's data (sdram.cl = {} cycles after \
                     it) is on the bus; allowed cl + 1 ({})..={MAX_TIMING_CYCLES} (or lower sdram.cl)",
                    self.t_rtw,
                    self.cl,
                    self.cl + 1
                ),
            ));
        }
        let wait = self.longest_refresh_wait(banks);
        if self.refresh && self.refresh_interval < wait {
            return Err(Error::config(
                source,
                "sdram.refresh_interval",
                format!(
                    "{} can leave no READ between two refreshes (a READ can wait t_ras + \
                     (memory.banks - 1) + t_rp + t_rfc + t_rcd = {wait} cycles behind a refresh); \
                     allowed {wait}..=4294967295",
                    self.refresh_interval
                ),
            ));
        }
        Ok(())
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum CommandKind {
    Act,
    Read,
    Pre,
    Ref,
    Write,
}

/// Command kinds (the index range of `CommandKind::index`).
pub const KINDS: usize = 5;

impl CommandKind {
    pub const ALL: [CommandKind; KINDS] = [
        CommandKind::Act,
        CommandKind::Read,
        CommandKind::Pre,
        CommandKind::Ref,
        CommandKind::Write,
    ];

    /// 0 ACT, 1 READ, 2 PRE, 3 REF, 4 WRITE.
    pub fn index(self) -> usize {
        self as usize
    }

    /// The command's name in traces and waveforms: ACT, READ, PRE, REF, WRITE.
    pub fn name(self) -> &'static str {
        match self {
            CommandKind::Act => "ACT",
            CommandKind::Read => "READ",
            CommandKind::Pre => "PRE",
            CommandKind::Ref => "REF",
            CommandKind::Write => "WRITE",
        }
    }

    pub fn from_name(name: &str) -> Option<CommandKind> {
        CommandKind::ALL.into_iter().find(|k| k.name() == name)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Command {
    Act {
        bank: usize,
        row: u32,
    },
    Read {
        bank: usize,
        column: u32,
    },
    Pre {
        bank: usize,
    },
    /// Refresh; needs every bank closed.
    Ref,
    /// One word written into the open row (burst length 1; the data goes with the command).
    Write {
        bank: usize,
        column: u32,
    },
}

impl Command {
    pub fn kind(self) -> CommandKind {
        match self {
            Command::Act { .. } => CommandKind::Act,
            Command::Read { .. } => CommandKind::Read,
            Command::Pre { .. } => CommandKind::Pre,
            Command::Ref => CommandKind::Ref,
            Command::Write { .. } => CommandKind::Write,
        }
    }

    fn bank(self) -> Option<usize> {
        match self {
            Command::Act { bank, .. }
            | Command::Read { bank, .. }
            | Command::Write { bank, .. }
            | Command::Pre { bank } => Some(bank),
            Command::Ref => None,
        }
    }
}

/// Which banks a rule constrains, relative to the bank of the preceding command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Scope {
    SameBank,
    OtherBanks,
    AllBanks,
}

impl Scope {
    /// The scope's name in traces: same_bank, other_banks, all_banks.
    pub fn name(self) -> &'static str {
        match self {
            Scope::SameBank => "same_bank",
            Scope::OtherBanks => "other_banks",
            Scope::AllBanks => "all_banks",
        }
    }

    pub fn from_name(name: &str) -> Option<Scope> {
        [Scope::SameBank, Scope::OtherBanks, Scope::AllBanks]
            .into_iter()
            .find(|s| s.name() == name)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct TimingRule {
    pub preceding: CommandKind,
    pub following: CommandKind,
    pub scope: Scope,
    pub latency: u32,
    /// The timing parameter the latency comes from (`t_rcd`, ...; `read_to_pre` for the fixed
    /// one-cycle READ-to-PRE rule).
    pub parameter: &'static str,
}

/// Every timing constraint of the device, in one table.
pub fn timing_rules(t: &SdramTiming) -> Vec<TimingRule> {
    use CommandKind::*;
    use Scope::*;
    let rule = |preceding, following, scope, (parameter, latency)| TimingRule {
        preceding,
        following,
        scope,
        latency,
        parameter,
    };
    vec![
        rule(Act, Read, SameBank, ("t_rcd", t.t_rcd)),
        rule(Act, Pre, SameBank, ("t_ras", t.t_ras)),
        rule(Act, Act, SameBank, ("t_rc", t.t_rc)),
        rule(Act, Act, OtherBanks, ("t_rrd", t.t_rrd)),
        rule(Pre, Act, SameBank, ("t_rp", t.t_rp)),
        rule(Pre, Ref, AllBanks, ("t_rp", t.t_rp)),
        rule(Read, Read, AllBanks, ("t_ccd", t.t_ccd)),
        // A read must leave its bank open until the access is under way (burst length 1).
        rule(Read, Pre, SameBank, ("read_to_pre", 1)),
        rule(Ref, Act, AllBanks, ("t_rfc", t.t_rfc)),
        rule(Ref, Ref, AllBanks, ("t_rfc", t.t_rfc)),
        // Writes (the update engine's path; burst length 1, write latency 0).
        rule(Act, Write, SameBank, ("t_rcd", t.t_rcd)),
        rule(Write, Write, AllBanks, ("t_ccd", t.t_ccd)),
        rule(Write, Pre, SameBank, ("t_wr", t.t_wr)),
        rule(Write, Read, AllBanks, ("t_wtr", t.t_wtr)),
        rule(Read, Write, AllBanks, ("t_rtw", t.t_rtw)),
    ]
}

/// The rules among the read path's commands (ACT, READ, PRE, REF): the table without the
/// rules that involve a WRITE. Command traces record the read path and list these.
pub fn read_path_rules(t: &SdramTiming) -> Vec<TimingRule> {
    timing_rules(t)
        .into_iter()
        .filter(|r| r.preceding != CommandKind::Write && r.following != CommandKind::Write)
        .collect()
}

#[derive(Clone, Debug)]
struct Bank {
    open_row: Option<u32>,
    /// Earliest legal cycle of each command kind on this bank (same- and other-bank rules).
    earliest: [u64; KINDS],
}

/// The rule table resolved for `issue`, per preceding command kind: the largest latency it
/// imposes on each following kind in its own bank, in the other banks, and in every bank.
/// Every-bank rules are kept once per module rather than per bank.
#[derive(Clone, Copy, Debug, Default)]
struct Effects {
    same: Raise,
    other: Raise,
    all: Raise,
}

/// The following kinds one scope of a preceding command constrains, and by how much: only the
/// kinds with a rule, so issuing a command touches no slot it does not constrain (the WRITE
/// rules cost the read path nothing).
#[derive(Clone, Copy, Debug, Default)]
struct Raise {
    n: usize,
    slot: [u8; KINDS],
    latency: [u32; KINDS],
}

impl Raise {
    /// Adds a rule: the largest latency per following kind holds.
    fn add(&mut self, following: usize, latency: u32) {
        match (0..self.n).find(|&i| self.slot[i] as usize == following) {
            Some(i) => self.latency[i] = self.latency[i].max(latency),
            None => {
                self.slot[self.n] = following as u8;
                self.latency[self.n] = latency;
                self.n += 1;
            }
        }
    }

    #[inline(always)]
    fn apply(&self, earliest: &mut [u64; KINDS], now: u64) {
        for i in 0..self.n {
            let slot = &mut earliest[self.slot[i] as usize];
            *slot = (*slot).max(now + self.latency[i] as u64);
        }
    }
}

/// The banks of one module with their timing state.
#[derive(Clone, Debug)]
pub struct SdramDevice {
    banks: Vec<Bank>,
    effects: [Effects; KINDS],
    /// Earliest legal cycle of each command kind by the every-bank rules.
    all_banks: [u64; KINDS],
    /// The command bus: one command per cycle.
    bus_free: u64,
    /// Open row per bank, `CLOSED` if none: a copy of `Bank::open_row` for the controller's
    /// per-request row-hit test (banks <= 16, so `bank & 15` indexes it without a check).
    open_rows: [u32; 16],
}

/// No row open (rows are < 2^24, validated).
const CLOSED: u32 = u32::MAX;

impl SdramDevice {
    pub fn new(banks: usize, timing: &SdramTiming) -> SdramDevice {
        let mut effects = [Effects::default(); KINDS];
        for rule in timing_rules(timing) {
            let e = &mut effects[rule.preceding.index()];
            // REF has no bank: every rule it precedes holds in every bank.
            let table = match rule.scope {
                _ if rule.preceding == CommandKind::Ref => &mut e.all,
                Scope::SameBank => &mut e.same,
                Scope::OtherBanks => &mut e.other,
                Scope::AllBanks => &mut e.all,
            };
            table.add(rule.following.index(), rule.latency);
        }
        SdramDevice {
            banks: vec![
                Bank {
                    open_row: None,
                    earliest: [0; KINDS],
                };
                banks
            ],
            effects,
            all_banks: [0; KINDS],
            bus_free: 0,
            open_rows: [CLOSED; 16],
        }
    }

    pub fn open_row(&self, bank: usize) -> Option<u32> {
        self.banks[bank].open_row
    }

    /// Whether `bank` has a row open.
    #[inline]
    pub fn is_open(&self, bank: usize) -> bool {
        self.open_rows[bank & 15] != CLOSED
    }

    /// The open row of `bank`, which has one (no `Option` to unwrap on the command path).
    #[inline]
    pub fn open_row_of_open_bank(&self, bank: usize) -> u32 {
        debug_assert!(self.is_open(bank));
        self.open_rows[bank & 15]
    }

    /// Whether `row` is the open row of `bank`.
    #[inline]
    pub fn row_is_open(&self, bank: u32, row: u32) -> bool {
        self.open_rows[bank as usize & 15] == row
    }

    pub fn banks(&self) -> usize {
        self.banks.len()
    }

    /// Whether the command's state precondition holds (independent of time).
    pub fn state_allows(&self, cmd: Command) -> bool {
        match cmd {
            Command::Act { bank, .. } => self.banks[bank].open_row.is_none(),
            Command::Read { bank, .. } | Command::Write { bank, .. } | Command::Pre { bank } => {
                self.banks[bank].open_row.is_some()
            }
            Command::Ref => self.banks.iter().all(|b| b.open_row.is_none()),
        }
    }

    /// The earliest cycle the timing rules and the command bus allow the command.
    #[inline]
    pub fn earliest(&self, cmd: Command) -> u64 {
        let k = cmd.kind().index();
        let timing = match cmd.bank() {
            Some(bank) => self.banks[bank].earliest[k],
            None => self.banks.iter().map(|b| b.earliest[k]).max().unwrap_or(0),
        };
        timing.max(self.all_banks[k]).max(self.bus_free)
    }

    pub fn is_legal(&self, cmd: Command, now: u64) -> bool {
        self.state_allows(cmd) && now >= self.earliest(cmd)
    }

    /// Issues a legal command at `now`: applies every rule it precedes and its state change.
    /// Inlined: on the controller's command path the command's kind is known, so only its own
    /// effects remain.
    #[inline(always)]
    pub fn issue(&mut self, cmd: Command, now: u64) {
        debug_assert!(self.is_legal(cmd, now), "illegal {cmd:?} at {now}");
        let effects = &self.effects[cmd.kind().index()];
        effects.all.apply(&mut self.all_banks, now);
        if let Some(own) = cmd.bank() {
            effects.same.apply(&mut self.banks[own].earliest, now);
            if effects.other.n > 0 {
                for (b, bank) in self.banks.iter_mut().enumerate() {
                    if b != own {
                        effects.other.apply(&mut bank.earliest, now);
                    }
                }
            }
        }
        match cmd {
            Command::Act { bank, row } => {
                self.banks[bank].open_row = Some(row);
                self.open_rows[bank] = row;
            }
            Command::Pre { bank } => {
                self.banks[bank].open_row = None;
                self.open_rows[bank] = CLOSED;
            }
            Command::Read { .. } | Command::Write { .. } | Command::Ref => {}
        }
        self.bus_free = now + 1;
    }
}

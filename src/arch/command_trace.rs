//! SDRAM command traces: one CSV line per command the memory controllers issue, in cycle order,
//! and a checker that re-checks every timing rule of `sdram::timing_rules` from the file alone.
//! The format is documented in docs/waveforms.md ("Command traces").
//!
//! ```text
//! # vizsim SDRAM command trace, format 1 (docs/waveforms.md)
//! # clock_mhz: 100
//! # period_ns: 10
//! # modules: 4
//! ...
//! # t_rcd: 2 cycles = 20 ns
//! # rule: ACT READ same_bank 2 t_rcd (20 ns)
//! ...
//! # window: all
//! cycle,module,command,bank,row,column,tag
//! 3,0,ACT,0,0,,
//! 5,0,READ,0,0,0,0
//! ...
//! # end: cycle 123456, 987 commands
//! ```
//!
//! Writing streams through a buffer (a frame's tens of millions of lines cost no memory),
//! gzip-compressed when the name ends in `.gz`, under a temporary name renamed by `finish`
//! (`output::PendingFile`): a failed run leaves no file.
//!
//! The checker keeps its own per-bank state (open row, last cycle of each command kind) and
//! never uses the simulator's `SdramDevice`: what it trusts is the rule table and the header.

use std::io::{BufRead, BufReader, Read, Write};
use std::ops::Range;
use std::path::{Path, PathBuf};

use flate2::write::GzEncoder;
use flate2::Compression;

use super::sdram::{read_path_rules, CommandKind, Scope, SdramTiming, TimingRule};
use crate::config::HardwareConfig;
use crate::error::{Error, Result};
use crate::output::PendingFile;

/// The column header line.
pub const COLUMNS: &str = "cycle,module,command,bank,row,column,tag";

/// One command as issued. Fields a command does not have are 0 (and empty in the trace):
/// `bank`, `row` for REF; `column`, `tag` for all but READ.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IssuedCommand {
    pub cycle: u64,
    pub module: u32,
    pub kind: CommandKind,
    pub bank: u32,
    /// ACT: the row opened; READ: the row read (the open row); PRE: the row closed.
    pub row: u32,
    /// READ: the word's column in the row.
    pub column: u32,
    /// READ: the tag of the sample request the word belongs to (the compositing-buffer entry).
    pub tag: u32,
}

enum Sink {
    Plain(PendingFile),
    Gzip(Box<GzEncoder<PendingFile>>),
}

impl Sink {
    fn write_all(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        match self {
            Sink::Plain(f) => f.write_all(bytes),
            Sink::Gzip(g) => g.write_all(bytes),
        }
    }

    /// Completes the stream (the gzip trailer) and gives the file its name.
    fn commit(self, path: &Path) -> Result<()> {
        match self {
            Sink::Plain(mut f) => f.commit(),
            Sink::Gzip(g) => g.finish().map_err(|e| Error::io(path, e))?.commit(),
        }
    }
}

/// Lines are collected in chunks of this size, which a writer thread compresses (`.gz`) and
/// writes, so that neither compression nor system calls hold up the simulation.
const CHUNK: usize = 1 << 16;
/// Chunks on their way to the writer thread at most (the memory a trace takes is about
/// `(CHUNKS_IN_FLIGHT + 2) × CHUNK`, whatever its length).
const CHUNKS_IN_FLIGHT: usize = 8;
/// The longest command line: 20 + 10 + 4 + 4 × 10 digits or letters, 7 separators.
const LINE_MAX: usize = 96;

enum Message {
    Chunk(Vec<u8>),
    /// Everything is sent: complete the file and rename it.
    Finish,
}

/// A command trace being written. Pass it to `pipeline::simulate_with`, then call `finish`.
pub struct CommandTrace {
    /// `CHUNK + LINE_MAX` bytes, the first `used` of them waiting for the writer.
    buf: Vec<u8>,
    used: usize,
    /// The header, until the first command or `finish` (notes go in before its column line).
    header: Option<String>,
    cycle_text: CycleText,
    to_writer: Option<std::sync::mpsc::SyncSender<Message>>,
    /// Written chunks coming back for reuse.
    recycled: std::sync::mpsc::Receiver<Vec<u8>>,
    writer: Option<std::thread::JoinHandle<Result<()>>>,
    path: PathBuf,
    window: Range<u64>,
    lines: u64,
    end: Option<u64>,
}

impl CommandTrace {
    /// Starts a trace of the commands of `config`'s memory, limited to the cycles of `window`
    /// (`None`: every cycle). The header holds everything a checker needs: the clock, the
    /// geometry, every timing parameter in cycles and ns and the rule table.
    pub fn create(
        path: &Path,
        config: &HardwareConfig,
        window: Option<Range<u64>>,
    ) -> Result<CommandTrace> {
        let file = PendingFile::create(path)?;
        let gzip = path.extension().is_some_and(|e| e == "gz");
        let mut sink = if gzip {
            Sink::Gzip(Box::new(GzEncoder::new(file, Compression::fast())))
        } else {
            Sink::Plain(file)
        };
        let (to_writer, chunks) = std::sync::mpsc::sync_channel::<Message>(CHUNKS_IN_FLIGHT);
        let (give_back, recycled) = std::sync::mpsc::channel::<Vec<u8>>();
        let thread_path = path.to_path_buf();
        // The writer: a chunk at a time to the file; on `Finish` the file gets its name. If
        // the trace is dropped (or the writer fails), the sink is dropped unfinished and the
        // temporary file removed.
        let writer = std::thread::Builder::new()
            .name("command-trace".into())
            .spawn(move || -> Result<()> {
                for message in chunks {
                    match message {
                        Message::Chunk(chunk) => {
                            sink.write_all(&chunk)
                                .map_err(|e| Error::io(&thread_path, e))?;
                            let _ = give_back.send(chunk);
                        }
                        Message::Finish => return sink.commit(&thread_path),
                    }
                }
                Ok(())
            })
            .map_err(|e| Error::io(path, e))?;
        Ok(CommandTrace {
            buf: vec![0; CHUNK + LINE_MAX],
            used: 0,
            header: Some(header_text(config, window.clone())),
            cycle_text: CycleText {
                cycle: 0,
                text: [0; 20],
                len: 0,
            },
            to_writer: Some(to_writer),
            recycled,
            writer: Some(writer),
            path: path.to_path_buf(),
            window: window.clone().unwrap_or(0..u64::MAX),
            lines: 0,
            end: None,
        })
    }

    /// Whether cycle `cycle` is in the trace's window.
    #[inline]
    pub fn wants(&self, cycle: u64) -> bool {
        self.window.contains(&cycle)
    }

    /// Adds comment lines (`# note: ...`), e.g. the frame the trace belongs to: in the header
    /// if no command was written yet. Checkers ignore them.
    pub fn note(&mut self, text: &str) -> Result<()> {
        let notes: String = text.lines().map(|l| format!("# note: {l}\n")).collect();
        match &mut self.header {
            Some(header) => {
                let at = header.len() - COLUMNS.len() - 1;
                header.insert_str(at, &notes);
                Ok(())
            }
            None => self.push_bytes(notes.as_bytes()),
        }
    }

    #[cold]
    fn write_header(&mut self) -> Result<()> {
        match self.header.take() {
            Some(header) => self.push_bytes(header.as_bytes()),
            None => Ok(()),
        }
    }

    fn push_bytes(&mut self, bytes: &[u8]) -> Result<()> {
        for piece in bytes.chunks(CHUNK) {
            if self.used + piece.len() > self.buf.len() {
                self.spill()?;
            }
            self.buf[self.used..self.used + piece.len()].copy_from_slice(piece);
            self.used += piece.len();
        }
        Ok(())
    }

    /// Writes one command (ignored outside the window). Commands must come in cycle order.
    #[inline]
    pub fn record(&mut self, c: &IssuedCommand) -> Result<()> {
        if !self.wants(c.cycle) {
            return Ok(());
        }
        if self.header.is_some() {
            self.write_header()?;
        }
        if self.used > CHUNK {
            self.spill()?;
        }
        let out: &mut [u8; LINE_MAX] = (&mut self.buf[self.used..self.used + LINE_MAX])
            .try_into()
            .expect("CHUNK + LINE_MAX bytes");
        self.used += format_line(out, c, &mut self.cycle_text);
        self.lines += 1;
        Ok(())
    }

    /// The simulation ended at cycle `cycles` (written as the `# end:` line by `finish`).
    pub fn end(&mut self, cycles: u64) {
        self.end = Some(cycles);
    }

    /// Command lines written so far.
    pub fn lines(&self) -> u64 {
        self.lines
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Hands the buffer's lines to the writer thread.
    #[cold]
    fn spill(&mut self) -> Result<()> {
        let next = self
            .recycled
            .try_recv()
            .unwrap_or_else(|_| vec![0; CHUNK + LINE_MAX]);
        let mut full = std::mem::replace(&mut self.buf, next);
        self.buf.resize(CHUNK + LINE_MAX, 0);
        full.truncate(self.used);
        self.used = 0;
        self.send(Message::Chunk(full))
    }

    fn send(&mut self, message: Message) -> Result<()> {
        let sent = match &self.to_writer {
            Some(to_writer) => to_writer.send(message).is_ok(),
            None => false,
        };
        if sent {
            return Ok(());
        }
        // The writer stopped: its error says why.
        self.to_writer = None;
        Err(self.join_writer().err().unwrap_or_else(|| {
            Error::Invalid(format!(
                "{}: the command trace's writer stopped",
                self.path.display()
            ))
        }))
    }

    fn join_writer(&mut self) -> Result<()> {
        match self.writer.take() {
            Some(handle) => handle.join().unwrap_or_else(|_| {
                Err(Error::Invalid(format!(
                    "{}: the command trace's writer panicked",
                    self.path.display()
                )))
            }),
            None => Ok(()),
        }
    }

    /// Writes the `# end:` line, completes the file and gives it its name. Returns the number
    /// of command lines. A trace dropped without `finish` leaves no file.
    pub fn finish(mut self) -> Result<u64> {
        let end = match self.end {
            Some(cycle) => format!("# end: cycle {cycle}, {} commands\n", self.lines),
            None => format!("# end: {} commands\n", self.lines),
        };
        self.write_header()?;
        self.push_bytes(end.as_bytes())?;
        self.spill()?;
        self.send(Message::Finish)?;
        self.to_writer = None;
        self.join_writer()?;
        Ok(self.lines)
    }
}

impl Drop for CommandTrace {
    /// An unfinished trace: the writer sees the channel close without `Finish` and removes the
    /// temporary file; wait for it so that the file is gone when this returns.
    fn drop(&mut self) {
        self.to_writer = None;
        let _ = self.join_writer();
    }
}

fn header_text(config: &HardwareConfig, window: Option<Range<u64>>) -> String {
    use std::fmt::Write as _;
    let t = &config.sdram;
    let mhz = config.clock.frequency_mhz;
    let period = 1e3 / mhz;
    let ns = |cycles: u32| cycles as f64 * period;
    let mut h = String::new();
    let _ = writeln!(
        h,
        "# vizsim SDRAM command trace, format 1 (docs/waveforms.md)"
    );
    let _ = writeln!(h, "# clock_mhz: {mhz}");
    let _ = writeln!(h, "# period_ns: {period}");
    let m = &config.memory;
    let _ = writeln!(h, "# modules: {}", m.modules());
    let _ = writeln!(h, "# banks: {}", m.banks);
    let _ = writeln!(h, "# rows: {}", m.rows);
    let _ = writeln!(h, "# columns: {}", m.columns);
    let mapping = serde_json::to_value(m.mapping).unwrap_or_default();
    let policy = serde_json::to_value(m.row_policy).unwrap_or_default();
    let _ = writeln!(
        h,
        "# note: mapping {}, row policy {}, overtaking {}",
        mapping.as_str().unwrap_or("?"),
        policy.as_str().unwrap_or("?"),
        m.overtaking
    );
    let _ = writeln!(h, "# refresh: {}", t.refresh);
    for (name, cycles) in t.parameters() {
        let _ = writeln!(h, "# {name}: {cycles} cycles = {} ns", ns(cycles));
    }
    for r in read_path_rules(t) {
        let _ = writeln!(
            h,
            "# rule: {} {} {} {} {} ({} ns)",
            r.preceding.name(),
            r.following.name(),
            r.scope.name(),
            r.latency,
            r.parameter,
            ns(r.latency)
        );
    }
    match window {
        Some(w) => {
            let _ = writeln!(h, "# window: {}..{}", w.start, w.end);
        }
        None => {
            let _ = writeln!(h, "# window: all");
        }
    }
    h.push_str(COLUMNS);
    h.push('\n');
    h
}

/// The text of the last cycle written (most cycles have several commands).
#[derive(Clone, Copy)]
struct CycleText {
    cycle: u64,
    text: [u8; 20],
    len: usize,
}

/// Writes the command's line into `out`; returns its length.
#[inline]
fn format_line(out: &mut [u8; LINE_MAX], c: &IssuedCommand, last: &mut CycleText) -> usize {
    if last.cycle != c.cycle || last.len == 0 {
        let len = put_u64(out, 0, c.cycle);
        last.text[..len].copy_from_slice(&out[..len]);
        last.len = len;
        last.cycle = c.cycle;
    } else {
        out[..20].copy_from_slice(&last.text);
    }
    let mut n = last.len;
    out[n] = b',';
    n = put_u64(out, n + 1, c.module as u64);
    out[n] = b',';
    n += 1;
    // Five bytes copied whatever the name's length (a fixed-size copy, no call).
    let (name, len): (&[u8; 5], usize) = match c.kind {
        CommandKind::Act => (b"ACT, ", 4),
        CommandKind::Read => (b"READ,", 5),
        CommandKind::Pre => (b"PRE, ", 4),
        CommandKind::Ref => (b"REF, ", 4),
        // The read path never writes; a WRITE would be written like a READ.
        CommandKind::Write => (b"WRITE", 5),
    };
    out[n..n + 5].copy_from_slice(name);
    n += len;
    if c.kind != CommandKind::Ref {
        n = put_u64(out, n, c.bank as u64);
        out[n] = b',';
        n = put_u64(out, n + 1, c.row as u64);
    } else {
        out[n] = b',';
        n += 1;
    }
    out[n] = b',';
    n += 1;
    if matches!(c.kind, CommandKind::Read | CommandKind::Write) {
        n = put_u64(out, n, c.column as u64);
        out[n] = b',';
        n = put_u64(out, n + 1, c.tag as u64);
    } else {
        out[n] = b',';
        n += 1;
    }
    out[n] = b'\n';
    n + 1
}

const DIGIT_PAIRS: &[u8; 200] = b"0001020304050607080910111213141516171819\
2021222324252627282930313233343536373839\
4041424344454647484950515253545556575859\
6061626364656667686970717273747576777879\
8081828384858687888990919293949596979899";

/// Writes `v` in decimal at `out[at..]`; returns the index after it.
#[inline(always)]
fn put_u64(out: &mut [u8; LINE_MAX], at: usize, v: u64) -> usize {
    // Modules, banks and tags are mostly one or two digits.
    if v < 10 {
        out[at] = b'0' + v as u8;
        at + 1
    } else if v < 100 {
        put_pair(out, at, v as usize);
        at + 2
    } else if v < 1000 {
        out[at] = b'0' + (v / 100) as u8;
        put_pair(out, at + 1, (v % 100) as usize);
        at + 3
    } else if v < 10000 {
        put_pair(out, at, (v / 100) as usize);
        put_pair(out, at + 2, (v % 100) as usize);
        at + 4
    } else {
        put_u64_long(out, at, v)
    }
}

/// Writes `v` < 100 as two digits.
#[inline(always)]
fn put_pair(out: &mut [u8; LINE_MAX], at: usize, v: usize) {
    out[at..at + 2].copy_from_slice(&DIGIT_PAIRS[2 * v..2 * v + 2]);
}

#[inline(never)]
fn put_u64_long(out: &mut [u8; LINE_MAX], at: usize, mut v: u64) -> usize {
    let len = v.checked_ilog10().map_or(1, |l| l as usize + 1);
    let mut i = at + len;
    while v >= 100 {
        let d = (v % 100) as usize * 2;
        v /= 100;
        i -= 2;
        out[i..i + 2].copy_from_slice(&DIGIT_PAIRS[d..d + 2]);
    }
    if v >= 10 {
        let d = v as usize * 2;
        out[i - 2..i].copy_from_slice(&DIGIT_PAIRS[d..d + 2]);
    } else {
        out[i - 1] = b'0' + v as u8;
    }
    at + len
}

// ---------------------------------------------------------------------------------------------
// Reading and checking

/// What a trace's header says.
#[derive(Clone, Debug, PartialEq)]
pub struct TraceHeader {
    pub clock_mhz: f64,
    pub period_ns: f64,
    pub modules: u32,
    pub banks: u32,
    pub rows: u32,
    pub columns: u32,
    pub timing: SdramTiming,
    /// Cycles the trace covers (`0..u64::MAX` for `all`).
    pub window: Range<u64>,
}

/// How one timing rule fared over the trace.
#[derive(Clone, Debug, PartialEq)]
pub struct RuleCheck {
    pub rule: TimingRule,
    /// Commands it constrained (a preceding command was in the trace).
    pub checked: u64,
    /// The smallest gap seen between a preceding and a following command, in cycles.
    pub min_gap: Option<u64>,
    /// Commands issued exactly at the rule's limit.
    pub at_limit: u64,
    /// The line of the first command issued exactly at the limit.
    pub first_at_limit: Option<u64>,
}

/// A command that broke a rule.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Violation {
    /// Line number in the file (1-based).
    pub line: u64,
    pub cycle: u64,
    pub module: u32,
    /// Short name: the rule's parameter (`t_rcd`, ...) or `bus`, `order`, `state`,
    /// `refresh`, `window`.
    pub rule: String,
    pub message: String,
}

impl std::fmt::Display for Violation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "line {}: cycle {} module {}: [{}] {}",
            self.line, self.cycle, self.module, self.rule, self.message
        )
    }
}

/// The checker's findings.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    pub header: TraceHeader,
    /// Commands by kind (`CommandKind::index`: ACT, READ, PRE, REF).
    pub commands: [u64; 4],
    /// Commands by module and kind.
    pub per_module: Vec<[u64; 4]>,
    pub first_cycle: Option<u64>,
    pub last_cycle: Option<u64>,
    /// The `# end:` line's cycle (the simulation's length), when written.
    pub end_cycle: Option<u64>,
    pub rules: Vec<RuleCheck>,
    /// Refresh intervals (per module) that lay wholly inside the trace and were checked to
    /// hold exactly one REF.
    pub refresh_intervals_checked: u64,
    /// The largest delay of a REF after its due cycle.
    pub max_refresh_delay: Option<u64>,
    /// The first violations (at most `MAX_VIOLATIONS` kept), and how many there were.
    pub violations: Vec<Violation>,
    pub violation_count: u64,
}

/// Violations kept in a report (all are counted).
pub const MAX_VIOLATIONS: usize = 1000;

impl Report {
    pub fn reads(&self) -> u64 {
        self.commands[CommandKind::Read.index()]
    }

    pub fn total(&self) -> u64 {
        self.commands.iter().sum()
    }
}

impl std::fmt::Display for Report {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let h = &self.header;
        writeln!(
            f,
            "{} commands ({} ACT, {} READ, {} PRE, {} REF) on {} modules x {} banks, cycles {}..{}{}",
            self.total(),
            self.commands[0],
            self.commands[1],
            self.commands[2],
            self.commands[3],
            h.modules,
            h.banks,
            self.first_cycle.unwrap_or(0),
            self.last_cycle.map_or(0, |c| c + 1),
            self.end_cycle
                .map_or(String::new(), |e| format!(" (simulation ended at cycle {e})"))
        )?;
        for r in &self.rules {
            writeln!(
                f,
                "  {:<4} -> {:<4} {:<11} >= {:>2} ({:<11}): {} checked, min gap {}, {} at the limit",
                r.rule.preceding.name(),
                r.rule.following.name(),
                r.rule.scope.name(),
                r.rule.latency,
                r.rule.parameter,
                r.checked,
                r.min_gap.map_or("-".into(), |g| g.to_string()),
                r.at_limit
            )?;
        }
        writeln!(
            f,
            "  refresh: {} intervals checked, largest delay {} cycles",
            self.refresh_intervals_checked,
            self.max_refresh_delay.map_or("-".into(), |g| g.to_string())
        )?;
        if self.violation_count == 0 {
            write!(f, "no violations")
        } else {
            writeln!(f, "{} violations; the first:", self.violation_count)?;
            for v in self.violations.iter().take(20) {
                writeln!(f, "  {v}")?;
            }
            Ok(())
        }
    }
}

/// Reads a trace and checks it; an error if the file cannot be read, is malformed, or breaks
/// any rule (the message lists the first violations).
pub fn check(path: &Path) -> Result<Report> {
    let report = analyze(path)?;
    if report.violation_count > 0 {
        let first: Vec<String> = report
            .violations
            .iter()
            .take(10)
            .map(|v| v.to_string())
            .collect();
        return Err(Error::format(
            path,
            format!(
                "{} SDRAM rule violations in the command trace:\n  {}",
                report.violation_count,
                first.join("\n  ")
            ),
        ));
    }
    Ok(report)
}

/// Reads a trace (gzip when the name ends in `.gz`) and checks every command; violations are
/// in the report. An error only if the file cannot be read or is malformed.
pub fn analyze(path: &Path) -> Result<Report> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let reader: Box<dyn Read> = if path.extension().is_some_and(|e| e == "gz") {
        Box::new(flate2::read::MultiGzDecoder::new(file))
    } else {
        Box::new(file)
    };
    analyze_reader(path, BufReader::with_capacity(1 << 18, reader))
}

/// `analyze` on any reader; `path` names it in errors.
pub fn analyze_reader(path: &Path, reader: impl BufRead) -> Result<Report> {
    let mut parser = HeaderParser::default();
    let mut checker: Option<Checker> = None;
    let mut line_no = 0u64;
    let mut end_cycle = None;
    let mut line = String::new();
    let mut reader = reader;
    loop {
        line.clear();
        let n = reader
            .read_line(&mut line)
            .map_err(|e| Error::io(path, e))?;
        if n == 0 {
            break;
        }
        line_no += 1;
        let text = line.trim_end_matches(['\n', '\r']);
        let bad = |msg: String| Error::format(path, format!("line {line_no}: {msg}"));
        if let Some(comment) = text.strip_prefix('#') {
            let comment = comment.trim();
            if let Some(end) = comment.strip_prefix("end:") {
                end_cycle = parse_end(end);
            } else if checker.is_none() {
                parser.line(comment).map_err(bad)?;
            }
            continue;
        }
        if text.is_empty() {
            continue;
        }
        match &mut checker {
            None => {
                if text != COLUMNS {
                    return Err(bad(format!(
                        "expected the column header `{COLUMNS}`, found `{text}`"
                    )));
                }
                checker = Some(Checker::new(
                    std::mem::take(&mut parser).finish().map_err(bad)?,
                ));
            }
            Some(c) => {
                let command = parse_command(text, &c.header).map_err(bad)?;
                c.command(line_no, &command);
            }
        }
    }
    let Some(checker) = checker else {
        return Err(Error::format(
            path,
            format!("no column header `{COLUMNS}`: not a command trace"),
        ));
    };
    Ok(checker.finish(end_cycle))
}

fn parse_end(text: &str) -> Option<u64> {
    // "cycle N, M commands" or "M commands"
    let rest = text.trim().strip_prefix("cycle ")?;
    rest.split(',').next()?.trim().parse().ok()
}

#[derive(Default)]
struct HeaderParser {
    clock_mhz: Option<f64>,
    modules: Option<u32>,
    banks: Option<u32>,
    rows: Option<u32>,
    columns: Option<u32>,
    refresh: Option<bool>,
    params: Vec<(String, u32)>,
    rules: Vec<(CommandKind, CommandKind, Scope, u32, String)>,
    window: Option<Range<u64>>,
}

impl HeaderParser {
    fn line(&mut self, comment: &str) -> std::result::Result<(), String> {
        let Some((key, value)) = comment.split_once(':') else {
            return Ok(()); // free text (the title line)
        };
        let (key, value) = (key.trim(), value.trim());
        let first = value.split_whitespace().next().unwrap_or("");
        let number = |what: &str| -> std::result::Result<u32, String> {
            first
                .parse()
                .map_err(|_| format!("header `{what}`: `{value}` is not a number"))
        };
        match key {
            "clock_mhz" => {
                self.clock_mhz = Some(
                    first
                        .parse()
                        .map_err(|_| format!("header `clock_mhz`: `{value}` is not a number"))?,
                )
            }
            "modules" => self.modules = Some(number(key)?),
            "banks" => self.banks = Some(number(key)?),
            "rows" => self.rows = Some(number(key)?),
            "columns" => self.columns = Some(number(key)?),
            "refresh" => {
                self.refresh = Some(
                    first
                        .parse()
                        .map_err(|_| format!("header `refresh`: `{value}` is not true/false"))?,
                )
            }
            "window" => {
                self.window = Some(if first == "all" {
                    0..u64::MAX
                } else {
                    let (a, b) = first
                        .split_once("..")
                        .ok_or_else(|| format!("header `window`: `{value}` is not A..B"))?;
                    let p = |s: &str| {
                        s.parse::<u64>()
                            .map_err(|_| format!("header `window`: `{value}` is not A..B"))
                    };
                    p(a)?..p(b)?
                })
            }
            "rule" => {
                let t: Vec<&str> = value.split_whitespace().collect();
                let parsed = (|| {
                    Some((
                        CommandKind::from_name(t.first()?)?,
                        CommandKind::from_name(t.get(1)?)?,
                        Scope::from_name(t.get(2)?)?,
                        t.get(3)?.parse().ok()?,
                        t.get(4)?.to_string(),
                    ))
                })();
                self.rules.push(parsed.ok_or_else(|| {
                    format!("header `rule`: `{value}` is not `PRECEDING FOLLOWING SCOPE CYCLES PARAMETER`")
                })?);
            }
            "cl" | "t_rcd" | "t_rp" | "t_ras" | "t_rc" | "t_rrd" | "t_ccd" | "t_rfc"
            | "refresh_interval" => self.params.push((key.to_string(), number(key)?)),
            _ => {} // notes, period_ns (derived from clock_mhz), future keys
        }
        Ok(())
    }

    fn finish(self) -> std::result::Result<TraceHeader, String> {
        let missing = |what: &str| format!("the header has no `# {what}:` line");
        let param = |name: &str| {
            self.params
                .iter()
                .find(|(n, _)| n == name)
                .map(|&(_, v)| v)
                .ok_or_else(|| missing(name))
        };
        let timing = SdramTiming {
            cl: param("cl")?,
            t_rcd: param("t_rcd")?,
            t_rp: param("t_rp")?,
            t_ras: param("t_ras")?,
            t_rc: param("t_rc")?,
            t_rrd: param("t_rrd")?,
            t_ccd: param("t_ccd")?,
            t_rfc: param("t_rfc")?,
            refresh_interval: param("refresh_interval")?,
            refresh: self.refresh.ok_or_else(|| missing("refresh"))?,
            ..HardwareConfig::default_config().sdram
        };
        // The rule lines must be the table the parameters give (a trace from another table
        // would be checked against rules it was not written under).
        if !self.rules.is_empty() {
            let table: Vec<_> = read_path_rules(&timing)
                .into_iter()
                .map(|r| {
                    (
                        r.preceding,
                        r.following,
                        r.scope,
                        r.latency,
                        r.parameter.to_string(),
                    )
                })
                .collect();
            if table != self.rules {
                return Err(format!(
                    "the header's rule lines differ from vizsim's rule table for these parameters \
                     ({} lines, {} rules in the table)",
                    self.rules.len(),
                    table.len()
                ));
            }
        }
        let clock_mhz = self.clock_mhz.ok_or_else(|| missing("clock_mhz"))?;
        let banks = self.banks.ok_or_else(|| missing("banks"))?;
        if !(1..=64).contains(&banks) {
            return Err(format!("header `banks`: {banks} is out of range 1..=64"));
        }
        Ok(TraceHeader {
            clock_mhz,
            period_ns: 1e3 / clock_mhz,
            modules: self.modules.ok_or_else(|| missing("modules"))?,
            banks,
            rows: self.rows.ok_or_else(|| missing("rows"))?,
            columns: self.columns.ok_or_else(|| missing("columns"))?,
            timing,
            window: self.window.ok_or_else(|| missing("window"))?,
        })
    }
}

fn parse_command(text: &str, h: &TraceHeader) -> std::result::Result<IssuedCommand, String> {
    let mut fields = text.split(',');
    let mut next = || fields.next();
    let (Some(cycle), Some(module), Some(kind), Some(bank), Some(row), Some(column), Some(tag)) =
        (next(), next(), next(), next(), next(), next(), next())
    else {
        return Err(format!("`{text}`: expected 7 fields ({COLUMNS})"));
    };
    if next().is_some() {
        return Err(format!("`{text}`: more than 7 fields ({COLUMNS})"));
    }
    // Traces record the read path: a WRITE is not one of its commands.
    let kind = CommandKind::from_name(kind)
        .filter(|&k| k != CommandKind::Write)
        .ok_or_else(|| format!("`{text}`: unknown command `{kind}` (ACT, READ, PRE, REF)"))?;
    let number = |name: &str, s: &str, limit: u64| -> std::result::Result<Option<u64>, String> {
        if s.is_empty() {
            return Ok(None);
        }
        let v: u64 = s
            .parse()
            .map_err(|_| format!("`{text}`: {name} `{s}` is not a number"))?;
        if v >= limit {
            return Err(format!("`{text}`: {name} {v} is out of range (< {limit})"));
        }
        Ok(Some(v))
    };
    let cycle = number("cycle", cycle, u64::MAX)?.ok_or_else(|| format!("`{text}`: no cycle"))?;
    let module = number("module", module, h.modules as u64)?
        .ok_or_else(|| format!("`{text}`: no module"))?;
    let bank = number("bank", bank, h.banks as u64)?;
    let row = number("row", row, h.rows as u64)?;
    let column = number("column", column, h.columns as u64)?;
    let tag = number("tag", tag, u32::MAX as u64 + 1)?;
    let has = [
        bank.is_some(),
        row.is_some(),
        column.is_some(),
        tag.is_some(),
    ];
    let wanted = match kind {
        CommandKind::Act | CommandKind::Pre => [true, true, false, false],
        CommandKind::Read | CommandKind::Write => [true; 4],
        CommandKind::Ref => [false; 4],
    };
    if has != wanted {
        return Err(format!(
            "`{text}`: {} has fields {}",
            kind.name(),
            match kind {
                CommandKind::Act | CommandKind::Pre => "bank, row",
                CommandKind::Read | CommandKind::Write => "bank, row, column, tag",
                CommandKind::Ref => "none of bank, row, column, tag",
            }
        ));
    }
    Ok(IssuedCommand {
        cycle,
        module: module as u32,
        kind,
        bank: bank.unwrap_or(0) as u32,
        row: row.unwrap_or(0) as u32,
        column: column.unwrap_or(0) as u32,
        tag: tag.unwrap_or(0) as u32,
    })
}

/// A bank's state as far as the trace shows it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Row {
    /// Before the bank's first command in a window that starts after cycle 0.
    Unknown,
    Closed,
    Open(u32),
}

/// (cycle, line) of the last command of each kind.
type Last = [Option<(u64, u64)>; 4];

struct ModuleState {
    rows: Vec<Row>,
    last: Vec<Last>,
    /// Last of each kind on any bank (REF has no bank: only here).
    last_any: Last,
    last_cycle: Option<u64>,
    /// Refresh intervals (cycle / refresh_interval) that had a REF, in order.
    refreshed: Vec<u64>,
}

struct Checker {
    header: TraceHeader,
    rules: Vec<RuleCheck>,
    modules: Vec<ModuleState>,
    commands: [u64; 4],
    per_module: Vec<[u64; 4]>,
    first_cycle: Option<u64>,
    last_cycle: Option<u64>,
    last_line: u64,
    max_refresh_delay: Option<u64>,
    violations: Vec<Violation>,
    violation_count: u64,
}

impl Checker {
    fn new(header: TraceHeader) -> Checker {
        let initial = if header.window.start == 0 {
            Row::Closed
        } else {
            Row::Unknown
        };
        let banks = header.banks as usize;
        Checker {
            rules: read_path_rules(&header.timing)
                .into_iter()
                .map(|rule| RuleCheck {
                    rule,
                    checked: 0,
                    min_gap: None,
                    at_limit: 0,
                    first_at_limit: None,
                })
                .collect(),
            modules: (0..header.modules)
                .map(|_| ModuleState {
                    rows: vec![initial; banks],
                    last: vec![[None; 4]; banks],
                    last_any: [None; 4],
                    last_cycle: None,
                    refreshed: Vec::new(),
                })
                .collect(),
            commands: [0; 4],
            per_module: vec![[0; 4]; header.modules as usize],
            first_cycle: None,
            last_cycle: None,
            last_line: 0,
            max_refresh_delay: None,
            violations: Vec::new(),
            violation_count: 0,
            header,
        }
    }

    fn violation(&mut self, line: u64, c: &IssuedCommand, rule: &str, message: String) {
        self.violation_count += 1;
        if self.violations.len() < MAX_VIOLATIONS {
            self.violations.push(Violation {
                line,
                cycle: c.cycle,
                module: c.module,
                rule: rule.to_string(),
                message,
            });
        }
    }

    fn command(&mut self, line: u64, c: &IssuedCommand) {
        let k = c.kind.index();
        let name = c.kind.name();
        self.commands[k] += 1;
        self.per_module[c.module as usize][k] += 1;
        self.first_cycle.get_or_insert(c.cycle);
        self.last_line = line;
        if !self.header.window.contains(&c.cycle) {
            let w = self.header.window.clone();
            self.violation(
                line,
                c,
                "window",
                format!("{name} outside the trace's window {}..{}", w.start, w.end),
            );
        }
        if let Some(last) = self.last_cycle {
            if c.cycle < last {
                self.violation(
                    line,
                    c,
                    "order",
                    format!("{name} at cycle {} after a line of cycle {last}", c.cycle),
                );
            }
        }
        self.last_cycle = Some(self.last_cycle.map_or(c.cycle, |l| l.max(c.cycle)));
        let m = c.module as usize;
        let bank = (c.kind != CommandKind::Ref).then_some(c.bank as usize);

        // The command bus: one command per module per cycle.
        if let Some(prev) = self.modules[m].last_cycle {
            if prev >= c.cycle {
                self.violation(
                    line,
                    c,
                    "bus",
                    format!(
                        "{name} in cycle {} but the module's command bus already carried a command in cycle {prev}",
                        c.cycle
                    ),
                );
            }
        }

        // Every timing rule whose following command this is.
        for i in 0..self.rules.len() {
            let rule = self.rules[i].rule;
            if rule.following != c.kind {
                continue;
            }
            let state = &self.modules[m];
            let prev = if rule.preceding == CommandKind::Ref || bank.is_none() {
                state.last_any[rule.preceding.index()]
            } else {
                let b = bank.unwrap_or(0);
                match rule.scope {
                    Scope::SameBank => state.last[b][rule.preceding.index()],
                    Scope::AllBanks => state.last_any[rule.preceding.index()],
                    Scope::OtherBanks => state
                        .last
                        .iter()
                        .enumerate()
                        .filter(|&(o, _)| o != b)
                        .filter_map(|(_, l)| l[rule.preceding.index()])
                        .max(),
                }
            };
            let Some((prev_cycle, prev_line)) = prev else {
                continue;
            };
            let gap = c.cycle.saturating_sub(prev_cycle);
            let r = &mut self.rules[i];
            r.checked += 1;
            r.min_gap = Some(r.min_gap.map_or(gap, |g| g.min(gap)));
            if gap == rule.latency as u64 {
                r.at_limit += 1;
                r.first_at_limit.get_or_insert(line);
            }
            if gap < rule.latency as u64 {
                let scope = match rule.scope {
                    Scope::SameBank => "in the same bank",
                    Scope::OtherBanks => "in another bank",
                    Scope::AllBanks => "in any bank",
                };
                self.violation(
                    line,
                    c,
                    rule.parameter,
                    format!(
                        "{} -> {} {scope} needs {} cycles ({} = {}), got {gap}: {} at cycle {prev_cycle} (line {prev_line})",
                        rule.preceding.name(),
                        name,
                        rule.latency,
                        rule.parameter,
                        rule.latency,
                        rule.preceding.name(),
                    ),
                );
            }
        }

        // Bank state.
        let state_error = match (c.kind, bank) {
            (CommandKind::Ref, _) => {
                let open: Vec<String> = self.modules[m]
                    .rows
                    .iter()
                    .enumerate()
                    .filter_map(|(b, r)| match r {
                        Row::Open(row) => Some(format!("bank {b} row {row}")),
                        _ => None,
                    })
                    .collect();
                (!open.is_empty()).then(|| format!("REF with open rows: {}", open.join(", ")))
            }
            (kind, Some(b)) => match (kind, self.modules[m].rows[b]) {
                (CommandKind::Act, Row::Open(r)) => Some(format!(
                    "ACT row {} to bank {b}, which has row {r} open",
                    c.row
                )),
                (CommandKind::Read | CommandKind::Pre, Row::Closed) => Some(format!(
                    "{name} row {} to bank {b}, which has no row open",
                    c.row
                )),
                (CommandKind::Read | CommandKind::Pre, Row::Open(r)) if r != c.row => Some(
                    format!("{name} row {} to bank {b}, which has row {r} open", c.row),
                ),
                _ => None,
            },
            (_, None) => None,
        };
        if let Some(message) = state_error {
            self.violation(line, c, "state", message);
        }

        // Refresh: due every refresh_interval cycles from cycle 0, delayed within its
        // interval, never skipped (missing ones are found at the end).
        if c.kind == CommandKind::Ref {
            let t = &self.header.timing;
            let interval = t.refresh_interval as u64;
            if !t.refresh {
                self.violation(line, c, "refresh", "REF with refresh off".into());
            } else {
                let k = c.cycle / interval;
                let delay = c.cycle - k * interval;
                let repeated = self.modules[m].refreshed.last() == Some(&k);
                if k == 0 {
                    self.violation(
                        line,
                        c,
                        "refresh",
                        format!("REF before the first is due (cycle {interval})"),
                    );
                } else if repeated {
                    self.violation(
                        line,
                        c,
                        "refresh",
                        format!(
                            "second REF in the refresh interval {}..{}",
                            k * interval,
                            (k + 1) * interval
                        ),
                    );
                } else {
                    self.max_refresh_delay =
                        Some(self.max_refresh_delay.map_or(delay, |d| d.max(delay)));
                    self.modules[m].refreshed.push(k);
                }
            }
        }

        // Apply.
        let state = &mut self.modules[m];
        state.last_cycle = Some(c.cycle);
        state.last_any[k] = Some((c.cycle, line));
        match (c.kind, bank) {
            (CommandKind::Ref, _) => state.rows.fill(Row::Closed),
            (kind, Some(b)) => {
                state.last[b][k] = Some((c.cycle, line));
                match kind {
                    CommandKind::Act | CommandKind::Read | CommandKind::Write => {
                        state.rows[b] = Row::Open(c.row)
                    }
                    CommandKind::Pre => state.rows[b] = Row::Closed,
                    CommandKind::Ref => {}
                }
            }
            (_, None) => {}
        }
    }

    fn finish(mut self, end_cycle: Option<u64>) -> Report {
        let t = &self.header.timing;
        let mut intervals = 0;
        if t.refresh {
            let interval = t.refresh_interval as u64;
            // Intervals wholly inside the window and the simulated cycles.
            let end = self
                .header
                .window
                .end
                .min(end_cycle.unwrap_or(self.last_cycle.map_or(0, |c| c + 1)));
            let first = self.header.window.start.div_ceil(interval).max(1);
            let last = end / interval; // intervals k with (k + 1)·interval <= end
            let line = self.last_line + 1;
            for m in 0..self.modules.len() {
                let refreshed = std::mem::take(&mut self.modules[m].refreshed);
                let mut seen = refreshed.iter().peekable();
                for k in first..last {
                    intervals += 1;
                    while seen.next_if(|&&s| s < k).is_some() {}
                    if seen.peek() != Some(&&k) {
                        let c = IssuedCommand {
                            cycle: k * interval,
                            module: m as u32,
                            kind: CommandKind::Ref,
                            bank: 0,
                            row: 0,
                            column: 0,
                            tag: 0,
                        };
                        self.violation(
                            line,
                            &c,
                            "refresh",
                            format!(
                                "no REF in the refresh interval {}..{}",
                                k * interval,
                                (k + 1) * interval
                            ),
                        );
                    }
                }
            }
        }
        if let (Some(end), Some(last)) = (end_cycle, self.last_cycle) {
            if end <= last {
                self.violation_count += 1;
                self.violations.push(Violation {
                    line: self.last_line + 1,
                    cycle: end,
                    module: 0,
                    rule: "order".into(),
                    message: format!(
                        "the end line's cycle {end} is not after the last command's cycle {last}"
                    ),
                });
            }
        }
        Report {
            header: self.header,
            commands: self.commands,
            per_module: self.per_module,
            first_cycle: self.first_cycle,
            last_cycle: self.last_cycle,
            end_cycle,
            rules: self.rules,
            refresh_intervals_checked: intervals,
            max_refresh_delay: self.max_refresh_delay,
            violations: self.violations,
            violation_count: self.violation_count,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_are_formatted_at_every_digit_count() {
        let mut last = CycleText {
            cycle: 0,
            text: [0; 20],
            len: 0,
        };
        let mut out = [0u8; LINE_MAX];
        for v in [0u64, 9, 10, 99, 100, 999, 1000, 9999, 10000, 123_456_789] {
            let v32 = v.min(u32::MAX as u64) as u32;
            for (kind, want) in [
                (
                    CommandKind::Read,
                    format!("{v},3,READ,{v32},{v32},{v32},{v32}\n"),
                ),
                (CommandKind::Act, format!("{v},3,ACT,{v32},{v32},,\n")),
                (CommandKind::Pre, format!("{v},3,PRE,{v32},{v32},,\n")),
                (CommandKind::Ref, format!("{v},3,REF,,,,\n")),
            ] {
                let c = IssuedCommand {
                    cycle: v,
                    module: 3,
                    kind,
                    bank: v32,
                    row: v32,
                    column: v32,
                    tag: v32,
                };
                // Twice: the second line of a cycle reuses the cycle's text.
                for _ in 0..2 {
                    let n = format_line(&mut out, &c, &mut last);
                    assert_eq!(std::str::from_utf8(&out[..n]).unwrap(), want);
                }
            }
        }
        let c = IssuedCommand {
            cycle: u64::MAX,
            module: u32::MAX,
            kind: CommandKind::Read,
            bank: u32::MAX,
            row: u32::MAX,
            column: u32::MAX,
            tag: u32::MAX,
        };
        let n = format_line(&mut out, &c, &mut last);
        let m = u32::MAX;
        assert_eq!(
            std::str::from_utf8(&out[..n]).unwrap(),
            format!("{},{m},READ,{m},{m},{m},{m}\n", u64::MAX)
        );
    }
}

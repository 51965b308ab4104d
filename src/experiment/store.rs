//! The results store of a sweep folder. `results.jsonl` holds one JSON object per finished
//! run, appended with one `write` per line and synced, so a killed sweep loses nothing it
//! finished. On reopening, a torn last line (a result cut short, with or without a newline
//! after it, or a blank line) is cut off and its run is done again; any other line that is not
//! a result is an error (a last line included, such as valid JSON without a key: it was edited
//! in, and cutting it would lose what it holds).
//! `timing.jsonl` holds one wall time per result, written after the result: on reopening it is
//! made consistent with the results (torn or malformed lines dropped, one entry per result,
//! `null` for a result whose time a kill lost, none for runs without a result).

use std::collections::{BTreeSet, HashMap, HashSet};
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

use serde_json::Value;

use super::spec::Expansion;
use super::Shard;
use crate::error::{Error, Result};

pub const RESULTS: &str = "results.jsonl";
pub const TIMING: &str = "timing.jsonl";
pub const RESOLVED: &str = "experiment.resolved.json";
/// A hash of the sources of the model that wrote a result (build.rs), written beside its wall
/// time: a resumed sweep reuses the timings of finished runs only when the same model measured
/// them (`experiment::sweep`).
pub const MODEL: &str = env!("VIZSIM_MODEL_HASH");
/// Held (advisory lock) while a sweep writes into the folder.
const LOCK: &str = ".sweep.lock";

/// The complete lines of a results file (missing file = none), with their text. A torn last
/// line is left out.
pub fn read_lines(path: &Path) -> Result<Vec<(Value, String)>> {
    Ok(scan(path)?.0)
}

/// As `read_lines`, and whether a torn last line was left out (for a reader that says so).
pub fn read_lines_and_torn(path: &Path) -> Result<(Vec<(Value, String)>, bool)> {
    let (lines, _, torn) = scan(path)?;
    Ok((lines, torn))
}

/// What a reader that leaves out a torn last line says (on stderr): a sweep killed mid-line, or
/// one still running, lost that run, and that is said, not silent.
pub fn torn_note(path: &Path) -> String {
    format!(
        "note: {}: the last line is incomplete (a sweep killed while writing it, or one still \
         running) and is left out; running the sweep again redoes that run",
        path.display()
    )
}

/// The keys of the complete lines of a results file (missing file = none), read line by line
/// so that only the keys are held (the dry run). A torn last line is left out; a malformed line
/// elsewhere, or a key on two lines with different text, is an error, as in `read_lines`.
pub fn result_keys(path: &Path) -> Result<HashSet<String>> {
    Ok(stream_keys(path)?.0)
}

/// As `result_keys`, with the experiment names the lines carry.
fn stream_keys(path: &Path) -> Result<(HashSet<String>, BTreeSet<String>)> {
    use std::io::BufRead;
    match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Default::default()),
        Err(e) => return Err(Error::io(path, e)),
        Ok(_) => {}
    }
    let file = crate::input::open_regular(path)?;
    let mut reader = std::io::BufReader::new(file);
    // Per key, its line and a hash of its text: the duplicate check of `scan` without
    // holding the lines.
    let mut keys: HashMap<String, (usize, u64)> = HashMap::new();
    let mut experiments = BTreeSet::new();
    let mut line = Vec::new();
    let mut number = 0;
    let mut malformed = None;
    loop {
        line.clear();
        let n = reader
            .read_until(b'\n', &mut line)
            .map_err(|e| Error::io(path, e))?;
        if n == 0 {
            break;
        }
        number += 1;
        // A cut line is an error only when another line follows it (else it is torn).
        if let Some(bad) = malformed.take() {
            return Err(Error::format(
                path,
                format!("line {bad} is not a result line (corrupt file?)"),
            ));
        }
        if line.last() != Some(&b'\n') {
            break;
        }
        let parsed = serde_json::from_slice::<Value>(&line[..n - 1]).ok();
        let key = parsed
            .as_ref()
            .and_then(|v| v.get("key").and_then(Value::as_str).map(str::to_string));
        // As in `scan`: a line a cut write can leave is an error only when another line
        // follows it (else it is torn); any other line that is not a result always is.
        let Some(key) = key else {
            if could_be_torn(&line) {
                malformed = Some(number);
                continue;
            }
            return Err(Error::format(
                path,
                format!("line {number} is not a result line (corrupt file?)"),
            ));
        };
        if let Some(field) = parsed.as_ref().and_then(missing_field) {
            return Err(Error::format(path, incomplete_run(number, &key, &field)));
        }
        if let Some(name) = parsed.as_ref().and_then(|v| v["experiment"].as_str()) {
            if !experiments.contains(name) {
                experiments.insert(name.to_string());
            }
        }
        let hash = {
            use std::hash::{Hash, Hasher};
            let mut h = std::collections::hash_map::DefaultHasher::new();
            line.hash(&mut h);
            h.finish()
        };
        match keys.get(&key) {
            Some(&(first, seen)) if seen != hash => {
                return Err(Error::format(path, repeated_run(number, &key, first)))
            }
            Some(_) => {}
            None => {
                keys.insert(key, (number, hash));
            }
        }
    }
    Ok((keys.into_keys().collect(), experiments))
}

/// The first complete result line whose key `wanted` accepts, read line by line.
fn first_line_where(path: &Path, wanted: impl Fn(&str) -> bool) -> Result<Option<Value>> {
    use std::io::BufRead;
    let Ok(file) = crate::input::open_regular(path) else {
        return Ok(None);
    };
    for line in std::io::BufReader::new(file).lines() {
        let line = line.map_err(|e| Error::io(path, e))?;
        let Ok(value) = serde_json::from_str::<Value>(&line) else {
            continue;
        };
        if value
            .get("key")
            .and_then(Value::as_str)
            .is_some_and(&wanted)
        {
            return Ok(Some(value));
        }
    }
    Ok(None)
}

/// The error of a run key on two lines with different text.
fn repeated_run(number: usize, key: &str, first: usize) -> String {
    format!(
        "line {number} repeats run {key} of line {first} with other figures (an edited file, or \
         two joined?)"
    )
}

/// A parsed result line and its text.
type Line = (Value, String);

/// The first field a result line lacks of those every sweep writes (what the run is, and the
/// model's figures), or holds as the wrong kind of value; a figure may be null (no figure). A
/// line without them (an edited file) would be tabulated as missing and, counted as done,
/// never be redone.
fn missing_field(line: &Value) -> Option<String> {
    let count = if line["model"] == "step" {
        "steps"
    } else {
        "cycles"
    };
    // (field, whether a value fits, what it must be)
    type Rule<'a> = (&'a str, fn(&Value) -> bool, &'a str);
    let required: [Rule; 7] = [
        ("model", Value::is_string, "text"),
        ("mode", Value::is_string, "text"),
        ("tf", Value::is_string, "text"),
        ("dataset", Value::is_string, "text"),
        ("frame", Value::is_number, "a number"),
        ("fps", |v| v.is_number() || v.is_null(), "a number"),
        (count, |v| v.is_number() || v.is_null(), "a number"),
    ];
    required
        .into_iter()
        .find_map(|(field, fits, kind)| match line.get(field) {
            None => Some(format!("`{field}` is missing")),
            Some(v) if !fits(v) => Some(format!("`{field}` is {v}, not {kind}")),
            Some(_) => None,
        })
}

/// The error of a result line that lacks a field every result has.
fn incomplete_run(number: usize, key: &str, what: &str) -> String {
    format!(
        "line {number}, run {key}: {what} (every result line has it; an edited file?); remove \
         the line to have the sweep run it again"
    )
}

/// Whether a line that is not a result can be what a write cut short left: blank, or the start
/// of a JSON object that does not parse (a result line cut anywhere before its end). A line
/// that parses, or does not start as an object, was written as it is.
fn could_be_torn(line: &[u8]) -> bool {
    let text = line.trim_ascii();
    text.is_empty() || (text.starts_with(b"{") && serde_json::from_slice::<Value>(text).is_err())
}

/// Lines, the byte length of the complete part of the file, and whether a torn last line
/// follows it.
fn scan(path: &Path) -> Result<(Vec<Line>, u64, bool)> {
    let Some(bytes) = crate::input::read_existing(path)? else {
        return Ok((Vec::new(), 0, false));
    };
    let mut lines: Vec<Line> = Vec::new();
    let mut offset = 0usize;
    let mut torn = false;
    let mut number = 0;
    // Line number and place in `lines` of each run key: a key twice with other figures is a
    // file edited or joined with another, and whichever line a reader kept would be a guess;
    // the same line twice (a file joined with itself) is read once.
    let mut first_line: std::collections::HashMap<String, (usize, usize)> = Default::default();
    while offset < bytes.len() {
        number += 1;
        let end = bytes[offset..].iter().position(|&b| b == b'\n');
        let (line, next) = match end {
            Some(e) => (&bytes[offset..offset + e], offset + e + 1),
            None => (&bytes[offset..], bytes.len()),
        };
        let parsed = std::str::from_utf8(line)
            .ok()
            .and_then(|t| serde_json::from_str::<Value>(t).ok().map(|v| (v, t)))
            .filter(|(v, _)| v.get("key").and_then(Value::as_str).is_some());
        match (parsed, end) {
            (Some((v, t)), Some(_)) => {
                let key = v["key"].as_str().unwrap_or_default().to_string();
                if let Some(field) = missing_field(&v) {
                    return Err(Error::format(path, incomplete_run(number, &key, &field)));
                }
                match first_line.get(&key) {
                    Some(&(_, at)) if lines[at].1 == t => {}
                    Some(&(first, _)) => {
                        return Err(Error::format(path, repeated_run(number, &key, first)))
                    }
                    None => {
                        first_line.insert(key, (number, lines.len()));
                        lines.push((v, t.to_string()));
                    }
                }
            }
            // The last line, cut short by a kill: redo its run.
            (_, None) => {
                torn = true;
                break;
            }
            // A last line a cut write can leave (`could_be_torn`) is cut, with or without a
            // newline after it; any other last line that is not a result was edited in, and
            // cutting it would lose what it holds, so it is refused like any line below.
            (None, Some(_)) if next == bytes.len() && could_be_torn(line) => {
                torn = true;
                break;
            }
            (None, Some(_)) => {
                return Err(Error::format(
                    path,
                    format!("line {number} is not a result line (corrupt file?)"),
                ))
            }
        }
        offset = next;
    }
    Ok((lines, offset as u64, torn))
}

/// The well-formed lines of a timing file (missing file = none): torn or malformed lines (a
/// full disk, a kill between the result and its time) are skipped, not errors.
pub fn read_timing(path: &Path) -> Result<Vec<Line>> {
    let Some(bytes) = crate::input::read_existing(path)? else {
        return Ok(Vec::new());
    };
    let text = String::from_utf8_lossy(&bytes);
    let mut lines = Vec::new();
    let complete = match text.rfind('\n') {
        Some(end) => &text[..end],
        None => "",
    };
    for line in complete.split('\n') {
        if let Ok(v) = serde_json::from_str::<Value>(line) {
            if v.get("key").and_then(Value::as_str).is_some() {
                lines.push((v, line.to_string()));
            }
        }
    }
    Ok(lines)
}

/// Makes `timing.jsonl` hold exactly one line per result key, in results order: the last
/// well-formed time of each, `"wall_seconds": null` where it was lost. Rewritten (atomically)
/// only when that changes the file; returns whether it did.
fn repair_timing(path: &Path, result_keys: &[String]) -> Result<bool> {
    let existing = crate::input::read_existing(path)?.unwrap_or_default();
    let mut times: std::collections::HashMap<String, String> = std::collections::HashMap::new();
    for (v, text) in read_timing(path)? {
        if let Some(key) = v.get("key").and_then(Value::as_str) {
            times.insert(key.to_string(), text);
        }
    }
    let mut repaired = String::new();
    for key in result_keys {
        match times.get(key) {
            Some(text) => repaired.push_str(text),
            None => repaired
                .push_str(&serde_json::json!({ "key": key, "wall_seconds": null }).to_string()),
        }
        repaired.push('\n');
    }
    if repaired.as_bytes() == existing.as_slice() {
        return Ok(false);
    }
    crate::output::write_atomically(path, |w| w.write_all(repaired.as_bytes()))?;
    Ok(true)
}

/// Creates `dir` if needed and takes its writer's lock (held while the returned file lives):
/// a sweep holds it while it appends, a merge while it replaces the folder's files, so neither
/// writes under the other.
pub fn lock_folder(dir: &Path) -> Result<File> {
    must_be_a_folder(dir)?;
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let lock_path = dir.join(LOCK);
    let lock = OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&lock_path)
        .map_err(|e| Error::io(&lock_path, e))?;
    match lock.try_lock() {
        Ok(()) => Ok(lock),
        Err(std::fs::TryLockError::WouldBlock) => Err(Error::Invalid(format!(
            "{}: another sweep is writing into this folder (or a merge)",
            dir.display()
        ))),
        Err(std::fs::TryLockError::Error(e)) => Err(Error::io(&lock_path, e)),
    }
}

/// An output folder's path must not name a file (else the error would be about a path inside
/// it: "Not a directory").
pub fn must_be_a_folder(dir: &Path) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(Error::Invalid(format!(
            "{}: is a file, not a folder (--out names a folder)",
            dir.display()
        )));
    }
    Ok(())
}

/// The experiment name in a folder's `experiment.resolved.json`, if it has one.
pub fn experiment_name(dir: &Path) -> Result<Option<String>> {
    let path = dir.join(RESOLVED);
    let Some(bytes) = crate::input::read_existing(&path)? else {
        return Ok(None);
    };
    Ok(serde_json::from_slice::<Value>(&bytes)
        .ok()
        .and_then(|v| v["experiment"]["name"].as_str().map(str::to_string)))
}

/// A run as messages name it, from its result line (or its identity: the first fields of
/// one): `fuel, tf class, mode ert, step model, frame 3, 256×256, memory.cl = 3`, with its
/// axis values and sampling rate.
pub fn describe_line(line: &Value) -> String {
    let text = |f: &str| crate::tables::field_text(line, f).unwrap_or_default();
    let axes = line
        .get("axes")
        .and_then(Value::as_object)
        .map(|a| {
            a.iter()
                .map(|(k, v)| format!(", {k} = {v}"))
                .collect::<String>()
        })
        .unwrap_or_default();
    let sampled = line
        .get("sample_rate")
        .map(|r| format!(", sampled at {r}"))
        .unwrap_or_default();
    format!(
        "{}, tf {}, mode {}, {} model, frame {}, {}×{}{axes}{sampled}",
        text("dataset"),
        text("tf"),
        text("mode"),
        text("model"),
        text("frame"),
        text("width"),
        text("height")
    )
}

pub struct ResultStore {
    dir: PathBuf,
    keys: HashSet<String>,
    results: File,
    timing: File,
    /// Keeps the folder's lock for the store's lifetime.
    _lock: File,
    pub torn_lines_dropped: usize,
}

impl ResultStore {
    pub fn open(dir: &Path) -> Result<ResultStore> {
        // One sweep per folder at a time: two writers would interleave their lines.
        Self::open_locked(dir, lock_folder(dir)?)
    }

    /// `open` with the folder's lock already taken (`lock_folder`).
    pub fn open_locked(dir: &Path, lock: File) -> Result<ResultStore> {
        let path = dir.join(RESULTS);
        let (lines, complete, torn) = scan(&path)?;
        if torn {
            // Cut the torn tail so the next append starts on a fresh line.
            let file = OpenOptions::new()
                .write(true)
                .open(&path)
                .map_err(|e| Error::io(&path, e))?;
            file.set_len(complete).map_err(|e| Error::io(&path, e))?;
            crate::note!(
                "{}: dropped a torn last line (interrupted write); its run is done again \
                 unless another line holds it",
                path.display()
            );
        }
        let ordered: Vec<String> = lines
            .iter()
            .filter_map(|(v, _)| v.get("key").and_then(Value::as_str).map(str::to_string))
            .collect();
        let timing_path = dir.join(TIMING);
        if (!ordered.is_empty() || timing_path.exists()) && repair_timing(&timing_path, &ordered)? {
            crate::note!(
                "{}: repaired (one wall time per result; torn lines dropped, lost times null)",
                timing_path.display()
            );
        }
        let keys = ordered.into_iter().collect();
        let append = |p: &Path| {
            OpenOptions::new()
                .create(true)
                .append(true)
                .open(p)
                .map_err(|e| Error::io(p, e))
        };
        Ok(ResultStore {
            dir: dir.to_path_buf(),
            keys,
            results: append(&path)?,
            timing: append(&dir.join(TIMING))?,
            _lock: lock,
            torn_lines_dropped: torn as usize,
        })
    }

    pub fn has(&self, key: &str) -> bool {
        self.keys.contains(key)
    }

    pub fn len(&self) -> usize {
        self.keys.len()
    }

    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// Appends a finished run: the whole line in one write, then synced.
    pub fn append(&mut self, key: &str, line: &Value, wall_seconds: f64) -> Result<()> {
        let mut text = line.to_string();
        text.push('\n');
        let path = self.dir.join(RESULTS);
        self.results
            .write_all(text.as_bytes())
            .and_then(|_| self.results.sync_data())
            .map_err(|e| Error::io(&path, e))?;
        let timing = format!(
            "{}\n",
            serde_json::json!({ "key": key, "wall_seconds": wall_seconds, "model": MODEL })
        );
        self.timing
            .write_all(timing.as_bytes())
            .map_err(|e| Error::io(self.dir.join(TIMING), e))?;
        self.keys.insert(key.to_string());
        Ok(())
    }

    /// Refuses a folder that holds another experiment's results (by name): its run keys would
    /// mix into this one's tables. The name is the resolved experiment's, or, when that file
    /// is missing or unreadable, the result lines' own.
    pub fn check_same_experiment(dir: &Path, name: &str) -> Result<()> {
        must_be_a_folder(dir)?;
        // The resolved experiment's name, then the result lines' own (streamed, as the dry run
        // reads: only keys and names are held): a folder whose resolved file names this
        // experiment can still hold another's lines.
        let other = match experiment_name(dir)? {
            Some(other) if other != name => Some(other),
            _ => stream_keys(&dir.join(RESULTS))?
                .1
                .into_iter()
                .find(|n| n != name),
        };
        match other {
            Some(other) if other != name => Err(Error::Invalid(format!(
                "{}: the folder holds results of experiment `{other}`, not `{name}`; sweep into \
                 another folder (or remove this one)",
                dir.display()
            ))),
            _ => Ok(()),
        }
    }

    /// Refuses a folder whose results include runs the experiment no longer has (`is_run`
    /// false for their keys): its file changed since they were written (a dataset, mode, axis
    /// value, frame, image size or sampling rate taken out or changed), and the folder's tables
    /// would mix the two versions. Results of runs it still has, and runs it gained, are fine.
    pub fn check_results_are_runs(
        dir: &Path,
        done: &HashSet<String>,
        is_run: impl Fn(&str) -> bool,
    ) -> Result<()> {
        let foreign = done.iter().filter(|k| !is_run(k)).count();
        if foreign == 0 {
            return Ok(());
        }
        let example = first_line_where(&dir.join(RESULTS), |key| !is_run(key))?
            .map(|line| format!(" (e.g. {})", describe_line(&line)))
            .unwrap_or_default();
        Err(Error::Invalid(format!(
            "{}: {foreign} of its {} results are not runs of the experiment as its file now \
             reads{example}: the file changed since they were written, and the folder's tables \
             would mix the two versions; sweep into a new folder, or restore the file",
            dir.display(),
            done.len()
        )))
    }

    /// The experiment as resolved (its file, base configuration and every run's parameters),
    /// written before any run.
    pub fn write_resolved(
        &self,
        expansion: &Expansion,
        shard: Option<Shard>,
        model: Option<crate::run::Model>,
    ) -> Result<()> {
        let runs: Vec<Value> = expansion
            .runs
            .iter()
            .map(|r| {
                serde_json::json!({
                    "key": r.key, "dataset": r.run.dataset, "tf": r.run.tf, "mode": r.mode.name(),
                    "model": r.run.model, "frame": r.frame, "axes": r.axes,
                    "fits_default_sram": r.fits_default_sram,
                })
            })
            .collect();
        let base = expansion.runs.first().map(|r| &r.run.hardware);
        let resolved = serde_json::json!({
            "experiment": expansion.experiment,
            "source": expansion.source,
            "shard": shard,
            "model": model,
            "first_run_config": base,
            "skipped": expansion.skipped,
            "runs": runs,
        });
        crate::output::write_json(&self.dir.join(RESOLVED), &resolved)
    }
}

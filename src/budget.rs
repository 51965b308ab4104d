//! The memory budget (issue 17, item 4). Requests whose memory is known before allocating it
//! (a volume from its header, a frame from its image size, an experiment from its run count)
//! are checked against the budget and refused with the figure and the limit, instead of
//! aborting the process when the allocation fails.
//!
//! The budget is `--memory-budget` (any command), else the environment variable
//! `VIZSIM_MEMORY_BUDGET`, else the memory the machine has (`MemTotal` in /proc/meminfo, or
//! the control group's `memory.max` when smaller); where none is known, nothing is refused.
//! Not the memory available at the moment: that changes with other processes, and the same
//! request must get the same answer. Values are bytes with an optional
//! K, M, G or T suffix (powers of 1024).

use std::sync::OnceLock;

use crate::error::{Error, Result};

/// The environment variable that sets the budget.
pub const ENV: &str = "VIZSIM_MEMORY_BUDGET";

static SET: OnceLock<u64> = OnceLock::new();

/// Sets the budget for this process (the CLI's `--memory-budget`); the first call wins.
pub fn set(bytes: u64) {
    let _ = SET.set(bytes);
}

/// Parses `8G`, `512M`, `1000000`.
pub fn parse(text: &str) -> std::result::Result<u64, String> {
    let t = text.trim();
    let (digits, shift) = match t.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => {
            let shift = match c.to_ascii_uppercase() {
                'K' => 10,
                'M' => 20,
                'G' => 30,
                'T' => 40,
                _ => return Err(format!("`{text}`: the unit must be K, M, G or T")),
            };
            (&t[..i], shift)
        }
        _ => (t, 0),
    };
    let value: u64 = digits
        .trim()
        .parse()
        .map_err(|_| format!("`{text}`: expected bytes, e.g. 8G or 512M"))?;
    value
        .checked_mul(1 << shift)
        .filter(|&b| b > 0)
        .ok_or_else(|| format!("`{text}`: out of range; allowed 1..=2^64-1 bytes"))
}

/// The budget in bytes, or None when nothing limits it.
pub fn budget() -> Result<Option<u64>> {
    if let Some(&b) = SET.get() {
        return Ok(Some(b));
    }
    if let Ok(text) = std::env::var(ENV) {
        return parse(&text)
            .map(Some)
            .map_err(|m| Error::Invalid(format!("{ENV}: {m}")));
    }
    Ok(machine_memory())
}

/// `MemTotal` from /proc/meminfo, or the control group's limit when smaller.
fn machine_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let total = line.split_whitespace().nth(1)?.parse::<u64>().ok()? * 1024;
    let group = std::fs::read_to_string("/sys/fs/cgroup/memory.max")
        .ok()
        .and_then(|t| t.trim().parse::<u64>().ok());
    Some(group.map_or(total, |g| g.min(total)))
}

/// Refuses `bytes` for `what` when over the budget.
pub fn check(what: &str, bytes: u64) -> Result<()> {
    match budget()? {
        Some(limit) if bytes > limit => Err(Error::Invalid(format!(
            "{what} needs about {} of memory, over the budget of {} (--memory-budget or \
             {ENV}; default: the machine's memory)",
            human(bytes),
            human(limit)
        ))),
        _ => Ok(()),
    }
}

/// Bytes as a person reads them.
pub fn human(bytes: u64) -> String {
    let b = bytes as f64;
    match bytes {
        0..=1023 => format!("{bytes} B"),
        1024..=1048575 => format!("{:.1} KiB", b / 1024.0),
        1048576..=1073741823 => format!("{:.1} MiB", b / 1048576.0),
        _ => format!("{:.1} GiB", b / 1073741824.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_units_and_refuses_nonsense() {
        assert_eq!(parse("512"), Ok(512));
        assert_eq!(parse("8K"), Ok(8192));
        assert_eq!(parse("3m"), Ok(3 << 20));
        assert_eq!(parse("2G"), Ok(2 << 30));
        assert!(parse("0").is_err());
        assert!(parse("5Q").is_err());
        assert!(parse("x").is_err());
        assert!(parse("99999999999T").is_err());
    }
}

//! Reading what a user hands in: only regular files (a FIFO or a device would block or never
//! end), and text inputs only up to a size cap (a configuration that is really `/dev/zero` or a
//! huge file must not exhaust memory).

use std::fs::File;
use std::io::Read;
use std::path::Path;

use crate::error::{Error, Result};

/// Largest text input (hardware configuration, transfer function, experiment, descriptor).
pub const MAX_TEXT_BYTES: u64 = 16 << 20;

/// Peak memory of parsing a TOML text input per byte of text (measured: about 60).
pub const PARSED_BYTES_PER_TEXT_BYTE: u64 = 64;

/// Opens `path` for reading when it is a regular file (after following links); anything else is
/// refused before it is opened, since opening a FIFO blocks until a writer appears.
pub fn open_regular(path: &Path) -> Result<File> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        let what = if meta.is_dir() {
            "a folder"
        } else {
            "not a regular file (a FIFO, socket or device)"
        };
        return Err(Error::format(
            path,
            format!("{what}; vizsim reads only regular files"),
        ));
    }
    File::open(path).map_err(|e| Error::io(path, e))
}

/// Reads a whole regular file, or None when there is none: the files of a sweep folder
/// (results, timings, the resolved experiment), which may be missing but must never be a FIFO
/// or a device (a FIFO would block the read, /dev/zero would never end). Their size is known
/// up front and checked against the memory budget.
pub fn read_existing(path: &Path) -> Result<Option<Vec<u8>>> {
    match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(Error::io(path, e)),
        Ok(_) => {}
    }
    let mut file = open_regular(path)?;
    let size = file.metadata().map_err(|e| Error::io(path, e))?.len();
    crate::budget::check(&format!("reading {}", path.display()), size)?;
    let mut bytes = Vec::with_capacity(size as usize);
    file.read_to_end(&mut bytes)
        .map_err(|e| Error::io(path, e))?;
    Ok(Some(bytes))
}

/// Reads a text input: a regular file of at most `MAX_TEXT_BYTES`, as UTF-8.
pub fn read_text(path: &Path) -> Result<String> {
    let file = open_regular(path)?;
    let mut text = String::new();
    // Read one byte past the cap so that a file that grew after the check is caught too.
    file.take(MAX_TEXT_BYTES + 1)
        .read_to_string(&mut text)
        .map_err(|e| Error::io(path, e))?;
    if text.len() as u64 > MAX_TEXT_BYTES {
        return Err(Error::format(
            path,
            format!(
                "larger than {} MiB, the limit for a text input",
                MAX_TEXT_BYTES >> 20
            ),
        ));
    }
    // Parsed TOML takes far more memory than its text: a 16 MiB transfer function of 350,000
    // points peaked at 1 GB. Checked before parsing, so a small budget refuses it cleanly.
    crate::budget::check(
        &format!("parsing {}", path.display()),
        text.len() as u64 * PARSED_BYTES_PER_TEXT_BYTE,
    )?;
    Ok(text)
}

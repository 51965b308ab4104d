//! Reading what a user hands in: only regular files (a FIFO or a device would block or never
//! end), and text inputs only up to a size cap (a configuration that is really `/dev/zero` or a
//! huge file must not exhaust memory).

use std::fs::File;
use std::io::Read;
use std::path::Path;

use crate::error::{Error, Result};

/// Largest text input (hardware configuration, transfer function, experiment, descriptor).
pub const MAX_TEXT_BYTES: u64 = 16 << 20;

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
    Ok(text)
}

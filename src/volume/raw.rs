//! Headerless raw volumes (8-bit, or 16-bit little-endian; x fastest) and the TOML dataset
//! descriptor that names a raw file with its dimensions and spacing.
//! (Contract for the implementer: see the functions' docs.)

use std::path::Path;

use super::Volume;
use crate::error::Result;

/// What the usual file name convention `NAME_XxYxZ_uint8.raw` / `NAME_XxYxZ_uint16.raw` says.
/// Anything after the type tag and before `.raw` is allowed (e.g. `.LOSSY_zfp_p8_preview`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RawFileName {
    pub name: String,
    pub dims: [usize; 3],
    pub bits: u8,
}

/// Parses a file name (no directory) by the convention; None if it does not follow it.
pub fn parse_raw_file_name(file_name: &str) -> Option<RawFileName> {
    let _ = file_name;
    unimplemented!("raw file-name parser")
}

/// Reads a raw file. The file size must equal X*Y*Z*(bits/8) exactly, else a Format error
/// naming the file, the size found and the size expected.
pub fn load_raw(
    path: &Path,
    name: &str,
    dims: [usize; 3],
    bits: u8,
    spacing: [f32; 3],
) -> Result<Volume> {
    let _ = (path, name, dims, bits, spacing);
    unimplemented!("raw loader")
}

/// Reads a raw file whose name follows the convention (spacing 1 1 1).
pub fn load_raw_by_file_name(path: &Path) -> Result<Volume> {
    let _ = path;
    unimplemented!("raw loader by file name")
}

/// Reads a dataset descriptor TOML (unknown fields rejected) and the raw or NRRD file it names,
/// relative to the descriptor's folder.
pub fn load_descriptor(path: &Path) -> Result<Volume> {
    let _ = path;
    unimplemented!("dataset descriptor")
}

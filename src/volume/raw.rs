//! Headerless raw volumes (8-bit, or 16-bit little-endian; x fastest) and the TOML dataset
//! descriptor that names a raw file with its dimensions and spacing.
//! (Contract for the implementer: see the functions' docs.)

use std::path::Path;

use super::Volume;
use crate::error::{Error, Result};

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
    let stem = file_name.strip_suffix(".raw")?;
    for (tag, bits) in [("_uint8", 8u8), ("_uint16", 16u8)] {
        // The type tag ends the dims: `NAME_XxYxZ_uint8` then an optional `.suffix`.
        let Some(at) = stem.find(tag) else { continue };
        let rest = &stem[at + tag.len()..];
        if !(rest.is_empty() || rest.starts_with('.')) {
            continue;
        }
        let head = &stem[..at];
        let (name, dims_text) = head.rsplit_once('_')?;
        let parts: Vec<&str> = dims_text.split('x').collect();
        if parts.len() != 3 || name.is_empty() {
            return None;
        }
        let mut dims = [0usize; 3];
        for (d, p) in dims.iter_mut().zip(&parts) {
            *d = p.parse().ok()?;
        }
        return Some(RawFileName {
            name: name.to_string(),
            dims,
            bits,
        });
    }
    None
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
    super::check_dims(&dims).map_err(|m| Error::format(path, m))?;
    let bytes_per_voxel = (bits / 8) as u64;
    let expected = dims.iter().map(|&d| d as u64).product::<u64>() * bytes_per_voxel;
    let found = std::fs::metadata(path)
        .map_err(|e| Error::io(path, e))?
        .len();
    if found != expected {
        return Err(Error::format(
            path,
            format!(
                "file holds {found} bytes but {}x{}x{} voxels of {bits} bits need {expected}",
                dims[0], dims[1], dims[2]
            ),
        ));
    }
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let data: Vec<u16> = match bits {
        8 => bytes.iter().map(|&b| b as u16).collect(),
        16 => bytes
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect(),
        _ => {
            return Err(Error::format(
                path,
                format!("{bits} bits per voxel; allowed 8 or 16"),
            ))
        }
    };
    Volume::new(name, dims, spacing, bits, data).map_err(|e| Error::format(path, e.to_string()))
}

/// Reads a raw file whose name follows the convention (spacing 1 1 1).
pub fn load_raw_by_file_name(path: &Path) -> Result<Volume> {
    let file_name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let parsed = parse_raw_file_name(&file_name).ok_or_else(|| {
        Error::format(
            path,
            "file name does not follow NAME_XxYxZ_uint8.raw / NAME_XxYxZ_uint16.raw; \
             give the dimensions in a dataset descriptor (.toml)",
        )
    })?;
    load_raw(path, &parsed.name, parsed.dims, parsed.bits, [1.0; 3])
}

/// Reads a dataset descriptor TOML (unknown fields rejected) and the raw or NRRD file it names,
/// relative to the descriptor's folder.
pub fn load_descriptor(path: &Path) -> Result<Volume> {
    let _ = path;
    unimplemented!("dataset descriptor")
}

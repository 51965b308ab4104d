//! Headerless raw volumes (8-bit, or 16-bit little-endian; x fastest) and the TOML dataset
//! descriptor that names a raw file with its dimensions and spacing.

use std::io::{self, Read};
use std::path::Path;

use super::{check_dims, Volume};
use crate::error::{Error, Result};

/// What the usual file name convention `NAME_XxYxZ_uint8.raw` / `NAME_XxYxZ_uint16.raw` says.
/// Anything after the type tag and before `.raw` is allowed (e.g. `.LOSSY_zfp_p8_preview`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RawFileName {
    pub name: String,
    pub dims: [usize; 3],
    pub bits: u8,
}

/// Byte order of 16-bit samples in a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Endian {
    Little,
    Big,
}

/// Parses a file name (no directory) by the convention; None if it does not follow it.
///
/// NAME may contain underscores (`boston_teapot_256x256x178_uint8.raw`). If several
/// `_XxYxZ_uintB` groups occur, the leftmost one wins: names are plain words, while the
/// suffix after the type tag is free-form.
pub fn parse_raw_file_name(file_name: &str) -> Option<RawFileName> {
    let stem = file_name.strip_suffix(".raw")?;
    let parts: Vec<&str> = stem.split('_').collect();
    parts.windows(2).enumerate().find_map(|(i, pair)| {
        let [dims_part, tag_part] = pair else {
            return None;
        };
        let name = parts.get(..i)?.join("_");
        if name.is_empty() {
            return None;
        }
        Some(RawFileName {
            name,
            dims: parse_dims_tag(dims_part)?,
            bits: parse_type_tag(tag_part)?,
        })
    })
}

/// `64x64x64` -> [64, 64, 64]; plain decimal digits only.
fn parse_dims_tag(text: &str) -> Option<[usize; 3]> {
    let parts: Vec<&str> = text.split('x').collect();
    let [x, y, z] = parts.as_slice() else {
        return None;
    };
    let number = |s: &str| {
        if !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()) {
            s.parse::<usize>().ok()
        } else {
            None
        }
    };
    Some([number(x)?, number(y)?, number(z)?])
}

/// `uint8`, `uint16`, optionally followed by a suffix that starts with a non-alphanumeric
/// character (`uint8.LOSSY...`), so that e.g. `uint80` or `uint8bit` is not taken for a tag.
fn parse_type_tag(text: &str) -> Option<u8> {
    [("uint16", 16), ("uint8", 8)]
        .into_iter()
        .find_map(|(tag, bits)| {
            let rest = text.strip_prefix(tag)?;
            let ends_tag = rest
                .chars()
                .next()
                .is_none_or(|c| !c.is_ascii_alphanumeric());
            ends_tag.then_some(bits)
        })
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
    load_raw_with_endian(path, name, dims, bits, spacing, Endian::Little)
}

/// [`load_raw`] with an explicit byte order for 16-bit samples (ignored for 8-bit).
pub fn load_raw_with_endian(
    path: &Path,
    name: &str,
    dims: [usize; 3],
    bits: u8,
    spacing: [f32; 3],
    endian: Endian,
) -> Result<Volume> {
    // Validate before touching the file so absurd dims never lead to an allocation.
    let expected = payload_bytes(dims, bits).map_err(|m| Error::format(path, m))?;
    let mut file = crate::input::open_regular(path)?;
    let found = file.metadata().map_err(|e| Error::io(path, e))?.len();
    if found != expected as u64 {
        return Err(Error::format(
            path,
            format!(
                "file size is {found} bytes, expected {expected} bytes \
                 ({} x {} x {} voxels, uint{bits})",
                dims[0], dims[1], dims[2]
            ),
        ));
    }
    let data = read_samples(&mut file, expected, bits, endian)
        .map_err(|e| e.into_error(path, expected))?;
    Volume::new(name, dims, spacing, bits, data)
}

/// Reads a raw file whose name follows the convention (spacing 1 1 1).
pub fn load_raw_by_file_name(path: &Path) -> Result<Volume> {
    let file_name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    let parsed = parse_raw_file_name(file_name).ok_or_else(|| {
        Error::format(
            path,
            "file name does not follow NAME_XxYxZ_uint8.raw or NAME_XxYxZ_uint16.raw",
        )
    })?;
    load_raw(path, &parsed.name, parsed.dims, parsed.bits, [1.0; 3])
}

/// Byte size of a payload with these dims and bits, after checking both.
pub(crate) fn payload_bytes(dims: [usize; 3], bits: u8) -> std::result::Result<usize, String> {
    check_dims(&dims)?;
    let bytes_per_voxel = match bits {
        8 => 1usize,
        16 => 2,
        _ => return Err(format!("{bits} bits per voxel; allowed: 8 or 16")),
    };
    let bytes = dims
        .iter()
        .try_fold(bytes_per_voxel, |acc, &d| acc.checked_mul(d))
        .ok_or_else(|| {
            format!("dimensions {dims:?} need more bytes than this platform can address")
        })?;
    // In memory every voxel is a 16-bit sample: checked before a byte is read, so a small
    // compressed file that declares a huge volume is refused, not expanded.
    let voxels = (dims[0] * dims[1] * dims[2]) as u64;
    crate::budget::check(&format!("a volume of {dims:?} voxels"), voxels * 2)
        .map_err(|e| e.to_string())?;
    Ok(bytes)
}

/// Why a payload could not be decoded.
pub(crate) enum PayloadError {
    Io(io::Error),
    /// The stream ended after `got` bytes.
    Truncated {
        got: usize,
    },
    /// More bytes follow the expected payload.
    TooLong,
    /// The payload was whole, but reading on to check that it ends failed (gzip: data after
    /// the stream that is no gzip member).
    AfterPayload(io::Error),
}

impl PayloadError {
    /// Turns the failure into a crate error naming `path` and the expected byte count.
    pub(crate) fn into_error(self, path: &Path, expected: usize) -> Error {
        match self {
            PayloadError::Io(e) | PayloadError::AfterPayload(e) => Error::io(path, e),
            PayloadError::Truncated { got } => Error::format(
                path,
                format!("truncated payload: {got} bytes, need {expected}"),
            ),
            PayloadError::TooLong => Error::format(
                path,
                format!("payload longer than the {expected} bytes needed"),
            ),
        }
    }
}

/// Bytes read per step. The sample vector grows with the data actually read (never beyond the
/// voxel count), so a header that promises a huge volume over a tiny stream costs nothing.
const CHUNK_BYTES: usize = 1 << 16;

/// Reads exactly `total_bytes` (from [`payload_bytes`]) of `bits`-bit samples and checks that
/// the stream ends right after them.
pub(crate) fn read_samples(
    reader: &mut impl Read,
    total_bytes: usize,
    bits: u8,
    endian: Endian,
) -> std::result::Result<Vec<u16>, PayloadError> {
    let bytes_per_voxel = if bits == 16 { 2 } else { 1 };
    let voxels = total_bytes / bytes_per_voxel;
    let mut data: Vec<u16> = Vec::new();
    let mut buf = vec![0u8; CHUNK_BYTES.min(total_bytes)];
    let mut done = 0usize;
    while done < total_bytes {
        let want = (total_bytes - done).min(buf.len());
        let chunk = &mut buf[..want];
        let got = fill(reader, chunk).map_err(PayloadError::Io)?;
        if got < want {
            return Err(PayloadError::Truncated { got: done + got });
        }
        reserve_capped(&mut data, want / bytes_per_voxel, voxels);
        match (bits, endian) {
            (16, Endian::Little) => data.extend(
                chunk
                    .chunks_exact(2)
                    .map(|p| u16::from_le_bytes([p[0], p[1]])),
            ),
            (16, Endian::Big) => data.extend(
                chunk
                    .chunks_exact(2)
                    .map(|p| u16::from_be_bytes([p[0], p[1]])),
            ),
            _ => data.extend(chunk.iter().map(|&b| u16::from(b))),
        }
        done += want;
    }
    let mut probe = [0u8; 1];
    if fill(reader, &mut probe).map_err(PayloadError::AfterPayload)? > 0 {
        return Err(PayloadError::TooLong);
    }
    Ok(data)
}

/// Makes room for `more` elements, doubling as a Vec would but never past `cap` in total.
fn reserve_capped(data: &mut Vec<u16>, more: usize, cap: usize) {
    if data.capacity() - data.len() < more {
        let target = (data.len() * 2).max(data.len() + more).min(cap);
        data.reserve_exact(target.saturating_sub(data.len()));
    }
}

/// Reads until `buf` is full or the stream ends; returns the number of bytes read.
fn fill(reader: &mut impl Read, buf: &mut [u8]) -> io::Result<usize> {
    let mut filled = 0;
    while let Some(rest) = buf.get_mut(filled..).filter(|r| !r.is_empty()) {
        match reader.read(rest) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(filled)
}

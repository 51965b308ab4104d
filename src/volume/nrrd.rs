//! NRRD volumes: attached (`.nrrd`) and detached (`.nhdr` + data file), encodings raw and gzip.
//!
//! Supported subset: magic `NRRD0001`..`NRRD0005`; `dimension: 3`; unsigned 8- or 16-bit
//! samples; `encoding` raw or gzip; `byte skip` / `line skip` 0 or absent; one data file.
//! Spacing comes from `spacings`, else from the lengths of the `space directions` vectors,
//! else 1. Comments, `key:=value` pairs and fields that do not affect the layout (`content`,
//! `kinds`, `space`, ...) are ignored. Anything else is an error naming what is wrong; no input
//! makes the loader panic or allocate more than the header's (checked) volume size.

use std::collections::BTreeMap;
use std::io::{self, BufRead, BufReader, Read};
use std::path::Path;

use flate2::read::MultiGzDecoder;

use super::raw::{payload_bytes, read_samples, Endian, PayloadError};
use super::Volume;
use crate::error::{Error, Result};

/// Real headers are a few hundred bytes; the cap stops a binary file without newlines from
/// being read whole as one header "line".
const MAX_HEADER_BYTES: u64 = 1 << 20;

/// Loads a `.nrrd` or `.nhdr` file.
pub fn load_nrrd(path: &Path) -> Result<Volume> {
    let file = crate::input::open_regular(path)?;
    let file_len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut reader = BufReader::new(file);
    let header = read_header(&mut reader, path)?;
    let layout = Layout::from_fields(&header.fields).map_err(|m| Error::format(path, m))?;

    let data = match header.fields.get("data file") {
        Some(data_file) => {
            let data_path = detached_payload(path, data_file);
            // Errors name the header too: the data file alone does not say which volume.
            (|| {
                let data = crate::input::open_regular(&data_path)?;
                let available = data.metadata().map_err(|e| Error::io(&data_path, e))?.len();
                read_payload(data, &data_path, available, &layout)
            })()
            .map_err(|e| Error::format(path, format!("`data file: {data_file}`: {e}")))?
        }
        None if header.ended_by_blank_line => {
            let available = file_len.saturating_sub(header.length);
            read_payload(reader, path, available, &layout)?
        }
        None => {
            return Err(Error::format(
                path,
                "header is not followed by a blank line and names no `data file`: no payload",
            ))
        }
    };
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    Volume::new(name, layout.dims, layout.spacing, layout.bits, data)
}

/// The dimensions and voxel width a NRRD header declares, without reading its payload.
pub fn describe_nrrd(path: &Path) -> Result<([usize; 3], u8)> {
    let file = crate::input::open_regular(path)?;
    let header = read_header(&mut BufReader::new(file), path)?;
    let layout = Layout::from_fields(&header.fields).map_err(|m| Error::format(path, m))?;
    Ok((layout.dims, layout.bits))
}

/// The detached payload file a NRRD header names (`data file:`), if any and readable.
pub fn data_file_of(path: &Path) -> Option<std::path::PathBuf> {
    let file = crate::input::open_regular(path).ok()?;
    let header = read_header(&mut BufReader::new(file), path).ok()?;
    Some(detached_payload(path, header.fields.get("data file")?))
}

/// A header's `data file`, relative to the header's folder.
fn detached_payload(header: &Path, data_file: &str) -> std::path::PathBuf {
    header.parent().unwrap_or(Path::new("")).join(data_file)
}

/// The header fields that matter for the layout, by canonical name (`data file`, ...).
struct Header {
    fields: BTreeMap<&'static str, String>,
    /// Bytes up to and including the line that ended the header.
    length: u64,
    /// An attached payload follows only a blank line; a header may also just end (detached).
    ended_by_blank_line: bool,
}

fn read_header(reader: &mut impl BufRead, path: &Path) -> Result<Header> {
    let mut fields = BTreeMap::new();
    let mut length = 0u64;
    let mut line = Vec::new();
    let mut line_number = 0usize;
    loop {
        let budget = MAX_HEADER_BYTES - length;
        line.clear();
        let n = reader
            .by_ref()
            .take(budget)
            .read_until(b'\n', &mut line)
            .map_err(|e| Error::io(path, e))?;
        if n == 0 {
            return Ok(Header {
                fields,
                length,
                ended_by_blank_line: false,
            });
        }
        length += n as u64;
        if !line.ends_with(b"\n") && n as u64 == budget {
            return Err(Error::format(
                path,
                format!("header longer than {MAX_HEADER_BYTES} bytes (is this a NRRD file?)"),
            ));
        }
        line_number += 1;
        let text = String::from_utf8_lossy(&line);
        let text = text.trim_end_matches(['\n', '\r']);
        if line_number == 1 {
            if !matches!(
                text.trim_end().strip_prefix("NRRD000"),
                Some("1" | "2" | "3" | "4" | "5")
            ) {
                return Err(Error::format(
                    path,
                    format!(
                        "not a NRRD file: first line \"{}\" is not NRRD0001..NRRD0005",
                        excerpt(text)
                    ),
                ));
            }
        } else if text.trim().is_empty() {
            return Ok(Header {
                fields,
                length,
                ended_by_blank_line: true,
            });
        } else {
            parse_line(text, &mut fields)
                .map_err(|m| Error::format(path, format!("header line {line_number}: {m}")))?;
        }
    }
}

/// Records one header line in `fields` if it is a field the layout needs.
fn parse_line(
    text: &str,
    fields: &mut BTreeMap<&'static str, String>,
) -> std::result::Result<(), String> {
    let text = text.trim_start();
    // Comments and key/value pairs carry no layout information.
    if text.starts_with('#') || text.contains(":=") {
        return Ok(());
    }
    let Some((name, value)) = text.split_once(':') else {
        return Err(format!(
            "\"{}\" is neither a field, a key:=value pair nor a comment",
            excerpt(text)
        ));
    };
    // NRRD spells some fields both ways (`data file` / `datafile`); compare without spaces.
    let normalized: String = name
        .chars()
        .filter(|c| !c.is_whitespace())
        .collect::<String>()
        .to_ascii_lowercase();
    let canonical = match normalized.as_str() {
        "type" => "type",
        "dimension" => "dimension",
        "sizes" => "sizes",
        "spacings" => "spacings",
        "spacedirections" => "space directions",
        "endian" => "endian",
        "encoding" => "encoding",
        "byteskip" => "byte skip",
        "lineskip" => "line skip",
        "datafile" => "data file",
        _ => return Ok(()),
    };
    if fields.insert(canonical, value.trim().to_string()).is_some() {
        return Err(format!("field `{canonical}` given twice"));
    }
    // `data file: LIST` is followed by file names, not fields: say what is unsupported
    // before those lines are read as malformed ones.
    if canonical == "data file" {
        check_single_data_file(value.trim())?;
    }
    Ok(())
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Encoding {
    Raw,
    Gzip,
}

/// Everything needed to decode the payload, checked for consistency.
struct Layout {
    dims: [usize; 3],
    bits: u8,
    spacing: [f32; 3],
    endian: Endian,
    encoding: Encoding,
    /// Payload size after decoding.
    bytes: usize,
}

type FieldResult<T> = std::result::Result<T, String>;

impl Layout {
    fn from_fields(fields: &BTreeMap<&'static str, String>) -> FieldResult<Layout> {
        let required = |name: &str| {
            fields
                .get(name)
                .map(String::as_str)
                .ok_or_else(|| format!("missing field `{name}`"))
        };
        let bits = parse_type(required("type")?)?;
        let dimension = required("dimension")?;
        if dimension.parse::<usize>().ok() != Some(3) {
            return Err(format!(
                "dimension `{}` not supported: only 3-D volumes (dimension: 3)",
                excerpt(dimension)
            ));
        }
        let dims = parse_sizes(required("sizes")?)?;
        let bytes = payload_bytes(dims, bits).map_err(|m| format!("sizes: {m}"))?;
        let encoding = match required("encoding")?.to_ascii_lowercase().as_str() {
            "raw" => Encoding::Raw,
            "gzip" | "gz" => Encoding::Gzip,
            other => {
                return Err(format!(
                    "unsupported encoding `{}`; supported: raw, gzip",
                    excerpt(other)
                ))
            }
        };
        let endian = match fields.get("endian").map(|e| e.to_ascii_lowercase()) {
            Some(e) if e == "little" => Endian::Little,
            Some(e) if e == "big" => Endian::Big,
            Some(e) => {
                return Err(format!(
                    "unsupported endian `{}`; allowed: little, big",
                    excerpt(&e)
                ))
            }
            None if bits == 16 => {
                return Err("16-bit data needs an `endian` field (little or big)".into())
            }
            // A single byte has no byte order.
            None => Endian::Little,
        };
        for skip in ["byte skip", "line skip"] {
            if let Some(value) = fields.get(skip) {
                if value.parse::<i64>().ok() != Some(0) {
                    return Err(format!("{skip} `{}` not supported; only 0", excerpt(value)));
                }
            }
        }
        let from_spacings = fields
            .get("spacings")
            .map(|v| parse_spacings(v))
            .transpose()?;
        let from_directions = fields
            .get("space directions")
            .map(|v| parse_space_directions(v))
            .transpose()?;
        let spacing = [0, 1, 2].map(|axis| {
            let given = |axes: Option<[Option<f32>; 3]>| axes.and_then(|a| a[axis]);
            given(from_spacings)
                .or(given(from_directions))
                .unwrap_or(1.0)
        });
        super::check_spacing(&spacing).map_err(|m| format!("spacings / space directions: {m}"))?;
        Ok(Layout {
            dims,
            bits,
            spacing,
            endian,
            encoding,
            bytes,
        })
    }
}

fn parse_type(value: &str) -> FieldResult<u8> {
    let words: Vec<&str> = value.split_whitespace().collect();
    match words.join(" ").to_ascii_lowercase().as_str() {
        "uchar" | "unsigned char" | "uint8" | "uint8_t" => Ok(8),
        "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => Ok(16),
        _ => Err(format!(
            "unsupported type `{}`; supported: unsigned 8-bit (uchar, uint8) \
             or unsigned 16-bit (ushort, uint16)",
            excerpt(value)
        )),
    }
}

/// Exactly three whitespace-separated numbers (fields that list one value per axis).
fn three_values<'a>(field: &str, value: &'a str) -> FieldResult<[&'a str; 3]> {
    let values: Vec<&str> = value.split_whitespace().collect();
    match values.as_slice() {
        [x, y, z] => Ok([*x, *y, *z]),
        _ => Err(format!(
            "{field}: expected 3 values, found {}",
            values.len()
        )),
    }
}

fn parse_sizes(value: &str) -> FieldResult<[usize; 3]> {
    let mut dims = [0; 3];
    for (dim, text) in dims.iter_mut().zip(three_values("sizes", value)?) {
        *dim = text
            .parse()
            .map_err(|_| format!("sizes: `{}` is not a valid size", excerpt(text)))?;
    }
    Ok(dims)
}

/// Per-axis spacing; `nan` is NRRD's "unknown" and leaves the axis to the fallbacks.
fn parse_spacings(value: &str) -> FieldResult<[Option<f32>; 3]> {
    let mut spacing = [None; 3];
    for (axis, text) in spacing.iter_mut().zip(three_values("spacings", value)?) {
        if text.eq_ignore_ascii_case("nan") {
            continue;
        }
        match text.parse::<f32>() {
            Ok(s) if s.is_finite() && s > 0.0 => *axis = Some(s),
            _ => {
                return Err(format!(
                    "spacings: `{}` must be a finite number > 0",
                    excerpt(text)
                ))
            }
        }
    }
    Ok(spacing)
}

/// `(1,0,0) (0,1,0) (0,0,2.5)` -> lengths [1, 1, 2.5]; `none` marks an axis without direction.
fn parse_space_directions(value: &str) -> FieldResult<[Option<f32>; 3]> {
    let mut axes = Vec::new();
    let mut rest = value.trim();
    while !rest.is_empty() {
        if let Some(after) = rest.strip_prefix("none") {
            axes.push(None);
            rest = after.trim_start();
        } else if let Some(after) = rest.strip_prefix('(') {
            let (vector, after) = after
                .split_once(')')
                .ok_or("space directions: `(` without `)`")?;
            axes.push(Some(vector_length(vector)?));
            rest = after.trim_start();
        } else {
            return Err(format!(
                "space directions: expected `(x,y,z)` or `none`, found \"{}\"",
                excerpt(rest)
            ));
        }
    }
    match axes.as_slice() {
        [x, y, z] => Ok([*x, *y, *z]),
        _ => Err(format!(
            "space directions: expected 3 vectors, found {}",
            axes.len()
        )),
    }
}

fn vector_length(vector: &str) -> FieldResult<f32> {
    let mut squares = 0.0f64;
    for component in vector.split(',') {
        let c: f64 = component.trim().parse().map_err(|_| {
            format!(
                "space directions: `{}` is not a number",
                excerpt(component.trim())
            )
        })?;
        squares += c * c;
    }
    let length = squares.sqrt() as f32;
    if length.is_finite() && length > 0.0 {
        Ok(length)
    } else {
        Err(format!(
            "space directions: vector ({}) must have a finite, non-zero length",
            excerpt(vector)
        ))
    }
}

/// NRRD can split the payload over several files (`data file: LIST`, or a `%d` pattern with
/// a range); we read exactly one.
fn check_single_data_file(value: &str) -> FieldResult<()> {
    let words: Vec<&str> = value.split_whitespace().collect();
    let is_list = words.first() == Some(&"LIST");
    let is_pattern = words.len() > 1 && words.first().is_some_and(|w| w.contains('%'));
    if value.is_empty() {
        Err("data file: empty file name".into())
    } else if is_list || is_pattern {
        Err(format!(
            "data file \"{}\": several data files are not supported",
            excerpt(value)
        ))
    } else {
        Ok(())
    }
}

/// Decodes the payload from `reader`; `available` is its byte count as stored (for raw).
fn read_payload(
    mut reader: impl Read,
    path: &Path,
    available: u64,
    layout: &Layout,
) -> Result<Vec<u16>> {
    let expected = layout.bytes;
    let decoded = match layout.encoding {
        Encoding::Raw => {
            // The size is known up front: reject a wrong one before reading anything.
            if available < expected as u64 {
                return Err(Error::format(
                    path,
                    format!("truncated payload: {available} bytes, need {expected}"),
                ));
            }
            if available > expected as u64 {
                return Err(Error::format(
                    path,
                    format!(
                        "payload has {available} bytes, need {expected}: trailing bytes \
                         are not allowed"
                    ),
                ));
            }
            read_samples(&mut reader, expected, layout.bits, layout.endian)
        }
        Encoding::Gzip => {
            // One byte past the expected size is enough to detect a too-long stream; the
            // limit keeps a small compressed file from expanding without bound.
            let mut limited = MultiGzDecoder::new(reader).take(expected as u64 + 1);
            read_samples(&mut limited, expected, layout.bits, layout.endian)
        }
    };
    decoded.map_err(|e| match e {
        PayloadError::AfterPayload(e) if layout.encoding == Encoding::Gzip => Error::format(
            path,
            format!(
                "corrupt gzip payload: the {expected} bytes needed decode, what follows them \
                 does not ({e}): a damaged end of the stream, or trailing bytes"
            ),
        ),
        PayloadError::Io(e)
            if layout.encoding == Encoding::Gzip
                && matches!(
                    e.kind(),
                    io::ErrorKind::InvalidInput
                        | io::ErrorKind::InvalidData
                        | io::ErrorKind::UnexpectedEof
                ) =>
        {
            Error::format(path, format!("corrupt gzip payload: {e}"))
        }
        other => other.into_error(path, expected),
    })
}

/// A header value, shortened and escaped so that any input is safe to show in a message.
fn excerpt(text: &str) -> String {
    const MAX_CHARS: usize = 60;
    let mut shown: String = text.chars().take(MAX_CHARS).collect();
    if text.chars().nth(MAX_CHARS).is_some() {
        shown.push_str("...");
    }
    shown.escape_debug().to_string()
}

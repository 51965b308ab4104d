//! Dataset descriptors: a small TOML file naming a raw or NRRD file and what its name or header
//! does not say. Its own module because it dispatches to both loaders (which stay independent).

use std::path::Path;

use serde::Deserialize;

use super::raw::{load_raw_with_endian, parse_raw_file_name, Endian};
use super::{check_dims, nrrd, Volume};
use crate::error::{Error, Result};

/// A dataset descriptor file, e.g.
/// ```toml
/// name = "teapot"                      # default: the descriptor's file stem
/// file = "boston_teapot_256x256x178_uint8.raw"   # relative to the descriptor's folder
/// dims = [256, 256, 178]               # raw only; default: from the file name
/// type = "uint8"                       # raw only; "uint8" | "uint16"
/// spacing = [1.0, 1.0, 1.0]            # each 1e-6..=1e6, axes within 1000× of each other
/// endian = "little"                    # raw uint16 only; "little" | "big"
/// ```
/// For `.nrrd` / `.nhdr` files the header gives dims, type and byte order; `name` and
/// `spacing` still override it.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Descriptor {
    name: Option<String>,
    file: String,
    dims: Option<[usize; 3]>,
    #[serde(rename = "type")]
    voxel_type: Option<String>,
    spacing: Option<[f32; 3]>,
    endian: Option<String>,
}

/// The file a dataset descriptor names, if the descriptor reads (relative to its folder).
pub fn data_file_of(path: &Path) -> Option<std::path::PathBuf> {
    let text = crate::input::read_text(path).ok()?;
    let desc: Descriptor = toml::from_str(&text).ok()?;
    Some(named_file(path, &desc.file))
}

/// The file a descriptor names, relative to the descriptor's folder.
fn named_file(descriptor: &Path, file: &str) -> std::path::PathBuf {
    descriptor.parent().unwrap_or(Path::new("")).join(file)
}

/// Reads a dataset descriptor TOML (unknown fields rejected) and the raw or NRRD file it names,
/// relative to the descriptor's folder.
pub fn load_descriptor(path: &Path) -> Result<Volume> {
    let text = crate::input::read_text(path)?;
    let desc: Descriptor = toml::from_str(&text)
        .map_err(|e| Error::format(path, format!("invalid dataset descriptor: {e}")))?;
    let source = path.display().to_string();
    let config = |field: &str, message: String| Error::config(source.as_str(), field, message);

    let name = match desc.name {
        Some(name) if name.trim().is_empty() => {
            return Err(config("name", "must not be empty".into()))
        }
        Some(name) => name,
        None => path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
    };
    if let Some(spacing) = desc.spacing {
        super::check_spacing(&spacing).map_err(|m| config("spacing", m))?;
    }
    if desc.file.trim().is_empty() {
        return Err(config("file", "must not be empty".into()));
    }
    let data_path = named_file(path, &desc.file);
    // Errors of the data file name the descriptor that pointed to it too.
    let in_file = |e: Error| config("file", e.to_string());
    let extension = data_path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);

    match extension.as_deref() {
        Some("nrrd" | "nhdr") => {
            // The header is authoritative for layout; a second copy here could only disagree.
            for (field, given) in [
                ("dims", desc.dims.is_some()),
                ("type", desc.voxel_type.is_some()),
                ("endian", desc.endian.is_some()),
            ] {
                if given {
                    return Err(config(
                        field,
                        "allowed only for raw files; the NRRD header gives it".into(),
                    ));
                }
            }
            let mut volume = nrrd::load_nrrd(&data_path).map_err(in_file)?;
            volume.name = name;
            if let Some(spacing) = desc.spacing {
                volume.spacing = spacing;
            }
            Ok(volume)
        }
        Some("raw") => {
            // A file that is not there is the error, not the dimensions its name would have
            // given: otherwise a missing file with a free-form name reads as "dims required".
            std::fs::metadata(&data_path).map_err(|e| in_file(Error::io(&data_path, e)))?;
            let from_file_name = data_path
                .file_name()
                .and_then(|n| n.to_str())
                .and_then(parse_raw_file_name);
            let dims = match (desc.dims, &from_file_name) {
                (Some(dims), _) => dims,
                (None, Some(parsed)) => parsed.dims,
                (None, None) => {
                    return Err(config(
                        "dims",
                        format!(
                            "required: file `{}` does not follow NAME_XxYxZ_uint8.raw",
                            desc.file
                        ),
                    ))
                }
            };
            check_dims(&dims).map_err(|m| config("dims", m))?;
            let bits = match desc.voxel_type.as_deref() {
                Some("uint8") => 8,
                Some("uint16") => 16,
                Some(other) => {
                    return Err(config(
                        "type",
                        format!("`{other}` not supported; allowed: \"uint8\", \"uint16\""),
                    ))
                }
                None => from_file_name.as_ref().map_or(8, |parsed| parsed.bits),
            };
            let endian = match desc.endian.as_deref() {
                None | Some("little") => Endian::Little,
                Some("big") => Endian::Big,
                Some(other) => {
                    return Err(config(
                        "endian",
                        format!("`{other}` not supported; allowed: \"little\", \"big\""),
                    ))
                }
            };
            let spacing = desc.spacing.unwrap_or([1.0; 3]);
            load_raw_with_endian(&data_path, &name, dims, bits, spacing, endian).map_err(in_file)
        }
        _ => Err(config(
            "file",
            format!(
                "`{}` has an unsupported extension; allowed: .raw, .nrrd, .nhdr",
                desc.file
            ),
        )),
    }
}

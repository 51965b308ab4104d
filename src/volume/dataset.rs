//! Datasets by name.
//!
//! A dataset argument is one of:
//! - `phantom:KIND[:SIZE][:seed=N][:t=F]`: a generated phantom (see `phantom`);
//! - a path to a `.raw` (named by the `NAME_XxYxZ_uint8.raw` convention), `.nrrd`, `.nhdr` or
//!   dataset descriptor `.toml` file;
//! - a short name found in the data directory: `fuel` finds `fuel_64x64x64_uint8.raw`. Files
//!   in a `lossy_previews` folder are named `NAME-lossy`. Where two files share a name (the two
//!   tooth crops) each is named by its full stem, e.g. `tooth_103x94x161`. `vessel` is the
//!   published name of `aneurism`.
//!
//! The data directory is `--data-dir`, else env `VIZSIM_DATA`, else `../shared/data` when that
//! folder exists.

use std::path::{Path, PathBuf};

use super::{descriptor, nrrd, phantom, raw, Volume};
use crate::error::{Error, Result};

pub const DATA_DIR_ENV: &str = "VIZSIM_DATA";
const DEFAULT_DATA_DIR: &str = "../shared/data";

/// Published names that refer to a dataset under another file name.
const ALIASES: &[(&str, &str)] = &[
    ("vessel", "aneurism"),
    ("skull", "tooth_103x94x161"),
    ("foot", "foot-lossy"),
];

/// Published datasets that are not available, with the dataset that stands in for each (brief,
/// section 6): `--dataset skull` loads the tooth, `--dataset foot` the lossy preview.
pub const STAND_INS: &[(&str, &str)] = &[("skull", "tooth_103x94x161"), ("foot", "foot-lossy")];

/// The dataset name `spec` picks: the name an alias (`vessel`, `skull`, `foot`) stands for, or
/// `spec` itself. The one resolution of aliases, for loading and for matching result lines.
pub fn alias_target(spec: &str) -> &str {
    ALIASES
        .iter()
        .find(|(alias, _)| *alias == spec)
        .map_or(spec, |(_, name)| *name)
}

/// Whether two dataset names pick the same dataset (`vessel` and `aneurism`).
pub fn same_dataset(a: &str, b: &str) -> bool {
    alias_target(a) == alias_target(b)
}

/// The stand-in a published name resolves to, when it does.
pub fn stand_in_for(spec: &str) -> Option<&'static str> {
    STAND_INS
        .iter()
        .find(|(name, _)| *name == spec)
        .map(|(_, stand_in)| *stand_in)
}

/// The data directory to use: the explicit option, else the environment, else the default
/// when it exists. None when no data directory is available.
pub fn data_dir(explicit: Option<&Path>) -> Option<PathBuf> {
    if let Some(p) = explicit {
        return Some(p.to_path_buf());
    }
    if let Some(p) = std::env::var_os(DATA_DIR_ENV) {
        if !p.is_empty() {
            return Some(PathBuf::from(p));
        }
    }
    let default = PathBuf::from(DEFAULT_DATA_DIR);
    default.is_dir().then_some(default)
}

/// A dataset file found in the data directory.
#[derive(Clone, Debug, PartialEq)]
pub struct DatasetEntry {
    pub name: String,
    pub path: PathBuf,
}

/// Every dataset in `dir` (and its immediate sub-folders), sorted by name.
pub fn scan(dir: &Path) -> Result<Vec<DatasetEntry>> {
    let mut found: Vec<(String, String, PathBuf)> = Vec::new(); // (short, stem, path)
    let mut folders = vec![(dir.to_path_buf(), false)];
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    for entry in entries.flatten() {
        if entry.path().is_dir() {
            let lossy = entry.file_name().to_string_lossy().contains("lossy");
            folders.push((entry.path(), lossy));
        }
    }
    // A folder reached twice (a symlink to the data directory or to a sibling) is scanned
    // once, else its datasets would be listed twice under disambiguated names.
    let mut seen = std::collections::HashSet::new();
    for (folder, lossy) in folders {
        let real = std::fs::canonicalize(&folder).unwrap_or_else(|_| folder.clone());
        if !seen.insert(real) {
            continue;
        }
        let Ok(entries) = std::fs::read_dir(&folder) else {
            continue;
        };
        for entry in entries.flatten() {
            let path = entry.path();
            let file_name = entry.file_name().to_string_lossy().into_owned();
            let short = if let Some(parsed) = raw::parse_raw_file_name(&file_name) {
                parsed.name
            } else if file_name.ends_with(".nrrd") || file_name.ends_with(".nhdr") {
                file_name
                    .rsplit_once('.')
                    .map(|(stem, _)| stem.to_string())
                    .unwrap_or_default()
            } else {
                continue;
            };
            // The full name for disambiguation: `tooth_103x94x161` (type tag dropped).
            let stem = file_name
                .split('.')
                .next()
                .unwrap_or_default()
                .trim_end_matches("_uint8")
                .trim_end_matches("_uint16")
                .to_string();
            let suffix = if lossy || file_name.contains("LOSSY") {
                "-lossy"
            } else {
                ""
            };
            found.push((format!("{short}{suffix}"), format!("{stem}{suffix}"), path));
        }
    }
    let mut out: Vec<DatasetEntry> = found
        .iter()
        .map(|(short, stem, path)| {
            let shared = found.iter().filter(|(s, _, _)| s == short).count() > 1;
            DatasetEntry {
                name: if shared { stem.clone() } else { short.clone() },
                path: path.clone(),
            }
        })
        .collect();
    out.sort_by(|a, b| a.name.cmp(&b.name));
    Ok(out)
}

/// Loads the dataset named by `spec` (see the module docs).
pub fn load(spec: &str, data_dir: Option<&Path>) -> Result<Volume> {
    if let Some(rest) = spec.strip_prefix("phantom:") {
        return Ok(phantom::generate(&phantom::parse_spec(rest)?));
    }
    let as_path = Path::new(spec);
    if as_path.is_file() {
        return load_file(as_path);
    }
    // A path (a folder in it, or a volume file's extension) names a file, not a dataset.
    let path_like = [".raw", ".nrrd", ".nhdr", ".toml"]
        .iter()
        .any(|ext| spec.ends_with(ext))
        || spec.contains(std::path::MAIN_SEPARATOR)
        || spec.contains('/');
    let name = alias_target(spec);
    let available = match data_dir {
        // A missing file named by its path is that, whatever the data folder.
        Some(dir) if !dir.is_dir() && path_like => return Err(not_a_volume_file(spec)),
        // A folder that is not there, named with where it came from (a stale environment).
        Some(dir) if !dir.is_dir() => {
            let from_env = std::env::var_os(DATA_DIR_ENV).is_some_and(|v| Path::new(&v) == dir);
            return Err(Error::Invalid(format!(
                "dataset `{spec}`: the data folder {} does not exist{}",
                dir.display(),
                if from_env {
                    format!(" (it is {DATA_DIR_ENV}; give --data-dir or set {DATA_DIR_ENV} to the folder of the datasets)")
                } else {
                    String::new()
                }
            )));
        }
        Some(dir) => match scan(dir) {
            Err(_) if path_like => return Err(not_a_volume_file(spec)),
            scanned => scanned?,
        },
        None => Vec::new(),
    };
    if let Some(entry) = available.iter().find(|e| e.name == name) {
        let mut volume = load_file(&entry.path)?;
        volume.name = entry.name.clone();
        return Ok(volume);
    }
    if path_like || as_path.is_dir() {
        return Err(not_a_volume_file(spec));
    }
    Err(unknown_dataset(spec, &available, data_dir))
}

/// The error for a dataset given as a path that is not a regular volume file: missing (with
/// the path read), a folder, or something else the loader explains (a FIFO, a device, a link
/// loop, a folder that cannot be read), rather than a list of dataset names.
fn not_a_volume_file(spec: &str) -> Error {
    let path = Path::new(spec);
    match std::fs::metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let full = std::env::current_dir()
                .map(|cwd| cwd.join(path))
                .unwrap_or_else(|_| path.to_path_buf());
            Error::Invalid(format!(
                "dataset `{spec}`: no such file ({})",
                full.display()
            ))
        }
        Err(e) => Error::io(path, e),
        Ok(m) if m.is_dir() => Error::Invalid(format!(
            "dataset `{spec}` is a folder; give a volume file (.raw, .nrrd, .nhdr or a .toml \
             descriptor) or a dataset name"
        )),
        // Not a regular file (`is_file` said so): the loader's own check names what it is.
        Ok(_) => match load_file(path) {
            Err(e) => e,
            Ok(_) => Error::Invalid(format!("dataset `{spec}`: not a regular file")),
        },
    }
}

/// The error for a name that resolves to nothing, listing every name that does, from what the
/// resolver itself reads (the folder's files, the aliases whose file is there, the phantom
/// kinds), so that the list cannot fall behind it.
fn unknown_dataset(spec: &str, available: &[DatasetEntry], data_dir: Option<&Path>) -> Error {
    // Two files of one name (fuel_64x64x64 and fuel_16x16x16) are listed by their full names:
    // the short one is ambiguous, not unknown.
    let prefix = format!("{spec}_");
    let same_name: Vec<&str> = available
        .iter()
        .filter(|e| e.name.starts_with(&prefix))
        .map(|e| e.name.as_str())
        .collect();
    if same_name.len() > 1 {
        return Error::Invalid(format!(
            "dataset `{spec}` is ambiguous: the data directory{} holds {}; give one of those \
             names",
            data_dir
                .map(|d| format!(" {}", d.display()))
                .unwrap_or_default(),
            same_name.join(", ")
        ));
    }
    let mut names: Vec<String> = available.iter().map(|e| e.name.clone()).collect();
    for (alias, name) in ALIASES {
        if available.iter().any(|e| e.name == *name) {
            let what = if stand_in_for(alias).is_some() {
                "stand-in:"
            } else {
                "alias of"
            };
            names.push(format!("{alias} ({what} {name})"));
        }
    }
    let kinds: Vec<&str> = phantom::PhantomKind::ALL.iter().map(|k| k.name()).collect();
    names.push(format!("phantom:{}[:SIZE]", kinds.join("|")));
    let where_ = match data_dir {
        Some(d) => format!(" (data directory {})", d.display()),
        None => format!(
            " (no data directory: give --data-dir or set {DATA_DIR_ENV}; the default \
             {DEFAULT_DATA_DIR} is looked for from the folder you run in)"
        ),
    };
    Error::UnknownDataset {
        name: spec.to_string(),
        available: format!("{}{where_}", names.join(", ")),
    }
}

/// The file a dataset name (or alias) picks in `data_dir`, if any (not phantoms or paths).
pub fn file_of(spec: &str, data_dir: &Path) -> Option<PathBuf> {
    let name = alias_target(spec);
    scan(data_dir)
        .ok()?
        .into_iter()
        .find(|e| e.name == name)
        .map(|e| e.path)
}

/// Every file loading the volume file `path` reads: the file itself, and the data file a
/// descriptor or detached NRRD header names (and that one's, a descriptor naming a `.nhdr`).
/// For `output::check_distinct`: writing any of them would destroy the dataset.
pub fn files_read(path: &Path) -> Vec<PathBuf> {
    let mut files = vec![path.to_path_buf()];
    // A descriptor names a raw or NRRD file, a header at most a payload: two links at most.
    for _ in 0..2 {
        let last = files.last().expect("starts with one");
        let name = last.to_string_lossy();
        let next = if name.ends_with(".toml") {
            descriptor::data_file_of(last)
        } else if name.ends_with(".nhdr") || name.ends_with(".nrrd") {
            nrrd::data_file_of(last)
        } else {
            None
        };
        match next {
            Some(next) if !files.contains(&next) => files.push(next),
            _ => break,
        }
    }
    files
}

/// The dimensions and voxel width of a raw or NRRD volume file, from its name or header alone
/// (None for another kind of file: it is known only once loaded).
pub fn describe_file(path: &Path) -> Result<Option<([usize; 3], u8)>> {
    let name = path.to_string_lossy();
    if name.ends_with(".nrrd") || name.ends_with(".nhdr") {
        return nrrd::describe_nrrd(path).map(Some);
    }
    let file_name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    Ok(raw::parse_raw_file_name(&file_name).map(|r| (r.dims, r.bits)))
}

/// Loads a volume file by its extension.
pub fn load_file(path: &Path) -> Result<Volume> {
    let name = path.to_string_lossy();
    if name.ends_with(".nrrd") || name.ends_with(".nhdr") {
        nrrd::load_nrrd(path)
    } else if name.ends_with(".toml") {
        descriptor::load_descriptor(path)
    } else if name.ends_with(".raw") {
        raw::load_raw_by_file_name(path)
    } else {
        Err(Error::format(
            path,
            "unknown volume file type; expected .raw (NAME_XxYxZ_uint8.raw), .nrrd, .nhdr or a .toml descriptor",
        ))
    }
}

//! NRRD volumes: attached (`.nrrd`) and detached (`.nhdr` + data file), encodings raw and gzip.

use std::path::Path;

use super::Volume;
use crate::error::Result;

/// Loads a `.nrrd` or `.nhdr` file.
pub fn load_nrrd(path: &Path) -> Result<Volume> {
    let _ = path;
    unimplemented!("nrrd loader")
}

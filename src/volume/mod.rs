//! Volumes: voxel arrays in memory, their loaders (raw, NRRD), generated phantoms and
//! dataset lookup by name.
//!
//! Voxel coordinates: voxel (x, y, z) sits at integer position (x, y, z); x varies fastest in
//! memory (`index = x + X*(y + Y*z)`). The volume's box for sampling is [0, X-1] x [0, Y-1] x
//! [0, Z-1]: every sample inside it has its whole trilinear neighbourhood inside the volume.

pub mod dataset;
pub mod descriptor;
pub mod nrrd;
pub mod phantom;
pub mod raw;

use crate::error::{Error, Result};

/// Largest accepted extent along one axis, and largest voxel count. Guards loaders against
/// headers that would make us allocate absurd amounts of memory.
pub const MAX_DIM: usize = 8192;
pub const MAX_VOXELS: usize = 1 << 31;

#[derive(Clone, Debug)]
pub struct Volume {
    /// Short name used in reports (`fuel`, `phantom:sphere:64`, ...).
    pub name: String,
    pub dims: [usize; 3],
    /// Physical size of a voxel along each axis (any unit; only ratios matter).
    pub spacing: [f32; 3],
    /// Bits per voxel as stored: 8 or 16.
    pub bits: u8,
    /// Densities, x fastest. Always u16 in memory; 8-bit data uses 0..=255.
    pub data: Vec<u16>,
}

/// Summary statistics printed by `vizsim info`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct VolumeInfo {
    pub name: String,
    pub dims: [usize; 3],
    pub spacing: [f32; 3],
    pub bits: u8,
    pub voxels: usize,
    pub min: u16,
    pub max: u16,
    pub mean: f64,
    /// Percentage of voxels whose value is > 0 (the published "occupied" figure).
    pub occupied_percent: f64,
    /// Value histogram in 16 equal bins over the value range of the voxel type.
    pub histogram16: Vec<u64>,
}

impl Volume {
    /// Checks dims, bits and the data length; the one constructor every loader goes through.
    pub fn new(
        name: impl Into<String>,
        dims: [usize; 3],
        spacing: [f32; 3],
        bits: u8,
        data: Vec<u16>,
    ) -> Result<Self> {
        let name = name.into();
        check_dims(&dims).map_err(|m| Error::Invalid(format!("volume `{name}`: {m}")))?;
        if bits != 8 && bits != 16 {
            return Err(Error::Invalid(format!(
                "volume `{name}`: {bits} bits per voxel; allowed: 8 or 16"
            )));
        }
        check_spacing(&spacing).map_err(|m| Error::Invalid(format!("volume `{name}`: {m}")))?;
        let expected = dims[0] * dims[1] * dims[2];
        if data.len() != expected {
            return Err(Error::Invalid(format!(
                "volume `{name}`: {} voxels given, dims {dims:?} need {expected}",
                data.len()
            )));
        }
        if bits == 8 && data.iter().any(|&v| v > 255) {
            return Err(Error::Invalid(format!(
                "volume `{name}`: 8-bit volume holds values above 255"
            )));
        }
        Ok(Volume {
            name,
            dims,
            spacing,
            bits,
            data,
        })
    }

    #[inline(always)]
    pub fn index(&self, x: usize, y: usize, z: usize) -> usize {
        x + self.dims[0] * (y + self.dims[1] * z)
    }

    #[inline(always)]
    pub fn get(&self, x: usize, y: usize, z: usize) -> u16 {
        self.data[self.index(x, y, z)]
    }

    /// Largest value the voxel type can hold (255 or 65535).
    pub fn max_value(&self) -> u16 {
        if self.bits == 8 {
            255
        } else {
            u16::MAX
        }
    }

    pub fn voxel_count(&self) -> usize {
        self.data.len()
    }

    /// Physical extent of the sampling box along each axis: (dim - 1) * spacing.
    pub fn extent(&self) -> [f32; 3] {
        [0, 1, 2].map(|i| (self.dims[i].saturating_sub(1)) as f32 * self.spacing[i])
    }

    pub fn info(&self) -> VolumeInfo {
        let mut min = u16::MAX;
        let mut max = 0u16;
        let mut sum = 0u64;
        let mut occupied = 0u64;
        let mut histogram16 = vec![0u64; 16];
        let shift = if self.bits == 8 { 4 } else { 12 };
        for &v in &self.data {
            min = min.min(v);
            max = max.max(v);
            sum += v as u64;
            occupied += (v > 0) as u64;
            histogram16[(v >> shift) as usize] += 1;
        }
        let n = self.data.len().max(1) as f64;
        VolumeInfo {
            name: self.name.clone(),
            dims: self.dims,
            spacing: self.spacing,
            bits: self.bits,
            voxels: self.data.len(),
            min,
            max,
            mean: sum as f64 / n,
            occupied_percent: 100.0 * occupied as f64 / n,
            histogram16,
        }
    }
}

/// Per-axis voxel spacing bounds: the camera frames the volume's extent, so a huge spacing
/// makes it infinite (NaN camera) and a tiny one, or a huge ratio between axes, flattens it
/// to nothing.
pub const SPACING_RANGE: std::ops::RangeInclusive<f32> = 1e-6..=1e6;
/// The largest ratio between two axes' spacings.
pub const SPACING_MAX_RATIO: f32 = 1e3;

/// Spacing must be finite, within `SPACING_RANGE` on each axis and at most
/// `SPACING_MAX_RATIO` between axes.
pub fn check_spacing(spacing: &[f32; 3]) -> std::result::Result<(), String> {
    if spacing
        .iter()
        .any(|s| !s.is_finite() || !SPACING_RANGE.contains(s))
    {
        return Err(format!(
            "spacing {spacing:?} is out of range; allowed {:e}..={:e} per axis",
            SPACING_RANGE.start(),
            SPACING_RANGE.end()
        ));
    }
    let (lo, hi) = spacing
        .iter()
        .fold((f32::MAX, 0f32), |(lo, hi), &s| (lo.min(s), hi.max(s)));
    if hi / lo > SPACING_MAX_RATIO {
        return Err(format!(
            "spacing {spacing:?}: the axes differ by more than {SPACING_MAX_RATIO}×"
        ));
    }
    Ok(())
}

/// Dims must be at least 2 per axis (trilinear needs two voxels) and within the guards.
pub fn check_dims(dims: &[usize; 3]) -> std::result::Result<(), String> {
    if dims.iter().any(|&d| !(2..=MAX_DIM).contains(&d)) {
        return Err(format!(
            "dimensions {dims:?} out of range: each must be 2..={MAX_DIM}"
        ));
    }
    let voxels = dims.iter().try_fold(1usize, |acc, &d| acc.checked_mul(d));
    match voxels {
        Some(v) if v <= MAX_VOXELS => Ok(()),
        _ => Err(format!(
            "dimensions {dims:?} hold more than {MAX_VOXELS} voxels"
        )),
    }
}

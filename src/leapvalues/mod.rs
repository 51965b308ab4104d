//! Preprocessing for the two "distance in the volume" accelerators of the brief's section 7
//! (docs/leapvalues.md is the full description, with the derivations and proofs):
//!
//! - **Leap values integrated into the volume** (Frey & Ertl, "Accelerating Raycasting
//!   Utilizing Volume Segmentation of Industrial CT Data"): `segment` (step 1, flood fill into
//!   homogeneous regions), `classify` (step 2, guard or leap voxel), `leap` (step 3, leap values
//!   from an exact distance transform), `word` (step 4, the voxel word with flag and leap field).
//! - **Distance volume** (Vettermann et al.): `distance` (step 5), a per-voxel conservative
//!   distance to the nearest cell that can contribute under a transfer function.
//!
//! Each step is its own function and reports its wall time in its result (`elapsed`);
//! `preprocess` runs steps 1–4 and collects the times. The renderer's and the cycle model's use
//! of these structures is not part of this module.

pub mod classify;
pub mod distance;
pub mod edt;
pub mod leap;
mod lines;
pub mod rendering;
pub mod segment;
pub mod word;

use std::time::Duration;

pub use classify::{classify, Classification, GuardDistance, VoxelClass};
pub use distance::{distance_steps, distance_volume, verify_distance_volume, DistanceVolume};
pub use leap::{leap_steps, leap_values, verify_leap_values, LeapValues};
pub use rendering::{LeapCells, LeapValueStats, LeapValueVolume};
pub use segment::{range_from_fraction, segment, Region, Segmentation, SegmentationParams};
pub use word::{encode_volume, DecodedWord, EncodedVolume, VolumeWord};

use crate::error::Result;
use crate::volume::Volume;

/// Everything steps 1–4 need.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct LeapValueParams {
    pub segmentation: SegmentationParams,
    /// The largest sample spacing (voxels) rays will use: sets the guard distance.
    pub max_spacing: f32,
    /// The sample spacing the leap values count steps of (<= `max_spacing`).
    pub spacing: f32,
    pub layout: VolumeWord,
}

/// Wall time of each step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct StepTimes {
    pub segmentation: Duration,
    pub classification: Duration,
    pub leap_values: Duration,
    pub encoding: Duration,
}

impl StepTimes {
    pub fn total(&self) -> Duration {
        self.segmentation + self.classification + self.leap_values + self.encoding
    }
}

/// The results of steps 1–4.
#[derive(Clone, Debug)]
pub struct Preprocessed {
    pub segmentation: Segmentation,
    pub classification: Classification,
    pub leap_values: LeapValues,
    pub encoded: EncodedVolume,
}

impl Preprocessed {
    pub fn times(&self) -> StepTimes {
        StepTimes {
            segmentation: self.segmentation.elapsed,
            classification: self.classification.elapsed,
            leap_values: self.leap_values.elapsed,
            encoding: self.encoded.elapsed,
        }
    }
}

/// Runs steps 1–4. Every parameter is checked before any work starts.
pub fn preprocess(volume: &Volume, params: &LeapValueParams) -> Result<Preprocessed> {
    params.segmentation.validate(volume)?;
    params.layout.check_volume(volume)?;
    let guard = GuardDistance::for_max_spacing(params.max_spacing)?;
    guard.check_spacing(params.spacing)?;
    let segmentation = segment(volume, params.segmentation)?;
    let classification = classify(&segmentation, guard);
    let leap_values = leap_values(
        &segmentation,
        &classification,
        params.spacing,
        &params.layout,
    )?;
    let encoded = encode_volume(
        volume,
        &segmentation,
        &classification,
        &leap_values,
        params.layout,
    )?;
    Ok(Preprocessed {
        segmentation,
        classification,
        leap_values,
        encoded,
    })
}

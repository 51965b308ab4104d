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
pub mod edt;
mod lines;
pub mod segment;

pub use classify::{classify, Classification, GuardDistance, VoxelClass};
pub use segment::{range_from_fraction, segment, Region, Segmentation, SegmentationParams};

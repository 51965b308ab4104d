//! Step 3: leap values (Frey & Ertl, section 4.3). For every leap voxel p of region R:
//!
//! ```text
//! L(p) = min( max { L >= 0 : L·S + g <= dist(p) },  2^leap_bits − 1 )
//! ```
//!
//! where dist(p) is the exact Euclidean distance from p to the nearest voxel outside R (or to
//! the outside of the volume), g the guard distance and S the sample spacing: the distance
//! minus the guard distance, in whole sample steps, rounded down, saturated to the leap field.
//! It never overestimates: dist comes from an exact distance transform (`edt`) and the
//! inequality is tested in exact integer arithmetic. A ray that reads L at a leap voxel
//! advances max(L, 1) steps; docs/leapvalues.md proves that no sample it passes or lands on has
//! a voxel outside R in its trilinear neighbourhood.
//!
//! The paper finds the nearest boundary voxel with a k-d tree query per leap voxel; a
//! separable distance transform gives all the distances in three linear passes instead.

use std::time::{Duration, Instant};

use rayon::prelude::*;

use super::classify::{Classification, GuardDistance, VoxelClass, SPACING_RANGE};
use super::edt::squared_distance_to_other_label;
use super::segment::{Segmentation, NO_REGION};
use super::word::VolumeWord;
use crate::error::{Error, Result};

/// The result of step 3.
#[derive(Clone, Debug)]
pub struct LeapValues {
    /// The sample spacing S the values count steps of.
    pub spacing: f32,
    pub guard: GuardDistance,
    /// Width of the leap field the values were saturated to.
    pub leap_bits: u32,
    /// Per voxel (x fastest): the leap value of a leap voxel, 0 for every other voxel.
    pub values: Vec<u32>,
    /// Leap voxels whose value was cut to the field's maximum.
    pub saturated: u64,
    /// Largest and mean leap value over the leap voxels (0 when there are none).
    pub max: u32,
    pub mean: f64,
    /// Wall time of `leap_values`.
    pub elapsed: Duration,
}

/// Step 3: the leap value of every leap voxel for sample spacing `spacing`, saturated to the
/// layout's leap field. An error when `spacing` is out of range or larger than the guard
/// distance allows.
pub fn leap_values(
    segmentation: &Segmentation,
    classification: &Classification,
    spacing: f32,
    layout: &VolumeWord,
) -> Result<LeapValues> {
    let guard = classification.guard;
    guard.check_spacing(spacing)?;
    if classification.classes.len() != segmentation.labels.len() {
        return Err(Error::Invalid(
            "leap_values: the classification is not of this segmentation".into(),
        ));
    }
    let started = Instant::now();
    let distance2 = squared_distance_to_other_label(segmentation.dims, &segmentation.labels, true);
    let g = guard.voxels();
    let cap = layout.max_leap();
    let values: Vec<u32> = classification
        .classes
        .par_iter()
        .zip(distance2.par_iter())
        .map(|(&class, &d2)| match class {
            VoxelClass::Leap => leap_steps(d2 as u64, g, spacing).min(cap as u64) as u32,
            _ => 0,
        })
        .collect();
    let (mut sum, mut max, mut saturated) = (0u64, 0u32, 0u64);
    for (&v, &class) in values.iter().zip(&classification.classes) {
        if class == VoxelClass::Leap {
            sum += v as u64;
            max = max.max(v);
            saturated += (v == cap) as u64;
        }
    }
    let leaps = classification.leaps;
    Ok(LeapValues {
        spacing,
        guard,
        leap_bits: layout.leap_bits(),
        values,
        saturated,
        max,
        mean: if leaps == 0 {
            0.0
        } else {
            sum as f64 / leaps as f64
        },
        elapsed: started.elapsed(),
    })
}

/// Fraction bits that make every spacing of `classify::SPACING_RANGE` an integer: an f32 >=
/// 2^-6 has its last mantissa bit at 2^-29 or above.
const SPACING_FRAC_BITS: u32 = 29;

/// Whether L·S + g <= sqrt(d2), exactly (S an f32 in the spacing range, integers in u128).
pub fn leap_fits(steps: u64, d2: u64, guard: u32, spacing: f32) -> bool {
    let s = (spacing as f64 * (1u64 << SPACING_FRAC_BITS) as f64) as u128;
    let lhs = steps as u128 * s + ((guard as u128) << SPACING_FRAC_BITS);
    match lhs.checked_mul(lhs) {
        Some(l2) => l2 <= (d2 as u128) << (2 * SPACING_FRAC_BITS),
        None => false,
    }
}

/// The largest L >= 0 with L·S + g <= sqrt(d2); 0 when even L = 0 does not fit, and 0 for a
/// spacing outside `classify::SPACING_RANGE`.
pub fn leap_steps(d2: u64, guard: u32, spacing: f32) -> u64 {
    if !SPACING_RANGE.contains(&spacing) {
        return 0;
    }
    let estimate = ((d2 as f64).sqrt() - guard as f64) / spacing as f64;
    let mut steps = if estimate > 0.0 { estimate as u64 } else { 0 };
    while steps > 0 && !leap_fits(steps, d2, guard, spacing) {
        steps -= 1;
    }
    while leap_fits(steps + 1, d2, guard, spacing) {
        steps += 1;
    }
    steps
}

/// Volumes larger than this are refused by the brute-force checker.
pub const VERIFY_MAX_VOXELS: usize = 1 << 15;

/// Checks steps 2 and 3 by brute force on a small volume (at most `VERIFY_MAX_VOXELS`): every
/// region voxel is a leap voxel exactly when the cube of half-width g around it lies inside the
/// volume and its region; every leap value satisfies L·S + g <= the true Euclidean distance to
/// the nearest voxel outside the region or the volume's outside (never overestimates) and fits
/// the leap field; every other voxel has value 0. An error lists the violations.
pub fn verify_leap_values(
    segmentation: &Segmentation,
    classification: &Classification,
    leap_values: &LeapValues,
) -> Result<()> {
    let dims = segmentation.dims;
    let labels = &segmentation.labels;
    let n = labels.len();
    if n > VERIFY_MAX_VOXELS {
        return Err(Error::Invalid(format!(
            "verify_leap_values: {n} voxels; the brute force checks at most {VERIFY_MAX_VOXELS}"
        )));
    }
    if classification.classes.len() != n || leap_values.values.len() != n {
        return Err(Error::Invalid(
            "verify_leap_values: inputs of different volumes".into(),
        ));
    }
    let g = leap_values.guard.voxels() as i64;
    let cap = ((1u64 << leap_values.leap_bits) - 1) as u32;
    let coords = |i: usize| {
        [
            (i % dims[0]) as i64,
            (i / dims[0] % dims[1]) as i64,
            (i / (dims[0] * dims[1])) as i64,
        ]
    };
    let mut violations = Vec::new();
    for p in 0..n {
        let label = labels[p];
        let class = classification.classes[p];
        let value = leap_values.values[p];
        if label == NO_REGION {
            if class != VoxelClass::NoRegion || value != 0 {
                violations.push(format!(
                    "voxel {p}: no region but class {class:?}, value {value}"
                ));
            }
            continue;
        }
        let pc = coords(p);
        let mut cube_inside = (0..3).all(|a| pc[a] >= g && pc[a] + g < dims[a] as i64);
        // Squared distance to the outside of the volume, then to every voxel of another label.
        let mut d2 = (0..3)
            .map(|a| (pc[a] + 1).min(dims[a] as i64 - pc[a]).pow(2))
            .min()
            .unwrap_or(0);
        for q in 0..n {
            if labels[q] != label {
                let qc = coords(q);
                d2 = d2.min((0..3).map(|a| (pc[a] - qc[a]).pow(2)).sum());
                if (0..3).all(|a| (pc[a] - qc[a]).abs() <= g) {
                    cube_inside = false;
                }
            }
        }
        let expected = if cube_inside {
            VoxelClass::Leap
        } else {
            VoxelClass::Guard
        };
        if class != expected {
            violations.push(format!(
                "voxel {pc:?}: class {class:?}, expected {expected:?}"
            ));
        }
        if class == VoxelClass::Leap {
            if !leap_fits(value as u64, d2 as u64, g as u32, leap_values.spacing) {
                violations.push(format!(
                    "voxel {pc:?}: leap value {value} overestimates: {value}·{} + {g} > \
                     distance {:.3}",
                    leap_values.spacing,
                    (d2 as f64).sqrt()
                ));
            }
            if value > cap {
                violations.push(format!(
                    "voxel {pc:?}: leap value {value} exceeds the {}-bit field",
                    leap_values.leap_bits
                ));
            }
        } else if value != 0 {
            violations.push(format!(
                "voxel {pc:?}: {class:?} voxel with leap value {value}"
            ));
        }
    }
    if violations.is_empty() {
        Ok(())
    } else {
        Err(Error::Invalid(format!(
            "verify_leap_values: {} violation(s), first: {}",
            violations.len(),
            violations[..violations.len().min(5)].join("; ")
        )))
    }
}

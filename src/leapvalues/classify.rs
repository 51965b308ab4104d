//! Step 2: voxel classification (Frey & Ertl, section 4.2). A region voxel is a **guard** when
//! some voxel within the guard distance g lies outside its region, else a **leap** voxel. Guards
//! store the region's mean density; leap voxels store a leap value (step 3).
//!
//! "Within the guard distance" is measured in the **Chebyshev** metric (the cube of half-width g
//! around the voxel), because a trilinear sample reads a 2×2×2 cube of voxels; positions outside
//! the volume count as outside the region, so a ray entering the box meets guards first. The
//! guard distance g = max(3, floor(S_max) + 2) for the largest sample spacing S_max a user will
//! render with; docs/leapvalues.md derives it.
//!
//! The test "the cube [v − g, v + g]³ lies inside the volume and inside v's region" is an
//! erosion by a box, which separates into three passes of a 1D window test along x, y and z.

use std::time::{Duration, Instant};

use super::lines::for_each_line;
use super::segment::{Segmentation, NO_REGION, SOURCE};
use crate::error::{Error, Result};

/// Sample spacings (voxels) a guard distance may be derived for: the renderer's range.
pub const SPACING_RANGE: std::ops::RangeInclusive<f32> = (1.0 / 64.0)..=16.0;

/// The guard distance and the largest sample spacing it was derived for.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct GuardDistance {
    max_spacing: f32,
    voxels: u32,
}

impl GuardDistance {
    /// g = max(3, floor(S_max) + 2) voxels (Chebyshev) for the largest sample spacing S_max
    /// (voxels, 1/64..=16). The step length the hardware actually takes (after the increment's
    /// rounding) must not exceed S_max.
    pub fn for_max_spacing(max_spacing: f32) -> Result<GuardDistance> {
        check_spacing_range(max_spacing, "leap_values.max_spacing")?;
        Ok(GuardDistance {
            max_spacing,
            voxels: 3.max(max_spacing.floor() as u32 + 2),
        })
    }

    /// g in voxels.
    pub fn voxels(&self) -> u32 {
        self.voxels
    }

    /// The largest sample spacing this guard distance is safe for.
    pub fn max_spacing(&self) -> f32 {
        self.max_spacing
    }

    /// An error when a ray with sample spacing `spacing` is not covered by this guard distance.
    pub fn check_spacing(&self, spacing: f32) -> Result<()> {
        check_spacing_range(spacing, "leap_values.spacing")?;
        if spacing > self.max_spacing {
            return Err(Error::config(
                SOURCE,
                "leap_values.max_spacing",
                format!(
                    "sample spacing {spacing} is larger than the guard distance allows: the guards \
                     ({} voxels) were derived for spacings up to {}; classify again with \
                     leap_values.max_spacing >= {spacing}",
                    self.voxels, self.max_spacing
                ),
            ));
        }
        Ok(())
    }
}

pub(crate) fn check_spacing_range(spacing: f32, field: &str) -> Result<()> {
    if !spacing.is_finite() || !SPACING_RANGE.contains(&spacing) {
        return Err(Error::config(
            SOURCE,
            field,
            format!(
                "{spacing} is out of range: allowed {}..={} voxels",
                SPACING_RANGE.start(),
                SPACING_RANGE.end()
            ),
        ));
    }
    Ok(())
}

/// What a voxel is after classification.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum VoxelClass {
    /// Belongs to no region: keeps its density.
    NoRegion = 0,
    /// Region voxel near the region's boundary: stores the region's mean.
    Guard = 1,
    /// Region voxel with its whole guard cube inside the region: stores a leap value.
    Leap = 2,
}

/// The result of step 2.
#[derive(Clone, Debug)]
pub struct Classification {
    pub guard: GuardDistance,
    /// One entry per voxel, x fastest.
    pub classes: Vec<VoxelClass>,
    pub guards: u64,
    pub leaps: u64,
    /// Wall time of `classify`.
    pub elapsed: Duration,
}

/// Step 2: classifies every region voxel as guard or leap (module documentation).
pub fn classify(segmentation: &Segmentation, guard: GuardDistance) -> Classification {
    let started = Instant::now();
    let dims = segmentation.dims;
    let labels = &segmentation.labels;
    let g = guard.voxels as usize;
    // inside[v] = 1 while the window tested so far lies inside v's region.
    let mut inside: Vec<u8> = labels.iter().map(|&l| (l != NO_REGION) as u8).collect();
    for axis in 0..3 {
        for_each_line(
            dims,
            axis,
            Some(labels),
            &mut inside,
            || (),
            |_, labels, line| {
                // Maximal runs of voxels still inside, of one label: v stays inside when its
                // window [v - g, v + g] lies within the run.
                let n = line.len();
                let mut a = 0;
                while a < n {
                    if line[a] == 0 {
                        a += 1;
                        continue;
                    }
                    let mut b = a;
                    while b + 1 < n && line[b + 1] == 1 && labels[b + 1] == labels[a] {
                        b += 1;
                    }
                    for (i, v) in line.iter_mut().enumerate().take(b + 1).skip(a) {
                        *v = (i >= a + g && i + g <= b) as u8;
                    }
                    a = b + 1;
                }
            },
        );
    }
    let classes: Vec<VoxelClass> = labels
        .iter()
        .zip(&inside)
        .map(|(&l, &inside)| match (l, inside) {
            (NO_REGION, _) => VoxelClass::NoRegion,
            (_, 1) => VoxelClass::Leap,
            _ => VoxelClass::Guard,
        })
        .collect();
    let leaps = classes.iter().filter(|&&c| c == VoxelClass::Leap).count() as u64;
    Classification {
        guard,
        leaps,
        guards: segmentation.region_voxels() - leaps,
        classes,
        elapsed: started.elapsed(),
    }
}

//! Step 1: region segmentation by automatic 3D flood fill (Frey & Ertl, "Accelerating
//! Raycasting Utilizing Volume Segmentation of Industrial CT Data", section 4.1).
//!
//! Every voxel not yet visited becomes a seed, in memory (scan) order, and grows a region over
//! its 6-connected neighbours. **Region criterion:** a voxel joins when it is unvisited and its
//! value v satisfies |v − seed value| <= `range` (docs/leapvalues.md says why this one). A
//! neighbour that was tried and refused (value out of range, or already taken by an earlier
//! region) goes into the region's boundary list: the one-voxel layer around the region. Positions
//! outside the volume are never tried. A region smaller than `min_region_size` voxels is
//! dissolved: its voxels belong to no region (label 0) and are not seeds again (they were
//! visited), and its boundary list is dropped.
//!
//! The fill is iterative: a scanline fill whose explicit stack holds one seed per run of
//! candidate voxels. Each popped seed is extended to the maximal run along x, and the four
//! neighbouring rows (y ± 1, z ± 1) are scanned over that run's extent.
//!
//! Because a voxel's admission depends only on its own value, the seed's value and whether an
//! earlier region took it, a region is exactly the 6-connected component of the seed within the
//! unvisited voxels inside the seed's value window: the result does not depend on the order in
//! which the stack is processed.

use std::time::{Duration, Instant};

use crate::error::{Error, Result};
use crate::volume::Volume;

/// Where parameter errors of this module say they come from.
pub const SOURCE: &str = "leap-value preprocessing";

/// Label of a voxel that belongs to no region.
pub const NO_REGION: u32 = 0;
/// Internal label of voxels of a dissolved region (visited, no region); 0 in the result.
const DISSOLVED: u32 = u32::MAX;

/// The parameters of the segmentation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct SegmentationParams {
    /// A voxel joins a region when |value − seed value| <= range (density units).
    pub range: u16,
    /// Regions with fewer voxels are dissolved (>= 1; 1 keeps every region).
    pub min_region_size: u64,
}

impl SegmentationParams {
    /// Checks the parameters against the volume: `range` may not exceed the largest value of
    /// the voxel type (255 or 65535), `min_region_size` must be >= 1.
    pub fn validate(&self, volume: &Volume) -> Result<()> {
        if self.range > volume.max_value() {
            return Err(Error::config(
                SOURCE,
                "leap_values.range",
                format!(
                    "{} is out of range for the {}-bit volume `{}`: allowed 0..={}",
                    self.range,
                    volume.bits,
                    volume.name,
                    volume.max_value()
                ),
            ));
        }
        if self.min_region_size == 0 {
            return Err(Error::config(
                SOURCE,
                "leap_values.min_region_size",
                "must be at least 1 (1 keeps every region)",
            ));
        }
        Ok(())
    }
}

/// The range in density units for a fraction of the voxel type's value range (the paper quotes
/// segmentation ranges as 3 %–20 % of the value range): round(fraction · max value).
pub fn range_from_fraction(fraction: f64, volume: &Volume) -> Result<u16> {
    if !fraction.is_finite() || !(0.0..=1.0).contains(&fraction) {
        return Err(Error::config(
            SOURCE,
            "leap_values.range_fraction",
            format!("{fraction} is out of range: allowed 0..=1 (a fraction of the value range)"),
        ));
    }
    Ok((fraction * volume.max_value() as f64).round() as u16)
}

/// One region found by the flood fill.
#[derive(Clone, Debug, PartialEq)]
pub struct Region {
    /// Voxel index of the seed (x fastest).
    pub seed: usize,
    pub seed_value: u16,
    /// Number of region voxels.
    pub voxels: u64,
    /// Mean value, rounded to nearest: what the guard voxels store.
    pub mean: u16,
    pub min: u16,
    pub max: u16,
    /// The boundary layer: voxel indices tried from the region and refused, sorted, each once.
    /// These are exactly the voxels inside the volume that are 6-adjacent to the region and not
    /// in it.
    pub boundary: Vec<u32>,
}

/// The result of step 1.
#[derive(Clone, Debug)]
pub struct Segmentation {
    pub dims: [usize; 3],
    pub params: SegmentationParams,
    /// Per voxel: 0 = no region, k >= 1 = region k (`regions[k - 1]`).
    pub labels: Vec<u32>,
    pub regions: Vec<Region>,
    /// Regions grown and dissolved for being smaller than `min_region_size`, and their voxels.
    pub dissolved_regions: u64,
    pub dissolved_voxels: u64,
    /// Wall time of `segment`.
    pub elapsed: Duration,
}

impl Segmentation {
    /// The region a voxel belongs to, if any.
    pub fn region_of(&self, index: usize) -> Option<&Region> {
        match self.labels[index] {
            NO_REGION => None,
            k => self.regions.get(k as usize - 1),
        }
    }

    /// Voxels that belong to some region.
    pub fn region_voxels(&self) -> u64 {
        self.regions.iter().map(|r| r.voxels).sum()
    }
}

/// Step 1: segments `volume` into regions (module documentation).
pub fn segment(volume: &Volume, params: SegmentationParams) -> Result<Segmentation> {
    params.validate(volume)?;
    let started = Instant::now();
    let [nx, ny, nz] = volume.dims;
    let data = &volume.data;
    let mut labels = vec![NO_REGION; data.len()];
    let mut regions = Vec::new();
    let (mut dissolved_regions, mut dissolved_voxels) = (0u64, 0u64);
    let mut stack: Vec<u32> = Vec::new();
    // Runs (first index, length) filled so far, kept only while the region is still small
    // enough to be dissolved.
    let mut small_runs: Vec<(usize, usize)> = Vec::new();
    for seed in 0..data.len() {
        if labels[seed] != NO_REGION {
            continue;
        }
        let label = regions.len() as u32 + 1;
        let seed_value = data[seed];
        let (lo, hi) = (
            seed_value.saturating_sub(params.range),
            seed_value.saturating_add(params.range),
        );
        let mut boundary: Vec<u32> = Vec::new();
        let (mut count, mut sum, mut min, mut max) = (0u64, 0u64, u16::MAX, 0u16);
        small_runs.clear();
        stack.clear();
        stack.push(seed as u32);
        while let Some(i) = stack.pop() {
            let i = i as usize;
            let fillable =
                |labels: &[u32], j: usize| labels[j] == NO_REGION && (lo..=hi).contains(&data[j]);
            if !fillable(&labels, i) {
                continue;
            }
            let row_start = i - i % nx;
            let row = i / nx;
            let (y, z) = (row % ny, row / ny);
            // Extend to the maximal run [a, b] along x.
            let mut a = i;
            while a > row_start && fillable(&labels, a - 1) {
                a -= 1;
            }
            let mut b = i;
            while b + 1 < row_start + nx && fillable(&labels, b + 1) {
                b += 1;
            }
            for (j, &v) in data.iter().enumerate().take(b + 1).skip(a) {
                labels[j] = label;
                sum += v as u64;
                min = min.min(v);
                max = max.max(v);
            }
            if count < params.min_region_size {
                small_runs.push((a, b + 1 - a));
            }
            count += (b + 1 - a) as u64;
            // The run's ends along x: refused (the run is maximal) unless already ours.
            if a > row_start && labels[a - 1] != label {
                boundary.push((a - 1) as u32);
            }
            if b + 1 < row_start + nx && labels[b + 1] != label {
                boundary.push((b + 1) as u32);
            }
            // The four neighbouring rows over [a, b]: members, candidates (one seed per run
            // of them) or refused.
            let neighbours = [
                (y > 0).then(|| a - nx),
                (y + 1 < ny).then(|| a + nx),
                (z > 0).then(|| a - nx * ny),
                (z + 1 < nz).then(|| a + nx * ny),
            ];
            for start in neighbours.into_iter().flatten() {
                let mut in_run = false;
                for j in start..=start + (b - a) {
                    if labels[j] == label {
                        in_run = false;
                    } else if fillable(&labels, j) {
                        if !in_run {
                            stack.push(j as u32);
                        }
                        in_run = true;
                    } else {
                        boundary.push(j as u32);
                        in_run = false;
                    }
                }
            }
        }
        if count < params.min_region_size {
            for &(first, len) in &small_runs {
                labels[first..first + len].fill(DISSOLVED);
            }
            dissolved_regions += 1;
            dissolved_voxels += count;
            continue;
        }
        boundary.sort_unstable();
        boundary.dedup();
        regions.push(Region {
            seed,
            seed_value,
            voxels: count,
            mean: ((sum + count / 2) / count) as u16,
            min,
            max,
            boundary,
        });
    }
    for l in labels.iter_mut() {
        if *l == DISSOLVED {
            *l = NO_REGION;
        }
    }
    Ok(Segmentation {
        dims: volume.dims,
        params,
        labels,
        regions,
        dissolved_regions,
        dissolved_voxels,
        elapsed: started.elapsed(),
    })
}

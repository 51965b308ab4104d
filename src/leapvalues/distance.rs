//! Step 5: the distance volume (Vettermann et al.; the proximity clouds of Cohen & Sheffer and
//! Zuiderveld et al.): per voxel, how far a ray may go without meeting anything visible.
//!
//! **Cells.** Cell b (b ∈ [0, dims − 2]³) is the unit cube [b, b + 1]³, whose eight corner
//! voxels a trilinear sample inside it reads. A sample at P uses the cell whose base is
//! b = min(floor(P), dims − 2) (the interpolation's own rule); P lies in that closed cube. Cell c
//! is **visible** when `visible(min, max)` holds for the minimum and maximum of its eight voxels:
//! the class occupancy map's test (pass `|lo, hi| table.any_visible(lo, hi)`), exact because an
//! interpolated density rounds into [min, max] of its voxels.
//!
//! **Stored distance.** For every base voxel b:
//!
//! ```text
//! d(b) = min( floor( min over visible cells c of gap(b, c) ),  2^bits − 1 ),
//! gap(b, c) = sqrt( Σ_i max(0, |b_i − c_i| − 1)² )
//! ```
//!
//! gap(b, c) is the Euclidean distance between the closed cubes of cells b and c (0 when they
//! touch). With no visible cell at all, d = 2^bits − 1. Voxels on the last layer of an axis are
//! no cell's base; they store 0.
//!
//! **The rule.** A ray at a sample position P whose cell base is b, with sample spacing S
//! (an upper bound of its actual step length), may advance n = floor(d(b) / S) steps: it takes
//! no sample at P, P + V, …, P + (n − 1)·V and continues at P + n·V. n = 0: take the sample.
//! docs/leapvalues.md proves that every sample so skipped has opacity 0.
//!
//! **Computation.** min over c of gap(b, c)² equals the squared Euclidean distance from b to
//! the visible cells dilated by one cell in every direction (a 3×3×3 dilation, the stencil
//! dilation the occupancy map applies): per axis, moving c by one towards b takes exactly the
//! 1 off |b_i − c_i|. So: cell min–max (three 2-wide passes), visibility, dilation (three 3-wide
//! passes), exact distance transform (`edt`), integer square root, saturation.

use std::time::{Duration, Instant};

use rayon::prelude::*;

use super::classify::SPACING_RANGE;
use super::edt::{isqrt, squared_distance_to_other_label, UNREACHABLE};
use super::lines::for_each_line;
use super::segment::SOURCE;
use crate::error::{Error, Result};
use crate::volume::Volume;

/// Allowed widths of a stored distance.
pub const DISTANCE_BITS: std::ops::RangeInclusive<u32> = 1..=8;

/// The result of step 5.
#[derive(Clone, Debug)]
pub struct DistanceVolume {
    pub dims: [usize; 3],
    /// Width of a stored distance (the saturation is 2^bits − 1).
    pub bits: u32,
    /// d(b) per voxel, x fastest (module documentation).
    pub values: Vec<u8>,
    /// Cells whose eight voxels can contribute.
    pub visible_cells: u64,
    /// Cells whose distance was cut to 2^bits − 1.
    pub saturated_cells: u64,
    /// Wall time of `distance_volume`.
    pub elapsed: Duration,
}

impl DistanceVolume {
    /// The stored distance of the cell with base voxel `base`.
    pub fn distance(&self, base: [usize; 3]) -> u32 {
        self.values[base[0] + self.dims[0] * (base[1] + self.dims[1] * base[2])] as u32
    }

    /// Steps a ray whose sample position lies in cell `base` may advance (the rule).
    pub fn steps(&self, base: [usize; 3], spacing: f32) -> u64 {
        distance_steps(self.distance(base), spacing)
    }

    /// The largest distance a stored value can hold.
    pub fn saturation(&self) -> u32 {
        (1u32 << self.bits) - 1
    }

    /// The same distances stored in `bits` (at most this volume's width): each value cut to
    /// 2^bits − 1. Equal to `distance_volume` at `bits` (the saturation is the transform's last
    /// step), without a second transform: the advisor builds the widest once and narrows it.
    pub fn narrowed(&self, bits: u32) -> Result<DistanceVolume> {
        if !DISTANCE_BITS.contains(&bits) || bits > self.bits {
            return Err(Error::Invalid(format!(
                "a {}-bit distance volume cannot be narrowed to {bits} bits",
                self.bits
            )));
        }
        let started = Instant::now();
        let cap = ((1u32 << bits) - 1) as u8;
        let values: Vec<u8> = self.values.iter().map(|&v| v.min(cap)).collect();
        let [nx, ny, nz] = self.dims;
        // Cells only (the last layer of each axis is no cell's base and stores 0).
        let saturated_cells = values
            .chunks(nx)
            .enumerate()
            .map(|(row, line)| {
                let (y, z) = (row % ny, row / ny);
                if y + 1 < ny && z + 1 < nz {
                    line[..nx - 1].iter().filter(|&&v| v == cap).count() as u64
                } else {
                    0
                }
            })
            .sum();
        Ok(DistanceVolume {
            dims: self.dims,
            bits,
            values,
            visible_cells: self.visible_cells,
            saturated_cells,
            elapsed: started.elapsed(),
        })
    }
}

/// n = floor(d / S), exactly (the largest n with n·S <= d); 0 for a spacing outside
/// `classify::SPACING_RANGE`.
pub fn distance_steps(distance: u32, spacing: f32) -> u64 {
    if !SPACING_RANGE.contains(&spacing) {
        return 0;
    }
    let (d, s) = (distance as f64, spacing as f64);
    // n·S is exact in f64 (n < 2^24, S has a 24-bit mantissa); the quotient only estimates.
    let mut n = (d / s) as u64;
    while n > 0 && n as f64 * s > d {
        n -= 1;
    }
    while (n + 1) as f64 * s <= d {
        n += 1;
    }
    n
}

/// Step 5: the distance volume of `volume` under the visibility test `visible(min, max)`,
/// distances saturated to `bits` (1..=8).
pub fn distance_volume(
    volume: &Volume,
    bits: u32,
    visible: impl Fn(u16, u16) -> bool + Sync,
) -> Result<DistanceVolume> {
    if !DISTANCE_BITS.contains(&bits) {
        return Err(Error::config(
            SOURCE,
            "distance_volume.bits",
            format!(
                "{bits} is out of range: allowed {}..={}",
                DISTANCE_BITS.start(),
                DISTANCE_BITS.end()
            ),
        ));
    }
    let started = Instant::now();
    let dims = volume.dims;
    let [nx, ny, nz] = dims;
    // Cell min–max: after the three passes, entry b holds [min, max] of cell b's voxels.
    let mut range: Vec<[u16; 2]> = volume.data.iter().map(|&v| [v, v]).collect();
    for axis in 0..3 {
        for_each_line(
            dims,
            axis,
            None,
            &mut range,
            || (),
            |_, _, line| {
                for i in 0..line.len() - 1 {
                    line[i] = [
                        line[i][0].min(line[i + 1][0]),
                        line[i][1].max(line[i + 1][1]),
                    ];
                }
            },
        );
    }
    // Visibility of every cell (0 on the last layers, which are no cell's base).
    let mut shown: Vec<u8> = vec![0; range.len()];
    shown
        .par_chunks_mut(nx)
        .zip(range.par_chunks(nx))
        .enumerate()
        .for_each(|(row, (out, cells))| {
            let (y, z) = (row % ny, row / ny);
            if y + 1 < ny && z + 1 < nz {
                for x in 0..nx - 1 {
                    out[x] = visible(cells[x][0], cells[x][1]) as u8;
                }
            }
        });
    drop(range);
    let visible_cells = shown.par_iter().map(|&v| v as u64).sum();
    // Dilation by one cell along each axis, within the cell grid.
    for axis in 0..3 {
        for_each_line(
            dims,
            axis,
            None,
            &mut shown,
            || (),
            |_, _, line| {
                let cells = line.len() - 1;
                let mut previous = 0;
                for i in 0..cells {
                    let current = line[i];
                    let next = if i + 1 < cells { line[i + 1] } else { 0 };
                    line[i] = previous | current | next;
                    previous = current;
                }
                line[cells] = 0;
            },
        );
    }
    // Distance to the dilated visible cells: they are the targets (label 0).
    let labels: Vec<u32> = shown.par_iter().map(|&v| (v == 0) as u32).collect();
    drop(shown);
    let distance2 = squared_distance_to_other_label(dims, &labels, false);
    drop(labels);
    let cap = (1u32 << bits) - 1;
    let mut values = vec![0u8; distance2.len()];
    values
        .par_chunks_mut(nx)
        .zip(distance2.par_chunks(nx))
        .enumerate()
        .for_each(|(row, (out, d2))| {
            let (y, z) = (row % ny, row / ny);
            if y + 1 < ny && z + 1 < nz {
                for x in 0..nx - 1 {
                    out[x] = if d2[x] == UNREACHABLE {
                        cap
                    } else {
                        (isqrt(d2[x] as u64) as u32).min(cap)
                    } as u8;
                }
            }
        });
    let saturated_cells = values
        .par_chunks(nx)
        .enumerate()
        .map(|(row, line)| {
            let (y, z) = (row % ny, row / ny);
            if y + 1 < ny && z + 1 < nz {
                line[..nx - 1].iter().filter(|&&v| v as u32 == cap).count() as u64
            } else {
                0
            }
        })
        .sum();
    Ok(DistanceVolume {
        dims,
        bits,
        values,
        visible_cells,
        saturated_cells,
        elapsed: started.elapsed(),
    })
}

/// Cells a brute-force check accepts at most.
pub const VERIFY_MAX_CELLS: usize = 1 << 15;

/// Checks a distance volume by brute force on a small volume: for every cell b and every
/// visible cell c (visibility recomputed from the voxels), d(b) <= gap(b, c), and d(b) fits
/// the saturation. An error lists the violations.
pub fn verify_distance_volume(
    volume: &Volume,
    distances: &DistanceVolume,
    visible: impl Fn(u16, u16) -> bool,
) -> Result<()> {
    let dims = volume.dims;
    let cell_dims = dims.map(|d| d - 1);
    let cells: usize = cell_dims.iter().product();
    if cells > VERIFY_MAX_CELLS {
        return Err(Error::Invalid(format!(
            "verify_distance_volume: {cells} cells; the brute force checks at most {VERIFY_MAX_CELLS}"
        )));
    }
    if distances.dims != dims {
        return Err(Error::Invalid(
            "verify_distance_volume: the distance volume is of another volume".into(),
        ));
    }
    let cell = |i: usize| {
        [
            i % cell_dims[0],
            i / cell_dims[0] % cell_dims[1],
            i / (cell_dims[0] * cell_dims[1]),
        ]
    };
    let shown: Vec<[usize; 3]> = (0..cells)
        .map(cell)
        .filter(|&c| {
            let (mut lo, mut hi) = (u16::MAX, 0);
            for dz in 0..2 {
                for dy in 0..2 {
                    for dx in 0..2 {
                        let v = volume.get(c[0] + dx, c[1] + dy, c[2] + dz);
                        lo = lo.min(v);
                        hi = hi.max(v);
                    }
                }
            }
            visible(lo, hi)
        })
        .collect();
    let mut violations = Vec::new();
    for b in (0..cells).map(cell) {
        let d = distances.distance(b) as u64;
        if d > distances.saturation() as u64 {
            violations.push(format!("cell {b:?}: {d} exceeds the saturation"));
        }
        for c in &shown {
            let gap2: u64 = (0..3)
                .map(|a| (b[a].abs_diff(c[a]).saturating_sub(1) as u64).pow(2))
                .sum();
            if d * d > gap2 {
                violations.push(format!(
                    "cell {b:?}: distance {d} overestimates: visible cell {c:?} is {:.3} away",
                    (gap2 as f64).sqrt()
                ));
                break;
            }
        }
    }
    if violations.is_empty() {
        Ok(())
    } else {
        Err(Error::Invalid(format!(
            "verify_distance_volume: {} violation(s), first: {}",
            violations.len(),
            violations[..violations.len().min(5)].join("; ")
        )))
    }
}

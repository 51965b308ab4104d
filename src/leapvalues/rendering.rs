//! The leap-value volume a renderer reads: steps 1–4 run for a hardware configuration and a
//! transfer function, reduced to what the ray loop needs (the words, and for homogeneous
//! leaping the density fields as a volume). docs/model.md, "Leap values in the volume".

use std::sync::Arc;
use std::time::Duration;

use super::VolumeWord;
use super::{preprocess, range_from_fraction, LeapValueParams, SegmentationParams, VoxelClass};
use crate::config::{LeapRegions, LeapValuesConfig, VolumeWordConfig};
use crate::error::Result;
use crate::volume::Volume;

/// The words of a volume with leap values, ready for the ray loop.
#[derive(Clone, Debug)]
pub struct LeapValueVolume {
    pub regions: LeapRegions,
    pub layout: VolumeWord,
    pub dims: [usize; 3],
    /// One word per voxel, x fastest.
    pub words: Vec<u32>,
    /// The words' flag and leap fields as the ray loop reads them (see `leap_code`), with the
    /// sampled densities when those fit a byte.
    pub cells: LeapCells,
    /// Homogeneous leaping: the density fields (region voxels hold their region's mean), the
    /// volume the renderer interpolates. None for empty-region leaping (densities unchanged).
    pub densities: Option<Volume>,
    pub stats: LeapValueStats,
}

/// The ray loop's copy of the words' flag and leap fields, one byte per voxel (`leap_code`):
/// the host's cache, not the words, bounds the ray loop's speed, so it reads as few bytes as
/// it can and, where it can, reads them from the cache lines its interpolation reads anyway.
#[derive(Clone, Debug)]
pub enum LeapCells {
    /// Sampled densities of at most 8 bits: one u16 per voxel, the density the renderer
    /// interpolates in the low byte and the leap code in the high byte. The renderer
    /// interpolates these cells instead of the volume (`FixedRenderer`).
    Packed(Arc<[u16]>),
    /// Wider densities: the leap codes alone, one byte per voxel beside the volume.
    Codes(Vec<u8>),
}

/// What preprocessing produced and what it cost.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct LeapValueStats {
    /// Segmentation range in density units.
    pub range: u16,
    /// The guard distance in voxels.
    pub guard_voxels: u32,
    /// Regions kept by the segmentation.
    pub regions: usize,
    /// Regions whose voxels carry leap information: for homogeneous leaping those with at
    /// least one leap voxel (the others keep their densities); for empty-region leaping those
    /// that classify to zero opacity.
    pub leap_regions: usize,
    /// Voxels whose word is flagged.
    pub leap_voxels: u64,
    /// Mean leap value over the flagged voxels, in sample steps.
    pub mean_leap: f64,
    /// Steps 1–4 and the reduction, in seconds.
    pub preprocessing_seconds: f64,
}

impl LeapValueVolume {
    /// Runs steps 1–4 on `volume` for a run with sample spacing `spacing`. `visible(lo, hi)` is
    /// the transfer function's conservative test over a value range (the occupancy map's); it
    /// decides which regions are empty.
    pub fn build(
        volume: &Volume,
        config: &LeapValuesConfig,
        word: &VolumeWordConfig,
        spacing: f32,
        visible: impl Fn(u16, u16) -> bool,
    ) -> Result<LeapValueVolume> {
        let layout = VolumeWord::new(word.word_bits, word.density_bits, word.leap_bits)?;
        let range = range_from_fraction(config.range_fraction, volume)?;
        let max_spacing = if config.max_spacing == 0.0 {
            spacing
        } else {
            config.max_spacing
        };
        let params = LeapValueParams {
            segmentation: SegmentationParams {
                range,
                min_region_size: config.min_region_size,
            },
            max_spacing,
            spacing,
            layout,
        };
        let started = std::time::Instant::now();
        let pre = preprocess(volume, &params)?;
        let regions = pre.segmentation.regions.len();
        let (words, densities, leap_regions) = match config.regions {
            LeapRegions::Homogeneous => {
                // Only regions with leap voxels are replaced by their means: a region too thin
                // for any leap voxel (a partial-volume shell) gains no leap from it and would
                // only turn a smooth ramp into a staircase, so its voxels keep their densities.
                let mut leaps_in = vec![false; regions];
                for (i, class) in pre.classification.classes.iter().enumerate() {
                    if *class == VoxelClass::Leap {
                        leaps_in[pre.segmentation.labels[i] as usize - 1] = true;
                    }
                }
                let mut words = pre.encoded.words;
                for (i, word) in words.iter_mut().enumerate() {
                    let label = pre.segmentation.labels[i] as usize;
                    if label >= 1 && !leaps_in[label - 1] {
                        *word = layout.encode(volume.data[i], None)?;
                    }
                }
                let encoded = super::EncodedVolume {
                    layout,
                    dims: volume.dims,
                    words,
                    elapsed: Duration::ZERO,
                };
                let densities = encoded.density_volume(volume)?;
                let used = leaps_in.iter().filter(|&&l| l).count();
                (encoded.words, Some(densities), used)
            }
            LeapRegions::Empty => {
                // Only regions whose whole range is invisible keep their leap voxels, and every
                // voxel keeps its own density: leaps pass only zero-opacity samples.
                let empty: Vec<bool> = pre
                    .segmentation
                    .regions
                    .iter()
                    .map(|r| !visible(r.min, r.max))
                    .collect();
                let mut words = Vec::with_capacity(volume.data.len());
                for (i, &density) in volume.data.iter().enumerate() {
                    let label = pre.segmentation.labels[i] as usize;
                    let leap = (pre.classification.classes[i] == VoxelClass::Leap
                        && label >= 1
                        && empty[label - 1])
                        .then(|| pre.leap_values.values[i]);
                    words.push(layout.encode(density, leap)?);
                }
                (words, None, empty.iter().filter(|&&e| e).count())
            }
        };
        let (mut flagged, mut sum) = (0u64, 0u64);
        for &w in &words {
            if let Some(l) = layout.decode(w).leap {
                flagged += 1;
                sum += l as u64;
            }
        }
        let codes = words.iter().map(|&w| leap_code(layout.decode(w).leap));
        let sampled = densities.as_ref().unwrap_or(volume);
        let cells = if sampled.max_value() <= u8::MAX as u16 {
            LeapCells::Packed(
                codes
                    .zip(&sampled.data)
                    .map(|(code, &density)| (code as u16) << 8 | density)
                    .collect(),
            )
        } else {
            LeapCells::Codes(codes.collect())
        };
        let elapsed = started.elapsed();
        Ok(LeapValueVolume {
            regions: config.regions,
            layout,
            dims: volume.dims,
            words,
            cells,
            densities,
            stats: LeapValueStats {
                range,
                guard_voxels: pre.classification.guard.voxels(),
                regions,
                leap_regions,
                leap_voxels: flagged,
                mean_leap: sum as f64 / flagged.max(1) as f64,
                preprocessing_seconds: Duration::as_secs_f64(&elapsed),
            },
        })
    }

    /// The leap field of voxel `index`: None when its word is not flagged, else its leap value.
    #[inline(always)]
    pub fn leap(&self, index: usize) -> Option<u32> {
        match self.code(index) {
            UNFLAGGED => None,
            LONG_LEAP => self.layout.decode(self.words[index]).leap,
            code => Some(code as u32 - 1),
        }
    }

    /// The positions a ray advances after sampling voxel `index`'s word under empty-region
    /// leaping: its leap value L when flagged (at least 1), else 1. Arithmetic on the leap code
    /// rather than a branch on the flag: whether a voxel leaps is the data's pattern, which a
    /// branch predictor cannot learn, and the ray's next address hangs on it.
    #[inline(always)]
    pub fn empty_region_advance(&self, index: usize) -> u32 {
        self.empty_region_advance_of_code(self.code(index), index)
    }

    /// `empty_region_advance` of voxel `index` whose leap code (`leap_code`) the caller has
    /// read already (from the packed cells it holds).
    #[inline(always)]
    pub fn empty_region_advance_of_code(&self, code: u8, index: usize) -> u32 {
        if code == LONG_LEAP {
            return self.leap(index).unwrap_or(1).max(1);
        }
        // 0 (unflagged) and 1 (L = 0) give 1; L + 1 gives L.
        (code as u32).saturating_sub(1).max(1)
    }

    /// Voxel `index`'s leap code (`leap_code`).
    #[inline(always)]
    fn code(&self, index: usize) -> u8 {
        match &self.cells {
            LeapCells::Packed(cells) => (cells[index] >> 8) as u8,
            LeapCells::Codes(codes) => codes[index],
        }
    }

    /// The packed cells (density in the low byte, leap code in the high byte), when the
    /// sampled densities fit a byte.
    #[inline(always)]
    pub fn packed_cells(&self) -> Option<&Arc<[u16]>> {
        match &self.cells {
            LeapCells::Packed(cells) => Some(cells),
            LeapCells::Codes(_) => None,
        }
    }

    /// The index of the voxel nearest to a position given per axis in voxels (already
    /// rounded), x fastest.
    #[inline(always)]
    pub fn index(&self, voxel: [usize; 3]) -> usize {
        voxel[0] + self.dims[0] * (voxel[1] + self.dims[1] * voxel[2])
    }
}

/// Leap code (`LeapCells`) of an unflagged word.
const UNFLAGGED: u8 = 0;
/// Leap code of a flagged word whose leap value does not fit a byte (read the word).
const LONG_LEAP: u8 = u8::MAX;

/// A word's leap field as one byte: 0 unflagged, L + 1 for L < 254, else `LONG_LEAP`.
fn leap_code(leap: Option<u32>) -> u8 {
    match leap {
        None => UNFLAGGED,
        Some(l) if l + 1 < LONG_LEAP as u32 => (l + 1) as u8,
        Some(_) => LONG_LEAP,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `leap` reads back every leap value a word can hold, through the byte codes and through
    /// the word for the long ones.
    #[test]
    fn leap_codes_give_back_every_leap_value() {
        let layout = VolumeWord::new(32, 16, 15).unwrap();
        let leaps = [
            None,
            Some(0),
            Some(1),
            Some(252),
            Some(253),
            Some(254),
            Some(32767),
        ];
        let words: Vec<u32> = leaps
            .iter()
            .map(|&l| layout.encode(7, l).unwrap())
            .collect();
        let volume = LeapValueVolume {
            regions: LeapRegions::Empty,
            layout,
            dims: [leaps.len(), 1, 1],
            cells: LeapCells::Codes(
                words
                    .iter()
                    .map(|&w| leap_code(layout.decode(w).leap))
                    .collect(),
            ),
            words,
            densities: None,
            stats: LeapValueStats::default(),
        };
        for (i, &l) in leaps.iter().enumerate() {
            assert_eq!(volume.leap(i), l, "voxel {i}");
        }
        assert!(matches!(&volume.cells, LeapCells::Codes(c) if c[5] == LONG_LEAP));
        // The same words packed beside 8-bit densities read back the same.
        let packed = LeapValueVolume {
            cells: LeapCells::Packed(
                volume
                    .words
                    .iter()
                    .map(|&w| (leap_code(layout.decode(w).leap) as u16) << 8 | 7)
                    .collect(),
            ),
            ..volume.clone()
        };
        for (i, &l) in leaps.iter().enumerate() {
            assert_eq!(packed.leap(i), l, "packed voxel {i}");
            let advance = l.unwrap_or(1).max(1);
            assert_eq!(volume.empty_region_advance(i), advance, "voxel {i}");
            assert_eq!(packed.empty_region_advance(i), advance, "packed voxel {i}");
        }
    }
}

//! The leap-value volume a renderer reads: steps 1–4 run for a hardware configuration and a
//! transfer function, reduced to what the ray loop needs (the words, and for homogeneous
//! leaping the density fields as a volume). docs/model.md, "Leap values in the volume".

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
    /// The words' flag and leap fields as the ray loop reads them, one byte per voxel (see
    /// `leap_code`): a quarter of the words' footprint, so that the volume and its leap fields
    /// stay in the host's cache (the ray loop's speed is bound by cache misses).
    pub leap_codes: Vec<u8>,
    /// Homogeneous leaping: the density fields (region voxels hold their region's mean), the
    /// volume the renderer interpolates. None for empty-region leaping (densities unchanged).
    pub densities: Option<Volume>,
    pub stats: LeapValueStats,
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
        let leap_codes = words
            .iter()
            .map(|&w| leap_code(layout.decode(w).leap))
            .collect();
        let elapsed = started.elapsed();
        Ok(LeapValueVolume {
            regions: config.regions,
            layout,
            dims: volume.dims,
            words,
            leap_codes,
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
        match self.leap_codes[index] {
            UNFLAGGED => None,
            LONG_LEAP => self.layout.decode(self.words[index]).leap,
            code => Some(code as u32 - 1),
        }
    }

    /// The index of the voxel nearest to a position given per axis in voxels (already
    /// rounded), x fastest.
    #[inline(always)]
    pub fn index(&self, voxel: [usize; 3]) -> usize {
        voxel[0] + self.dims[0] * (voxel[1] + self.dims[1] * voxel[2])
    }
}

/// `leap_codes` entry of an unflagged word.
const UNFLAGGED: u8 = 0;
/// `leap_codes` entry of a flagged word whose leap value does not fit a byte (read the word).
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
            leap_codes: words
                .iter()
                .map(|&w| leap_code(layout.decode(w).leap))
                .collect(),
            words,
            densities: None,
            stats: LeapValueStats::default(),
        };
        for (i, &l) in leaps.iter().enumerate() {
            assert_eq!(volume.leap(i), l, "voxel {i}");
        }
        assert_eq!(volume.leap_codes[5], LONG_LEAP);
    }
}

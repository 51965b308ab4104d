//! Step 4: the voxel word that carries density and leap value (Frey & Ertl store `d | 0x8000`
//! in 16-bit voxels; VIZARD II has up to 32 bits per voxel).
//!
//! Layout of a `word_bits`-wide word, most significant bit first:
//!
//! ```text
//! | flag (1) | leap value (leap_bits) | unused (zero) | density (density_bits) |
//!   bit W-1    bits W-1-L .. W-2                        bits 0 .. D-1
//! ```
//!
//! The flag (the word's MSB, as in the paper) marks a leap voxel. Every word keeps a density
//! field: non-region voxels their own value, guards **and leap voxels** their region's mean (the
//! paper's 16-bit word has no room for it; a 32-bit word has, and a density in every word means
//! that no read of any word is undefined). Non-leap words have flag 0 and leap field 0.

use std::time::{Duration, Instant};

use super::classify::{Classification, VoxelClass};
use super::leap::LeapValues;
use super::segment::Segmentation;
use crate::error::{Error, Result};
use crate::volume::Volume;

/// Where layout errors say they come from.
const LAYOUT_SOURCE: &str = "leap-value word layout";

/// Widths of the voxel word's fields. Build it with `new` (validated) or take the default
/// (32-bit word, 16-bit density, 15-bit leap value).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct VolumeWord {
    word_bits: u32,
    density_bits: u32,
    leap_bits: u32,
}

impl Default for VolumeWord {
    fn default() -> Self {
        VolumeWord {
            word_bits: 32,
            density_bits: 16,
            leap_bits: 15,
        }
    }
}

/// A word taken apart.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DecodedWord {
    pub density: u16,
    /// The leap value in sample steps when the flag is set.
    pub leap: Option<u32>,
}

impl VolumeWord {
    /// Validates the layout: word 2..=32 bits, density 1..=16 bits, leap >= 1 bit, and
    /// density + flag + leap <= word. Errors name the field.
    pub fn new(word_bits: u32, density_bits: u32, leap_bits: u32) -> Result<VolumeWord> {
        let field = |name: &str| format!("volume_word.{name}");
        if !(2..=32).contains(&word_bits) {
            return Err(Error::config(
                LAYOUT_SOURCE,
                field("word_bits"),
                format!("{word_bits} is out of range: allowed 2..=32"),
            ));
        }
        if !(1..=16).contains(&density_bits) {
            return Err(Error::config(
                LAYOUT_SOURCE,
                field("density_bits"),
                format!("{density_bits} is out of range: allowed 1..=16"),
            ));
        }
        if leap_bits == 0 {
            return Err(Error::config(
                LAYOUT_SOURCE,
                field("leap_bits"),
                "must be at least 1: a leap voxel needs a leap value",
            ));
        }
        if density_bits as u64 + 1 + leap_bits as u64 > word_bits as u64 {
            return Err(Error::config(
                LAYOUT_SOURCE,
                field("leap_bits"),
                format!(
                    "density ({density_bits}) + flag (1) + leap ({leap_bits}) = {} bits do not fit \
                     the {word_bits}-bit word; at most {} leap bits fit",
                    density_bits as u64 + 1 + leap_bits as u64,
                    word_bits.saturating_sub(density_bits + 1)
                ),
            ));
        }
        Ok(VolumeWord {
            word_bits,
            density_bits,
            leap_bits,
        })
    }

    pub fn word_bits(&self) -> u32 {
        self.word_bits
    }
    pub fn density_bits(&self) -> u32 {
        self.density_bits
    }
    pub fn leap_bits(&self) -> u32 {
        self.leap_bits
    }

    /// Bit position of the leap flag (the MSB).
    pub fn flag_bit(&self) -> u32 {
        self.word_bits - 1
    }

    /// Largest leap value the leap field holds.
    pub fn max_leap(&self) -> u32 {
        ((1u64 << self.leap_bits) - 1) as u32
    }

    /// Largest density the density field holds.
    pub fn max_density(&self) -> u16 {
        ((1u32 << self.density_bits) - 1) as u16
    }

    fn leap_shift(&self) -> u32 {
        self.word_bits - 1 - self.leap_bits
    }

    /// An error when the density field cannot hold the volume's voxel type.
    pub fn check_volume(&self, volume: &Volume) -> Result<()> {
        if volume.bits as u32 > self.density_bits {
            return Err(Error::config(
                LAYOUT_SOURCE,
                "volume_word.density_bits",
                format!(
                    "{} bits cannot hold the {}-bit volume `{}`",
                    self.density_bits, volume.bits, volume.name
                ),
            ));
        }
        Ok(())
    }

    /// Encodes one word: a density word (`leap` None) or a leap word. An error when a value
    /// does not fit its field.
    pub fn encode(&self, density: u16, leap: Option<u32>) -> Result<u32> {
        if density > self.max_density() {
            return Err(Error::Invalid(format!(
                "density {density} does not fit the {}-bit density field",
                self.density_bits
            )));
        }
        match leap {
            None => Ok(density as u32),
            Some(l) if l > self.max_leap() => Err(Error::Invalid(format!(
                "leap value {l} does not fit the {}-bit leap field",
                self.leap_bits
            ))),
            Some(l) => Ok(1 << self.flag_bit() | l << self.leap_shift() | density as u32),
        }
    }

    /// Takes a word apart (the inverse of `encode`; unused bits are ignored).
    #[inline]
    pub fn decode(&self, word: u32) -> DecodedWord {
        let density = (word & self.max_density() as u32) as u16;
        let leap =
            (word >> self.flag_bit() & 1 == 1).then(|| word >> self.leap_shift() & self.max_leap());
        DecodedWord { density, leap }
    }
}

/// The volume with leap values integrated: one word per voxel, x fastest.
#[derive(Clone, Debug)]
pub struct EncodedVolume {
    pub layout: VolumeWord,
    pub dims: [usize; 3],
    pub words: Vec<u32>,
    /// Wall time of `encode_volume`.
    pub elapsed: Duration,
}

impl EncodedVolume {
    pub fn decode(&self, index: usize) -> DecodedWord {
        self.layout.decode(self.words[index])
    }

    /// The density fields as a volume (what a renderer that ignores the flags would see):
    /// region voxels read their region's mean.
    pub fn density_volume(&self, original: &Volume) -> Result<Volume> {
        let data = self
            .words
            .iter()
            .map(|&w| self.layout.decode(w).density)
            .collect();
        Volume::new(
            format!("{}+leap-values", original.name),
            self.dims,
            original.spacing,
            original.bits,
            data,
        )
    }
}

/// Step 4: writes every voxel's word: non-region voxels their density, guards their region's
/// mean, leap voxels flag + leap value + their region's mean. Errors when the volume's voxel
/// type does not fit the density field or the inputs belong to different volumes or layouts.
pub fn encode_volume(
    volume: &Volume,
    segmentation: &Segmentation,
    classification: &Classification,
    leap_values: &LeapValues,
    layout: VolumeWord,
) -> Result<EncodedVolume> {
    layout.check_volume(volume)?;
    let n = volume.data.len();
    if segmentation.dims != volume.dims
        || classification.classes.len() != n
        || leap_values.values.len() != n
    {
        return Err(Error::Invalid(format!(
            "encode_volume: the segmentation, classification and leap values are not of volume \
             `{}` ({:?})",
            volume.name, volume.dims
        )));
    }
    if leap_values.leap_bits != layout.leap_bits {
        return Err(Error::Invalid(format!(
            "encode_volume: leap values were quantised to {} bits, the layout has {}",
            leap_values.leap_bits, layout.leap_bits
        )));
    }
    let started = Instant::now();
    let means: Vec<u16> = segmentation.regions.iter().map(|r| r.mean).collect();
    let mut words = Vec::with_capacity(n);
    for i in 0..n {
        let label = segmentation.labels[i];
        let word = match classification.classes[i] {
            VoxelClass::NoRegion => layout.encode(volume.data[i], None)?,
            class => {
                let mean = *(label as usize)
                    .checked_sub(1)
                    .and_then(|k| means.get(k))
                    .ok_or_else(|| {
                        Error::Invalid(format!(
                            "encode_volume: voxel {i} is classified {class:?} but has region \
                             label {label}"
                        ))
                    })?;
                match class {
                    VoxelClass::Leap => layout.encode(mean, Some(leap_values.values[i]))?,
                    _ => layout.encode(mean, None)?,
                }
            }
        };
        words.push(word);
    }
    Ok(EncodedVolume {
        layout,
        dims: volume.dims,
        words,
        elapsed: started.elapsed(),
    })
}

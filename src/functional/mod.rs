//! The functional fixed-point model: the hardware's arithmetic, untimed. It is the golden model
//! of the cycle-accurate pipeline, which calls these same functions, so that bit-identical images
//! follow from the design rather than from coincidence.
//!
//! - `setup`: per-ray fixed-point start position, increment, reciprocals and sample count;
//! - `arith`: trilinear interpolation, classification table and compositing in fixed point;
//! - `leaping`: the space-skipping strategies (none, occupancy map, two-level hierarchy);
//! - `renderer`: a frame, with steps counted per ray (the published cost: 12.5 ns per step).

pub mod arith;
pub mod leaping;
pub mod renderer;
pub mod setup;

use crate::config::HardwareConfig;
use crate::skip::SkipWidths;

/// The bit widths the functional model uses, taken once from the configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Widths {
    pub position_int_bits: u32,
    pub position_frac_bits: u32,
    pub increment_frac_bits: u32,
    pub reciprocal_bits: u32,
    pub distance_frac_bits: u32,
    pub weight_bits: u32,
    pub lut_bits: u32,
    pub accumulator_bits: u32,
}

impl Widths {
    pub fn from_config(config: &HardwareConfig) -> Widths {
        Widths {
            position_int_bits: config.ray.position_int_bits,
            position_frac_bits: config.ray.position_frac_bits,
            increment_frac_bits: config.ray.increment_frac_bits,
            reciprocal_bits: config.skip.reciprocal_bits,
            distance_frac_bits: config.skip.distance_frac_bits,
            weight_bits: config.interpolation.weight_bits,
            lut_bits: config.classification.lut_bits,
            accumulator_bits: config.compositing.accumulator_bits,
        }
    }

    pub fn skip(&self) -> SkipWidths {
        SkipWidths {
            pos_frac_bits: self.position_frac_bits,
            inc_frac_bits: self.increment_frac_bits,
            reciprocal_bits: self.reciprocal_bits,
            distance_frac_bits: self.distance_frac_bits,
        }
    }
}

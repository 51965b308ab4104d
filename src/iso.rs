//! First-hit iso-surface mode with hitpoint refinement (`[iso]`, docs/model.md "Iso-surface
//! mode"): what every model shares. A ray stops at its first sample whose interpolated density
//! is at least the iso value; when the sample before it is a position of the same ray, the hit
//! is refined by bisection between the two (`refinement_steps` times) and the surface colour is
//! shaded at the refined position, composited opaque.

use crate::config::HardwareConfig;
use crate::error::{Error, Result};
use crate::volume::Volume;

/// The iso mode of a run, resolved against its dataset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IsoSurface {
    /// The iso value in density units (`iso.value`, or half the dataset's largest density).
    pub value: f64,
    pub refinement_steps: u32,
    /// Surface colour, RGB 0..=1.
    pub colour: [f32; 3],
}

impl IsoSurface {
    /// The configuration's iso mode on `volume`; None when off. An error naming `iso.value`
    /// when the value is not inside the dataset's densities (smallest, largest].
    pub fn from_config(config: &HardwareConfig, volume: &Volume) -> Result<Option<IsoSurface>> {
        let iso = &config.iso;
        if !iso.enabled {
            return Ok(None);
        }
        let (lo, hi) = volume
            .data
            .iter()
            .fold((u16::MAX, 0u16), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        let value = if iso.value == 0.0 {
            hi as f64 / 2.0
        } else {
            iso.value
        };
        if !(value > lo as f64 && value <= hi as f64) {
            return Err(Error::config(
                "hardware configuration",
                "iso.value",
                format!(
                    "{value} is outside the densities of dataset `{}`: allowed ({lo}, {hi}], \
                     or 0 for half the largest density",
                    volume.name
                ),
            ));
        }
        Ok(Some(IsoSurface {
            value,
            refinement_steps: iso.refinement_steps,
            colour: iso.colour,
        }))
    }

    /// The smallest integer density at or above the iso value: the first opaque entry of the
    /// iso classification table (the leaping structures' emptiness test).
    pub fn first_opaque(&self) -> usize {
        self.value.ceil() as usize
    }
}

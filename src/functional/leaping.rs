//! Space-skipping strategies. Each decides, at a ray's current position, whether the ray takes
//! its sample or leaps n >= 1 steps without a memory request. The functional renderer and the
//! cycle model's skip unit both ask the same strategy, so adding a strategy (bounding bricks,
//! leap values in the volume...) touches neither.

use super::setup::FixedRay;
use crate::occupancy::OccupancyMap;
use crate::skip::{leap_steps, SkipWidths};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    /// Take the sample at this position (send its memory request).
    Sample,
    /// Take no sample; advance this many steps (>= 1).
    Leap(u64),
}

pub trait SpaceSkipper: Sync {
    fn decide(&self, pos: [i64; 3], ray: &FixedRay) -> Action;
}

/// Every position is sampled.
pub struct NoSkipping;

impl SpaceSkipper for NoSkipping {
    #[inline(always)]
    fn decide(&self, _: [i64; 3], _: &FixedRay) -> Action {
        Action::Sample
    }
}

/// Occupancy-map space leaping (Meißner et al. 2001), optionally with the two-level hierarchy:
/// an empty sub-cube is left in one leap; when its whole 2×2×2 group is empty, the group is.
pub struct OccupancyLeaping<'a> {
    map: &'a OccupancyMap,
    hierarchy: bool,
    widths: SkipWidths,
    /// Position bits below the sub-cube address: log2(s) + position fraction bits.
    shift: u32,
}

impl<'a> OccupancyLeaping<'a> {
    pub fn new(map: &'a OccupancyMap, hierarchy: bool, widths: SkipWidths) -> Self {
        OccupancyLeaping {
            map,
            hierarchy,
            widths,
            shift: map.cube_log2 + widths.pos_frac_bits,
        }
    }
}

impl SpaceSkipper for OccupancyLeaping<'_> {
    #[inline(always)]
    fn decide(&self, pos: [i64; 3], ray: &FixedRay) -> Action {
        let cube = pos.map(|p| (p >> self.shift) as usize);
        if self.map.occupied(cube) {
            return Action::Sample;
        }
        let level = if self.hierarchy && !self.map.group_occupied(cube) {
            self.map.cube_log2 + 1
        } else {
            self.map.cube_log2
        };
        // A ray whose increment rounded to zero on every axis cannot leap: one step at a time.
        Action::Leap(leap_steps(pos, ray.step, &ray.reciprocals, level, &self.widths).unwrap_or(1))
    }
}

/// The strategy a hardware configuration selects, as one type (so callers need no dispatch of
/// their own). New strategies are added here and in `FixedRenderer::skipper`.
pub enum ConfiguredSkipper<'a> {
    None(NoSkipping),
    Occupancy(OccupancyLeaping<'a>),
}

impl SpaceSkipper for ConfiguredSkipper<'_> {
    #[inline(always)]
    fn decide(&self, pos: [i64; 3], ray: &FixedRay) -> Action {
        match self {
            ConfiguredSkipper::None(s) => s.decide(pos, ray),
            ConfiguredSkipper::Occupancy(s) => s.decide(pos, ray),
        }
    }
}

//! Space-skipping strategies. Each decides, at a ray's current position, what the ray's next
//! issue slot does: whether it takes the sample there (a memory request) and how many positions
//! it then advances. The functional renderer and the cycle model's issue stage both ask the same
//! strategy and consume its `Step` the same way (`Step::within`, `Step::record`), so adding a
//! strategy (bounding bricks, leap values in the volume...) touches neither.

use super::setup::FixedRay;
use crate::config::SkipPolicy;
use crate::leapvalues::distance::{distance_steps, DistanceVolume};
use crate::occupancy::OccupancyMap;
use crate::render::RayRecord;
use crate::skip::{leap_steps, SkipWidths};

/// One issue slot of a ray: sample or not, then advance. Every step costs one slot, whatever
/// it does; a leap that follows a sample costs no extra slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Step {
    /// Take the sample at this position (memory request, classification, compositing).
    pub sample: bool,
    /// Positions to advance (>= 1): the ray's next position is P + advance·V.
    pub advance: u64,
}

impl Step {
    /// An ordinary sample: take it, then the next position.
    pub const SAMPLE: Step = Step {
        sample: true,
        advance: 1,
    };

    /// The step at a position in an empty sub-cube whose leap is `n` >= 1 positions: the skip
    /// policy says whether the position is sampled first. With sample-then-leap and n = 1 this
    /// is an ordinary sample.
    #[inline(always)]
    pub fn in_empty_subcube(policy: SkipPolicy, n: u64) -> Step {
        Step {
            sample: policy == SkipPolicy::SampleThenLeap,
            advance: n.max(1),
        }
    }

    /// The step limited to the ray's `remaining` (>= 1) positions: a leap past the ray's last
    /// position simply ends the ray.
    #[inline(always)]
    pub fn within(self, remaining: u64) -> Step {
        Step {
            advance: self.advance.min(remaining),
            ..self
        }
    }

    /// Positions passed over without a sample.
    #[inline(always)]
    pub fn skipped(self) -> u64 {
        self.advance - self.sample as u64
    }

    /// A sample followed by a leap (sample-then-leap in an empty sub-cube).
    #[inline(always)]
    pub fn is_leap_sample(self) -> bool {
        self.sample && self.advance > 1
    }

    /// Counts the step in a ray's record: a sample or a leap (a slot without a sample), the
    /// positions passed over, and whether it was a leap sample. Both models count through here.
    #[inline(always)]
    pub fn record(self, r: &mut RayRecord) {
        r.samples += self.sample as u32;
        r.leaps += !self.sample as u32;
        r.skipped += self.skipped() as u32;
        r.leap_samples += self.is_leap_sample() as u32;
    }
}

pub trait SpaceSkipper: Sync {
    /// The step at position `pos` of `ray` (not yet limited to the ray's remaining positions).
    fn decide(&self, pos: [i64; 3], ray: &FixedRay) -> Step;

    /// The voxel whose word in volume memory the decision at `pos` reads, when the strategy's
    /// structure lives in volume memory (the distance volume); None when it is on chip. The
    /// cycle model reads that word before the ray at `pos` may issue.
    #[inline(always)]
    fn memory_word(&self, _pos: [i64; 3]) -> Option<[usize; 3]> {
        None
    }
}

/// Every position is sampled.
pub struct NoSkipping;

impl SpaceSkipper for NoSkipping {
    #[inline(always)]
    fn decide(&self, _: [i64; 3], _: &FixedRay) -> Step {
        Step::SAMPLE
    }
}

/// Occupancy-map space leaping (Meißner et al. 2001), optionally with the two-level hierarchy:
/// an empty sub-cube is left in one leap; when its whole 2×2×2 group is empty, the group is.
/// `policy` says whether the position in the empty sub-cube is sampled before the leap.
pub struct OccupancyLeaping<'a> {
    map: &'a OccupancyMap,
    hierarchy: bool,
    policy: SkipPolicy,
    widths: SkipWidths,
    /// Position bits below the sub-cube address: log2(s) + position fraction bits.
    shift: u32,
}

impl<'a> OccupancyLeaping<'a> {
    pub fn new(
        map: &'a OccupancyMap,
        hierarchy: bool,
        policy: SkipPolicy,
        widths: SkipWidths,
    ) -> Self {
        OccupancyLeaping {
            map,
            hierarchy,
            policy,
            widths,
            shift: map.cube_log2 + widths.pos_frac_bits,
        }
    }
}

impl SpaceSkipper for OccupancyLeaping<'_> {
    #[inline(always)]
    fn decide(&self, pos: [i64; 3], ray: &FixedRay) -> Step {
        let cube = pos.map(|p| (p >> self.shift) as usize);
        if self.map.occupied(cube) {
            return Step::SAMPLE;
        }
        let level = if self.hierarchy && !self.map.group_occupied(cube) {
            self.map.cube_log2 + 1
        } else {
            self.map.cube_log2
        };
        // A ray whose increment rounded to zero on every axis cannot leap: one step at a time.
        let n = leap_steps(pos, ray.step, &ray.reciprocals, level, &self.widths).unwrap_or(1);
        Step::in_empty_subcube(self.policy, n)
    }
}

/// Distance-volume leaping (docs/leapvalues.md, step 5; docs/model.md): at a position whose
/// sample cell has base voxel b, the stored distance d(b) allows n = floor(d / S) steps; n >= 1
/// leaps n positions (sampling the position first under sample-then-leap), n = 0 samples.
/// floor(d / S) is a table of 2^bits entries per spacing, as the hardware would hold it.
pub struct DistanceLeaping<'a> {
    volume: &'a DistanceVolume,
    policy: SkipPolicy,
    /// floor(d / S) per stored distance d.
    steps: Vec<u64>,
    /// Position fraction bits (the base voxel is the position's integer part).
    pos_frac_bits: u32,
}

impl<'a> DistanceLeaping<'a> {
    /// `spacing` is the sample spacing S (an upper bound of |V| up to the increment's rounding,
    /// which the rule's one-step margin covers: docs/leapvalues.md).
    pub fn new(
        volume: &'a DistanceVolume,
        spacing: f32,
        policy: SkipPolicy,
        pos_frac_bits: u32,
    ) -> Self {
        DistanceLeaping {
            volume,
            policy,
            steps: (0..=volume.saturation())
                .map(|d| distance_steps(d, spacing))
                .collect(),
            pos_frac_bits,
        }
    }

    /// The base voxel of the cell a sample at `pos` interpolates in (as
    /// `FixedRenderer::base_voxel`).
    #[inline(always)]
    pub fn base_voxel(&self, pos: [i64; 3]) -> [usize; 3] {
        let d = self.volume.dims;
        [0, 1, 2].map(|a| ((pos[a] >> self.pos_frac_bits) as usize).min(d[a] - 2))
    }
}

impl SpaceSkipper for DistanceLeaping<'_> {
    #[inline(always)]
    fn decide(&self, pos: [i64; 3], _: &FixedRay) -> Step {
        let n = self.steps[self.volume.distance(self.base_voxel(pos)) as usize];
        if n == 0 {
            Step::SAMPLE
        } else {
            Step::in_empty_subcube(self.policy, n)
        }
    }

    #[inline(always)]
    fn memory_word(&self, pos: [i64; 3]) -> Option<[usize; 3]> {
        Some(self.base_voxel(pos))
    }
}

/// The strategy a hardware configuration selects, as one type (so callers need no dispatch of
/// their own). New strategies are added here and in `FixedRenderer::skipper`.
pub enum ConfiguredSkipper<'a> {
    None(NoSkipping),
    Occupancy(OccupancyLeaping<'a>),
    Distance(DistanceLeaping<'a>),
}

impl SpaceSkipper for ConfiguredSkipper<'_> {
    #[inline(always)]
    fn decide(&self, pos: [i64; 3], ray: &FixedRay) -> Step {
        match self {
            ConfiguredSkipper::None(s) => s.decide(pos, ray),
            ConfiguredSkipper::Occupancy(s) => s.decide(pos, ray),
            ConfiguredSkipper::Distance(s) => s.decide(pos, ray),
        }
    }

    #[inline(always)]
    fn memory_word(&self, pos: [i64; 3]) -> Option<[usize; 3]> {
        match self {
            ConfiguredSkipper::Distance(s) => s.memory_word(pos),
            _ => None,
        }
    }
}

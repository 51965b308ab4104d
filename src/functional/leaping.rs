//! Space-skipping strategies. Each decides, at a ray's current position, what the ray's next
//! issue slot does: whether it takes the sample there (a memory request) and how many positions
//! it then advances. The functional renderer and the cycle model's issue stage both ask the same
//! strategy and consume its `Step` the same way (`Step::within`, `Step::record`), so adding a
//! strategy (bounding bricks, leap values in the volume...) touches neither.

use super::setup::FixedRay;
use crate::config::SkipPolicy;
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

/// The strategy a hardware configuration selects, as one type (so callers need no dispatch of
/// their own). New strategies are added here and in `FixedRenderer::skipper`.
pub enum ConfiguredSkipper<'a> {
    None(NoSkipping),
    Occupancy(OccupancyLeaping<'a>),
}

impl SpaceSkipper for ConfiguredSkipper<'_> {
    #[inline(always)]
    fn decide(&self, pos: [i64; 3], ray: &FixedRay) -> Step {
        match self {
            ConfiguredSkipper::None(s) => s.decide(pos, ray),
            ConfiguredSkipper::Occupancy(s) => s.decide(pos, ray),
        }
    }
}

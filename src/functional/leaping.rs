//! Space-skipping strategies. Each decides, at a ray's current position, what the ray's next
//! issue slot does: whether it takes the sample there (a memory request) and how many positions
//! it then advances. The functional renderer and the cycle model's issue stage both ask the same
//! strategy and consume its `Step` the same way (`Step::within`, `Step::record`), so adding a
//! strategy (bounding bricks, leap values in the volume...) touches neither.

use super::setup::FixedRay;
use crate::config::LeapRegions;
use crate::config::SkipPolicy;
use crate::leapvalues::distance::{distance_steps, DistanceVolume};
use crate::leapvalues::LeapValueVolume;
use crate::occupancy::OccupancyMap;
use crate::render::RayRecord;
use crate::skip::{leap_steps, SkipWidths};

/// What a sample composites.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SampleValue {
    /// The density interpolated trilinearly at the sample's position.
    #[default]
    Interpolated,
    /// A region's value (nearest-neighbour or a leap over a homogeneous region), composited
    /// over `steps` sample positions: opacity 1 - (1 - a)^steps (leap values, homogeneous).
    Region { density: u16, steps: u32 },
    /// Iso mode: a sample read only to test it against the iso value (a marching sample or a
    /// refinement sample); it composites nothing.
    Probe,
    /// Iso mode: the hit, composited opaque in the iso colour, shaded at the (refined)
    /// surface position (`SkipState::surface`, `SkipState::sample_position`).
    Surface,
}

impl SampleValue {
    /// Sample positions the value stands for.
    #[inline(always)]
    pub fn steps(self) -> u64 {
        match self {
            SampleValue::Interpolated => 1,
            SampleValue::Region { steps, .. } => steps as u64,
            SampleValue::Probe | SampleValue::Surface => 1,
        }
    }
}

/// Per-ray state a strategy may keep between steps (leap values: trilinear mode, or region
/// mode with the region's value). The other strategies keep none.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SkipState {
    /// Region mode M(m): Some(m); trilinear mode T: None.
    pub region: Option<u16>,
    /// Iso mode: the bisection interval while the ray refines its hit.
    pub bisection: Option<Bisection>,
    /// Iso mode: where the surface was found, once a step returned `SampleValue::Surface`.
    /// Kept here rather than in the value so that steps stay small enough for registers.
    pub surface: [i64; 3],
}

impl SkipState {
    /// Where the sample of a step with `value` at `pos` is classified and shaded: `pos`, or
    /// for the iso surface the surface position (the upper end of its bisection interval).
    #[inline(always)]
    pub fn sample_position(&self, value: SampleValue, pos: [i64; 3]) -> [i64; 3] {
        match value {
            SampleValue::Surface => self.surface,
            _ => pos,
        }
    }

    /// The position after a step that `bisects`: the midpoint of the bisection interval.
    pub fn midpoint(&self) -> [i64; 3] {
        let b = self
            .bisection
            .expect("a step that bisects leaves its interval in the state");
        crate::functional::arith::midpoint(b.lo, b.hi)
    }
}

/// Iso hitpoint refinement of one ray: the density at `lo` is below the iso value, at `hi`
/// at or above it; `left` refinement samples remain.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Bisection {
    pub lo: [i64; 3],
    pub hi: [i64; 3],
    pub left: u32,
}

/// One issue slot of a ray: sample or not, then advance. Every step costs one slot, whatever
/// it does; a leap that follows a sample costs no extra slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Step {
    /// Take the sample at this position (memory request, classification, compositing).
    pub sample: bool,
    /// Positions to advance (>= 1): the ray's next position is P + advance·V.
    pub advance: u64,
    /// What the sample composites.
    pub value: SampleValue,
    /// The advance is read from this sample's own words (leap values): in the cycle model the
    /// ray may not issue again until they are back from memory.
    pub waits_for_words: bool,
    /// Iso refinement: the ray's next position is the midpoint of its bisection interval
    /// (`SkipState::midpoint`) instead of P + advance·V (its sample index stays). A flag, not
    /// the position: the step stays small enough for registers in the ray loop.
    pub bisects: bool,
    /// Iso mode: the ray ends after this step (its surface is found).
    pub ends_ray: bool,
    /// Iso mode: a refinement sample (counted in `RayRecord::refinement_samples` too).
    pub refinement: bool,
}

impl Step {
    /// An ordinary sample: take it, then the next position.
    pub const SAMPLE: Step = Step {
        sample: true,
        advance: 1,
        value: SampleValue::Interpolated,
        waits_for_words: false,
        bisects: false,
        ends_ray: false,
        refinement: false,
    };

    /// The step at a position in an empty sub-cube whose leap is `n` >= 1 positions: the skip
    /// policy says whether the position is sampled first. With sample-then-leap and n = 1 this
    /// is an ordinary sample.
    #[inline(always)]
    pub fn in_empty_subcube(policy: SkipPolicy, n: u64) -> Step {
        Step {
            sample: policy == SkipPolicy::SampleThenLeap,
            advance: n.max(1),
            ..Step::SAMPLE
        }
    }

    /// The step limited to the ray's `remaining` (>= 1) positions: a leap past the ray's last
    /// position simply ends the ray (and a region value covers no position past it).
    #[inline(always)]
    pub fn within(self, remaining: u64) -> Step {
        let value = match self.value {
            SampleValue::Region { density, steps } => SampleValue::Region {
                density,
                steps: steps.min(remaining.min(u32::MAX as u64) as u32),
            },
            v => v,
        };
        Step {
            advance: self.advance.min(remaining),
            value,
            ..self
        }
    }

    /// Positions passed over without a sample (none by an iso refinement step, which
    /// advances 0).
    #[inline(always)]
    pub fn skipped(self) -> u64 {
        self.advance.saturating_sub(self.sample as u64)
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
        r.refinement_samples += self.refinement as u32;
    }
}

/// A skipper is a small value (references and widths): the ray loop copies it per ray, so that
/// its fields live in registers rather than being read again at every step.
pub trait SpaceSkipper: Sync + Copy {
    /// The step at position `pos` of `ray` (not yet limited to the ray's remaining positions),
    /// updating the ray's `state` (which starts at `SkipState::default()`).
    fn decide(&self, pos: [i64; 3], ray: &FixedRay, state: &mut SkipState) -> Step;

    /// The voxel whose word in volume memory the decision at `pos` reads, when the strategy's
    /// structure lives in volume memory (the distance volume); None when it is on chip. The
    /// cycle model reads that word before the ray at `pos` may issue.
    #[inline(always)]
    fn memory_word(&self, _pos: [i64; 3]) -> Option<[usize; 3]> {
        None
    }
}

/// Every position is sampled.
#[derive(Clone, Copy)]
pub struct NoSkipping;

impl SpaceSkipper for NoSkipping {
    #[inline(always)]
    fn decide(&self, _: [i64; 3], _: &FixedRay, _: &mut SkipState) -> Step {
        Step::SAMPLE
    }
}

/// Occupancy-map space leaping (Meißner et al. 2001), optionally with the two-level hierarchy:
/// an empty sub-cube is left in one leap; when its whole 2×2×2 group is empty, the group is.
/// `policy` says whether the position in the empty sub-cube is sampled before the leap.
#[derive(Clone, Copy)]
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
    fn decide(&self, pos: [i64; 3], ray: &FixedRay, _: &mut SkipState) -> Step {
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
#[derive(Clone, Copy)]
pub struct DistanceLeaping<'a> {
    volume: &'a DistanceVolume,
    policy: SkipPolicy,
    /// floor(d / S) per stored distance d (`DistanceLeaping::steps_table`).
    steps: &'a [u64],
    /// Position fraction bits (the base voxel is the position's integer part).
    pos_frac_bits: u32,
}

impl<'a> DistanceLeaping<'a> {
    /// `steps` is `steps_table(volume, S)` for the sample spacing S.
    pub fn new(
        volume: &'a DistanceVolume,
        steps: &'a [u64],
        policy: SkipPolicy,
        pos_frac_bits: u32,
    ) -> Self {
        debug_assert_eq!(steps.len(), volume.saturation() as usize + 1);
        DistanceLeaping {
            volume,
            policy,
            steps,
            pos_frac_bits,
        }
    }

    /// floor(d / S) for every distance d the volume stores. `spacing` is the sample spacing S
    /// (an upper bound of |V| up to the increment's rounding, which the rule's one-step margin
    /// covers: docs/leapvalues.md).
    pub fn steps_table(volume: &DistanceVolume, spacing: f32) -> Vec<u64> {
        (0..=volume.saturation())
            .map(|d| distance_steps(d, spacing))
            .collect()
    }

    /// The base voxel of the cell a sample at `pos` interpolates in (as
    /// `FixedRenderer::base_voxel`).
    #[inline(always)]
    pub fn base_voxel(&self, pos: [i64; 3]) -> [usize; 3] {
        super::arith::base_voxel(self.volume.dims, pos, self.pos_frac_bits)
    }
}

impl SpaceSkipper for DistanceLeaping<'_> {
    #[inline(always)]
    fn decide(&self, pos: [i64; 3], _: &FixedRay, _: &mut SkipState) -> Step {
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

/// Leap values in the volume (Frey & Ertl; docs/model.md, "Leap values in the volume"). The
/// decision reads the sample's own words, so every step that may leap waits for them.
///
/// - Empty-region leaping: every step samples (trilinearly, as without leaping); when the
///   nearest voxel n(P) is a leap voxel with value L >= 1, the ray then advances L positions.
/// - Homogeneous leaping (protocol R of docs/leapvalues.md): in trilinear mode T the sample is
///   interpolated and the ray enters region mode M(m) when n(P) is flagged (m = its density
///   field) or the cell's eight words are identical and unflagged (m = their density). In
///   M(m), n(P)'s word w decides: flagged with L: composite w's density over k = max(L, 1)
///   positions and advance k; unflagged with density m: composite m, advance 1; anything else:
///   back to T, processing this sample there.
///
/// `HOMOGENEOUS` selects the use at compile time (`EmptyRegionLeaping`,
/// `HomogeneousRegionLeaping`): the empty-region ray loop then carries no region-mode code,
/// and its samples are known to be interpolated ones.
#[derive(Clone, Copy)]
pub struct LeapValueLeaping<'a, const HOMOGENEOUS: bool> {
    volume: &'a LeapValueVolume,
    /// The words' density fields (homogeneous leaping's density volume); None for empty-region
    /// leaping, which never reads them.
    densities: Option<&'a [u16]>,
    /// The packed cells (`LeapCells::Packed`): the same densities in their low bytes.
    packed: Option<&'a [u16]>,
    pos_frac_bits: u32,
    /// Index strides of the axes (1, x size, x·y size): the nearest voxel's index from three
    /// independent products, not a chain, since the ray's next address waits for it.
    strides: [usize; 3],
}

/// Leap values used for empty regions only (lossless).
pub type EmptyRegionLeaping<'a> = LeapValueLeaping<'a, false>;
/// Leap values used for every homogeneous region (lossy).
pub type HomogeneousRegionLeaping<'a> = LeapValueLeaping<'a, true>;

impl<'a, const HOMOGENEOUS: bool> LeapValueLeaping<'a, HOMOGENEOUS> {
    /// The strategy for `volume`, whose words were built for the same use (`regions`).
    pub fn new(volume: &'a LeapValueVolume, pos_frac_bits: u32) -> Self {
        debug_assert_eq!(
            volume.regions == LeapRegions::Homogeneous,
            HOMOGENEOUS,
            "leap words built for another use"
        );
        LeapValueLeaping {
            volume,
            densities: volume.densities.as_ref().map(|v| &v.data[..]),
            packed: volume.packed_cells().map(|c| &c[..]),
            pos_frac_bits,
            strides: [1, volume.dims[0], volume.dims[0] * volume.dims[1]],
        }
    }

    /// The index of the voxel nearest to `pos` (round half up, clamped into the volume): one
    /// of the eight words the sample reads.
    #[inline(always)]
    fn nearest(&self, pos: [i64; 3]) -> usize {
        let (pf, d) = (self.pos_frac_bits, self.volume.dims);
        let half = 1i64 << (pf - 1);
        let v = [0, 1, 2].map(|a| (((pos[a] + half) >> pf).max(0) as usize).min(d[a] - 1));
        v[0] + v[1] * self.strides[1] + v[2] * self.strides[2]
    }

    /// Empty-region leaping's advance after sampling word `i` (`empty_region_advance`), its
    /// leap code read from the packed cells when there are.
    #[inline(always)]
    fn empty_region_advance(&self, i: usize) -> u32 {
        match self.packed {
            Some(cells) => self
                .volume
                .empty_region_advance_of_code((cells[i] >> 8) as u8, i),
            None => self.volume.empty_region_advance(i),
        }
    }

    /// The density field of word `i`.
    #[inline(always)]
    fn density(&self, i: usize) -> u16 {
        match (self.packed, self.densities) {
            (Some(cells), Some(_)) => cells[i] & 0xFF,
            (_, Some(d)) => d[i],
            (_, None) => self.volume.layout.decode(self.volume.words[i]).density,
        }
    }

    /// Trilinear mode T: the interpolated sample, and whether the ray enters region mode.
    #[inline(always)]
    fn trilinear(&self, pos: [i64; 3], nearest: usize, state: &mut SkipState) -> Step {
        let density = self.density(nearest);
        state.region = if self.volume.leap(nearest).is_some() {
            Some(density)
        } else {
            // The cell's eight words are identical when all are unflagged with one density
            // (`nearest` is one of them).
            let base = super::arith::base_voxel(self.volume.dims, pos, self.pos_frac_bits);
            let same = (0..8).all(|c| {
                let i = self.volume.index([
                    base[0] + (c & 1),
                    base[1] + ((c >> 1) & 1),
                    base[2] + (c >> 2),
                ]);
                self.volume.leap(i).is_none() && self.density(i) == density
            });
            same.then_some(density)
        };
        Step::SAMPLE
    }
}

impl<const HOMOGENEOUS: bool> SpaceSkipper for LeapValueLeaping<'_, HOMOGENEOUS> {
    #[inline(always)]
    fn decide(&self, pos: [i64; 3], _: &FixedRay, state: &mut SkipState) -> Step {
        let nearest = self.nearest(pos);
        if !HOMOGENEOUS {
            return Step {
                advance: self.empty_region_advance(nearest) as u64,
                waits_for_words: true,
                ..Step::SAMPLE
            };
        }
        let Some(m) = state.region else {
            return self.trilinear(pos, nearest, state);
        };
        let density = self.density(nearest);
        let steps = match self.volume.leap(nearest) {
            Some(l) => l.max(1),
            None if density == m => 1,
            None => {
                // Rule (c): this sample is processed in T; the step was issued in M, so it
                // still waited for its words.
                return Step {
                    waits_for_words: true,
                    ..self.trilinear(pos, nearest, state)
                };
            }
        };
        state.region = Some(density);
        Step {
            sample: true,
            advance: steps as u64,
            value: SampleValue::Region { density, steps },
            waits_for_words: true,
            ..Step::SAMPLE
        }
    }
}

/// The strategy a hardware configuration selects, as one type (so callers need no dispatch of
/// their own). New strategies are added here and in `FixedRenderer::skipper`.
#[derive(Clone, Copy)]
pub enum ConfiguredSkipper<'a> {
    None(NoSkipping),
    Occupancy(OccupancyLeaping<'a>),
    Distance(DistanceLeaping<'a>),
    EmptyRegionLeapValues(EmptyRegionLeaping<'a>),
    HomogeneousLeapValues(HomogeneousRegionLeaping<'a>),
}

impl SpaceSkipper for ConfiguredSkipper<'_> {
    #[inline(always)]
    fn decide(&self, pos: [i64; 3], ray: &FixedRay, state: &mut SkipState) -> Step {
        match self {
            ConfiguredSkipper::None(s) => s.decide(pos, ray, state),
            ConfiguredSkipper::Occupancy(s) => s.decide(pos, ray, state),
            ConfiguredSkipper::Distance(s) => s.decide(pos, ray, state),
            ConfiguredSkipper::EmptyRegionLeapValues(s) => s.decide(pos, ray, state),
            ConfiguredSkipper::HomogeneousLeapValues(s) => s.decide(pos, ray, state),
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

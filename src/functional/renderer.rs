//! The functional fixed-point renderer: per ray, set up in fixed point, then at each position
//! ask the space-skipping strategy whether to sample or leap, and composite the samples with
//! the fixed-point arithmetic of `arith`. It counts steps (samples + leaps, one issue slot
//! each); the published cost is one step per 12.5 ns (`clock.step_time_ns`).

use super::arith::{
    base_voxel, interpolate, interpolate_exact, interpolate_low_bytes, iso_entry, iso_threshold,
    Accumulator, ClassificationTable, Compositor, Neighbourhood,
};
use std::borrow::Cow;

use super::leaping::{
    Bisection, ConfiguredSkipper, DistanceLeaping, EmptyRegionLeaping, HomogeneousRegionLeaping,
    NoSkipping, OccupancyLeaping, SampleValue, SkipState, SpaceSkipper, Step,
};
use super::setup::{check_widths, setup_ray, FixedRay};
use super::Widths;
use crate::blocking::{check_block_size, BlockTable};
use crate::bricks::FixedRange;
use crate::camera::Camera;
use crate::config::{HardwareConfig, LeapRegions, LeapStructure, SkipPolicy};
use crate::error::Result;
use crate::iso::IsoSurface;
use crate::leapvalues::distance::{distance_volume, DistanceVolume};
use crate::leapvalues::LeapValueVolume;
use crate::occupancy::{check_subcube_size, OccupancyKind, OccupancyMap};
use crate::render::{render_frame, Frame, RayRecord, RenderSettings};
use crate::shading::{phong_fixed, GradientVolume};
use crate::transfer::TransferFunction;
use crate::volume::Volume;

/// How rays skip empty space.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Leaping {
    None,
    Occupancy {
        subcube: usize,
        hierarchy: bool,
        kind: OccupancyKind,
    },
    /// The distance volume (`occupancy.structure = "distance"`), `bits` per stored distance.
    Distance {
        bits: u32,
        kind: OccupancyKind,
    },
    /// Leap values in the voxel words (`occupancy.structure = "leap-values"`).
    LeapValues {
        regions: LeapRegions,
        kind: OccupancyKind,
    },
}

impl Leaping {
    pub fn from_config(config: &HardwareConfig) -> Leaping {
        let o = &config.occupancy;
        if o.structure == LeapStructure::Distance {
            Leaping::Distance {
                bits: o.distance_bits,
                kind: o.kind,
            }
        } else if o.structure == LeapStructure::LeapValues {
            Leaping::LeapValues {
                regions: config.leap_values.regions,
                kind: o.kind,
            }
        } else if o.subcube == 0 {
            Leaping::None
        } else {
            Leaping::Occupancy {
                subcube: o.subcube,
                hierarchy: o.hierarchy,
                kind: o.kind,
            }
        }
    }
}

pub struct FixedRenderer<'a> {
    /// The volume sampled: the dataset, or with homogeneous leap values its density fields.
    volume: Cow<'a, Volume>,
    pub widths: Widths,
    pub table: ClassificationTable,
    pub compositor: Compositor,
    pub settings: RenderSettings,
    pub leaping: Leaping,
    /// What a step in an empty sub-cube does (`skip.policy`); no effect without leaping.
    pub skip_policy: SkipPolicy,
    pub map: Option<OccupancyMap>,
    /// The distance volume, with `Leaping::Distance` (`set_distance_volume` replaces it).
    distance: Option<DistanceVolume>,
    /// floor(d / S) per stored distance d of `distance` (`DistanceLeaping::steps_table`).
    distance_steps: Vec<u64>,
    /// The voxel words with leap values, with `Leaping::LeapValues`.
    pub leap_values: Option<LeapValueVolume>,
    /// Leap values over 8-bit densities: their packed cells, which the renderer interpolates
    /// instead of the volume (same densities; the leap decision then reads a cache line the
    /// sample reads anyway).
    packed_cells: Option<std::sync::Arc<[u16]>>,
    /// Per-voxel quantised gradients, present when shading.
    pub gradients: Option<GradientVolume>,
    /// Ray start and end (`[bricks]`, `[clip]`, `[geometry]`); None when all are off.
    pub ray_range: Option<FixedRange>,
    /// 2-way blocking (`[blocking]`): the indirection table; a sample whose lower corner lies
    /// in an inactive block reads zero voxels and gradients.
    pub blocks: Option<std::sync::Arc<BlockTable>>,
    /// Iso-surface mode (`[iso]`); None when off.
    pub iso: Option<IsoSurface>,
    /// Iso mode: the comparator's threshold on the exact interpolation sum
    /// (`arith::iso_threshold`) and the surface's table-format RGBA (opacity 1).
    iso_threshold: i64,
    iso_rgba: [u16; 4],
}

/// The '0' kind skips what holds only voxels of density 0: lossless only while the
/// classification makes density 0 invisible. A transfer function that gives density 0 some
/// opacity (fog around an object) would have leaping and bricks change the image, breaking the
/// invariant that they never do; refused, naming the kind that follows the table.
pub fn check_zero_is_invisible(table: &ClassificationTable) -> Result<()> {
    if table.any_visible(0, 0) {
        return Err(zero_kind_refused());
    }
    Ok(())
}

/// The refusal of the '0' kind where density 0 has some opacity: in the fixed-point table, or
/// in the transfer function itself (an opacity that rounds to 0 in the table still shows in the
/// float reference, whose bricks would then change its image).
pub fn zero_kind_refused() -> crate::error::Error {
    crate::error::Error::config(
        "hardware configuration",
        "occupancy.kind",
        "'0' (zero) skips voxels of density 0 as empty, but the transfer function gives \
         density 0 some opacity, so skipping them would change the image; use \
         occupancy.kind = \"class\" (--occupancy class), whose test follows the transfer \
         function"
            .to_string(),
    )
}

impl<'a> FixedRenderer<'a> {
    /// Prepares a frame: validates the widths against the volume, builds the classification
    /// table and, when leaping, the occupancy map (an error when it does not fit the SRAM).
    pub fn new(
        volume: &'a Volume,
        tf: &TransferFunction,
        settings: &RenderSettings,
        config: &HardwareConfig,
        leaping: Leaping,
    ) -> Result<Self> {
        settings.validate()?;
        let widths = Widths::from_config(config);
        check_widths(&widths, volume.dims, settings.sample_spacing)?;
        let iso = IsoSurface::from_config(config, volume)?;
        // In iso mode the table only feeds the leaping structures and bricks: opacity 0 below
        // the iso value, 1 at and above it.
        let table = match &iso {
            Some(iso) => ClassificationTable::iso(
                iso.first_opaque(),
                iso.colour,
                volume.max_value() as usize + 1,
                widths.lut_bits,
            ),
            None => ClassificationTable::build(
                tf,
                volume.max_value() as usize + 1,
                widths.lut_bits,
                settings.sample_spacing,
            ),
        };
        // Bricks follow `occupancy.kind` too.
        let zero_kind_in_use = match leaping {
            Leaping::None => false,
            Leaping::Occupancy { kind, .. }
            | Leaping::Distance { kind, .. }
            | Leaping::LeapValues { kind, .. } => kind == OccupancyKind::Zero,
        } || (config.bricks.size > 0
            && config.occupancy.kind == OccupancyKind::Zero);
        if zero_kind_in_use {
            check_zero_is_invisible(&table)?;
            // Refused alike when only the table rounds it away: the float reference sees it.
            if iso.is_none() && tf.eval(0.0)[3] > 0.0 {
                return Err(zero_kind_refused());
            }
        }
        let iso_rgba = iso.map_or([0; 4], |iso| iso_entry(iso.colour, widths.lut_bits));
        let iso_threshold = iso.map_or(0, |iso| iso_threshold(iso.value, widths.weight_bits));
        let compositor = Compositor::new(
            widths.accumulator_bits,
            widths.lut_bits,
            settings.ert_threshold,
            settings.background,
        );
        let map = match leaping {
            Leaping::None | Leaping::Distance { .. } | Leaping::LeapValues { .. } => None,
            Leaping::Occupancy {
                subcube,
                hierarchy,
                kind,
            } => {
                let log2 = check_subcube_size(subcube, volume.dims)?;
                let map =
                    OccupancyMap::build(volume, kind, log2, 0, |lo, hi| table.any_visible(lo, hi));
                map.check_fits(
                    hierarchy,
                    config.occupancy.sram_bits,
                    "hardware configuration",
                )?;
                Some(map)
            }
        };
        // Visible cells as the occupancy map's kinds define them: '0' any non-zero voxel,
        // class the classification table's test.
        let distance = match leaping {
            Leaping::Distance { bits, kind } => {
                Some(distance_volume(volume, bits, |lo, hi| match kind {
                    OccupancyKind::Zero => hi > 0,
                    OccupancyKind::Class => table.any_visible(lo, hi),
                })?)
            }
            _ => None,
        };
        let leap_values = match leaping {
            Leaping::LeapValues { regions, kind } => Some(LeapValueVolume::build(
                volume,
                &crate::config::LeapValuesConfig {
                    regions,
                    ..config.leap_values.clone()
                },
                &config.volume_word,
                settings.sample_spacing,
                |lo, hi| match kind {
                    OccupancyKind::Zero => hi > 0,
                    OccupancyKind::Class => table.any_visible(lo, hi),
                },
            )?),
            _ => None,
        };
        // Homogeneous leap values replace region voxels by their means: the renderer samples
        // those density fields (the dataset itself otherwise).
        let volume = match leap_values.as_ref().and_then(|l| l.densities.clone()) {
            Some(densities) => Cow::Owned(densities),
            None => Cow::Borrowed(volume),
        };
        // The iso surface is always shaded.
        let gradients = (settings.shading || iso.is_some())
            .then(|| GradientVolume::build(&volume, config.shading.gradient_bits));
        // Bricks are built from the volume the renderer samples (the density fields with
        // homogeneous leap values).
        let ray_range = FixedRange::from_config(
            &volume,
            config,
            &table,
            widths.position_frac_bits,
            compositor.unit,
        )?;
        let blocks = match config.blocking.enabled {
            true => {
                let log2 = check_block_size(config.blocking.block_size, volume.dims)?;
                Some(std::sync::Arc::new(BlockTable::build(
                    &volume,
                    config.occupancy.kind,
                    log2,
                    table.any_visible(0, 0),
                    |lo, hi| table.any_visible(lo, hi),
                )))
            }
            false => None,
        };
        let packed_cells = leap_values.as_ref().and_then(|l| l.packed_cells().cloned());
        Ok(FixedRenderer {
            packed_cells,
            blocks,
            ray_range,
            iso,
            iso_threshold,
            iso_rgba,
            gradients,
            volume,
            leap_values,
            widths,
            table,
            compositor,
            settings: settings.clone(),
            leaping,
            skip_policy: config.skip.policy,
            map,
            distance_steps: distance
                .as_ref()
                .map(|d| DistanceLeaping::steps_table(d, settings.sample_spacing))
                .unwrap_or_default(),
            distance,
        })
    }

    /// Leaps with `distance` from now on (with its steps table for this renderer's spacing).
    pub fn set_distance_volume(&mut self, distance: DistanceVolume) {
        self.distance_steps = DistanceLeaping::steps_table(&distance, self.settings.sample_spacing);
        self.distance = Some(distance);
    }

    /// The space-skipping strategy of this renderer's effective leaping (`effective_leaping`:
    /// the configured one, without a structure or a hierarchy that would never leap).
    pub fn skipper(&self) -> ConfiguredSkipper<'_> {
        match (&self.map, self.effective_leaping()) {
            (Some(map), Leaping::Occupancy { hierarchy, .. }) => ConfiguredSkipper::Occupancy(
                OccupancyLeaping::new(map, hierarchy, self.skip_policy, self.widths.skip()),
            ),
            _ => match (&self.distance, &self.leap_values) {
                (Some(distance), _) => ConfiguredSkipper::Distance(DistanceLeaping::new(
                    distance,
                    &self.distance_steps,
                    self.skip_policy,
                    self.widths.position_frac_bits,
                )),
                (None, Some(words)) => match words.regions {
                    LeapRegions::Empty => ConfiguredSkipper::EmptyRegionLeapValues(
                        EmptyRegionLeaping::new(words, self.widths.position_frac_bits),
                    ),
                    LeapRegions::Homogeneous => ConfiguredSkipper::HomogeneousLeapValues(
                        HomogeneousRegionLeaping::new(words, self.widths.position_frac_bits),
                    ),
                },
                (None, None) => ConfiguredSkipper::None(NoSkipping),
            },
        }
    }

    /// The leaping this renderer's steps actually do: the configured leaping, except that an
    /// occupancy map with no empty sub-cube never leaps (`OccupancyLeaping::decide` samples
    /// every position, as `NoSkipping` does), so it is `Leaping::None`, and the hierarchy does
    /// nothing when no 2×2×2 group of sub-cubes is empty (an empty sub-cube's leap never goes
    /// up a level), so it is left out. The skipper is chosen by it, and runs whose renderers
    /// leap alike take the same steps and cycles (`run::timing_description`).
    pub fn effective_leaping(&self) -> Leaping {
        match (&self.map, self.leaping) {
            (Some(map), Leaping::Occupancy { .. }) if map.empty_subcubes() == 0 => Leaping::None,
            (
                Some(map),
                Leaping::Occupancy {
                    subcube,
                    hierarchy: true,
                    kind,
                },
            ) if map.empty_groups() == 0 => Leaping::Occupancy {
                subcube,
                hierarchy: false,
                kind,
            },
            (_, leaping) => leaping,
        }
    }

    /// Renders a frame with the configured skipper. Each strategy gets its own ray loop
    /// (`render_with` is generic over it), so no step dispatches on the strategy.
    pub fn render(&self, camera: &Camera) -> Frame {
        match self.skipper() {
            ConfiguredSkipper::None(s) => self.render_with(camera, &s),
            ConfiguredSkipper::Occupancy(s) => self.render_with(camera, &s),
            ConfiguredSkipper::Distance(s) => self.render_with(camera, &s),
            ConfiguredSkipper::EmptyRegionLeapValues(s) => self.render_with(camera, &s),
            ConfiguredSkipper::HomogeneousLeapValues(s) => self.render_with(camera, &s),
        }
    }

    /// Renders a frame with `skipper`. The iso comparator is also chosen once per frame (a ray
    /// loop with it and one without), so the ray loop of a frame without it carries none of its
    /// code.
    pub fn render_with<S: SpaceSkipper>(&self, camera: &Camera, skipper: &S) -> Frame {
        match self.iso {
            Some(_) => self.render_frame_with::<S, true>(camera, skipper),
            None => self.render_frame_with::<S, false>(camera, skipper),
        }
    }

    fn render_frame_with<S: SpaceSkipper, const ISO: bool>(
        &self,
        camera: &Camera,
        skipper: &S,
    ) -> Frame {
        render_frame(camera.width, camera.height, |px, py| {
            let ray = self.setup(camera, px, py);
            let (rgba, mut record) = self.cast_with::<S, ISO>(&ray, skipper);
            record.positions_cut = ray.cut;
            (rgba, record)
        })
    }

    pub fn volume_dims(&self) -> [usize; 3] {
        self.volume.dims
    }

    /// The lower corner voxel of the 2×2×2 neighbourhood a sample at `pos` reads: the
    /// address source of its memory request.
    pub fn base_voxel(&self, pos: [i64; 3]) -> [usize; 3] {
        let pf = self.widths.position_frac_bits;
        base_voxel(self.volume.dims, pos, pf)
    }

    /// Fixed-point setup of the ray through pixel (px, py).
    pub fn setup(&self, camera: &Camera, px: u32, py: u32) -> FixedRay {
        let ray = camera.voxel_ray(px, py, self.volume.spacing);
        let ray = crate::camera::interleave_ray(ray, px, py, &self.settings);
        let fixed = setup_ray(
            &ray,
            self.volume.dims,
            self.settings.sample_spacing,
            &self.widths,
        );
        match &self.ray_range {
            Some(range) => range.apply(&ray, fixed, (px, py), self.settings.sample_spacing),
            None => fixed,
        }
    }

    /// The classified (and, when shading, shaded) sample at a position of a ray.
    #[inline(always)]
    pub fn classify(&self, pos: [i64; 3], light: [i32; 3]) -> [u16; 4] {
        self.classify_value(pos, SampleValue::Interpolated, light)
    }

    /// The classified (and, when shading, shaded) sample of a value at a position: the
    /// interpolated density or a region's value. Shading uses the gradient interpolated at the
    /// position either way.
    #[inline(always)]
    pub fn classify_value(&self, pos: [i64; 3], value: SampleValue, light: [i32; 3]) -> [u16; 4] {
        let (pf, wb) = (self.widths.position_frac_bits, self.widths.weight_bits);
        if let Some(blocks) = &self.blocks {
            if blocks.slot_at(self.base_voxel(pos)).is_none() {
                // An inactive block: not in memory, its voxels and gradients read as zero.
                let rgba = self.table.lookup(0);
                return match &self.gradients {
                    Some(_) if rgba[3] != 0 => {
                        phong_fixed(rgba, [0; 3], light, (1u32 << self.widths.lut_bits) - 1)
                    }
                    _ => rgba,
                };
            }
        }
        let (rgba, pos) = match value {
            SampleValue::Interpolated => {
                let density = match &self.packed_cells {
                    Some(cells) => interpolate_low_bytes(cells, self.volume.dims, pos, pf, wb),
                    None => interpolate(&self.volume, pos, pf, wb),
                };
                (self.table.lookup(density), pos)
            }
            SampleValue::Region { density, .. } => (self.table.lookup(density), pos),
            SampleValue::Probe => return [0; 4],
            SampleValue::Surface => (self.iso_rgba, pos),
        };
        match &self.gradients {
            Some(gradients) if rgba[3] != 0 => {
                let n = Neighbourhood::new(self.volume.dims, pos, pf, wb);
                let g = [0, 1, 2].map(|c| n.weighted_sum(|i| gradients.at(i)[c] as i64));
                phong_fixed(rgba, g, light, (1u32 << self.widths.lut_bits) - 1)
            }
            _ => rgba,
        }
    }

    /// The step of a ray at `pos` with `remaining` (>= 1) positions left: the skipper's step
    /// (limited to them), and in iso mode the iso comparator's part (docs/model.md, "Iso-surface
    /// mode"): a sample below the iso value composites nothing; the first at or above it is the
    /// hit, which ends the ray or, when the position before it is the ray's too and refinement
    /// is on, starts the bisection between the two; each refinement sample halves the interval
    /// and the last composites the surface at its upper end. Hits and refinement samples wait
    /// for their words (the next position depends on them). Both models take steps through here.
    #[inline(always)]
    pub fn step<S: SpaceSkipper>(
        &self,
        skipper: &S,
        pos: [i64; 3],
        ray: &FixedRay,
        state: &mut SkipState,
        remaining: u64,
    ) -> Step {
        match self.iso {
            Some(_) => self.step_with::<S, true>(skipper, pos, ray, state, remaining),
            None => self.step_with::<S, false>(skipper, pos, ray, state, remaining),
        }
    }

    /// `step` with the iso comparator's presence known at compile time (`ISO` must be
    /// `self.iso.is_some()`).
    #[inline(always)]
    fn step_with<S: SpaceSkipper, const ISO: bool>(
        &self,
        skipper: &S,
        pos: [i64; 3],
        ray: &FixedRay,
        state: &mut SkipState,
        remaining: u64,
    ) -> Step {
        let iso = match &self.iso {
            Some(iso) if ISO => iso,
            _ => return skipper.decide(pos, ray, state).within(remaining),
        };
        let (pf, wb) = (self.widths.position_frac_bits, self.widths.weight_bits);
        let hit = |p: [i64; 3]| interpolate_exact(&self.volume, p, pf, wb) >= self.iso_threshold;
        if let Some(mut b) = state.bisection {
            // A refinement sample at the midpoint of the interval.
            if hit(pos) {
                b.hi = pos;
            } else {
                b.lo = pos;
            }
            b.left -= 1;
            let refinement = Step {
                advance: 0,
                refinement: true,
                ..Step::SAMPLE
            };
            if b.left == 0 {
                state.bisection = None;
                state.surface = b.hi;
                return Step {
                    value: SampleValue::Surface,
                    ends_ray: true,
                    ..refinement
                };
            }
            state.bisection = Some(b);
            return Step {
                value: SampleValue::Probe,
                waits_for_words: true,
                bisects: true,
                ..refinement
            };
        }
        let step = skipper.decide(pos, ray, state).within(remaining);
        if !step.sample {
            return step;
        }
        if !hit(pos) {
            return Step {
                value: SampleValue::Probe,
                ..step
            };
        }
        if iso.refinement_steps == 0 || (pos == ray.start && !ray.refinable_start) {
            // No refinement, or no position before the first (outside the box, or cut by
            // clipping or geometry): the surface at the hit.
            state.surface = pos;
            return Step {
                advance: 1,
                value: SampleValue::Surface,
                waits_for_words: true,
                ends_ray: true,
                ..Step::SAMPLE
            };
        }
        let lo = [0, 1, 2].map(|a| pos[a] - ray.step[a]);
        state.bisection = Some(Bisection {
            lo,
            hi: pos,
            left: iso.refinement_steps,
        });
        Step {
            advance: 0,
            value: SampleValue::Probe,
            waits_for_words: true,
            bisects: true,
            ..Step::SAMPLE
        }
    }

    /// Marches one ray: at each position the step (sample or not, then advance), until the
    /// last position, ERT or (iso mode) the refined surface.
    pub fn cast<S: SpaceSkipper>(&self, ray: &FixedRay, skipper: &S) -> ([u8; 4], RayRecord) {
        match self.iso {
            Some(_) => self.cast_with::<S, true>(ray, skipper),
            None => self.cast_with::<S, false>(ray, skipper),
        }
    }

    /// `cast` with the iso comparator's presence known at compile time (`ISO` must be
    /// `self.iso.is_some()`).
    #[inline(always)]
    fn cast_with<S: SpaceSkipper, const ISO: bool>(
        &self,
        ray: &FixedRay,
        skipper: &S,
    ) -> ([u8; 4], RayRecord) {
        let mut record = RayRecord {
            hit: ray.samples > 0,
            first_sample: ray.first_k,
            end_sample: ray.first_k + ray.samples as i64,
            t_enter: ray.t_range[0],
            t_exit: ray.t_range[1],
            ..RayRecord::default()
        };
        let mut acc = Accumulator::default();
        let mut state = SkipState::default();
        // A copy per ray: a local the compiler keeps in registers (the frame's skipper is
        // shared with the other threads, so its fields would be read again at every step).
        let skipper = &{ *skipper };
        let mut pos = ray.start;
        let mut k: u64 = 0;
        let n = ray.samples as u64;
        while k < n {
            let step = self.step_with::<S, ISO>(skipper, pos, ray, &mut state, n - k);
            step.record(&mut record);
            if step.sample
                && self.compositor.composite_steps(
                    &mut acc,
                    self.classify_value(
                        state.sample_position(step.value, pos),
                        step.value,
                        ray.light,
                    ),
                    step.value.steps() as u32,
                )
            {
                // Early when positions remained after those this sample stands for (as the
                // cycle model counts).
                record.terminated_early = k + step.value.steps() < n;
                break;
            }
            if step.ends_ray {
                break;
            }
            if step.bisects {
                pos = state.midpoint();
                continue;
            }
            k += step.advance;
            for a in 0..3 {
                pos[a] += step.advance as i64 * ray.step[a];
            }
        }
        (self.compositor.finish_ray(&acc, ray.surface), record)
    }
}

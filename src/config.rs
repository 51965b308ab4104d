//! Hardware configuration: typed TOML (`configs/hardware/*.toml`), unknown fields rejected,
//! every value validated once at load with an error naming the file, the field and the allowed
//! range. `--set section.field=value` overrides are applied to the TOML before it is read, so
//! they are validated exactly like the file. Field meanings: docs/config.md.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::arch::address_map::MemoryConfig;
use crate::arch::sdram::SdramTiming;
use crate::error::{Error, Result};
use crate::occupancy::{OccupancyKind, SUBCUBE_SIZES};

/// The embedded default (`configs/hardware/vizard2.toml`), so a fresh clone runs with no file.
pub const DEFAULT_TOML: &str = include_str!("../configs/hardware/vizard2.toml");
pub const DEFAULT_NAME: &str = "configs/hardware/vizard2.toml";

/// What a run reads of its configuration: its model and, when it cannot leap whatever the
/// configuration asks, why (`HardwareConfig::why_without_effect`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ConfigUse {
    pub model: crate::run::Model,
    pub not_leaping: Option<&'static str>,
}

/// Fields only the cycle model reads (field paths or their prefixes): the clock, the ray
/// queue, the skip unit's latency, the memory's queues, timing and host link, the lookup
/// stage and the ray setup's costs. The untimed models ignore them.
const TIMING_FIELDS: [&str; 15] = [
    "clock.frequency_mhz",
    "ray_queue.",
    "skip.latency",
    "sdram.",
    "memory.address_fifo_depth",
    "memory.voxel_fifo_depth",
    "memory.overtaking",
    "memory.max_bypass",
    "memory.row_policy",
    "memory.distance_placement",
    "memory.host_link_bits",
    "memory.host_link_mhz",
    "blocking.lookup_latency",
    "bricks.setup",
    "bricks.table_entry_bytes",
];

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HardwareConfig {
    pub clock: ClockConfig,
    pub ray: RayConfig,
    pub ray_queue: RayQueueConfig,
    pub skip: SkipConfig,
    pub occupancy: OccupancyConfig,
    pub interpolation: InterpolationConfig,
    pub classification: ClassificationConfig,
    pub shading: ShadingConfig,
    pub compositing: CompositingConfig,
    pub memory: MemoryConfig,
    pub sdram: SdramTiming,
    /// Leap values in the volume (`occupancy.structure = "leap-values"`): how regions are
    /// segmented and which are leapt. Written out only when not the default.
    #[serde(default, skip_serializing_if = "LeapValuesConfig::is_default")]
    pub leap_values: LeapValuesConfig,
    /// The voxel word's fields when it carries leap values. Written out only when not the
    /// default.
    #[serde(default, skip_serializing_if = "VolumeWordConfig::is_default")]
    pub volume_word: VolumeWordConfig,
    /// Bounding bricks: per-ray start and end (docs/model.md, "Ray start and end"). Written
    /// out only when on (`size` > 0), so existing run keys are unchanged.
    #[serde(default, skip_serializing_if = "BricksConfig::is_off")]
    pub bricks: BricksConfig,
    /// Clip planes and a clip box. Written out only when any is set.
    #[serde(default, skip_serializing_if = "ClipConfig::is_off")]
    pub clip: ClipConfig,
    /// Opaque geometry embedded in the volume. Written out only when a shape is set.
    #[serde(default, skip_serializing_if = "GeometryConfig::is_off")]
    pub geometry: GeometryConfig,
    /// 2-way blocking: volume memory holds only the active blocks, found through an on-chip
    /// indirection table (docs/model.md, "Blocking"). Written out only when not the default.
    #[serde(default, skip_serializing_if = "BlockingConfig::is_default")]
    pub blocking: BlockingConfig,
    /// First-hit iso-surface rendering with hitpoint refinement (docs/model.md, "Iso-surface
    /// mode"). Written out only when on, so existing run keys are unchanged.
    #[serde(default, skip_serializing_if = "IsoConfig::is_default")]
    pub iso: IsoConfig,
}

impl HardwareConfig {
    /// Whether the cycle model's timing can depend on the transfer function: through early ray
    /// termination (when rays stop), leaping with any structure (which positions are sampled),
    /// bounding bricks (where rays start and end), blocking (which blocks the memory holds) or
    /// iso mode (where rays stop). Without them every ray samples every position it reaches
    /// and nothing looks at a sample's value before it is composited, so runs that differ only
    /// in the transfer function take the same cycles, stalls and memory counts: a sweep
    /// reuses them (`experiment::sweep`).
    pub fn timing_depends_on_transfer_function(&self) -> bool {
        self.compositing.ert
            || self.occupancy.subcube > 0
            || self.occupancy.structure != LeapStructure::Map
            || !self.bricks.is_off()
            || self.blocking.enabled
            || self.iso.enabled
    }
}

/// `[blocking]`: the volume memory holds only the active blocks of `block_size`³ voxels, each
/// stored with a one-voxel border in a slot; the address generator finds a sample's slot in an
/// on-chip indirection table (block index → slot), which costs `lookup_latency` cycles.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BlockingConfig {
    pub enabled: bool,
    /// Block edge in voxels: a power of two 4..=256, at least `bricks.size` and
    /// `occupancy.subcube`, dividing every dimension of the volume.
    pub block_size: usize,
    /// Cycles the indirection-table lookup adds to address generation (a pipelined stage).
    pub lookup_latency: u32,
}

impl Default for BlockingConfig {
    fn default() -> Self {
        BlockingConfig {
            enabled: false,
            block_size: 32,
            lookup_latency: 2,
        }
    }
}

/// `[iso]`: first-hit iso-surface mode. A ray stops at its first sample whose density is at
/// least `value`; the hit is refined by `refinement_steps` bisections between that sample and
/// the one before it, and shaded there in `colour`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IsoConfig {
    pub enabled: bool,
    /// Iso value in the dataset's density units; 0 = half the dataset's largest density.
    /// Must lie in (smallest, largest] density of the dataset (checked when a run is prepared).
    pub value: f64,
    /// Bisection steps between the last two samples, 0..=16 (0 = shade at the first hit).
    pub refinement_steps: u32,
    /// Surface colour (RGB 0..=1), Phong-shaded with the headlight.
    pub colour: [f32; 3],
}

impl Default for IsoConfig {
    fn default() -> Self {
        IsoConfig {
            enabled: false,
            value: 0.0,
            refinement_steps: 6,
            colour: [0.9, 0.85, 0.75],
        }
    }
}

impl BlockingConfig {
    pub fn is_default(&self) -> bool {
        *self == BlockingConfig::default()
    }
}

/// Largest `iso.refinement_steps`.
pub const MAX_REFINEMENT_STEPS: u32 = 16;

impl IsoConfig {
    pub fn is_default(&self) -> bool {
        *self == IsoConfig::default()
    }
}

/// `[bricks]`: bounding bricks give each ray a start (the first sample in an active brick) and
/// an end (after the last one); how ray setup learns them is `setup`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BricksConfig {
    /// Brick edge in voxels: 0 = off, else 4, 8, 16 or 32 (not larger than the volume).
    /// Bricks are active by `occupancy.kind` ('0': any non-zero voxel; class: min-max test).
    pub size: usize,
    /// "traversal" (ray setup walks the brick grid per ray) or "table" (a per-pixel start/end
    /// table loaded from the host each frame).
    pub setup: BrickSetup,
    /// Traversal: cycles of ray setup per ray, plus `setup_cycles_per_brick` per brick visited.
    pub setup_cycles_per_ray: u32,
    pub setup_cycles_per_brick: u32,
    /// Table: bytes per pixel entry (start and end sample index).
    pub table_entry_bytes: u32,
    /// Traversal: ray-setup units working in parallel (each on one ray at a time; rays enter
    /// the queue in pixel order).
    pub setup_units: u32,
}

impl Default for BricksConfig {
    fn default() -> Self {
        BricksConfig {
            size: 0,
            setup: BrickSetup::Traversal,
            setup_cycles_per_ray: 1,
            setup_cycles_per_brick: 1,
            table_entry_bytes: 4,
            setup_units: 1,
        }
    }
}

impl BricksConfig {
    pub fn is_off(&self) -> bool {
        self.size == 0
    }
}

/// How ray setup obtains a ray's start and end from the bricks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BrickSetup {
    /// Ray setup walks the brick grid (a 3D DDA) per ray; its cycles are counted.
    #[default]
    Traversal,
    /// The host supplies a per-pixel start/end table each frame; its load time is counted.
    Table,
}

/// Allowed `bricks.size` (besides 0 = off).
pub const BRICK_SIZES: [usize; 4] = [4, 8, 16, 32];

/// `[clip]`: clip planes and a clip box in voxel coordinates; a sample is kept when it is on
/// the kept side of every plane and inside the box.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClipConfig {
    /// Planes: a sample at x is kept when (x - point)·normal >= 0.
    #[serde(default)]
    pub planes: Vec<ClipPlane>,
    /// Clip box `[[min x, y, z], [max x, y, z]]` (voxel coordinates, inclusive); empty = none.
    #[serde(default, rename = "box")]
    pub clip_box: Vec<[f32; 3]>,
}

impl ClipConfig {
    pub fn is_off(&self) -> bool {
        self.planes.is_empty() && self.clip_box.is_empty()
    }

    /// The clip box as (min, max), when set (validated: two corners).
    pub fn box_corners(&self) -> Option<([f32; 3], [f32; 3])> {
        match self.clip_box.as_slice() {
            [lo, hi] => Some((*lo, *hi)),
            _ => None,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClipPlane {
    pub point: [f32; 3],
    pub normal: [f32; 3],
}

/// `[geometry]`: one opaque object; rays end at its surface and its colour is composited
/// behind the volume.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeometryConfig {
    /// "none", "sphere" (analytic: `centre`, `radius`), "cylinder" (a capped "pointer" from
    /// `centre` to `end`, `radius`) or "depth-file" (`file`).
    pub shape: GeometryShape,
    /// Sphere centre (cylinder: one end) and radius, voxel coordinates.
    pub centre: [f32; 3],
    pub radius: f32,
    /// Surface colour (RGB 0..=1); the sphere is lit by the headlight.
    pub colour: [f32; 3],
    /// Depth image (docs/model.md, "Depth file format"); must match the image size.
    pub file: String,
    /// Cylinder: the other end of its axis (voxel coordinates).
    #[serde(default)]
    pub end: [f32; 3],
}

impl Default for GeometryConfig {
    fn default() -> Self {
        GeometryConfig {
            shape: GeometryShape::None,
            centre: [0.0; 3],
            radius: 1.0,
            colour: [1.0, 1.0, 1.0],
            file: String::new(),
            end: [0.0; 3],
        }
    }
}

impl GeometryConfig {
    pub fn is_off(&self) -> bool {
        self.shape == GeometryShape::None
    }
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GeometryShape {
    #[default]
    None,
    Sphere,
    Cylinder,
    DepthFile,
}

/// The published cost of one step of the functional model, in ns (the preset's
/// `clock.step_time_ns`).
pub const PUBLISHED_STEP_TIME_NS: f64 = 12.5;

/// A step time as output names it: "the published 12.5 ns per step", or the configured value
/// as `clock.step_time_ns = 5 ns per step, not the published 12.5 ns`, so a changed step time
/// is not called published.
pub fn step_cost_text(step_time_ns: f64) -> String {
    if step_time_ns == PUBLISHED_STEP_TIME_NS {
        format!("the published {PUBLISHED_STEP_TIME_NS} ns per step")
    } else {
        format!(
            "clock.step_time_ns = {} ns per step, not the published {PUBLISHED_STEP_TIME_NS} ns",
            ns_text(step_time_ns)
        )
    }
}

/// A time in ns with at most 6 decimals and no trailing zeros: `5`, `12.5`, `3.3` (a step time
/// recovered as frame time / steps may carry rounding noise in the last bits).
pub fn ns_text(ns: f64) -> String {
    let text = format!("{ns:.6}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    text.to_string()
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClockConfig {
    /// The published cost of one step (sample or leap) of the functional model, in ns.
    pub step_time_ns: f64,
    /// Clock of the cycle-accurate pipeline, in MHz (frame rate = f / cycles).
    pub frequency_mhz: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RayQueueConfig {
    /// Rays in flight (R): each has one slot; a ray is busy while its update is in the skip unit.
    pub rays: usize,
    /// Which ready ray issues: "round-robin", "oldest-first" or "lagging-first".
    pub selection: RaySelection,
    /// Pixel order: tiles of `tile = [w, h]` pixels so neighbouring rays travel together.
    pub tile: [u32; 2],
    /// Rays the ray-setup unit produces per cycle at most (pipelined setup).
    pub setups_per_cycle: u32,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RaySelection {
    RoundRobin,
    OldestFirst,
    /// The ready ray with the fewest positions done (k), so rays in flight stay side by side
    /// and their samples share memory rows; ties round-robin.
    LaggingFirst,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RayConfig {
    /// Integer bits of a sample position (unsigned): positions up to 2^bits - 1 voxels.
    pub position_int_bits: u32,
    /// Fraction bits of a sample position.
    pub position_frac_bits: u32,
    /// Fraction bits of the per-sample increment V (its integer part is as wide as the sample
    /// spacing needs).
    pub increment_frac_bits: u32,
    /// Interleaved sampling: pixel (px, py) shifts its first sample by an offset in [0, 1)
    /// sample steps from an N×N pattern (`camera::interleave_offset`); 1 = off, 0 is an
    /// error. Written out only when not 1, so existing run keys are unchanged.
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub interleave: u32,
}

fn one() -> u32 {
    1
}

fn is_one(n: &u32) -> bool {
    *n == 1
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SkipConfig {
    /// Significant bits of the per-ray reciprocals 1/|V_i| (mantissa of an exponent-scaled
    /// value, rounded down).
    pub reciprocal_bits: u32,
    /// Fraction bits kept of the distance to the sub-cube boundary (truncated).
    pub distance_frac_bits: u32,
    /// Cycles from issuing a step to its new position being back in the ray queue (published: 8).
    pub latency: u32,
    /// What a step at a position in an empty sub-cube does: "leap-only" (no sample, no memory
    /// request) or "sample-then-leap" (the published cost: the position is sampled like any
    /// other, then the ray leaps from it). Written out only when not the default, so the
    /// serialised default configuration, and every run key derived from it, is unchanged.
    #[serde(default, skip_serializing_if = "SkipPolicy::is_leap_only")]
    pub policy: SkipPolicy,
}

/// How the skip unit treats a position in an empty sub-cube (docs/model.md, "Steps and the
/// published cost"). Both advance the ray by the same leap n computed at that position.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SkipPolicy {
    /// Take no sample: the step is one issue slot with no memory request.
    #[default]
    LeapOnly,
    /// Sample the position like any other (memory request, classification, compositing of a
    /// zero-opacity sample), then leap: "for each sub-cube at least one sample needs to be
    /// processed" (Meißner et al. 2001).
    SampleThenLeap,
}

impl SkipPolicy {
    pub fn is_leap_only(&self) -> bool {
        *self == SkipPolicy::LeapOnly
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OccupancyConfig {
    /// Sub-cube edge in voxels (2, 4, ..., 64), or 0 for no space leaping.
    pub subcube: usize,
    /// Two-level hierarchy: a zero byte of 2×2×2 sub-cubes leaps the whole 2s group.
    pub hierarchy: bool,
    /// Which map: "zero" ('0') or "class".
    pub kind: OccupancyKind,
    /// On-chip SRAM capacity for the map, in bits (XCV1000 block RAM: 131072).
    pub sram_bits: u64,
    /// The leaping structure: "map" (the occupancy map above, on-chip SRAM) or "distance"
    /// (a distance volume in SDRAM beside the volume; `subcube` is then not used). Written out
    /// only when not the default "map", so existing run keys are unchanged.
    #[serde(default, skip_serializing_if = "LeapStructure::is_map")]
    pub structure: LeapStructure,
    /// Bits of a stored distance with `structure = "distance"`: 4 or 8. Written out only when
    /// not the default 8.
    #[serde(
        default = "default_distance_bits",
        skip_serializing_if = "is_default_distance_bits"
    )]
    pub distance_bits: u32,
}

/// Which acceleration structure leaps (docs/model.md, "The distance volume").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LeapStructure {
    /// The occupancy map of sub-cubes in on-chip SRAM (`occupancy.subcube`, 0 = no leaping).
    #[default]
    Map,
    /// The distance volume: one distance word per voxel in SDRAM, read at every step.
    Distance,
    /// Leap values in the voxel words themselves (`[leap_values]`, `[volume_word]`): a sample
    /// whose nearest voxel is a leap voxel leaps by the value its word holds.
    LeapValues,
}

impl LeapStructure {
    pub fn is_map(&self) -> bool {
        *self == LeapStructure::Map
    }
}

/// Allowed `occupancy.distance_bits`.
pub const DISTANCE_BITS_ALLOWED: [u32; 2] = [4, 8];

fn default_distance_bits() -> u32 {
    8
}

fn is_default_distance_bits(bits: &u32) -> bool {
    *bits == default_distance_bits()
}

/// Which segmented regions get leap voxels (docs/model.md, "Leap values in the volume").
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize,
)]
#[serde(rename_all = "kebab-case")]
pub enum LeapRegions {
    /// Only regions whose whole value range classifies to zero opacity; densities are kept,
    /// so the image equals the non-leaping image bit for bit.
    #[default]
    Empty,
    /// Every region: region voxels hold their region's mean, rays composite the mean over a
    /// leap with opacity 1 - (1 - a)^L and sample regions nearest-neighbour. Lossy by design.
    Homogeneous,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LeapValuesConfig {
    /// "empty" (lossless) or "homogeneous" (lossy).
    pub regions: LeapRegions,
    /// Region criterion: |value - seed value| <= range_fraction · the voxel type's maximum.
    pub range_fraction: f64,
    /// Regions with fewer voxels are dissolved (their voxels belong to no region).
    pub min_region_size: u64,
    /// The largest sample spacing the guards must cover, in voxels; 0 = the run's spacing.
    pub max_spacing: f32,
}

impl Default for LeapValuesConfig {
    fn default() -> Self {
        LeapValuesConfig {
            regions: LeapRegions::Empty,
            range_fraction: 0.03,
            min_region_size: 64,
            max_spacing: 0.0,
        }
    }
}

impl LeapValuesConfig {
    pub fn is_default(&self) -> bool {
        *self == LeapValuesConfig::default()
    }
}

/// The voxel word when it carries leap values (`src/leapvalues/word.rs`): flag (MSB), leap
/// value, unused bits, density.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VolumeWordConfig {
    pub word_bits: u32,
    pub density_bits: u32,
    pub leap_bits: u32,
}

impl Default for VolumeWordConfig {
    fn default() -> Self {
        VolumeWordConfig {
            word_bits: 32,
            density_bits: 16,
            leap_bits: 15,
        }
    }
}

impl VolumeWordConfig {
    pub fn is_default(&self) -> bool {
        *self == VolumeWordConfig::default()
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InterpolationConfig {
    /// Bits of each trilinear weight (the position's fraction truncated to this many bits).
    pub weight_bits: u32,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClassificationConfig {
    /// Bits per entry (R, G, B and A) of the classification lookup table.
    pub lut_bits: u32,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShadingConfig {
    /// Signed bits per component of the gradient stored with each voxel (used with --shading).
    pub gradient_bits: u32,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CompositingConfig {
    /// Bits of the colour and alpha accumulators (unsigned fractions, 2^bits - 1 = 1.0).
    pub accumulator_bits: u32,
    /// Early ray termination on/off.
    pub ert: bool,
    /// Accumulated opacity at which a ray terminates.
    pub ert_threshold: f64,
    /// Samples the compositing (reorder) buffer holds; full = back-pressure to the ray queue.
    pub buffer_capacity: usize,
    /// Cycles from an assembled sample entering interpolation to its compositing
    /// (interpolation, classification, shading, compositing stages).
    pub stage_latency: u32,
    /// Cycles from the compositing stage detecting termination to the ray queue knowing it.
    pub ert_feedback_latency: u32,
    /// Stop with an error when no unit makes progress for this many cycles.
    pub watchdog_cycles: u64,
}

impl HardwareConfig {
    /// The embedded default configuration.
    pub fn default_config() -> HardwareConfig {
        Self::from_toml_str(DEFAULT_TOML, DEFAULT_NAME, &[])
            .expect("embedded default config is valid")
    }

    /// Reads a file (or the embedded default when `path` is None) and applies `--set` overrides.
    pub fn load(path: Option<&Path>, overrides: &[String]) -> Result<HardwareConfig> {
        let shown: Vec<String> = overrides.iter().map(|o| format!("--set {o}")).collect();
        Self::load_shown(path, overrides, &shown)
    }

    /// `load`, with each override named in messages as `shown` says (`--subcube 8` for the
    /// flag that set `occupancy.subcube=8`), so an error names what the user typed.
    pub fn load_shown(
        path: Option<&Path>,
        overrides: &[String],
        shown: &[String],
    ) -> Result<HardwareConfig> {
        match path {
            Some(p) => {
                let text = crate::input::read_text(p)?;
                Self::from_toml_str_shown(&text, &p.display().to_string(), overrides, shown)
            }
            None => Self::from_toml_str_shown(DEFAULT_TOML, DEFAULT_NAME, overrides, shown),
        }
    }

    pub fn from_toml_str(text: &str, source: &str, overrides: &[String]) -> Result<HardwareConfig> {
        let shown: Vec<String> = overrides.iter().map(|o| format!("--set {o}")).collect();
        Self::from_toml_str_shown(text, source, overrides, &shown)
    }

    fn from_toml_str_shown(
        text: &str,
        source: &str,
        overrides: &[String],
        shown: &[String],
    ) -> Result<HardwareConfig> {
        let mut table: toml::Table = text
            .parse()
            .map_err(|e| Error::format(source, format!("invalid TOML: {e}")))?;
        // Sections added after the preset files were written: present with their defaults,
        // so `--set bricks.size=8` works on any file.
        insert_default_sections(&mut table);
        for assignment in overrides {
            apply_override(&mut table, assignment)?;
        }
        let source_name = if overrides.is_empty() {
            source.to_string()
        } else {
            format!("{source} with {}", shown.join(" "))
        };
        let config: HardwareConfig = table
            .try_into()
            .map_err(|e| Error::format(&source_name, format!("invalid configuration: {e}")))?;
        config.validate(&source_name)?;
        Ok(config)
    }

    /// The fields where this configuration differs from the embedded default (the calibrated
    /// preset), as `section.field = value`, in file order: what a preset or override resolved to.
    pub fn differences_from_default(&self) -> Vec<String> {
        fn flatten(prefix: &str, table: &toml::Table, out: &mut Vec<(String, toml::Value)>) {
            for (key, value) in table {
                let path = if prefix.is_empty() {
                    key.clone()
                } else {
                    format!("{prefix}.{key}")
                };
                match value {
                    toml::Value::Table(t) => flatten(&path, t, out),
                    v => out.push((path, v.clone())),
                }
            }
        }
        let fields = |config: &HardwareConfig| {
            let mut out = Vec::new();
            if let Ok(mut table) = toml::Table::try_from(config) {
                insert_default_sections(&mut table);
                flatten("", &table, &mut out);
            }
            out
        };
        // The default as written in its file: sections the serialisation leaves out when they
        // are at their defaults ([leap_values]...) are there too, field by field.
        let mut default_fields = Vec::new();
        if let Ok(mut table) = DEFAULT_TOML.parse::<toml::Table>() {
            insert_default_sections(&mut table);
            flatten("", &table, &mut default_fields);
        }
        let default: std::collections::BTreeMap<String, toml::Value> =
            default_fields.into_iter().collect();
        fields(self)
            .into_iter()
            .filter(|(path, value)| default.get(path) != Some(value))
            .map(|(path, value)| format!("{path} = {value}"))
            .collect()
    }

    /// The fields that differ from the default but do nothing in this run, each with the
    /// reason (`why_without_effect`): a setting that is shown as set while nothing reads it
    /// misleads.
    pub fn settings_without_effect(&self, used: ConfigUse) -> Vec<String> {
        self.differences_from_default()
            .into_iter()
            .filter_map(|difference| {
                let path = difference.split(" = ").next().unwrap_or_default();
                self.why_without_effect(path, used)
                    .map(|why| format!("{difference} ({why})"))
            })
            .collect()
    }

    /// Why the field at `path` (`iso.value`) does nothing in this configuration and run, if it
    /// does nothing:
    /// - a timing rule that another rule always outlasts;
    /// - the switch of its feature is off (`iso.enabled`, `memory.overtaking`,
    ///   `sdram.refresh`...), or there is no leaping structure for the skip unit's widths;
    /// - the run's model does not read it: the untimed models (float, step) no timing field,
    ///   the cycle model not the step model's cost;
    /// - in a run that does not leap (`used.not_leaping`: the float model, a sequence's
    ///   `--map none`), a field of the leaping structures (`occupancy.*` but the kind that
    ///   chooses the bricks' and blocks' test, `leap_values.*`, `volume_word.*`, `skip.policy`).
    pub fn why_without_effect(&self, path: &str, used: ConfigUse) -> Option<String> {
        let t = &self.sdram;
        // On a datasheet t_rc is t_ras + t_rp, and t_ras at least t_rcd.
        match path {
            "sdram.t_rc" if t.t_rc < t.t_ras + t.t_rp => {
                return Some(format!(
                    "shorter than t_ras + t_rp = {}: ACT to PRE to ACT takes longer",
                    t.t_ras + t.t_rp
                ))
            }
            "sdram.t_ras" if t.t_ras < t.t_rcd => {
                return Some(format!(
                    "shorter than t_rcd = {}: a row is open until its first READ anyway",
                    t.t_rcd
                ))
            }
            _ => {}
        }
        let structure = self.occupancy.structure;
        let no_map = structure == LeapStructure::Map && self.occupancy.subcube == 0;
        // (field prefix, field that is the switch itself, the feature is off, why)
        let rules: [(&str, &str, bool, &str); 17] = [
            (
                "iso.",
                "iso.enabled",
                !self.iso.enabled,
                "iso.enabled is false",
            ),
            (
                "leap_values.",
                "",
                structure != LeapStructure::LeapValues,
                "occupancy.structure is not \"leap-values\"",
            ),
            (
                "volume_word.",
                "",
                structure != LeapStructure::LeapValues,
                "occupancy.structure is not \"leap-values\"",
            ),
            (
                "occupancy.distance_bits",
                "",
                structure != LeapStructure::Distance,
                "occupancy.structure is not \"distance\"",
            ),
            (
                "blocking.",
                "blocking.enabled",
                !self.blocking.enabled,
                "blocking.enabled is false",
            ),
            (
                "bricks.",
                "bricks.size",
                self.bricks.size == 0,
                "bricks.size is 0",
            ),
            (
                "geometry.",
                "geometry.shape",
                self.geometry.shape == GeometryShape::None,
                "geometry.shape is \"none\"",
            ),
            (
                "memory.overtaking_window",
                "",
                !self.memory.overtaking,
                "memory.overtaking is false",
            ),
            (
                "memory.max_bypass",
                "",
                !self.memory.overtaking,
                "memory.overtaking is false",
            ),
            (
                "sdram.refresh_interval",
                "",
                !t.refresh,
                "sdram.refresh is false",
            ),
            ("sdram.t_rfc", "", !t.refresh, "sdram.refresh is false"),
            (
                "occupancy.sram_bits",
                "",
                no_map,
                "occupancy.subcube is 0: no map",
            ),
            (
                "occupancy.hierarchy",
                "",
                no_map,
                "occupancy.subcube is 0: no map",
            ),
            // Which steps in empty space sample: without a leaping structure none is empty.
            ("skip.policy", "", no_map, "no leaping structure"),
            // The skip unit's leap arithmetic; the skip latency applies to every step.
            ("skip.reciprocal_bits", "", no_map, "no leaping structure"),
            (
                "skip.distance_frac_bits",
                "",
                no_map,
                "no leaping structure",
            ),
            // The test of empty sub-cubes, bricks and blocks.
            (
                "occupancy.kind",
                "",
                no_map && self.bricks.size == 0 && !self.blocking.enabled,
                "no leaping structure, bricks or blocking",
            ),
        ];
        let switch_off = rules
            .iter()
            .find(|(prefix, switch, off, _)| *off && path.starts_with(prefix) && path != *switch)
            .map(|(_, _, _, why)| *why);
        // Bricks and blocks follow `occupancy.kind` in every model, leaping or not.
        let leaping_field = ["occupancy.", "leap_values.", "volume_word.", "skip.policy"]
            .iter()
            .any(|prefix| path.starts_with(prefix))
            && !(path == "occupancy.kind" && (self.bricks.size > 0 || self.blocking.enabled));
        let model = match used.model {
            // The untimed models: what only the pipeline's clock, queues and memory timing read
            // (the memory's layout stays: the blocking and distance figures report rows).
            crate::run::Model::Float | crate::run::Model::Step => TIMING_FIELDS
                .iter()
                .any(|prefix| path.starts_with(prefix))
                .then_some(if used.model == crate::run::Model::Float {
                    "the float model is untimed"
                } else {
                    "the step model counts steps, not cycles"
                }),
            crate::run::Model::Cycle => (path == "clock.step_time_ns")
                .then_some("the step model's cost per step; the cycle model counts cycles"),
        };
        // A run that cannot leap at all says so first: it is the reason whatever the switches.
        used.not_leaping
            .filter(|_| leaping_field)
            .or(switch_off)
            .or(model)
            .map(str::to_string)
    }

    /// The ERT threshold the models apply: None when ERT is off.
    pub fn ert_threshold(&self) -> Option<f32> {
        self.compositing
            .ert
            .then_some(self.compositing.ert_threshold as f32)
    }

    /// Host-link bytes per pipeline clock cycle in 32.32 fixed point: `memory.host_link_bits` ×
    /// `memory.host_link_mhz` over `clock.frequency_mhz`. The one rate of the link, for volume
    /// updates and the start/end table alike. Within the validated ranges it is at least 5
    /// (1.2e-9 bytes per cycle, rounded: the slowest link's load times come out up to 7 %
    /// long) and saturates at `u64::MAX` (2^32 bytes per cycle and more: any load is one cycle).
    pub fn host_link_per_cycle_q32(&self) -> u64 {
        let bytes_per_cycle =
            self.memory.host_link_bytes_per_second() / (self.clock.frequency_mhz * 1e6);
        (bytes_per_cycle * (1u64 << 32) as f64).round() as u64
    }

    /// Checks every field against its allowed range.
    pub fn validate(&self, source: &str) -> Result<()> {
        let range =
            |field: &str, value: u64, lo: u64, hi: u64| check_range(source, field, value, lo, hi);
        let r = &self.ray;
        range("ray.position_int_bits", r.position_int_bits as u64, 2, 16)?;
        range("ray.position_frac_bits", r.position_frac_bits as u64, 1, 24)?;
        range(
            "ray.interleave",
            r.interleave as u64,
            1,
            crate::camera::MAX_INTERLEAVE as u64,
        )?;
        // Bounded by another field: the error says which (a probe read "allowed 1..=8" after
        // changing only ray.position_frac_bits).
        let at_most_position = |field: &str, value: u32, low: u32| -> Result<()> {
            if (low..=r.position_frac_bits).contains(&value) {
                return Ok(());
            }
            Err(Error::config(
                source,
                field,
                format!(
                    "{value} is out of range; allowed {low}..=ray.position_frac_bits ({}): no \
                     more fraction bits than a position has",
                    r.position_frac_bits
                ),
            ))
        };
        at_most_position("ray.increment_frac_bits", r.increment_frac_bits, 1)?;
        range(
            "skip.reciprocal_bits",
            self.skip.reciprocal_bits as u64,
            2,
            32,
        )?;
        at_most_position("skip.distance_frac_bits", self.skip.distance_frac_bits, 0)?;
        range("skip.latency", self.skip.latency as u64, 1, 64)?;
        let q = &self.ray_queue;
        range("ray_queue.rays", q.rays as u64, 1, 4096)?;
        range("ray_queue.tile[0]", q.tile[0] as u64, 1, 256)?;
        range("ray_queue.tile[1]", q.tile[1] as u64, 1, 256)?;
        range(
            "ray_queue.setups_per_cycle",
            q.setups_per_cycle as u64,
            1,
            64,
        )?;
        let c = &self.compositing;
        range(
            "compositing.buffer_capacity",
            c.buffer_capacity as u64,
            1,
            1 << 20,
        )?;
        range("compositing.stage_latency", c.stage_latency as u64, 1, 256)?;
        range(
            "compositing.ert_feedback_latency",
            c.ert_feedback_latency as u64,
            1,
            256,
        )?;
        range(
            "compositing.watchdog_cycles",
            c.watchdog_cycles,
            100,
            1 << 40,
        )?;
        let f = self.clock.frequency_mhz;
        // A lower bound, not just > 0: a denormal clock gives an infinite frame time.
        if !(f.is_finite() && (1e-3..=1e5).contains(&f)) {
            return Err(Error::config(
                source,
                "clock.frequency_mhz",
                format!("{f:?} is out of range; allowed 0.001..=100000 MHz"),
            ));
        }
        self.memory.validate(source)?;
        self.sdram.validate(source, self.memory.banks)?;
        let o = &self.occupancy;
        if o.subcube != 0 && !SUBCUBE_SIZES.contains(&o.subcube) {
            return Err(Error::config(
                source,
                "occupancy.subcube",
                format!(
                    "{} is not allowed; allowed 0 (no leaping) or {SUBCUBE_SIZES:?}",
                    o.subcube
                ),
            ));
        }
        range("occupancy.sram_bits", o.sram_bits, 1, 1 << 32)?;
        if !DISTANCE_BITS_ALLOWED.contains(&o.distance_bits) {
            return Err(Error::config(
                source,
                "occupancy.distance_bits",
                format!(
                    "{} is not allowed; allowed {DISTANCE_BITS_ALLOWED:?}",
                    o.distance_bits
                ),
            ));
        }
        // The other structures have no sub-cubes: a size given with them would be shown as
        // set ("differs ... occupancy.subcube = 8") while nothing used it.
        if o.structure != LeapStructure::Map && o.subcube > 0 {
            return Err(Error::config(
                source,
                "occupancy.subcube",
                format!(
                    "{} needs occupancy.structure = \"map\"; the {} has no sub-cubes (leave \
                     occupancy.subcube at 0)",
                    o.subcube,
                    match o.structure {
                        LeapStructure::Distance => "distance volume",
                        _ => "leap-value volume",
                    }
                ),
            ));
        }
        if o.structure != LeapStructure::Map && o.hierarchy {
            return Err(Error::config(
                source,
                "occupancy.hierarchy",
                "true needs occupancy.structure = \"map\"; only the occupancy map has a \
                 hierarchy"
                    .to_string(),
            ));
        }
        let lv = &self.leap_values;
        if !(lv.range_fraction.is_finite() && (0.0..=1.0).contains(&lv.range_fraction)) {
            return Err(Error::config(
                source,
                "leap_values.range_fraction",
                format!(
                    "{:?} is out of range; allowed 0..=1 (a fraction of the voxel type's maximum)",
                    lv.range_fraction
                ),
            ));
        }
        range(
            "leap_values.min_region_size",
            lv.min_region_size,
            1,
            1 << 40,
        )?;
        let m = lv.max_spacing;
        if !(m == 0.0 || (m.is_finite() && (1.0 / 64.0..=16.0).contains(&m))) {
            return Err(Error::config(
                source,
                "leap_values.max_spacing",
                format!("{m:?} is out of range; allowed 0 (the run's spacing) or 1/64..=16 voxels"),
            ));
        }
        let w = &self.volume_word;
        crate::leapvalues::VolumeWord::new(w.word_bits, w.density_bits, w.leap_bits)
            .map_err(|e| e.with_source(source))?;
        range(
            "interpolation.weight_bits",
            self.interpolation.weight_bits as u64,
            1,
            15,
        )?;
        range(
            "classification.lut_bits",
            self.classification.lut_bits as u64,
            2,
            16,
        )?;
        range(
            "shading.gradient_bits",
            self.shading.gradient_bits as u64,
            2,
            16,
        )?;
        range(
            "compositing.accumulator_bits",
            self.compositing.accumulator_bits as u64,
            2,
            30,
        )?;
        let t = self.compositing.ert_threshold;
        if !(t > 0.0 && t <= 1.0) {
            return Err(Error::config(
                source,
                "compositing.ert_threshold",
                format!("{t:?} is out of range; allowed (0, 1]"),
            ));
        }
        let step = self.clock.step_time_ns;
        if !(step.is_finite() && (1e-3..=1e6).contains(&step)) {
            return Err(Error::config(
                source,
                "clock.step_time_ns",
                format!("{step:?} is out of range; allowed 0.001..=1e6 ns"),
            ));
        }
        self.validate_ray_range(source)?;
        self.validate_blocking(source)
    }

    /// `[blocking]`: the block size and what it must cover (the volume's dimensions are
    /// checked when a volume is prepared: `blocking::check_block_size`).
    fn validate_blocking(&self, source: &str) -> Result<()> {
        let b = &self.blocking;
        let err = |field: &str, msg: String| Err(Error::config(source, field, msg));
        if !b.block_size.is_power_of_two() || !(4..=256).contains(&b.block_size) {
            return err(
                "blocking.block_size",
                format!(
                    "{} is not allowed; allowed a power of two 4..=256",
                    b.block_size
                ),
            );
        }
        check_range(
            source,
            "blocking.lookup_latency",
            b.lookup_latency as u64,
            0,
            64,
        )?;
        if !b.enabled {
            return Ok(());
        }
        for (field, size) in [
            ("bricks.size", self.bricks.size),
            ("occupancy.subcube", self.occupancy.subcube),
        ] {
            if size > b.block_size {
                return err(
                    "blocking.block_size",
                    format!(
                        "{} is smaller than {field} ({size}); a block must hold whole bricks \
                         and sub-cubes",
                        b.block_size
                    ),
                );
            }
        }
        if self.occupancy.structure != LeapStructure::Map {
            return err(
                "blocking.enabled",
                format!(
                    "blocking works with occupancy.structure = \"map\" only (not {}): the \
                     distance volume and leap values are stored in volume memory outside the \
                     blocks",
                    toml::Value::try_from(self.occupancy.structure)
                        .map(|v| v.to_string())
                        .unwrap_or_default()
                ),
            );
        }
        if self.iso.enabled {
            return err(
                "blocking.enabled",
                "blocking is not modelled in iso mode (iso.enabled): the block table is built \
                 from the transfer function's visibility, not from the iso test"
                    .to_string(),
            );
        }
        Ok(())
    }

    /// `[bricks]`, `[clip]`, `[geometry]` and `[iso]`.
    fn validate_ray_range(&self, source: &str) -> Result<()> {
        let b = &self.bricks;
        if b.size != 0 && !BRICK_SIZES.contains(&b.size) {
            return Err(Error::config(
                source,
                "bricks.size",
                format!(
                    "{} is not allowed; allowed 0 (off) or a power of two in {BRICK_SIZES:?}",
                    b.size
                ),
            ));
        }
        let range =
            |field: &str, value: u64, lo: u64, hi: u64| check_range(source, field, value, lo, hi);
        range(
            "bricks.setup_cycles_per_ray",
            b.setup_cycles_per_ray as u64,
            0,
            1 << 16,
        )?;
        range(
            "bricks.setup_cycles_per_brick",
            b.setup_cycles_per_brick as u64,
            0,
            1 << 16,
        )?;
        range(
            "bricks.table_entry_bytes",
            b.table_entry_bytes as u64,
            1,
            64,
        )?;
        range("bricks.setup_units", b.setup_units as u64, 1, 64)?;
        let finite = |field: String, v: &[f32]| -> Result<()> {
            if v.iter().all(|x| x.is_finite() && x.abs() <= 1e6) {
                Ok(())
            } else {
                Err(Error::config(
                    source,
                    field,
                    format!("{v:?}: every component must be finite, |x| <= 1e6"),
                ))
            }
        };
        for (i, plane) in self.clip.planes.iter().enumerate() {
            finite(format!("clip.planes[{i}].point"), &plane.point)?;
            finite(format!("clip.planes[{i}].normal"), &plane.normal)?;
            if plane.normal.iter().all(|&x| x == 0.0) {
                return Err(Error::config(
                    source,
                    format!("clip.planes[{i}].normal"),
                    "is zero; a clip plane needs a non-zero normal (it points to the kept side)",
                ));
            }
        }
        match self.clip.clip_box.as_slice() {
            [] => {}
            [lo, hi] => {
                finite("clip.box".into(), lo)?;
                finite("clip.box".into(), hi)?;
                if (0..3).any(|a| lo[a] > hi[a]) {
                    return Err(Error::config(
                        source,
                        "clip.box",
                        format!("max corner {hi:?} is below the min corner {lo:?} on some axis"),
                    ));
                }
            }
            other => {
                return Err(Error::config(
                    source,
                    "clip.box",
                    format!(
                        "{} corners; expected none or two: [[min x, y, z], [max x, y, z]]",
                        other.len()
                    ),
                ))
            }
        }
        let g = &self.geometry;
        finite("geometry.centre".into(), &g.centre)?;
        if !(g.radius.is_finite() && g.radius > 0.0 && g.radius <= 1e6) {
            return Err(Error::config(
                source,
                "geometry.radius",
                format!("{:?} is out of range; allowed (0, 1e6] voxels", g.radius),
            ));
        }
        if g.colour.iter().any(|c| !(0.0..=1.0).contains(c)) {
            return Err(Error::config(
                source,
                "geometry.colour",
                format!("{:?}: each component allowed 0..=1", g.colour),
            ));
        }
        finite("geometry.end".into(), &g.end)?;
        if g.shape == GeometryShape::Cylinder && g.end == g.centre {
            return Err(Error::config(
                source,
                "geometry.end",
                "equals geometry.centre; a cylinder needs an axis of non-zero length",
            ));
        }
        if g.shape == GeometryShape::DepthFile && g.file.is_empty() {
            return Err(Error::config(
                source,
                "geometry.file",
                "is empty; geometry.shape = \"depth-file\" needs a depth image file",
            ));
        }
        let iso = &self.iso;
        range(
            "iso.refinement_steps",
            iso.refinement_steps as u64,
            0,
            MAX_REFINEMENT_STEPS as u64,
        )?;
        if !(iso.value.is_finite() && (0.0..=65535.0).contains(&iso.value)) {
            return Err(Error::config(
                source,
                "iso.value",
                format!(
                    "{:?} is out of range; allowed 0 (half the dataset's largest density) or a \
                     density in (0, 65535]",
                    iso.value
                ),
            ));
        }
        if iso.colour.iter().any(|c| !(0.0..=1.0).contains(c)) {
            return Err(Error::config(
                source,
                "iso.colour",
                format!("{:?}: each component allowed 0..=1", iso.colour),
            ));
        }
        if iso.enabled && self.occupancy.structure == LeapStructure::LeapValues {
            return Err(Error::config(
                source,
                "iso.enabled",
                "true needs occupancy.structure = \"map\" or \"distance\"; leap values in \
                 the volume are not supported in iso mode"
                    .to_string(),
            ));
        }
        Ok(())
    }
}

/// Adds the optional sections (`[bricks]`, `[clip]`, `[geometry]`, `[iso]`) with their defaults
/// where a table lacks them, and their missing fields (they are not written out when off).
fn insert_default_sections(table: &mut toml::Table) {
    // `ray.interleave` is written out only when not 1.
    if let Some(toml::Value::Table(ray)) = table.get_mut("ray") {
        ray.entry("interleave").or_insert(toml::Value::Integer(1));
    }
    for (name, default) in [
        ("bricks", toml::Table::try_from(BricksConfig::default())),
        ("clip", toml::Table::try_from(ClipConfig::default())),
        ("geometry", toml::Table::try_from(GeometryConfig::default())),
        ("blocking", toml::Table::try_from(BlockingConfig::default())),
        ("iso", toml::Table::try_from(IsoConfig::default())),
    ] {
        let Ok(default) = default else { continue };
        match table.get_mut(name) {
            // A section without some fields (written before they existed): add them.
            Some(toml::Value::Table(section)) => {
                for (key, value) in default {
                    section.entry(key).or_insert(value);
                }
            }
            Some(_) => {}
            None => {
                table.insert(name.to_string(), toml::Value::Table(default));
            }
        }
    }
}

/// An error naming `source` and `field` when `value` is outside `lo..=hi`.
fn check_range(source: &str, field: &str, value: u64, lo: u64, hi: u64) -> Result<()> {
    if value < lo || value > hi {
        return Err(Error::config(
            source,
            field,
            format!("{value} is out of range; allowed {lo}..={hi}"),
        ));
    }
    Ok(())
}

/// The field path an override sets (`occupancy.subcube` of `occupancy.subcube = 8`), as
/// `apply_override` reads it.
pub fn override_path(assignment: &str) -> &str {
    assignment.split('=').next().unwrap_or_default().trim()
}

/// Applies `a.b.c=value` to a TOML table. The value is read as TOML (`8`, `true`, `0.9`,
/// `"class"`); a bare word that is not TOML is taken as a string (`kind=class`). The path must
/// name an existing field, so a typo is an error rather than a silently ignored setting.
pub fn apply_override(table: &mut toml::Table, assignment: &str) -> Result<()> {
    let bad = |msg: &str| Error::config("--set", assignment, msg);
    let (_, raw) = assignment
        .split_once('=')
        .ok_or_else(|| bad("expected section.field=value"))?;
    let path = override_path(assignment);
    let raw = raw.trim();
    let value: toml::Value = toml::from_str::<toml::Table>(&format!("v = {raw}"))
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(raw.to_string()));
    let keys: Vec<&str> = path.split('.').collect();
    let (last, parents) = keys.split_last().ok_or_else(|| bad("empty field path"))?;
    let mut current = table;
    for key in parents {
        // A misspelt section is named with the sections there, as a misspelt field is.
        let problem = match current.get(*key) {
            Some(v) if v.is_table() => None,
            Some(_) => Some(format!("`{key}` is a field, not a section")),
            None => Some(format!(
                "no section `{key}`; sections here: {}",
                current
                    .iter()
                    .filter(|(_, v)| v.is_table())
                    .map(|(k, _)| k.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )),
        };
        if let Some(problem) = problem {
            return Err(Error::config("--set", path, problem));
        }
        current = current
            .get_mut(*key)
            .and_then(|v| v.as_table_mut())
            .expect("checked above: a section");
    }
    match current.get_mut(*last) {
        // A number TOML cannot hold would otherwise reach the field as a string, and be
        // reported as the wrong type rather than as too large.
        Some(_) if value.is_str() && too_large_for_toml(raw) => Err(Error::config(
            "--set",
            path,
            format!(
                "{raw} is too large a number: TOML reads whole numbers as 64-bit integers and \
                 others as 64-bit floats"
            ),
        )),
        Some(slot) if !slot.is_table() => {
            *slot = value;
            Ok(())
        }
        Some(_) => Err(Error::config("--set", path, "is a section, not a field")),
        None => Err(Error::config(
            "--set",
            path,
            format!(
                "unknown field `{last}`; fields here: {}",
                current.keys().cloned().collect::<Vec<_>>().join(", ")
            ),
        )),
    }
}

/// Whether `raw` is a number as TOML writes it (an integer, decimal with an optional sign or
/// `0x`/`0o`/`0b`, or a float) whose value TOML cannot hold; other text TOML refuses (`007`,
/// `1__0`, a file name) is not.
fn too_large_for_toml(raw: &str) -> bool {
    // Digits with single underscores between them, as TOML allows.
    let digits = |s: &str, digit: fn(char) -> bool| {
        !s.is_empty()
            && s.split('_')
                .all(|group| !group.is_empty() && group.chars().all(digit))
    };
    let unsigned = raw.strip_prefix(['+', '-']).unwrap_or(raw);
    let prefixed = [
        ("0x", (|c: char| c.is_ascii_hexdigit()) as fn(char) -> bool),
        ("0o", |c: char| ('0'..='7').contains(&c)),
        ("0b", |c: char| c == '0' || c == '1'),
    ];
    for (prefix, digit) in prefixed {
        if let Some(rest) = raw.strip_prefix(prefix) {
            return digits(rest, digit);
        }
    }
    let decimal = |s: &str| digits(s, |c| c.is_ascii_digit()) && (s == "0" || !s.starts_with('0'));
    if decimal(unsigned) {
        return true;
    }
    // A float: an integer part, then a fraction, an exponent or both; too large if it
    // overflows to infinity.
    let starts_with_digit = unsigned.starts_with(|c: char| c.is_ascii_digit());
    starts_with_digit
        && unsigned.contains(['.', 'e', 'E'])
        && raw
            .replace('_', "")
            .parse::<f64>()
            .is_ok_and(|v| v.is_infinite())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    /// Field paths of a table's leaves (a value that is not a table; arrays of tables such as
    /// `clip.planes` are one field).
    fn leaf_paths(table: &toml::Table, prefix: &str, out: &mut Vec<String>) {
        for (key, value) in table {
            let path = format!("{prefix}{key}");
            match value {
                toml::Value::Table(t) => leaf_paths(t, &format!("{path}."), out),
                _ => out.push(path),
            }
        }
    }

    /// The fields the first column of docs/config.md's field table names. A name without a
    /// section (`t_rcd` in "`sdram.cl`, `t_rcd`") belongs to the section named before it in
    /// its cell.
    fn documented_fields() -> Vec<String> {
        let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/config.md"))
            .expect("docs/config.md");
        let rows = doc
            .lines()
            .skip_while(|l| !l.starts_with("| field | default | allowed | meaning |"))
            .skip(2)
            .take_while(|l| l.starts_with('|'));
        let mut fields = Vec::new();
        for row in rows {
            let first_cell = row.split('|').nth(1).unwrap_or_default();
            let mut section = String::new();
            for name in first_cell.split('`').skip(1).step_by(2) {
                match name.rsplit_once('.') {
                    Some((s, _)) => {
                        section = s.to_string();
                        fields.push(name.to_string());
                    }
                    None => fields.push(format!("{section}.{name}")),
                }
            }
        }
        fields
    }

    /// A number too large for TOML is named as too large, not as "invalid type: string";
    /// numbers that fit, words, quoted digits and text TOML refuses for other reasons (a
    /// leading zero: a file named `007`) are read as before, and a wrong field path is named
    /// first.
    #[test]
    fn an_override_too_large_for_toml_is_named_so() {
        let mut table: toml::Table = DEFAULT_TOML.parse().expect("the embedded default");
        for raw in [
            "99999999999999999999",
            "-99999999999999999999",
            "+10_000_000_000_000_000_000",
            "0xFFFFFFFFFFFFFFFFFF",
            "0b11111111111111111111111111111111111111111111111111111111111111111",
            "1e999",
            "-1.5e999",
        ] {
            let e = apply_override(&mut table, &format!("sdram.cl={raw}"))
                .expect_err(raw)
                .to_string();
            assert!(
                e.contains("sdram.cl") && e.contains("too large a number"),
                "{e}"
            );
        }
        for raw in [
            "007",
            "1__0",
            "_1",
            "1_",
            "00000000000000000000000",
            "0x",
            "1e5x",
        ] {
            assert!(!too_large_for_toml(raw), "{raw}");
        }
        apply_override(&mut table, "geometry.file=007").expect("a file name of digits");
        assert_eq!(table["geometry"]["file"].as_str(), Some("007"));
        let e = apply_override(&mut table, "sdram.nosuch=99999999999999999999")
            .expect_err("no such field")
            .to_string();
        assert!(e.contains("unknown field `nosuch`"), "{e}");
        apply_override(&mut table, "sdram.cl=3").expect("a number that fits");
        assert_eq!(table["sdram"]["cl"].as_integer(), Some(3));
        apply_override(&mut table, "memory.row_policy=close").expect("a bare word");
        assert_eq!(table["memory"]["row_policy"].as_str(), Some("close"));
        apply_override(&mut table, "memory.row_policy=\"42\"").expect("quoted digits");
        assert_eq!(table["memory"]["row_policy"].as_str(), Some("42"));
    }

    /// Every field `--set` can set on the default configuration has its row in
    /// docs/config.md (default, range, meaning), and every row names such a field: the
    /// reference cannot drift from the configuration as fields come and go.
    #[test]
    fn docs_config_md_documents_every_field_and_only_fields() {
        let mut table: toml::Table = DEFAULT_TOML.parse().expect("the embedded default");
        insert_default_sections(&mut table);
        let mut settable = Vec::new();
        leaf_paths(&table, "", &mut settable);
        let settable: BTreeSet<String> = settable.into_iter().collect();
        let documented: BTreeSet<String> = documented_fields().into_iter().collect();
        assert!(
            documented.len() > 60,
            "the table was not found: {documented:?}"
        );
        let undocumented: Vec<&String> = settable.difference(&documented).collect();
        assert!(
            undocumented.is_empty(),
            "fields without a row in docs/config.md: {undocumented:?}"
        );
        let unknown: Vec<&String> = documented.difference(&settable).collect();
        assert!(
            unknown.is_empty(),
            "docs/config.md has rows for fields --set does not know: {unknown:?}"
        );
    }
}

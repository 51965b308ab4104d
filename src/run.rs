//! One run path. A run is described once (`RunDescription`: dataset, transfer function, view,
//! model, memory, hardware with its leaping and ERT fields) and executed by one function
//! (`execute`) that returns one report type (`RunReport`). Every command (`render`, `sim`,
//! `sweep`, `precision`, `demo`) builds descriptions and calls it, so their defaults and their
//! figures cannot drift apart.
//!
//! Preparing a run (`prepare`: transfer function, classification table, occupancy map) does
//! not depend on the view, so callers that render many views of one setting (a sweep's frame
//! group, an orbit) prepare once and execute per view.

use std::borrow::Cow;
use std::time::Instant;

use serde::Serialize;
use serde_json::Value;

use crate::arch::address_map::AddressMap;
use crate::arch::block_lookup::BlockLookup;
use crate::arch::command_trace::CommandTrace;
use crate::arch::pipeline::{
    simulate_with, tile_order, CycleResult, CycleStats, SimOptions, StallCycles,
};
use crate::arch::sampling::{seed_of, simulate_sampled, SampledEstimate, Sampling, Warm};
use crate::arch::sdram_module::SdramMemory;
use crate::arch::trace::Waveform;
use crate::arch::voxel_memory::{IdealMemory, VoxelMemory};
use crate::blocking::{BlockTable, BlockingStats};
use crate::bricks::RayRangeStats;
use crate::camera::{check_image_size, Camera, Projection, View};
use crate::compare::Comparison;
use crate::config::{HardwareConfig, LeapRegions, LeapStructure, RaySelection};
use crate::error::{Error, Result};
use crate::functional::leaping::ConfiguredSkipper;
use crate::functional::renderer::{FixedRenderer, Leaping};
use crate::leapvalues::{distance_volume, DistanceVolume, LeapValueStats, LeapValueVolume};
use crate::occupancy::OccupancyKind;
use crate::render::float::FloatRenderer;
use crate::render::{Frame, FrameStats, RayRecord, RenderSettings};
use crate::transfer;
use crate::volume::Volume;

/// Which of the three models renders the frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Model {
    /// The floating-point reference ray caster.
    Float,
    /// The functional fixed-point model: counts steps (samples + leaps).
    Step,
    /// The cycle-accurate pipeline.
    Cycle,
}

impl Model {
    pub fn name(self) -> &'static str {
        match self {
            Model::Float => "float",
            Model::Step => "step",
            Model::Cycle => "cycle",
        }
    }

    /// `float`, `step` (alias `fixed`) or `cycle`.
    pub fn parse(text: &str) -> std::result::Result<Model, String> {
        match text {
            "float" => Ok(Model::Float),
            "step" | "fixed" => Ok(Model::Step),
            "cycle" => Ok(Model::Cycle),
            other => Err(format!(
                "`{other}`: expected `float`, `step` (or `fixed`) or `cycle`"
            )),
        }
    }
}

/// The cycle model's voxel memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase", tag = "kind")]
pub enum Memory {
    /// SDRAM modules, banks, address and voxel FIFOs, overtaking (`[memory]`, `[sdram]`).
    Sdram,
    /// Every request served after a fixed latency with unlimited bandwidth: the bound with
    /// free memory.
    Ideal { latency: u64 },
}

/// Largest latency of the ideal memory, in cycles.
pub const MAX_IDEAL_LATENCY: u64 = 1 << 20;

/// Everything that decides a frame's result.
#[derive(Clone, Debug, Serialize)]
pub struct RunDescription {
    /// Dataset name, phantom spec or file.
    pub dataset: String,
    /// Transfer function: `zero`, `class`, a preset name or a TOML file.
    pub tf: String,
    /// `front` or `orbit:K/N`.
    pub view: String,
    pub projection: Projection,
    /// Image width and height in pixels.
    pub size: (u32, u32),
    /// Distance between samples along a ray, in voxels.
    pub sample_spacing: f32,
    /// Phong shading from per-voxel gradients.
    pub shading: bool,
    pub model: Model,
    /// The cycle model's memory (ignored by the other models).
    pub memory: Memory,
    /// The resolved hardware configuration: widths, leaping (`occupancy`), ERT
    /// (`compositing`), the pipeline and the memory. The float model takes its ERT threshold.
    pub hardware: HardwareConfig,
    /// Cycle model: simulate a sample of the frame and estimate its timing (docs/sampling.md);
    /// `None` (the default) simulates every cycle. Written out only when set.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sample: Option<Sampling>,
}

impl RunDescription {
    /// A front view at 256×256, orthographic, one sample per voxel, no shading, SDRAM: the
    /// published protocol's defaults.
    pub fn new(dataset: &str, tf: &str, model: Model, hardware: HardwareConfig) -> Self {
        RunDescription {
            dataset: dataset.to_string(),
            tf: tf.to_string(),
            view: "front".into(),
            projection: Projection::Ortho,
            size: (256, 256),
            sample_spacing: 1.0,
            shading: false,
            model,
            memory: Memory::Sdram,
            hardware,
            sample: None,
        }
    }

    /// The render settings every model shares: spacing, shading, ERT from the hardware.
    pub fn settings(&self) -> RenderSettings {
        RenderSettings {
            sample_spacing: self.sample_spacing,
            ert_threshold: self.hardware.ert_threshold(),
            shading: self.shading,
            interleave: self.hardware.ray.interleave,
            ..RenderSettings::default()
        }
    }

    /// The sampling a sampled run simulates with: the description's, its warm-up raised to
    /// `LONG_WARMUP_RAYS` where a ray waits for its own reads before each step (a distance
    /// volume), which a short warm-up leaves biased low (docs/sampling.md, "Limits").
    pub fn sampling(&self) -> Option<Sampling> {
        self.sample.map(|mut sampling| {
            if self.hardware.occupancy.structure == LeapStructure::Distance {
                sampling.warmup_rays = sampling
                    .warmup_rays
                    .max(crate::arch::sampling::LONG_WARMUP_RAYS);
            }
            sampling
        })
    }

    /// Checks what the hardware configuration's own validation cannot: view, size, spacing
    /// and memory.
    pub fn validate(&self) -> Result<()> {
        View::parse(&self.view)?;
        check_image_size(self.size.0, self.size.1)?;
        check_frame_budget(self.size)?;
        self.settings().validate()?;
        // Checked again here, not only when the configuration was read: an experiment's mode
        // sets the leaping structure, bricks and iso mode after that (a sweep crossed blocking
        // with distance volumes, which `sim` refuses, and reported cycles for it).
        self.hardware.validate("the run's hardware configuration")?;
        if let Some(sampling) = &self.sample {
            sampling.validate("sample")?;
            if self.model != Model::Cycle {
                return Err(Error::Invalid(format!(
                    "sampling (rate {}) applies to the cycle model only; the {} model is \
                     exact and fast",
                    sampling.rate,
                    self.model.name()
                )));
            }
            // Measured: on fuel at 128² (rate 0.05) the estimate falls 9–11 % low, outside its
            // interval; the waits for a leap voxel's words are not what the sample sees.
            if self.hardware.occupancy.structure == LeapStructure::LeapValues {
                return Err(Error::Invalid(format!(
                    "sampling (rate {}) is not available with leap values in the volume: its \
                     estimates fall about 10 % low, outside their interval (docs/sampling.md, \
                     \"Limits\"); run this structure exactly",
                    sampling.rate
                )));
            }
        }
        // Leap values share the voxel word with the density, and shading stores a gradient
        // there too (`shading.gradient_bits` per component): all must fit the word. The
        // fixed-point models model that word; the float reference does not.
        if self.shading
            && self.model != Model::Float
            && self.hardware.occupancy.structure == LeapStructure::LeapValues
        {
            let word = &self.hardware.volume_word;
            let gradient = 3 * self.hardware.shading.gradient_bits;
            let needed = word.density_bits + 1 + word.leap_bits + gradient;
            if needed > word.word_bits {
                return Err(Error::config(
                    "hardware configuration",
                    "volume_word.word_bits",
                    format!(
                        "leap values with shading need {needed} bits per voxel word ({} density, \
                         1 flag, {} leap, 3 × {} gradient), the word has {}; turn shading off, \
                         or narrow volume_word.density_bits, volume_word.leap_bits or \
                         shading.gradient_bits",
                        word.density_bits,
                        word.leap_bits,
                        self.hardware.shading.gradient_bits,
                        word.word_bits
                    ),
                ));
            }
        }
        // Every volume has at least 8 bits: a gradient that does not fit the word beside 8 is
        // refused here, before a sweep's first run (`check_gradient_word` refines it with the
        // volume's own width when it is loaded).
        if self.model == Model::Cycle && self.memory == Memory::Sdram {
            check_gradient_word(self, None)?;
        }
        if let Memory::Ideal { latency } = self.memory {
            if !(1..=MAX_IDEAL_LATENCY).contains(&latency) {
                return Err(Error::Invalid(format!(
                    "ideal memory latency {latency}: allowed 1..={MAX_IDEAL_LATENCY} cycles"
                )));
            }
        }
        Ok(())
    }

    /// The leaping a model runs: the configuration's for the fixed-point models; for the
    /// float reference only homogeneous leap values, the one structure that changes the image
    /// (every other one only skips zero-opacity samples).
    pub fn leaping(&self) -> Leaping {
        match (self.model, Leaping::from_config(&self.hardware)) {
            (
                Model::Float,
                l @ Leaping::LeapValues {
                    regions: LeapRegions::Homogeneous,
                    ..
                },
            ) => l,
            (Model::Float, _) => Leaping::None,
            (Model::Step | Model::Cycle, l) => l,
        }
    }

    /// What this run reads of its configuration (`HardwareConfig::why_without_effect`).
    pub fn config_use(&self) -> crate::config::ConfigUse {
        crate::config::ConfigUse {
            model: self.model,
            not_leaping: self.why_not_leaping(),
        }
    }

    /// Why the run's occupancy hierarchy groups nothing on a volume of `dims`
    /// (`occupancy::hierarchy_without_effect`); None without one, or when it can group.
    pub fn hierarchy_without_effect(&self, dims: [usize; 3]) -> Option<String> {
        match self.leaping() {
            Leaping::Occupancy {
                subcube,
                hierarchy: true,
                ..
            } => crate::occupancy::hierarchy_without_effect(dims, subcube),
            _ => None,
        }
    }

    /// Why this run does not leap although its configuration may ask it to (the float
    /// reference, but with homogeneous leap values), None when it leaps as configured: then
    /// the leaping structure's fields are without effect
    /// (`HardwareConfig::settings_without_effect`).
    pub fn why_not_leaping(&self) -> Option<&'static str> {
        (self.model == Model::Float && self.leaping() == Leaping::None)
            .then_some("the float model does not leap")
    }

    /// The camera of this run's view of a volume.
    pub fn camera(&self, volume: &Volume) -> Result<Camera> {
        Camera::for_volume(
            glam::Vec3::from(volume.extent()),
            View::parse(&self.view)?,
            self.projection,
            self.size.0,
            self.size.1,
        )
    }
}

/// Both boxed: each holds its tables and, when configured, a leaping structure.
enum Renderer<'v> {
    Float(Box<FloatRenderer<'v>>),
    Fixed(Box<FixedRenderer<'v>>),
}

/// A run made ready for any view: transfer function, tables, occupancy map.
pub struct Prepared<'v> {
    volume: &'v Volume,
    /// The transfer function's name (a preset's or the file's).
    pub transfer_function: String,
    renderer: Renderer<'v>,
}

impl<'v> Prepared<'v> {
    /// The volume the run was prepared for.
    pub fn volume(&self) -> &'v Volume {
        self.volume
    }

    /// The fixed-point renderer, for the step and cycle models.
    pub fn fixed(&self) -> Option<&FixedRenderer<'v>> {
        match &self.renderer {
            Renderer::Fixed(r) => Some(r),
            Renderer::Float(_) => None,
        }
    }

    /// Replaces the occupancy map the run leaps with by `map` (built elsewhere: the update
    /// engine's map of a dynamic sequence, conservative for the volume). An error when the run
    /// does not leap with an occupancy map or `map` has another grid.
    pub fn set_occupancy_map(&mut self, map: crate::occupancy::OccupancyMap) -> Result<()> {
        match &mut self.renderer {
            Renderer::Fixed(r) => match &r.map {
                Some(old) if old.dims == map.dims && old.cube_log2 == map.cube_log2 => {
                    r.map = Some(map);
                    Ok(())
                }
                _ => Err(Error::Invalid(format!(
                    "the run leaps without an occupancy map of {:?} sub-cubes of edge {}",
                    map.dims,
                    map.subcube_size()
                ))),
            },
            Renderer::Float(_) => Err(Error::Invalid(
                "the float model does not leap with an occupancy map".into(),
            )),
        }
    }

    /// Replaces the bounding bricks' flags by `map` (built elsewhere: the update engine's, in a
    /// dynamic sequence). An error when the run has no bricks or `map` has another grid.
    pub fn set_brick_map(&mut self, map: crate::occupancy::OccupancyMap) -> Result<()> {
        match &mut self.renderer {
            Renderer::Fixed(r) => match &mut r.ray_range {
                Some(range) => range.set_brick_map(map),
                None => Err(Error::Invalid("the run has no bricks".into())),
            },
            Renderer::Float(_) => Err(Error::Invalid(
                "the float model's bricks come from its own table".into(),
            )),
        }
    }

    /// The distance volume of `bits` this run's renderer would build for the transfer function
    /// and the map kind `kind` (as `FixedRenderer::new` builds it: '0' any non-zero voxel,
    /// class the classification table's test). Fixed-point models only.
    pub fn build_distance_volume(&self, bits: u32, kind: OccupancyKind) -> Result<DistanceVolume> {
        let Renderer::Fixed(r) = &self.renderer else {
            return Err(Error::Invalid(
                "the float model has no distance volume".into(),
            ));
        };
        if kind == OccupancyKind::Zero {
            crate::functional::renderer::check_zero_is_invisible(&r.table)?;
        }
        distance_volume(self.volume, bits, |lo, hi| match kind {
            OccupancyKind::Zero => hi > 0,
            OccupancyKind::Class => r.table.any_visible(lo, hi),
        })
    }

    /// Makes a run prepared without leaping leap with `distance` (kind `kind`), as if it had
    /// been prepared with the distance structure of `distance.bits` bits: the advisor builds one
    /// transform and narrows it for each width (`DistanceVolume::narrowed`). An error for a
    /// run that already leaps or is not fixed-point, or a volume of other dimensions.
    pub fn set_distance_volume(
        &mut self,
        distance: DistanceVolume,
        kind: OccupancyKind,
    ) -> Result<()> {
        match &mut self.renderer {
            Renderer::Fixed(r)
                if r.leaping == Leaping::None
                    && r.leap_values.is_none()
                    && distance.dims == self.volume.dims =>
            {
                r.leaping = Leaping::Distance {
                    bits: distance.bits,
                    kind,
                };
                r.set_distance_volume(distance);
                Ok(())
            }
            _ => Err(Error::Invalid(
                "a distance volume replaces no leaping of a fixed-point run of the same volume"
                    .into(),
            )),
        }
    }

    /// Leap values in the volume: what preprocessing found.
    pub fn leap_value_stats(&self) -> Option<LeapValueStats> {
        match &self.renderer {
            Renderer::Fixed(r) => r.leap_values.as_ref().map(|l| l.stats),
            Renderer::Float(r) => r.leap_value_stats(),
        }
    }
}

/// Bytes one frame of this size holds per pixel: the RGBA8 pixel, its ray record and the cycle
/// model's per-ray state (an estimate for the memory budget, rounded up).
/// Refuses a frame whose pixels and ray records would not fit the memory budget.
pub fn check_frame_budget(size: (u32, u32)) -> Result<()> {
    crate::budget::check(&format!("a {}x{} frame", size.0, size.1), frame_bytes(size))
}

fn frame_bytes(size: (u32, u32)) -> u64 {
    size.0 as u64 * size.1 as u64 * (4 + std::mem::size_of::<RayRecord>() as u64 + 96)
}

/// Bytes per voxel the structures built from the volume take at their peak (an estimate for
/// the memory budget, rounded up): leap-value preprocessing keeps labels, classes, squared
/// distances and two word arrays at once; the distance volume its transform; shading 3×16-bit
/// gradients.
fn structure_bytes_per_voxel(run: &RunDescription) -> u64 {
    let leaping = match Leaping::from_config(&run.hardware) {
        Leaping::LeapValues { .. } => 32,
        Leaping::Distance { .. } => 12,
        _ => 0,
    };
    leaping + if run.shading { 6 } else { 0 }
}

/// What preparing `run` on `volume` refuses before it builds anything: the memory budget for
/// its structures and frame, and with the SDRAM model the voxel word and the rows the volume
/// needs. `prepare` checks it first; a sweep checks it for every configuration when it expands
/// (with `blocked_fit_table` and `check_blocked_fit`), so that such a run is refused before a result is
/// written rather than stopping the sweep when its turn comes.
pub fn check_on_volume(run: &RunDescription, volume: &Volume) -> Result<()> {
    crate::budget::check(
        &format!("this run's structures for `{}`", volume.name),
        volume.data.len() as u64 * structure_bytes_per_voxel(run) + frame_bytes(run.size),
    )?;
    if run.model == Model::Cycle && run.memory == Memory::Sdram {
        check_gradient_word(run, Some(volume.bits))?;
        let distance = matches!(run.leaping(), Leaping::Distance { .. });
        if let Err(e) = check_volume_memory(&run.hardware, volume.dims, distance) {
            let tf = transfer::resolve_for(&run.tf, volume)?;
            return Err(with_blocking_hint(e, run, volume, &tf, &run.settings()));
        }
    }
    Ok(())
}

/// With blocking and the SDRAM model, the blocks the transfer function makes active must fit
/// the memory's slots (`check_blocked_fit`). `prepare` checks the renderer's own table; a
/// sweep's expansion builds the same table here (the blocks depend on the dataset and the
/// transfer function, so a configuration alone cannot tell) and keeps it for the
/// configurations that share it.
/// None when the run has no such check (not the SDRAM model, or no blocking).
pub fn blocked_fit_table(run: &RunDescription, volume: &Volume) -> Result<Option<BlockTable>> {
    let config = &run.hardware;
    if !(run.model == Model::Cycle && run.memory == Memory::Sdram && config.blocking.enabled) {
        return Ok(None);
    }
    let size = crate::blocking::check_block_size(config.blocking.block_size, volume.dims)?;
    let tf = transfer::resolve_for(&run.tf, volume)?;
    Ok(Some(block_table(
        run,
        volume,
        &tf,
        &run.settings(),
        1 << size,
    )))
}

/// The block table of edge `size` the fixed-point renderer builds for `run` (blocking works
/// with the occupancy map only, so from the dataset itself).
fn block_table(
    run: &RunDescription,
    volume: &Volume,
    tf: &transfer::TransferFunction,
    settings: &RenderSettings,
    size: usize,
) -> BlockTable {
    let config = &run.hardware;
    let table = crate::functional::arith::ClassificationTable::build(
        tf,
        volume.max_value() as usize + 1,
        config.classification.lut_bits,
        settings.sample_spacing,
    );
    BlockTable::build(
        volume,
        config.occupancy.kind,
        size.trailing_zeros(),
        table.any_visible(0, 0),
        |lo, hi| table.any_visible(lo, hi),
    )
}

/// The blocked volume's active blocks must fit the memory's slots.
pub fn check_blocked_fit(
    run: &RunDescription,
    dims: [usize; 3],
    blocks: &BlockTable,
) -> Result<()> {
    let memory = &run.hardware.memory;
    let stats = BlockingStats::new(blocks, memory, dims, 0);
    if stats.fits(memory) {
        return Ok(());
    }
    Err(Error::config(
        "hardware configuration",
        "memory.rows",
        format!(
            "the {dims:?} volume does not fit with blocking: {}; the modules have {} rows per \
             bank{}",
            stats.describe(),
            memory.rows,
            if stats.rows_unblocked <= memory.rows as u64 {
                format!(
                    ", and without blocking it takes {} (a slot of (B + 2)³ voxels fills whole \
                     rows; use a larger blocking.block_size or none)",
                    stats.rows_unblocked
                )
            } else {
                String::new()
            }
        ),
    ))
}

/// What `prepare` refuses for `run` on `volume` that can be told without building its
/// structures: the run's own checks (`RunDescription::validate`, the hardware's included),
/// `check_on_volume`, and with blocking and the SDRAM model the block size dividing the volume
/// and the active blocks fitting the memory (the checks a sweep makes when it expands). The
/// occupancy map's SRAM fit needs the map's size only: `occupancy::map_bits`. `advise` checks
/// every candidate with it, so that what it calls fitting is what `sim` runs.
pub fn check_without_building(run: &RunDescription, volume: &Volume) -> Result<()> {
    run.validate()?;
    check_on_volume(run, volume)?;
    if let Some(table) = blocked_fit_table(run, volume)? {
        check_blocked_fit(run, volume.dims, &table)?;
    }
    Ok(())
}

/// Validates `run` and prepares it on `volume` (which must be the run's dataset).
pub fn prepare<'v>(run: &RunDescription, volume: &'v Volume) -> Result<Prepared<'v>> {
    run.validate()?;
    check_on_volume(run, volume)?;
    let tf = transfer::resolve_for(&run.tf, volume)?;
    let settings = run.settings();
    let renderer = match run.model {
        Model::Float => {
            let mut renderer = FloatRenderer::new(volume, &tf, &settings)?;
            if let Leaping::LeapValues { .. } = run.leaping() {
                // Homogeneous: every region leaps, whatever the transfer function.
                let words = LeapValueVolume::build(
                    volume,
                    &run.hardware.leap_values,
                    &run.hardware.volume_word,
                    settings.sample_spacing,
                    |_, _| true,
                )?;
                renderer = renderer.with_leap_values(words);
            }
            Renderer::Float(Box::new(
                renderer
                    .with_iso(&run.hardware)?
                    .with_ray_range(&run.hardware)?,
            ))
        }
        Model::Step | Model::Cycle => {
            let sdram = run.model == Model::Cycle && run.memory == Memory::Sdram;
            let renderer =
                FixedRenderer::new(volume, &tf, &settings, &run.hardware, run.leaping())?;
            if let (true, Some(blocks)) = (sdram, &renderer.blocks) {
                check_blocked_fit(run, volume.dims, blocks)?;
            }
            Renderer::Fixed(Box::new(renderer))
        }
    };
    // A depth image must match the image it is rendered into.
    if let Some(scene) = crate::clip::Scene::from_config(&run.hardware)? {
        scene.check_image_size(run.size.0, run.size.1)?;
    }
    Ok(Prepared {
        volume,
        transfer_function: tf.name,
        renderer,
    })
}

/// With shading (or the iso surface, which shades its hit), each voxel word holds the density
/// and the three stored gradient components, as VIZARD II's 32-bit word holds 8 + 3 × 8 bits.
/// The SDRAM model reads one word per voxel, so a voxel that does not fit its word is refused
/// rather than timed as if it did. (With leap values `validate` checks the word with their
/// fields too.)
/// `volume_bits` None: the smallest width a volume has (8), before the volume is loaded.
fn check_gradient_word(run: &RunDescription, volume_bits: Option<u8>) -> Result<()> {
    let hardware = &run.hardware;
    if !(run.shading || hardware.iso.enabled) {
        return Ok(());
    }
    let word = hardware.volume_word.word_bits;
    let gradient = hardware.shading.gradient_bits;
    let bits = volume_bits.unwrap_or(8) as u32;
    let needed = bits + 3 * gradient;
    if needed > word {
        let fits = word.saturating_sub(bits) / 3;
        let volume = match volume_bits {
            Some(bits) => format!("a shaded {bits}-bit volume needs"),
            None => "a shaded volume needs at least".to_string(),
        };
        return Err(Error::config(
            "hardware configuration",
            "shading.gradient_bits",
            format!(
                "{volume} {needed} bits per voxel word ({bits} density + 3 × {gradient} \
                 gradient), the word has {word} (volume_word.word_bits); the cycle model reads \
                 one word per voxel, so narrow the gradient to at most {fits} bits (--set \
                 shading.gradient_bits={fits}), or simulate without shading"
            ),
        ));
    }
    Ok(())
}

/// The SDRAM check the cycle model makes before a run: the volume, and with `distance` its
/// distance array in the rows after it, must fit `memory.rows` (with blocking, the block
/// table's own check applies instead). `advise` asks the same question of its candidates.
pub fn check_volume_memory(
    hardware: &HardwareConfig,
    dims: [usize; 3],
    distance: bool,
) -> Result<()> {
    if hardware.blocking.enabled {
        return Ok(());
    }
    hardware
        .memory
        .check_covers_with(dims, distance, "hardware configuration")
}

/// A memory error without blocking, with what blocking (at `blocking.block_size`, or 32 when
/// that does not divide the volume) would need: "does not fit; with blocking (block 32) it needs
/// N active blocks of M ...".
fn with_blocking_hint(
    error: Error,
    run: &RunDescription,
    volume: &Volume,
    tf: &transfer::TransferFunction,
    settings: &RenderSettings,
) -> Error {
    let Error::Config {
        source_name,
        field,
        message,
    } = error
    else {
        return error;
    };
    let config = &run.hardware;
    let size = [config.blocking.block_size, 32, 16, 8]
        .into_iter()
        .find(|&b| volume.dims.iter().all(|&d| d.is_multiple_of(b)));
    let hint = match (size, run.leaping()) {
        (Some(size), Leaping::None | Leaping::Occupancy { .. }) => {
            let blocks = block_table(run, volume, tf, settings, size);
            let stats = BlockingStats::new(&blocks, &config.memory, volume.dims, 0);
            if stats.fits(&config.memory) {
                format!(
                    "; it does not fit without blocking, {}: it fits with --set \
                     blocking.enabled=true{}",
                    stats.describe(),
                    if size == config.blocking.block_size {
                        String::new()
                    } else {
                        format!(" --set blocking.block_size={size}")
                    }
                )
            } else {
                format!(
                    "; it does not fit with blocking either ({})",
                    stats.describe()
                )
            }
        }
        _ => String::new(),
    };
    Error::config(source_name, field, format!("{message}{hint}"))
}

/// Optional observers of a run: of the cycle model, and the check of invariant (c).
#[derive(Default)]
pub struct Probes<'a> {
    /// VCD waveform of a cycle window.
    pub waveform: Option<&'a mut Waveform>,
    /// Every SDRAM command of a cycle window, as a checkable trace (docs/waveforms.md).
    pub command_trace: Option<&'a mut CommandTrace>,
    /// `run` also checks invariant (c) on the frame (`check_error_bound`) into
    /// `RunReport::error_bound`.
    pub check_bound: bool,
    /// `run` also renders the float reference and compares the frame with it into
    /// `RunReport::float_reference` (a step or cycle run; the float model's own frame is the
    /// reference).
    pub compare_float: bool,
}

/// The figures of one run. Fields a model does not produce are absent (not zero).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Measurements {
    /// Issue steps: samples + leaps (the published cost unit).
    pub steps: u64,
    pub samples: u64,
    pub leaps: u64,
    /// Samples followed by a leap (`skip.policy = "sample-then-leap"`); included in `samples`.
    pub leap_samples: u64,
    pub rays_terminated_early: u64,
    /// Iso mode: samples refining hits (included in `samples`); not written out when 0.
    #[serde(skip_serializing_if = "is_zero")]
    pub refinement_samples: u64,
    /// Cycle model: clock cycles of the frame (sampled: the estimate).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cycles: Option<u64>,
    /// Sampled cycle model: half-width of the 95 % confidence interval of `cycles`, cycles.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cycles_ci95: Option<f64>,
    /// Sampled cycle model: `true`; the timing figures (cycles, fps, stalls, discards, SDRAM
    /// counters and rates) are estimates, the counts (steps, samples...) the functional
    /// model's (docs/sampling.md). Absent for exact runs.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sampled: Option<bool>,
    /// Sampled cycle model: the sampling rate.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sample_rate: Option<f64>,
    /// Cycle model: samples issued after their ray's ERT, discarded at compositing.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub discarded_after_ert: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stall_cycles: Option<StallCycles>,
    /// Step model: steps × `clock.step_time_ns`; cycle model: cycles at `clock.frequency_mhz`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frame_time_ns: Option<f64>,
    /// 1e9 / `frame_time_ns`; absent when the frame time is 0 (a frame of no steps).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fps: Option<f64>,
    /// SDRAM: reads that found their row open / had to open it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub row_hits: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub row_misses: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refreshes: Option<u64>,
    /// SDRAM: row hits / reads (the published calibration: about 95 %).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub page_hit_rate: Option<f64>,
    /// SDRAM: module busy time per voxel access (the published calibration: 12.5 ns).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub avg_ns_per_voxel_access: Option<f64>,
    /// Leaping: empty sub-cubes of the occupancy map, percent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub skippable_subcubes_percent: Option<f64>,
    /// Leap values in the volume: voxels whose word carries a leap value.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub leap_voxels: Option<u64>,
    /// Ray start and end (`[bricks]`, `[clip]`, `[geometry]`): positions before and after,
    /// and (cycle model) the setup's cycles or the start/end table; absent when all are off.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ray_range: Option<RayRangeStats>,
    /// 2-way blocking (`[blocking]`): blocks active of all, memory rows and words with and
    /// without blocking, the table's bits; absent when off.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub blocking: Option<BlockingStats>,
    /// What the leaping structure and the bricks store beside the volume; absent without them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub structure_memory: Option<StructureMemory>,
}

/// What a run's leaping structure and bounding bricks store beside the volume, from the
/// configuration and the volume's dimensions (docs/accelerators.md, "Memory, logic and
/// latency"): the memory column of a comparison of the structures.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct StructureMemory {
    /// The occupancy map's bits in the on-chip SRAM (with the hierarchy, one byte per 2×2×2
    /// group, padded to whole groups): what `occupancy.sram_bits` must hold.
    pub map_sram_bits: u64,
    /// One flag per brick, kept by ray setup (its own storage, not the map's SRAM).
    pub brick_flag_bits: u64,
    /// SDRAM rows per bank beyond the volume's: the distance array, one distance per word in
    /// the rows after the volume's (`AddressMap::distance_word`), so the volume's rows again.
    pub extra_sdram_rows_per_bank: u64,
    /// Bits of every voxel word that carry leap values (flag and leap bits), in the words the
    /// volume already has: no extra memory while the word has room.
    pub voxel_word_bits: u32,
}

impl StructureMemory {
    /// None when the run has neither a leaping structure nor bricks.
    pub fn of(run: &RunDescription, dims: [usize; 3]) -> Option<StructureMemory> {
        let config = &run.hardware;
        let mut memory = StructureMemory::default();
        match run.leaping() {
            Leaping::None => {}
            Leaping::Occupancy {
                subcube, hierarchy, ..
            } => memory.map_sram_bits = crate::occupancy::map_bits(dims, subcube, hierarchy),
            Leaping::Distance { .. } => {
                memory.extra_sdram_rows_per_bank = config.memory.rows_needed(dims)
            }
            Leaping::LeapValues { .. } => memory.voxel_word_bits = 1 + config.volume_word.leap_bits,
        }
        let brick = config.bricks.size;
        if brick > 0 {
            memory.brick_flag_bits = dims
                .iter()
                .map(|d| d.div_ceil(brick) as u64)
                .product::<u64>();
        }
        (memory != StructureMemory::default()).then_some(memory)
    }
}

/// What a run produced: its description, the figures, the image.
#[derive(Serialize)]
pub struct RunReport {
    pub run: RunDescription,
    /// The volume's name as loaded.
    pub volume: String,
    /// The transfer function's name.
    pub transfer_function: String,
    pub leaping: Leaping,
    pub ray_selection: RaySelection,
    /// Rays, rays that hit the volume, samples, leaps, as the frame's ray records count them.
    pub stats: FrameStats,
    #[serde(flatten)]
    pub measurements: Measurements,
    /// Cycle model: everything the pipeline counted (stalls, occupancy histograms...).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pipeline: Option<CycleStats>,
    /// Cycle model: the memory's own statistics (sampled: its counters estimated).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub memory_stats: Option<Value>,
    /// Sampled cycle model: the sample and the estimate (docs/sampling.md).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sampling: Option<SampledEstimate>,
    /// Wall-clock time of the frame (not of loading or preparing).
    pub wall_seconds: f64,
    /// Samples per wall-clock second of this frame.
    pub samples_per_second: f64,
    /// Cycle model: simulated cycles per wall-clock second of this frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sim_cycles_per_second: Option<f64>,
    /// Leap values in the volume: what preprocessing found and its wall time (steps 1–4, done
    /// once per prepared run).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub leap_values: Option<LeapValueStats>,
    /// The frame against the float reference of the same description (`Probes::compare_float`):
    /// the measured error, without the bound `error_bound` adds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub float_reference: Option<Comparison>,
    /// Invariant (c), when the run was asked to check it (`check_error_bound`): the
    /// fixed-point image against the float reference and the bound its widths predict.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error_bound: Option<crate::bound::BoundCheck>,
    #[serde(skip)]
    pub frame: Frame,
    /// What the run's configuration asks that this volume leaves without effect (a hierarchy
    /// that groups nothing), for `sim` and `render` to say.
    #[serde(skip)]
    pub notes: Vec<String>,
}

/// Loads the run's dataset from `data_dir` and runs it.
pub fn run(
    run: &RunDescription,
    data_dir: Option<&std::path::Path>,
    probes: Probes,
) -> Result<RunReport> {
    run.validate()?;
    let volume = crate::volume::dataset::load(&run.dataset, data_dir)?;
    let prepared = prepare(run, &volume)?;
    let check_bound = probes.check_bound;
    let compare_float = probes.compare_float && run.model != Model::Float;
    let mut report = execute(run, &prepared, probes)?;
    drop(prepared);
    // Rendered once for both (a float run's own frame is the reference).
    let float = match (check_bound || compare_float) && run.model != Model::Float {
        true => Some(frame_of(run, &volume, Model::Float)?),
        false => None,
    };
    if let (true, Some(float)) = (compare_float, &float) {
        report.float_reference = Some(compare_frames(&report.frame, float)?);
    }
    if check_bound {
        // The fixed-point image: the step model's, or the cycle model's (equal to it).
        let (fixed, float) = match run.model {
            Model::Float => (None, Some(&report.frame)),
            _ => (Some(&report.frame), float.as_ref()),
        };
        report.error_bound = Some(check_error_bound_with(run, &volume, fixed, float)?);
    }
    Ok(report)
}

/// The run as far as its frame's timing and counts can tell: the run with what they cannot
/// depend on left out. Runs with equal timing descriptions take the same cycles, stalls, memory
/// counts and step counts (the measurements but `skippable_subcubes_percent`, the map's own
/// figure), so a sweep reuses them (`experiment::sweep`), and a sampled run draws its sample
/// by it (so such twins sample alike). Left out:
/// - a leaping structure that never leaps, or a hierarchy that never leaps further
///   (`FixedRenderer::effective_leaping`: an occupancy map with no empty sub-cube, or no empty
///   group): the renderer steps as without it;
/// - without a map, its SRAM size and hierarchy flag (nothing reads them; experiments raise the
///   SRAM for large maps only);
/// - when nothing reads a sample's value before compositing
///   (`HardwareConfig::timing_depends_on_transfer_function` false on what is left), the
///   transfer function and the occupancy kind that follows it.
pub fn timing_description(run: &RunDescription, prepared: &Prepared) -> RunDescription {
    let mut timing = run.clone();
    let occupancy = &mut timing.hardware.occupancy;
    if let Some(renderer) = prepared.fixed() {
        match renderer.effective_leaping() {
            Leaping::None => occupancy.subcube = 0,
            Leaping::Occupancy {
                hierarchy: false, ..
            } => occupancy.hierarchy = false,
            _ => {}
        }
    }
    if occupancy.structure == LeapStructure::Map && occupancy.subcube == 0 {
        occupancy.sram_bits = 0;
        occupancy.hierarchy = false;
    }
    if !timing.hardware.timing_depends_on_transfer_function() {
        timing.tf.clear();
        timing.hardware.occupancy.kind = OccupancyKind::Zero;
    }
    timing
}

/// What a sweep shares simulations by: the timing description, with one more thing left out
/// for an exact run whose timing reads no voxel value (`timing_depends_on_transfer_function`
/// false): the dataset, of which only the geometry is then kept (dimensions, spacing, bits per
/// voxel). Rays then reach, step and read alike on any volume of that shape, so fuel and neghip
/// (64³), or aneurism and foot-lossy (256³), without ERT or leaping take the same cycles. A
/// sampled run keeps the dataset's name: it draws its sample by the timing description, which
/// names it, and two samples of one timing are not one result.
pub fn reuse_description(run: &RunDescription, prepared: &Prepared) -> RunDescription {
    let mut timing = timing_description(run, prepared);
    if run.sample.is_none() && !timing.hardware.timing_depends_on_transfer_function() {
        let v = prepared.volume;
        timing.dataset = format!(
            "any volume of {:?} voxels, spacing {:?}, {} bits",
            v.dims, v.spacing, v.bits
        );
    }
    timing
}

/// The share of the run's occupancy map that is empty, percent (None without a map).
pub fn skippable_subcubes_percent(prepared: &Prepared) -> Option<f64> {
    let map = prepared.fixed().and_then(|r| r.map.as_ref())?;
    Some(100.0 * map.empty_subcubes() as f64 / map.subcubes().max(1) as f64)
}

/// Frames per second of a frame taking `frame_time_ns`; none for a frame of no time (no number
/// stands in for one: a sentinel would dominate any mean or chart of the results).
pub fn fps_of(frame_time_ns: f64) -> Option<f64> {
    (frame_time_ns > 0.0).then(|| 1e9 / frame_time_ns)
}

/// Runs one frame of a prepared run: the one function every command calls.
pub fn execute(run: &RunDescription, prepared: &Prepared, probes: Probes) -> Result<RunReport> {
    let camera = run.camera(prepared.volume)?;
    let config = &run.hardware;
    let start = Instant::now();
    let mut pipeline = None;
    let mut memory_stats = None;
    let mut sampled = None;
    let dims = prepared.volume.dims;
    let frame = match (&prepared.renderer, run.model) {
        (Renderer::Float(r), _) => r.render(&camera),
        (Renderer::Fixed(r), Model::Step) => r.render(&camera),
        (Renderer::Fixed(r), _) => match run.sampling() {
            Some(sampling) => {
                if probes.waveform.is_some() || probes.command_trace.is_some() {
                    return Err(Error::Invalid(
                        "a sampled simulation records no waveform or command trace: simulate \
                         the frame exactly (without --sample)"
                            .into(),
                    ));
                }
                // The image and every ray's steps from the functional model (equal to the
                // cycle model's image bit for bit); only the timing is sampled.
                let frame = r.render(&camera);
                let order = tile_order(camera.width, camera.height, config.ray_queue.tile);
                // Rays that miss the volume before each issue-order position.
                let mut misses_before = Vec::with_capacity(order.len() + 1);
                misses_before.push(0u64);
                for &ray in &order {
                    let last = *misses_before.last().expect("starts with 0");
                    misses_before.push(last + !frame.rays[ray].hit as u64);
                }
                // Built once: with the hierarchy it is a structure of its own.
                let skipper = r.skipper();
                // Runs that time alike sample alike (a sweep may reuse one for the other).
                let timing = timing_description(run, prepared);
                let seed = seed_of(&serde_json::to_string(&timing).map_err(|e| {
                    Error::Invalid(format!("run description not serialisable: {e}"))
                })?);
                let estimate = simulate_sampled(
                    &order,
                    &sampling,
                    seed,
                    config.clock.frequency_mhz,
                    {
                        let stats = frame.stats();
                        [stats.samples, stats.leaps]
                    },
                    |range| misses_before[range.end] - misses_before[range.start],
                    |rays, checkpoints, warm| {
                        let options = SimOptions {
                            rays: Some(rays),
                            checkpoints: Some(checkpoints),
                            ..SimOptions::default()
                        };
                        simulate_cycle(run, r, &skipper, &camera, dims, options, warm)?;
                        Ok(())
                    },
                )?;
                let mut estimate = estimate;
                // The start/end table's load comes before the first ray, the pipeline idle
                // (as `simulate_with` adds it): exact, not sampled.
                if let Some((_, load)) = crate::bricks::table_cost(config, order.len() as u64) {
                    estimate.cycles += load;
                }
                memory_stats = Some(estimate.memory_stats.clone());
                sampled = Some(estimate);
                frame
            }
            None => {
                let options = SimOptions {
                    waveform: probes.waveform,
                    command_trace: probes.command_trace,
                    ..SimOptions::default()
                };
                let (result, stats) =
                    simulate_cycle(run, r, &r.skipper(), &camera, dims, options, Warm::Cold)?;
                memory_stats = Some(stats);
                pipeline = Some(result.stats);
                result.frame
            }
        },
    };
    let wall_seconds = start.elapsed().as_secs_f64();
    let stats = frame.stats();
    let mut m = Measurements {
        steps: stats.steps(),
        samples: stats.samples,
        leaps: stats.leaps,
        leap_samples: stats.leap_samples,
        rays_terminated_early: stats.rays_terminated_early,
        refinement_samples: stats.refinement_samples,
        ..Measurements::default()
    };
    let frame_time_ns = match (run.model, &pipeline, &sampled) {
        (Model::Float, _, _) => None,
        (Model::Step, _, _) => Some(m.steps as f64 * config.clock.step_time_ns),
        (Model::Cycle, Some(s), _) => Some(s.cycles as f64 * 1e3 / config.clock.frequency_mhz),
        (Model::Cycle, None, Some(e)) => Some(e.cycles as f64 * 1e3 / config.clock.frequency_mhz),
        (Model::Cycle, None, None) => None,
    };
    m.frame_time_ns = frame_time_ns;
    // A frame of no steps (no ray meets the volume or the clip box) takes no time in the step
    // model: it has no frame rate, and no number stands in for one (a sentinel such as 1e18
    // would dominate any mean or chart of the results). Tables leave such a cell empty.
    m.fps = frame_time_ns.and_then(fps_of);
    if let Some(s) = &pipeline {
        m.cycles = Some(s.cycles);
        // The pipeline's own counts (they equal the frame's: checked on every run).
        m.steps = s.steps;
        m.samples = s.samples;
        m.leaps = s.leaps;
        m.leap_samples = s.leap_samples;
        m.refinement_samples = s.refinement_samples;
        m.rays_terminated_early = s.rays_terminated_early;
        m.discarded_after_ert = Some(s.discarded_after_ert);
        m.stall_cycles = Some(s.stall_cycles);
    }
    if let (Some(e), Some(sampling)) = (&sampled, &run.sample) {
        // The counts stay the functional model's (exact); the timing is the estimate.
        m.cycles = Some(e.cycles);
        m.cycles_ci95 = Some(e.cycles_ci95);
        m.sampled = Some(true);
        m.sample_rate = Some(sampling.rate);
        m.discarded_after_ert = Some(e.discarded_after_ert);
        m.stall_cycles = Some(e.stall_cycles);
    }
    if let Some(ms) = memory_stats.as_ref().filter(|ms| ms["row_hits"].is_u64()) {
        m.row_hits = ms["row_hits"].as_u64();
        m.row_misses = ms["row_misses"].as_u64();
        m.refreshes = ms["refreshes"].as_u64();
        m.page_hit_rate = ms["row_hit_rate"].as_f64();
        m.avg_ns_per_voxel_access = ms["avg_ns_per_voxel_access"].as_f64();
    }
    if ray_range_on(config) {
        m.ray_range = Some(match pipeline.as_ref().and_then(|p| p.ray_range.clone()) {
            Some(r) => r,
            None => RayRangeStats::from_records(&frame.rays),
        });
    }
    m.skippable_subcubes_percent = skippable_subcubes_percent(prepared);
    if let Some(blocks) = prepared.fixed().and_then(|r| r.blocks.as_ref()) {
        let mut stats = BlockingStats::new(
            blocks,
            &config.memory,
            prepared.volume.dims,
            config.blocking.lookup_latency,
        );
        stats.zero_samples = memory_stats
            .as_ref()
            .and_then(|ms| ms["zero_samples"].as_u64());
        m.blocking = Some(stats);
    }
    let leap_values = prepared.leap_value_stats();
    m.leap_voxels = leap_values.map(|s| s.leap_voxels);
    m.structure_memory = StructureMemory::of(run, prepared.volume.dims);
    Ok(RunReport {
        run: run.clone(),
        volume: prepared.volume.name.clone(),
        transfer_function: prepared.transfer_function.clone(),
        leaping: run.leaping(),
        ray_selection: config.ray_queue.selection,
        stats,
        pipeline,
        memory_stats,
        sampling: sampled,
        wall_seconds,
        samples_per_second: m.samples as f64 / wall_seconds.max(1e-12),
        // Simulated cycles per second (sampled: the frame's estimated cycles per second, how
        // fast the frame's timing was found).
        sim_cycles_per_second: m.cycles.map(|c| c as f64 / wall_seconds.max(1e-12)),
        leap_values,
        float_reference: None,
        error_bound: None,
        measurements: m,
        frame,
        notes: run
            .hierarchy_without_effect(prepared.volume.dims)
            .map(|why| {
                format!("the hierarchy (occupancy.hierarchy) is without effect here, as {why}")
            })
            .into_iter()
            .collect(),
    })
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

/// Whether any of `[bricks]`, `[clip]`, `[geometry]` is on.
pub fn ray_range_on(config: &HardwareConfig) -> bool {
    !(config.bricks.is_off() && config.clip.is_off() && config.geometry.is_off())
}

/// Simulates the run on a fresh memory of its kind (SDRAM or ideal), behind the block table's
/// lookup stage when the renderer blocks; returns the result and the memory's statistics.
fn simulate_cycle(
    run: &RunDescription,
    renderer: &FixedRenderer,
    skipper: &ConfiguredSkipper,
    camera: &Camera,
    dims: [usize; 3],
    options: SimOptions,
    warm: Warm,
) -> Result<(CycleResult, Value)> {
    let config = &run.hardware;
    match run.memory {
        Memory::Sdram => {
            let map = match &renderer.blocks {
                Some(blocks) => AddressMap::blocked(&config.memory, dims, blocks.clone()),
                None => AddressMap::new(&config.memory, dims),
            };
            let mut memory = SdramMemory::with_map(
                &config.memory,
                &config.sdram,
                map,
                config.clock.frequency_mhz,
            );
            // A sampled segment inside the frame: the refresh counter at a pseudo-random
            // phase (docs/sampling.md, "Warming").
            if let Warm::Inside { phase } = warm {
                memory.warm_refresh_phase(phase);
            }
            simulate_memory(renderer, skipper, camera, memory, config, options)
        }
        Memory::Ideal { latency } => simulate_memory(
            renderer,
            skipper,
            camera,
            IdealMemory::new(latency),
            config,
            options,
        ),
    }
}

/// Simulates on `memory`, behind the block table's lookup stage when the renderer blocks;
/// returns the result and the memory's statistics.
fn simulate_memory<M: VoxelMemory>(
    renderer: &FixedRenderer,
    skipper: &ConfiguredSkipper,
    camera: &Camera,
    memory: M,
    config: &HardwareConfig,
    options: SimOptions,
) -> Result<(CycleResult, Value)> {
    match &renderer.blocks {
        Some(blocks) => {
            let latency = config.blocking.lookup_latency;
            let mut memory = BlockLookup::new(memory, blocks.clone(), latency);
            let result = simulate_with(renderer, camera, skipper, &mut memory, config, options)?;
            Ok((result, memory.stats_json()))
        }
        None => {
            let mut memory = memory;
            let result = simulate_with(renderer, camera, skipper, &mut memory, config, options)?;
            Ok((result, memory.stats_json()))
        }
    }
}

/// Invariant (c): `run`'s frame from the fixed-point model and the float reference, every pixel
/// checked against the error bound its widths predict (`bound`). `fixed` is the fixed-point
/// frame when the caller has it (a step or cycle run of this description; their images are
/// equal), else it is rendered here. An error when the configuration is outside the bound.
pub fn check_error_bound(
    run: &RunDescription,
    volume: &Volume,
    fixed: Option<&Frame>,
) -> Result<crate::bound::BoundCheck> {
    check_error_bound_with(run, volume, fixed, None)
}

/// The float reference of `run`: the mathematically intended image (brief, section 5), so
/// without homogeneous leap values, whose lossy region means the float model follows when it is
/// asked to render them (every other structure leaves the float image as it is). What the
/// fixed-point frame is compared with (`Probes::compare_float`, a sweep's `float_reference`,
/// the bound's check).
pub fn reference_run(run: &RunDescription) -> RunDescription {
    let mut reference = RunDescription {
        model: Model::Float,
        sample: None,
        ..run.clone()
    };
    if let Leaping::LeapValues { .. } = reference.leaping() {
        reference.hardware.occupancy.structure = LeapStructure::Map;
    }
    reference
}

/// `run`'s fixed-point frame (the step model's, equal to the cycle model's), rendered with
/// `fixed` (prepared for `run`, or for its group of frames), against its float reference,
/// rendered with `reference` (prepared for `reference_run(run)`): what a sweep's line carries
/// with the experiment's `float_reference` (a twin that reused another run's timing has no frame
/// of its own).
pub fn compare_with_reference(
    run: &RunDescription,
    fixed: &Prepared,
    reference: &Prepared,
) -> Result<Comparison> {
    let step = RunDescription {
        model: Model::Step,
        sample: None,
        ..run.clone()
    };
    compare_frames(
        &execute(&step, fixed, Probes::default())?.frame,
        &execute(&reference_run(run), reference, Probes::default())?.frame,
    )
}

fn compare_frames(fixed: &Frame, float: &Frame) -> Result<Comparison> {
    crate::compare::compare(&fixed.pixels, &float.pixels, fixed.width, fixed.height)
}

/// `run`'s frame from `model` (exact, whatever `run` samples; the float model's is the
/// reference, `reference_run`).
fn frame_of(run: &RunDescription, volume: &Volume, model: Model) -> Result<Frame> {
    let run = match model {
        Model::Float => reference_run(run),
        _ => RunDescription {
            model,
            sample: None,
            ..run.clone()
        },
    };
    Ok(execute(&run, &prepare(&run, volume)?, Probes::default())?.frame)
}

/// `check_error_bound` with the float frame when the caller has it.
fn check_error_bound_with(
    run: &RunDescription,
    volume: &Volume,
    fixed: Option<&Frame>,
    float: Option<&Frame>,
) -> Result<crate::bound::BoundCheck> {
    let settings = run.settings();
    if let Some(reason) = crate::bound::unsupported(&run.hardware) {
        return Err(Error::Invalid(reason));
    }
    // The frames the caller has, else rendered here.
    fn given_or<'a>(
        frame: Option<&'a Frame>,
        render: impl FnOnce() -> Result<Frame>,
    ) -> Result<Cow<'a, Frame>> {
        Ok(match frame {
            Some(frame) => Cow::Borrowed(frame),
            None => Cow::Owned(render()?),
        })
    }
    let fixed = given_or(fixed, || frame_of(run, volume, Model::Step))?;
    let float = given_or(float, || frame_of(run, volume, Model::Float))?;
    let (fixed, float) = (fixed.as_ref(), float.as_ref());
    let tf = transfer::resolve_for(&run.tf, volume)?;
    let bound = crate::bound::ErrorBound::new(volume, &tf, &settings, &run.hardware)?
        .predict(&run.camera(volume)?);
    crate::bound::check(fixed, float, &bound)
}

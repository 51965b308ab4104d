//! `vizsim advise`: predicts the frame rate of every leaping configuration of a dataset and
//! transfer function without the cycle model, ranks them and recommends the fastest whose
//! occupancy map fits the configured SRAM (issue 19; the model is explained in docs/advise.md).
//!
//! Two measured quantities per configuration, one cost model:
//! - **steps and samples** from the functional fixed-point model (`run::execute` with the step
//!   model, through the one run path) on the requested views at a reduced image size; sums over
//!   rays scale with the number of rays, so they are multiplied by the pixel ratio. At the full
//!   size the counts are the functional model's exactly.
//! - **cycles** from steps and samples by a cost model whose parameters come from the hardware
//!   configuration (SDRAM timing, modules, rays in flight, skip latency) and one calibration
//!   figure of the memory (the row-miss rate of the voxel reads, docs/model.md).

use std::time::Instant;

use serde::Serialize;

use crate::config::{HardwareConfig, LeapRegions, LeapStructure};
use crate::error::{Error, Result};
use crate::experiment::spec::{Mode, MODE_FIELDS};
use crate::leapvalues::distance::DISTANCE_BITS;
use crate::occupancy::OccupancyKind;
use crate::run::{self, Model, RunDescription};
use crate::volume::Volume;

/// Leaping structures the advisor can consider.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Structure {
    /// Occupancy maps in on-chip SRAM, every sub-cube size, with and without the hierarchy.
    Map,
    /// Distance volumes (4 and 8 bits) in SDRAM: a distance transform per transfer function.
    Distance,
    /// Lossless leap values in the voxel words (empty regions): a segmentation per volume.
    LeapValues,
}

impl Structure {
    /// The name `--structures` takes.
    pub fn name(self) -> &'static str {
        match self {
            Structure::Map => "map",
            Structure::Distance => "distance",
            Structure::LeapValues => "leap-values",
        }
    }

    pub fn parse(text: &str) -> std::result::Result<Structure, String> {
        match text {
            "map" => Ok(Structure::Map),
            "distance" => Ok(Structure::Distance),
            "leap-values" | "leapvalues" => Ok(Structure::LeapValues),
            other => Err(format!(
                "`{other}`: expected `map`, `distance` or `leap-values`"
            )),
        }
    }
}

/// Sections of the configuration whose cost the advisor does not model: ray start and end
/// (bricks, clip planes, geometry) and iso mode.
pub const NOT_MODELLED: [&str; 4] = ["bricks", "iso", "clip", "geometry"];

/// Which of `NOT_MODELLED` `hardware` turns on (from a `--config` file), if any.
pub fn not_modelled_in(hardware: &HardwareConfig) -> Option<&'static str> {
    if !hardware.bricks.is_off() {
        Some("bricks.size")
    } else if hardware.iso.enabled {
        Some("iso.enabled")
    } else if !hardware.clip.is_off() {
        Some("clip")
    } else if hardware.geometry.shape != crate::config::GeometryShape::None {
        Some("geometry.shape")
    } else {
        None
    }
}

/// Refuses `--set` overrides of the fields the candidates set themselves (ERT, the map, its
/// kind, the structures): the ranking would override them without a word.
pub fn check_overrides(overrides: &[String]) -> Result<()> {
    for o in overrides {
        let field = o.split_once('=').map_or(o.as_str(), |(f, _)| f).trim();
        if let Some(section) = NOT_MODELLED
            .iter()
            .find(|s| field.starts_with(&format!("{s}.")))
        {
            return Err(Error::Invalid(format!(
                "--set {o}: the advisor's cost model has no per-ray setup or ray range \
                 (`{section}.*`: bricks, iso mode, clip planes and geometry), so it would predict \
                 such a run 13–22 % too fast (docs/advise.md); use `vizsim sim` for it"
            )));
        }
        // The fields `apply_mode` sets (bricks and iso mode were refused above).
        if MODE_FIELDS.contains(&field) {
            return Err(Error::Invalid(format!(
                "--set {o}: the advisor ranks configurations that set `{field}` themselves \
                 (ERT, maps, hierarchy, distance volumes, leap values; the map kind follows --tf)"
            )));
        }
    }
    Ok(())
}

/// The file name of the table `validate_table` reads: the cycle model's mean frame rates, as
/// `vizsim table --model cycle --metric fps` writes them. The cells carry no unit, so a table of
/// another metric or model would be read as frame rates without a word; its name tells.
pub const FPS_TABLE: &str = "cycle-fps.csv";

/// What the advice is computed on.
#[derive(Clone, Debug, Serialize)]
pub struct AdviseOptions {
    /// Views whose mean frame rate is predicted (`orbit:K/N`, `front`...).
    pub views: Vec<String>,
    /// Image size the functional model runs at; the prediction is for the run's own size.
    pub sample_size: (u32, u32),
    /// Structures to consider; ERT alone is always the baseline.
    pub structures: Vec<Structure>,
}

/// `count` views evenly spaced on the 72-frame orbit, starting at frame `first`.
pub fn orbit_views(count: u32, first: u32) -> Vec<String> {
    let count = count.clamp(1, 72);
    (0..count)
        .map(|i| format!("orbit:{}/72", (first + i * 72 / count) % 72))
        .collect()
}

/// The largest image of at most `max_rays` rays with the run's aspect ratio, never larger than
/// the run's own size (at least 8x8).
pub fn reduced_size(size: (u32, u32), max_rays: u64) -> (u32, u32) {
    let rays = size.0 as u64 * size.1 as u64;
    if rays <= max_rays {
        return size;
    }
    let f = (max_rays as f64 / rays as f64).sqrt();
    let scale = |n: u32| ((n as f64 * f).floor() as u32).clamp(8.min(n), n);
    let (w, h) = (scale(size.0), scale(size.1));
    // A side held at its minimum (a 16384x1 image) leaves the budget to the other side.
    let fit = |n: u32, other: u32, full: u32| {
        ((max_rays / other as u64).min(full as u64) as u32).clamp(8.min(full), n)
    };
    if w as u64 * h as u64 <= max_rays {
        (w, h)
    } else if w >= h {
        (fit(w, h, size.0), h)
    } else {
        (w, fit(h, w, size.1))
    }
}

/// The cost model's parameters, from the hardware configuration (docs/advise.md).
#[derive(Clone, Debug, Serialize)]
pub struct CostModel {
    /// Cycles a row miss adds to a module's access (t_RP + t_RCD).
    pub miss_penalty: f64,
    /// Row misses per voxel read of a sample with a map or without leaping: the calibrated
    /// figure of docs/model.md (97 % row hits with lagging-first selection).
    pub row_miss_rate: f64,
    /// Memory cycles a sample occupies each module: 1 + miss rate × penalty.
    pub cycles_per_sample: f64,
    /// Memory modules; a step's distance word lies on one of them.
    pub modules: f64,
    /// Modules the distance words of the views' rays actually spread over: the modules' count
    /// over the busiest module's share of the words (`distance_module_spread`). Fewer than
    /// `modules` when every ray's words keep one parity: axis-aligned views with an even
    /// number of voxels between rays put every distance word of the frame on half of the
    /// modules under `replicated4`.
    pub distance_modules: f64,
    /// Cycles a ray waits per step besides queueing at a module and at the issue slot: the
    /// skip unit's latency, CL and two cycles of request and return.
    pub step_delay: f64,
    /// Memory cycles a leap-value step's sample occupies each module: 1 + the leap-value
    /// row-miss rate × the miss penalty (`LEAP_VALUE_ROW_MISS_RATE`).
    pub leap_value_cycles_per_sample: f64,
    /// Rays in flight.
    pub rays: f64,
    /// Voxels between adjacent rays (the image's view width over its pixels): below 1, several
    /// rays read the same words.
    pub ray_spacing: f64,
    /// Distance words share the voxel's bank (`memory.distance_placement = same-bank`): the
    /// distance read's row miss also closes the voxel row.
    pub distance_same_bank: bool,
}

/// The calibrated row-miss rate of voxel reads (docs/model.md, "Calibration": about 97 % row
/// hits with lagging-first selection on the protocol's volumes).
pub const CALIBRATED_ROW_MISS_RATE: f64 = 0.03;

/// Row misses of a leap step's distance read (the ray lands in another row and no neighbour
/// has opened it), per leap step: the design data's (`runs/leaping-structures`, 256×256:
/// 0–0.45, docs/advise.md).
pub const LEAP_DISTANCE_MISS_RATE: f64 = 0.25;

/// Row misses per voxel read with leap values in the volume (docs/advise.md, "Leap values"):
/// every ray waits for its own sample's words, so the ray queue rarely has more than one ready
/// ray to choose from and lagging-first selection cannot keep the rays side by side; they drift
/// into different rows of a bank, as with round-robin selection. Calibrated on the six
/// leap-value runs of the review (engine, tooth 140×120×161, hydrogen atom; '0' and class;
/// 128×128, orbit frame 0: 20.5–32.8 % misses, mean 27.6 %), not per dataset.
pub const LEAP_VALUE_ROW_MISS_RATE: f64 = 0.28;

/// Mean value analysis of a closed network: `customers` rays, each step a pure delay of
/// `delay` cycles and a visit to each of `count` alike stations `(demand per step, count)`:
/// returns the cycles per step of the network (the inverse of its throughput). Service times
/// are fixed (a module's access, an issue slot), so an arriving ray waits for half of the
/// service in progress, not a whole one: residence = D (1 + Q − U / 2).
pub fn closed_network_cycles_per_step(
    customers: f64,
    delay: f64,
    stations: &[(f64, usize)],
) -> f64 {
    let n = customers.max(1.0).round() as usize;
    let mut queue: Vec<f64> = vec![0.0; stations.len()];
    let mut throughput = 0.0f64;
    let mut cycles = delay + stations.iter().map(|(d, c)| d * *c as f64).sum::<f64>();
    for k in 1..=n {
        let residence: Vec<f64> = stations
            .iter()
            .zip(&queue)
            .map(|((d, _), q)| d * (1.0 + q - (throughput * d).min(1.0) / 2.0).max(1.0))
            .collect();
        let total = delay
            + residence
                .iter()
                .zip(stations)
                .map(|(r, (_, c))| r * *c as f64)
                .sum::<f64>();
        throughput = k as f64 / total;
        queue = residence.iter().map(|r| throughput * r).collect();
        cycles = 1.0 / throughput;
    }
    // Never faster than the busiest station (the half-service correction alone can be).
    stations.iter().map(|(d, _)| *d).fold(cycles, f64::max)
}

impl CostModel {
    /// `ray_spacing`: voxels between adjacent rays of the run's image.
    pub fn new(config: &HardwareConfig, ray_spacing: f64) -> CostModel {
        let s = &config.sdram;
        let miss_penalty = (s.t_rp + s.t_rcd) as f64;
        let row_miss_rate = CALIBRATED_ROW_MISS_RATE;
        let step_delay = config.skip.latency as f64 + s.cl as f64 + 2.0;
        CostModel {
            miss_penalty,
            row_miss_rate,
            cycles_per_sample: 1.0 + row_miss_rate * miss_penalty,
            modules: config.memory.modules() as f64,
            distance_modules: config.memory.modules() as f64,
            step_delay,
            leap_value_cycles_per_sample: 1.0 + LEAP_VALUE_ROW_MISS_RATE * miss_penalty,
            rays: config.ray_queue.rays.max(1) as f64,
            ray_spacing,
            distance_same_bank: config.memory.distance_placement
                == crate::arch::address_map::DistancePlacement::SameBank,
        }
    }

    /// Row misses per step of a distance-volume run whose steps are a share `sample_share`
    /// samples: with same-bank placement a sample step's distance read and voxel read open two
    /// rows of one bank in turn (two misses, shared by rays closer than a voxel: √spacing);
    /// a leap step's read misses when the leap lands in a row nobody opened.
    pub fn distance_misses_per_step(&self, sample_share: f64) -> f64 {
        let ping_pong = if self.distance_same_bank {
            2.0 * self.ray_spacing.min(1.0).sqrt()
        } else {
            0.0
        };
        sample_share * ping_pong + (1.0 - sample_share) * LEAP_DISTANCE_MISS_RATE
    }

    /// Predicted cycles of a frame that takes `steps` issue steps, `samples` of them samples.
    pub fn cycles(&self, structure: CandidateStructure, steps: f64, samples: f64) -> f64 {
        if steps <= 0.0 {
            return 0.0;
        }
        let sample_share = (samples / steps).clamp(0.0, 1.0);
        // One step per clock at best; a sample's extra memory time (row misses) stalls issue
        // only when the memory has no slack, i.e. when the slots around it are samples too,
        // which happens with the probability of a slot being a sample.
        let issue = 1.0 + (self.cycles_per_sample - 1.0) * sample_share * sample_share;
        let per_step = match structure {
            CandidateStructure::None | CandidateStructure::Map => issue,
            CandidateStructure::Distance => {
                // Every step, leap or sample, reads a distance word on one of the modules and
                // the ray waits for it: a closed network of R rays, each step a delay (skip
                // latency, CL, request and return), the issue slot (1 cycle) and a module
                // (the word and the row misses of the step, docs/advise.md). The samples'
                // voxel words occupy every module a share of the time the rays cannot use.
                let spread = self.distance_modules.clamp(1.0, self.modules);
                let per_module = (1.0
                    + self.distance_misses_per_step(sample_share) * self.miss_penalty)
                    / spread;
                let voxel_load = sample_share * self.cycles_per_sample;
                let modules = spread.round().max(1.0) as usize;
                let mut per_step = issue.max(voxel_load + per_module);
                for _ in 0..50 {
                    let busy = (voxel_load / per_step).min(0.95);
                    let network = closed_network_cycles_per_step(
                        self.rays,
                        self.step_delay,
                        &[(1.0, 1), (per_module / (1.0 - busy), modules)],
                    );
                    let next = network.max(voxel_load + per_module).max(issue);
                    if (next - per_step).abs() < 1e-9 {
                        break;
                    }
                    per_step = next;
                }
                per_step
            }
            CandidateStructure::LeapValues => {
                // Every step samples, and the ray's next position waits for that sample's words
                // (the leap value comes with them): each ray has one step in flight, a closed
                // network of R rays through a delay (skip latency, CL, request and return), the
                // issue slot and the modules. With the rays drifting apart, a module's word
                // costs 1 + the leap-value miss rate × (t_RP + t_RCD): that work is the bound at
                // the default 16 rays, the round trip below about 8.
                let per_module = self.leap_value_cycles_per_sample;
                let network = closed_network_cycles_per_step(
                    self.rays,
                    self.step_delay,
                    &[(1.0, 1), (per_module, 1)],
                );
                issue.max(per_module).max(network)
            }
        };
        steps * per_step
    }
}

/// Modules the distance words of `views` spread over (docs/advise.md): for each view a block of
/// 32×32 adjacent pixels at the centre of the run's image (adjacent, so the real spacing
/// between rays), each ray walked through the volume at the sample spacing, each position's
/// base voxel's distance word located by the address map; the result is the modules' count
/// times the mean over the busiest module's share (1 / share: 4 when the words are spread
/// evenly, 2 when they keep to half of the modules).
pub fn distance_module_spread(
    base: &RunDescription,
    volume: &Volume,
    views: &[String],
) -> Result<f64> {
    let map = crate::arch::address_map::AddressMap::new(&base.hardware.memory, volume.dims);
    let modules = base.hardware.memory.modules().max(1);
    let spacing = base.settings().sample_spacing.max(1.0 / 64.0);
    let dims = volume.dims.map(|d| d as f32);
    let mut counts = vec![0u64; modules];
    for view in views {
        let run = RunDescription {
            view: view.clone(),
            ..base.clone()
        };
        let camera = run.camera(volume)?;
        let (w, h) = base.size;
        let (x0, y0) = (w.saturating_sub(32) / 2, h.saturating_sub(32) / 2);
        for py in y0..(y0 + 32).min(h) {
            for px in x0..(x0 + 32).min(w) {
                let ray = camera.voxel_ray(px, py, volume.spacing);
                // The ray's span inside [0, dims − 1] per axis (slab test).
                let (mut t0, mut t1) = (ray.t_min, f32::INFINITY);
                for a in 0..3 {
                    let (o, d) = (ray.origin[a], ray.dir[a]);
                    if d.abs() < 1e-12 {
                        if o < 0.0 || o > dims[a] - 1.0 {
                            t1 = -1.0;
                        }
                        continue;
                    }
                    let (ta, tb) = ((0.0 - o) / d, (dims[a] - 1.0 - o) / d);
                    t0 = t0.max(ta.min(tb));
                    t1 = t1.min(ta.max(tb));
                }
                if t1 <= t0 {
                    continue;
                }
                let mut t = (t0 / spacing).ceil() * spacing;
                while t <= t1 {
                    let p = ray.origin + ray.dir * t;
                    let base_voxel = [0, 1, 2].map(|a| {
                        (p[a].max(0.0).floor() as usize).min(volume.dims[a].saturating_sub(2))
                    });
                    counts[map.distance_word(base_voxel).module as usize % modules] += 1;
                    t += spacing;
                }
            }
        }
    }
    let total: u64 = counts.iter().sum();
    let busiest = counts.iter().copied().max().unwrap_or(0);
    Ok(if busiest == 0 {
        modules as f64
    } else {
        total as f64 / busiest as f64
    })
}

/// A candidate's structure, for the cost model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum CandidateStructure {
    None,
    Map,
    Distance,
    LeapValues,
}

/// One configuration's prediction.
#[derive(Clone, Debug, Serialize)]
pub struct Candidate {
    /// The experiment mode that runs this configuration (`ert+leap8+hier`).
    pub mode: String,
    /// As a reader reads it: `ERT`, `8³ + hierarchy`, `distance 8 bits`.
    pub label: String,
    pub structure: CandidateStructure,
    pub subcube: usize,
    pub hierarchy: bool,
    /// SRAM bits the occupancy map needs (map candidates).
    pub map_bits: Option<u64>,
    /// The cycle model accepts the configuration: its map fits `occupancy.sram_bits`, and
    /// everything `sim` checks before it runs holds (`run::check_without_building`: the
    /// hardware's validation, blocking included, and the volume with its distance array in the
    /// SDRAM's `memory.rows`).
    pub fits: bool,
    /// Why it does not fit, in short, as the cycle model would refuse it (None when it fits).
    pub misfit: Option<String>,
    /// Empty sub-cubes of the map, percent.
    pub skippable_percent: Option<f64>,
    /// Mean per frame at the run's image size (scaled from the reduced image).
    pub steps: f64,
    pub samples: f64,
    pub leaps: f64,
    pub predicted_cycles: f64,
    pub predicted_fps: f64,
    /// Predicted frame rate over ERT alone's.
    pub speedup_over_ert: f64,
    /// May be recommended (validation restricted to some structures); always true in advice.
    #[serde(skip)]
    pub allowed: bool,
}

/// The advisor's answer.
#[derive(Clone, Debug, Serialize)]
pub struct Advice {
    pub dataset: String,
    pub tf: String,
    pub transfer_function: String,
    pub dims: [usize; 3],
    pub size: (u32, u32),
    pub sample_size: (u32, u32),
    pub views: Vec<String>,
    pub sram_bits: u64,
    pub cost_model: CostModel,
    /// Best predicted first.
    pub ranking: Vec<Candidate>,
    /// Candidates the cycle model refuses whose steps the functional model could not count
    /// either (not ranked). Written out only when there are some.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub not_predicted: Vec<NotPredicted>,
    /// The fastest predicted candidate that fits the SRAM (`mode`).
    pub recommended: String,
    /// Wall time of the advice (loading the volume excluded), seconds.
    pub seconds: f64,
    /// CPU time of the process over the advice, all threads, seconds (Linux; on a shared
    /// machine the wall time includes waiting for a core).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cpu_seconds: Option<f64>,
}

/// User + system CPU time of this process so far, from /proc/self/stat (Linux), seconds.
fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which may hold spaces) end with ')'.
    let rest = &stat[stat.rfind(')')? + 2..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    // utime and stime are fields 14 and 15 of the line, 12 and 13 after the name.
    let ticks = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    // The clock tick is 100 Hz on every Linux configuration vizsim runs on (USER_HZ).
    Some(ticks / 100.0)
}

impl Advice {
    pub fn recommended(&self) -> &Candidate {
        self.ranking
            .iter()
            .find(|c| c.mode == self.recommended)
            .expect("the recommendation is one of the candidates")
    }
}

/// The modes the advisor ranks for a volume of `dims`: ERT, every map size 2³..64³ not larger
/// than the volume with and without the hierarchy (2³..32³), the distance volumes, leap values.
pub fn candidate_modes(dims: [usize; 3], structures: &[Structure]) -> Vec<Mode> {
    let mut names = vec!["ert".to_string()];
    let largest = dims.iter().copied().max().unwrap_or(0);
    if structures.contains(&Structure::Map) {
        for n in [2usize, 4, 8, 16, 32, 64] {
            if n <= largest {
                names.push(format!("ert+leap{n}"));
                // Not where the hierarchy groups nothing: it would rank a twin of the map.
                if n <= 32 && crate::occupancy::hierarchy_without_effect(dims, n).is_none() {
                    names.push(format!("ert+leap{n}+hier"));
                }
            }
        }
    }
    if structures.contains(&Structure::Distance) {
        names.push("ert+distance4".into());
        names.push("ert+distance8".into());
    }
    if structures.contains(&Structure::LeapValues) {
        names.push("ert+leapvalues".into());
    }
    names
        .iter()
        .map(|n| Mode::parse(n).expect("the advisor's modes parse"))
        .collect()
}

pub use crate::occupancy::map_bits;

/// `base`'s hardware with `mode` applied the way an experiment applies it (ERT, sub-cube,
/// hierarchy, structure; the map kind from the transfer function: '0' for `zero`, else class).
pub fn apply_mode(base: &HardwareConfig, mode: &Mode, tf: &str) -> HardwareConfig {
    let mut config = base.clone();
    config.compositing.ert = mode.ert;
    config.occupancy.subcube = mode.subcube;
    config.occupancy.hierarchy = mode.hierarchy;
    config.occupancy.kind = OccupancyKind::for_tf(tf);
    if mode.distance_bits > 0 {
        config.occupancy.structure = LeapStructure::Distance;
        config.occupancy.distance_bits = mode.distance_bits;
    } else if let Some(regions) = mode.leap_values {
        config.occupancy.structure = LeapStructure::LeapValues;
        config.leap_values.regions = regions;
    } else {
        config.occupancy.structure = LeapStructure::Map;
    }
    config
}

/// Whether a ranked mode's cost rests on the leap-value row-miss rate, one calibrated figure
/// whose cycle-model values spread widely (docs/advise.md "Leap values").
fn leap_value_calibrated(mode: &str) -> bool {
    mode.split('+').any(|t| t == "leapvalues")
}

fn label(mode: &Mode) -> String {
    if mode.distance_bits > 0 {
        format!("distance {} bits", mode.distance_bits)
    } else if mode.leap_values == Some(LeapRegions::Empty) {
        "leap values".into()
    } else if mode.subcube > 0 {
        format!(
            "{}³{}",
            mode.subcube,
            if mode.hierarchy { " + hierarchy" } else { "" }
        )
    } else {
        "ERT".into()
    }
}

/// Steps, samples and leaps summed over the views, and the map's skippable share.
struct Counts {
    steps: u64,
    samples: u64,
    leaps: u64,
    skippable: Option<f64>,
}

/// Counts `mode`'s steps with the functional model (`run` is its step run at the reduced size)
/// over `views`; returns the counts and the transfer function's name. The widest distance
/// volume is built once (on a run prepared without leaping) and kept in `widest_distance` for
/// the narrower widths, which is exact (the saturation is the transform's last step).
fn count_steps(
    run: &RunDescription,
    volume: &Volume,
    mode: &Mode,
    views: &[String],
    widest_distance: &mut Option<crate::leapvalues::DistanceVolume>,
) -> Result<(Counts, String)> {
    let prepared = if mode.distance_bits > 0 {
        let mut plain = run.clone();
        plain.hardware.occupancy.structure = LeapStructure::Map;
        plain.hardware.occupancy.subcube = 0;
        let mut prepared = run::prepare(&plain, volume)?;
        let kind = run.hardware.occupancy.kind;
        if widest_distance.is_none() {
            *widest_distance = Some(prepared.build_distance_volume(*DISTANCE_BITS.end(), kind)?);
        }
        let distance = widest_distance
            .as_ref()
            .expect("built above")
            .narrowed(mode.distance_bits)?;
        prepared.set_distance_volume(distance, kind)?;
        prepared
    } else {
        run::prepare(run, volume)?
    };
    let mut counts = Counts {
        steps: 0,
        samples: 0,
        leaps: 0,
        skippable: None,
    };
    for view in views {
        let run = RunDescription {
            view: view.clone(),
            ..run.clone()
        };
        let report = run::execute(&run, &prepared, run::Probes::default())?;
        counts.steps += report.measurements.steps;
        counts.samples += report.measurements.samples;
        counts.leaps += report.measurements.leaps;
        counts.skippable = report.measurements.skippable_subcubes_percent;
    }
    Ok((counts, prepared.transfer_function.clone()))
}

/// A configuration error as a short reason for the advice's table: the field and the
/// message's first clause (`blocking.block_size`: 32 is smaller than occupancy.subcube (64)).
fn short_reason(error: &Error) -> String {
    match error {
        Error::Config { field, message, .. } => {
            let cut = [message.find("; "), message.find(": ")]
                .into_iter()
                .flatten()
                .min()
                .unwrap_or(message.len());
            format!("`{field}`: {}", &message[..cut])
        }
        other => other.to_string(),
    }
}

/// A candidate the cycle model refuses and the functional model cannot count either: listed
/// with its reasons, not ranked.
#[derive(Clone, Debug, Serialize)]
pub struct NotPredicted {
    pub mode: String,
    pub label: String,
    /// Why the cycle model refuses it.
    pub reason: String,
    /// Why its steps could not be counted.
    pub error: String,
}

/// Runs the advisor for `base` (its dataset, transfer function, image size, hardware) on
/// `volume`, which must be the run's dataset.
pub fn advise(base: &RunDescription, volume: &Volume, options: &AdviseOptions) -> Result<Advice> {
    let start = Instant::now();
    let cpu_start = process_cpu_seconds();
    if options.views.is_empty() {
        return Err(Error::Invalid("advise: no views to predict".into()));
    }
    let (w, h) = options.sample_size;
    if w == 0 || h == 0 || w > base.size.0 || h > base.size.1 {
        return Err(Error::Invalid(format!(
            "advise: sample size {w}x{h} must be at least 1x1 and at most the image size {}x{}",
            base.size.0, base.size.1
        )));
    }
    let scale = (base.size.0 as f64 * base.size.1 as f64) / (w as f64 * h as f64);
    // The view width is the volume's largest extent (`Camera::for_volume`).
    let ray_spacing = *volume.dims.iter().max().unwrap_or(&1) as f64 / base.size.0.max(1) as f64;
    let mut cost = CostModel::new(&base.hardware, ray_spacing);
    if options.structures.contains(&Structure::Distance) {
        cost.distance_modules = distance_module_spread(base, volume, &options.views)?;
    }
    let sram_bits = base.hardware.occupancy.sram_bits;
    // Every candidate is checked as the cycle model (`sim`) checks its run before it builds
    // anything (`run::check_without_building`: the hardware's validation, the SDRAM rows of the
    // volume and of a distance array, blocking), at the size the functional model traces (the
    // frame itself is never rendered, so the memory budget applies to that image). ERT alone is
    // the configuration as given: what refuses it refuses every candidate, and is an error, as
    // it is for `sim`.
    let cycle_check = |hardware: &HardwareConfig| {
        run::check_without_building(
            &RunDescription {
                model: Model::Cycle,
                size: (w, h),
                hardware: hardware.clone(),
                sample: None,
                ..base.clone()
            },
            volume,
        )
    };
    let mut transfer_function = String::new();
    let mut ranking = Vec::new();
    let mut not_predicted = Vec::new();
    let mut widest_distance: Option<crate::leapvalues::DistanceVolume> = None;
    for mode in candidate_modes(volume.dims, &options.structures) {
        let mut hardware = apply_mode(&base.hardware, &mode, &base.tf);
        let map_bits =
            (mode.subcube > 0).then(|| map_bits(volume.dims, mode.subcube, mode.hierarchy));
        let misfit = match cycle_check(&hardware) {
            Err(e) if mode.name() == "ert" => return Err(e),
            Err(e) => Some(short_reason(&e)),
            Ok(()) => map_bits.filter(|&bits| bits > sram_bits).map(|bits| {
                format!("its map needs {bits} bits, `occupancy.sram_bits` is {sram_bits}")
            }),
        };
        // A configuration that does not fit is predicted anyway (a map with the SRAM raised,
        // as `raise_sram` does; one that blocking refuses without blocking) so the ranking
        // shows what it would gain where it runs; it is never recommended.
        if let Some(bits) = map_bits.filter(|&bits| bits > hardware.occupancy.sram_bits) {
            hardware.occupancy.sram_bits = bits.next_power_of_two();
        }
        let mut run = RunDescription {
            model: Model::Step,
            size: (w, h),
            hardware,
            ..base.clone()
        };
        if misfit.is_some() && run.hardware.blocking.enabled && run.validate().is_err() {
            run.hardware.blocking.enabled = false;
        }
        let counted = count_steps(&run, volume, &mode, &options.views, &mut widest_distance);
        let (counts, prepared_tf) = match counted {
            Ok(counted) => counted,
            // What the functional model cannot run either is listed with its reason: the
            // advice goes on without it.
            Err(e) if misfit.is_some() => {
                not_predicted.push(NotPredicted {
                    mode: mode.name(),
                    label: label(&mode),
                    reason: misfit.unwrap_or_default(),
                    error: short_reason(&e),
                });
                continue;
            }
            Err(e) => return Err(e),
        };
        transfer_function = prepared_tf;
        let per_frame = scale / options.views.len() as f64;
        let (steps, samples, leaps) = (
            counts.steps as f64 * per_frame,
            counts.samples as f64 * per_frame,
            counts.leaps as f64 * per_frame,
        );
        let skippable = counts.skippable;
        let structure = if mode.distance_bits > 0 {
            CandidateStructure::Distance
        } else if mode.leap_values.is_some() {
            CandidateStructure::LeapValues
        } else if mode.subcube > 0 {
            CandidateStructure::Map
        } else {
            CandidateStructure::None
        };
        let cycles = cost.cycles(structure, steps, samples);
        ranking.push(Candidate {
            mode: mode.name(),
            label: label(&mode),
            structure,
            subcube: mode.subcube,
            hierarchy: mode.hierarchy,
            map_bits,
            fits: misfit.is_none(),
            misfit,
            skippable_percent: skippable,
            steps,
            samples,
            leaps,
            predicted_cycles: cycles,
            predicted_fps: base.hardware.clock.frequency_mhz * 1e6 / cycles.max(1.0),
            speedup_over_ert: 0.0,
            allowed: true,
        });
    }
    let ert_fps = ranking
        .iter()
        .find(|c| c.mode == "ert")
        .map(|c| c.predicted_fps)
        .expect("ERT is always a candidate");
    for c in &mut ranking {
        c.speedup_over_ert = c.predicted_fps / ert_fps;
    }
    // Stable: among equal predictions the earlier (simpler, smaller map) candidate stays first.
    ranking.sort_by(|a, b| b.predicted_fps.total_cmp(&a.predicted_fps));
    let recommended = ranking
        .iter()
        .find(|c| c.fits)
        .map(|c| c.mode.clone())
        .expect("ERT always fits");
    Ok(Advice {
        dataset: base.dataset.clone(),
        tf: base.tf.clone(),
        transfer_function,
        dims: volume.dims,
        size: base.size,
        sample_size: options.sample_size,
        views: options.views.clone(),
        sram_bits,
        cost_model: cost,
        ranking,
        not_predicted,
        recommended,
        seconds: start.elapsed().as_secs_f64(),
        cpu_seconds: process_cpu_seconds()
            .zip(cpu_start)
            .map(|(end, start)| end - start),
    })
}

/// One (dataset, transfer function, swept fields) of a results folder: the advice against the
/// cycle model's truth.
#[derive(Clone, Debug, Serialize)]
pub struct ValidationRow {
    pub dataset: String,
    pub tf: String,
    pub transfer_function: String,
    /// Swept fields of the pair other than the mode's (`skip.policy=leap-only`), or empty.
    pub axes: String,
    /// Frames of the truth (mean over them; 0: a table's means, frames not known) and the views
    /// the advisor used.
    pub frames: usize,
    pub advisor_views: usize,
    pub size: (u32, u32),
    /// The advisor's pick among the configurations the folder has that fit the SRAM.
    pub advised: String,
    pub advised_fps: f64,
    /// The fastest configuration of the folder that fits the SRAM, by the cycle model.
    pub best: String,
    pub best_fps: f64,
    /// 1 − advised / best frame rate, percent.
    pub loss_percent: f64,
    /// The advisor's predicted frame rate of its pick and the cycle model's ERT frame rate.
    pub predicted_fps: f64,
    pub ert_fps: Option<f64>,
    pub advice_seconds: f64,
    pub advice_cpu_seconds: Option<f64>,
    /// Predicted against measured frame rate over every configuration of the pair the advisor
    /// predicted: mean and largest |predicted / measured − 1|, percent.
    pub fps_error_mean_percent: f64,
    pub fps_error_max_percent: f64,
    /// Modes the advisor does not rank (bricks, iso, ...) that the cycle model ran faster than
    /// the advised configuration for this pair, fastest first: then the advice is the true best
    /// among the ranked modes only.
    pub faster_not_ranked: Vec<FasterUnranked>,
    /// Every predicted configuration's error (the mean and largest above are over these).
    pub fps_errors: Vec<ConfigError>,
}

/// The structure groups the prediction error is reported by.
pub const ERROR_GROUPS: [&str; 5] = [
    "ERT alone",
    "map",
    "map + hierarchy",
    "distance",
    "leap values",
];

impl Candidate {
    /// Its group in the error report (`ERROR_GROUPS`).
    pub fn error_group(&self) -> &'static str {
        match self.structure {
            CandidateStructure::None => ERROR_GROUPS[0],
            CandidateStructure::Map if self.hierarchy => ERROR_GROUPS[2],
            CandidateStructure::Map => ERROR_GROUPS[1],
            CandidateStructure::Distance => ERROR_GROUPS[3],
            CandidateStructure::LeapValues => ERROR_GROUPS[4],
        }
    }
}

/// One configuration's predicted frame rate against the cycle model's.
#[derive(Clone, Debug, Serialize)]
pub struct ConfigError {
    pub mode: String,
    /// `ERROR_GROUPS`.
    pub group: String,
    pub predicted_fps: f64,
    pub measured_fps: f64,
    /// predicted / measured − 1, percent: positive is optimistic (predicted faster).
    pub error_percent: f64,
}

/// The error of every configuration of `truth` (`(mode, measured fps)`) the advisor predicted,
/// and the mean and largest |error| in percent over them.
fn fps_errors<'a>(
    advice: &Advice,
    truth: impl Iterator<Item = (&'a str, f64)>,
) -> (f64, f64, Vec<ConfigError>) {
    let errors: Vec<ConfigError> = truth
        .filter_map(|(m, fps)| {
            let c = advice.ranking.iter().find(|c| c.mode == m)?;
            Some(ConfigError {
                mode: c.mode.clone(),
                group: c.error_group().to_string(),
                predicted_fps: c.predicted_fps,
                measured_fps: fps,
                error_percent: 100.0 * (c.predicted_fps / fps - 1.0),
            })
        })
        .collect();
    let mean =
        errors.iter().map(|e| e.error_percent.abs()).sum::<f64>() / errors.len().max(1) as f64;
    let max = errors
        .iter()
        .map(|e| e.error_percent.abs())
        .fold(0.0, f64::max);
    (mean, max, errors)
}

/// The prediction error of one structure group over a validation's pairs.
#[derive(Clone, Debug, Serialize)]
pub struct GroupError {
    pub group: String,
    /// Configurations of the group over all pairs, and the pairs that have one.
    pub configurations: usize,
    pub pairs: usize,
    /// Mean |error|, mean signed error (positive: predicted faster than the cycle model) and
    /// the largest |error|, percent, over the group's configurations.
    pub mean_abs_percent: f64,
    pub mean_percent: f64,
    pub max_abs_percent: f64,
}

/// The rows' configuration errors by structure group (`ERROR_GROUPS` order; groups without a
/// configuration left out).
pub fn errors_by_group(rows: &[ValidationRow]) -> Vec<GroupError> {
    ERROR_GROUPS
        .iter()
        .filter_map(|group| {
            let errors: Vec<f64> = rows
                .iter()
                .flat_map(|r| &r.fps_errors)
                .filter(|e| e.group == *group)
                .map(|e| e.error_percent)
                .collect();
            if errors.is_empty() {
                return None;
            }
            let n = errors.len() as f64;
            Some(GroupError {
                group: group.to_string(),
                configurations: errors.len(),
                pairs: rows
                    .iter()
                    .filter(|r| r.fps_errors.iter().any(|e| e.group == *group))
                    .count(),
                mean_abs_percent: errors.iter().map(|e| e.abs()).sum::<f64>() / n,
                mean_percent: errors.iter().sum::<f64>() / n,
                max_abs_percent: errors.iter().map(|e| e.abs()).fold(0.0, f64::max),
            })
        })
        .collect()
}

/// How `validate` runs the advisor.
#[derive(Clone, Debug)]
pub struct ValidateOptions {
    /// Largest number of rays per view the functional model runs (`reduced_size`).
    pub max_rays: u64,
    /// Largest number of the pair's frames the advisor uses (evenly spaced among them).
    pub max_views: usize,
    /// Structures the advisor may pick from; `None`: every structure the folder ran. The true
    /// best is always taken over every configuration of the folder that fits.
    pub structures: Option<Vec<Structure>>,
}

/// Mean cycle-model frame rate per mode of one pair, and what is needed to re-run the advisor.
struct Pair {
    dataset: String,
    tf: String,
    transfer_function: String,
    axes: Vec<(String, serde_json::Value)>,
    size: (u32, u32),
    views: std::collections::BTreeSet<(u32, String)>,
    /// Result lines of the pair.
    lines: usize,
    /// mode -> (frame -> fps, fits the default SRAM)
    modes: std::collections::BTreeMap<String, (std::collections::BTreeMap<u32, f64>, bool)>,
}

/// A mode the advisor does not rank that the cycle model ran faster than the advised one, on
/// the frames both ran.
#[derive(Clone, Debug, Serialize)]
pub struct FasterUnranked {
    pub mode: String,
    pub fps: f64,
    /// The advised configuration's mean over the same frames.
    pub advised_fps: f64,
    /// fps − advised fps, and that over the advised fps in percent.
    pub faster_fps: f64,
    pub faster_percent: f64,
}

impl FasterUnranked {
    /// `mode` at `fps` against the advised configuration's `advised_fps` (the same frames):
    /// Some when it is faster.
    fn if_faster(mode: String, fps: f64, advised_fps: f64) -> Option<FasterUnranked> {
        (fps > advised_fps).then(|| FasterUnranked {
            mode,
            fps,
            advised_fps,
            faster_fps: fps - advised_fps,
            faster_percent: 100.0 * (fps / advised_fps.max(1e-12) - 1.0),
        })
    }

    fn describe(&self) -> String {
        format!(
            "{} {:.2} fps, {:.2} fps ({:.1} %) faster",
            self.mode, self.fps, self.faster_fps, self.faster_percent
        )
    }
}

/// What `validate` found: a row per pair whose results are all there, and the pairs left out.
#[derive(Clone, Debug, Serialize)]
pub struct Validation {
    pub rows: Vec<ValidationRow>,
    /// The prediction error by structure over every pair (`errors_by_group`).
    pub errors_by_structure: Vec<GroupError>,
    /// Pairs whose runs are not all in the folder yet (`dataset tf: N of M runs`).
    pub incomplete: Vec<String>,
    /// Modes of the folder's cycle-model runs that the advisor does not rank (bricks, iso,
    /// homogeneous leap values, leaping without ERT), left out of the true best; `none` is
    /// not listed. Written out only when there are some.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub not_ranked: Vec<String>,
    /// The results file's last line was incomplete (a sweep killed while writing it, or one
    /// still running) and was left out.
    pub torn_last_line: bool,
    /// The cycle model's figures are sampled estimates at these rates (docs/sampling.md), not
    /// exact simulations. Written out only when there are some.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub sample_rates: Vec<f64>,
}

/// The pair's identity: dataset, tf and the swept fields other than the mode's.
fn pair_id(dataset: &str, tf: &str, axes: &[(String, serde_json::Value)]) -> String {
    format!(
        "{dataset}\u{0}{tf}\u{0}{}",
        serde_json::to_string(axes).unwrap_or_default()
    )
}

fn axes_of(v: &serde_json::Value) -> Vec<(String, serde_json::Value)> {
    v.as_object()
        .map(|o| {
            o.iter()
                // What a mode or the tf axis sets is never part of a pair's identity.
                .filter(|(k, _)| !MODE_FIELDS.contains(&k.as_str()))
                .map(|(k, v)| (k.clone(), v.clone()))
                .collect()
        })
        .unwrap_or_default()
}

/// A mode the advisor ranks: ERT with a map, a distance volume or lossless leap values.
fn ranked_mode(mode: &str) -> bool {
    Mode::parse(mode).is_ok_and(|m| {
        m.ert && m.bricks == 0 && m.iso.is_none() && m.leap_values != Some(LeapRegions::Homogeneous)
    })
}

/// Runs the advisor for every (dataset, tf, swept fields) of the sweep results in `dir` (cycle
/// model lines) and compares its pick with the fastest configuration there that fits the SRAM.
/// Only modes the advisor ranks count (lossless leaping with ERT); `none`, bricks, iso and
/// homogeneous leap values are ignored. A pair whose runs (by the folder's
/// `experiment.resolved.json`) are not all there yet is left out and listed.
pub fn validate(
    dir: &std::path::Path,
    data_dir: Option<&std::path::Path>,
    options: &ValidateOptions,
    mut progress: impl FnMut(&ValidationRow),
) -> Result<Validation> {
    use std::collections::BTreeMap;
    if !dir.is_dir() {
        return Err(Error::Invalid(if dir.exists() {
            format!("not a folder: a sweep's results folder or a `{FPS_TABLE}` table")
        } else {
            "no such folder".to_string()
        }));
    }
    let results = dir.join(crate::experiment::store::RESULTS);
    if !results.is_file() {
        return Err(Error::Invalid(format!(
            "no {} (not a sweep's results folder)",
            crate::experiment::store::RESULTS
        )));
    }
    let resolved: Option<serde_json::Value> =
        std::fs::read_to_string(dir.join("experiment.resolved.json"))
            .ok()
            .and_then(|text| serde_json::from_str(&text).ok());
    // The experiment's base configuration file, when it named one.
    let base_config = resolved.as_ref().and_then(|v| {
        v["experiment"]["config"]
            .as_str()
            .map(std::path::PathBuf::from)
    });
    // Runs the experiment expands to, per pair.
    let mut expected: BTreeMap<String, usize> = BTreeMap::new();
    if let Some(runs) = resolved.as_ref().and_then(|v| v["runs"].as_array()) {
        for run in runs {
            let text = |k: &str| run[k].as_str().unwrap_or_default();
            if text("model") == "cycle" && ranked_mode(text("mode")) {
                let id = pair_id(text("dataset"), text("tf"), &axes_of(&run["axes"]));
                *expected.entry(id).or_default() += 1;
            }
        }
    }
    let mut pairs: BTreeMap<String, Pair> = BTreeMap::new();
    let mut not_ranked = std::collections::BTreeSet::new();
    // pair id -> unranked mode -> frame -> fps
    let mut unranked: BTreeMap<String, BTreeMap<String, BTreeMap<u32, f64>>> = BTreeMap::new();
    let mut sample_rates: Vec<f64> = Vec::new();
    let (read, torn_last_line) = crate::experiment::store::read_lines_and_torn(&results)?;
    for (line, _) in read {
        if line["model"].as_str() != Some("cycle") || line.get("time_step").is_some() {
            continue;
        }
        let text = |k: &str| line[k].as_str().unwrap_or_default().to_string();
        let mode = text("mode");
        if !ranked_mode(&mode) {
            // Kept to say where such a mode beat the advice (the pair's frames are known only
            // once every line is read); one whose map does not fit the SRAM is no contender.
            let fits = line["fits_default_sram"].as_bool().unwrap_or(true);
            if let (Some(fps), true) = (line["fps"].as_f64(), fits) {
                let id = pair_id(&text("dataset"), &text("tf"), &axes_of(&line["axes"]));
                let frame = line["frame"].as_u64().unwrap_or(0) as u32;
                unranked
                    .entry(id)
                    .or_default()
                    .entry(mode.clone())
                    .or_default()
                    .insert(frame, fps);
            }
            if mode != "none" {
                not_ranked.insert(mode);
            }
            continue;
        }
        let (Some(fps), Some(w), Some(h)) = (
            line["fps"].as_f64(),
            line["width"].as_u64(),
            line["height"].as_u64(),
        ) else {
            continue;
        };
        let axes = axes_of(&line["axes"]);
        let id = pair_id(&text("dataset"), &text("tf"), &axes);
        let pair = pairs.entry(id).or_insert_with(|| Pair {
            dataset: text("dataset"),
            tf: text("tf"),
            transfer_function: text("transfer_function"),
            axes,
            size: (w as u32, h as u32),
            views: Default::default(),
            lines: 0,
            modes: BTreeMap::new(),
        });
        pair.lines += 1;
        let frame = line["frame"].as_u64().unwrap_or(0) as u32;
        pair.views.insert((frame, text("view")));
        let fits = line["fits_default_sram"].as_bool().unwrap_or(true);
        if let Some(rate) = line["sample_rate"].as_f64() {
            if !sample_rates.contains(&rate) {
                sample_rates.push(rate);
            }
        }
        let entry = pair
            .modes
            .entry(mode.clone())
            .or_insert_with(|| (BTreeMap::new(), fits));
        // Two results of one frame (exact and sampled runs joined into one file) would leave
        // whichever came last.
        if entry.0.insert(frame, fps).is_some() {
            return Err(Error::Invalid(format!(
                "{}: two results of {} with {}, mode {mode}, frame {frame} (exact and sampled \
                 runs, or two image sizes, in one folder?); validate each from its own folder",
                results.display(),
                text("dataset"),
                text("tf")
            )));
        }
    }
    sample_rates.sort_by(f64::total_cmp);
    // A pair whose results are not all there (a sweep still running) is left out: its best
    // configuration may be among the missing runs.
    let mut incomplete = Vec::new();
    pairs.retain(|id, p| match expected.get(id) {
        Some(&n) if p.lines < n => {
            incomplete.push(format!("{} {}: {} of {n} runs", p.dataset, p.tf, p.lines));
            false
        }
        _ => true,
    });
    // Means over the frames every mode of a pair has (a folder that grew by frames holds more
    // frames of some modes than of others).
    for pair in pairs.values_mut() {
        let common: std::collections::BTreeSet<u32> = pair
            .views
            .iter()
            .map(|(f, _)| *f)
            .filter(|f| {
                pair.modes
                    .values()
                    .all(|(frames, _)| frames.contains_key(f))
            })
            .collect();
        pair.views.retain(|(f, _)| common.contains(f));
        for (frames, _) in pair.modes.values_mut() {
            frames.retain(|f, _| common.contains(f));
        }
    }
    pairs.retain(|_, p| !p.views.is_empty());
    if pairs.is_empty() && incomplete.is_empty() {
        return Err(Error::Invalid(
            "no cycle-model results of modes the advisor ranks (ert, ert+leapN[+hier], \
             ert+distanceN, ert+leapvalues)"
                .to_string(),
        ));
    }
    let mut rows = Vec::new();
    // A structure asked for that no run of the folder has would restrict the advice to
    // nothing of it: refused before any pair is advised.
    if let Some(asked) = &options.structures {
        let ran = |s: &Structure| {
            pairs
                .values()
                .flat_map(|p| p.modes.keys())
                .any(|m| match s {
                    Structure::Map => m.contains("leap") && !m.contains("leapvalues"),
                    Structure::Distance => m.contains("distance"),
                    Structure::LeapValues => m.contains("leapvalues"),
                })
        };
        if let Some(missing) = asked.iter().find(|s| !ran(s)) {
            return Err(Error::Invalid(format!(
                "--structures {}: the folder holds no run with it",
                missing.name()
            )));
        }
    }
    for (id, pair) in &pairs {
        let overrides: Vec<String> = pair
            .axes
            .iter()
            .map(|(k, v)| match v {
                serde_json::Value::String(s) => format!("{k}=\"{s}\""),
                other => format!("{k}={other}"),
            })
            .collect();
        let hardware = HardwareConfig::load(base_config.as_deref(), &overrides)?;
        let views: Vec<String> = pair.views.iter().map(|(_, v)| v.clone()).collect();
        let step = views.len().div_ceil(options.max_views.max(1));
        let used: Vec<String> = views.iter().step_by(step.max(1)).cloned().collect();
        let volume = crate::volume::dataset::load(&pair.dataset, data_dir)?;
        let base = RunDescription {
            size: pair.size,
            ..RunDescription::new(&pair.dataset, &pair.tf, Model::Step, hardware)
        };
        let mut structures = vec![Structure::Map];
        if pair.modes.keys().any(|m| m.contains("distance")) {
            structures.push(Structure::Distance);
        }
        if pair.modes.keys().any(|m| m.contains("leapvalues")) {
            structures.push(Structure::LeapValues);
        }
        // The advice is restricted to the structures asked for; the truth ranks them all.
        let allowed = options.structures.clone().unwrap_or(structures.clone());
        let mut advice = advise(
            &base,
            &volume,
            &AdviseOptions {
                views: used.clone(),
                sample_size: reduced_size(pair.size, options.max_rays),
                structures,
            },
        )?;
        // ERT alone is the baseline every structure is ranked against: always allowed.
        for c in &mut advice.ranking {
            c.allowed = match c.structure {
                CandidateStructure::None => true,
                CandidateStructure::Map => allowed.contains(&Structure::Map),
                CandidateStructure::Distance => allowed.contains(&Structure::Distance),
                CandidateStructure::LeapValues => allowed.contains(&Structure::LeapValues),
            };
        }
        let mean = |m: &str| {
            pair.modes
                .get(m)
                .map(|(frames, _)| frames.values().sum::<f64>() / frames.len().max(1) as f64)
        };
        // The advisor's pick among what the folder ran (it ranks more than a folder may hold).
        let advised = advice
            .ranking
            .iter()
            .find(|c| c.fits && c.allowed && pair.modes.contains_key(&c.mode))
            .ok_or_else(|| {
                Error::Invalid(format!(
                    "{} with {}: no configuration that fits the SRAM",
                    pair.dataset, pair.tf
                ))
            })?;
        let (best, best_fps) = pair
            .modes
            .iter()
            .filter(|(m, (_, fits))| {
                *fits && advice.ranking.iter().any(|c| &c.mode == *m && c.fits)
            })
            .map(|(m, _)| (m.clone(), mean(m).unwrap_or(0.0)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap_or_else(|| (advised.mode.clone(), mean(&advised.mode).unwrap_or(0.0)));
        let advised_fps = mean(&advised.mode).unwrap_or(0.0);
        let (error_mean, error_max, config_errors) = fps_errors(
            &advice,
            pair.modes
                .keys()
                .filter_map(|m| Some((m.as_str(), mean(m)?))),
        );
        // Modes outside the advisor's range that beat its pick, each on the frames it shares
        // with the pair's (a mode run on fewer frames is compared on those).
        let advised_frames = pair.modes.get(&advised.mode).map(|(f, _)| f);
        let mut faster_not_ranked: Vec<FasterUnranked> = unranked
            .get(id)
            .into_iter()
            .flatten()
            .filter_map(|(mode, frames)| {
                let advised_frames = advised_frames?;
                let shared: Vec<u32> = frames
                    .keys()
                    .filter(|f| advised_frames.contains_key(f))
                    .copied()
                    .collect();
                if shared.is_empty() {
                    return None;
                }
                let n = shared.len() as f64;
                let fps = shared.iter().map(|f| frames[f]).sum::<f64>() / n;
                let advised_fps = shared.iter().map(|f| advised_frames[f]).sum::<f64>() / n;
                FasterUnranked::if_faster(mode.clone(), fps, advised_fps)
            })
            .collect();
        faster_not_ranked.sort_by(|a, b| b.fps.total_cmp(&a.fps));
        let row = ValidationRow {
            dataset: pair.dataset.clone(),
            tf: pair.tf.clone(),
            transfer_function: pair.transfer_function.clone(),
            axes: overrides.join(" "),
            frames: pair.views.len(),
            advisor_views: used.len(),
            size: pair.size,
            advised: advised.mode.clone(),
            advised_fps,
            best,
            best_fps,
            loss_percent: 100.0 * (1.0 - advised_fps / best_fps.max(1e-12)),
            predicted_fps: advised.predicted_fps,
            ert_fps: mean("ert"),
            advice_seconds: advice.seconds,
            advice_cpu_seconds: advice.cpu_seconds,
            fps_error_mean_percent: error_mean,
            fps_error_max_percent: error_max,
            faster_not_ranked,
            fps_errors: config_errors,
        };
        progress(&row);
        rows.push(row);
    }
    Ok(Validation {
        errors_by_structure: errors_by_group(&rows),
        rows,
        incomplete,
        not_ranked: not_ranked.into_iter().collect(),
        torn_last_line,
        sample_rates,
    })
}

/// The ranking as a table, the recommendation and the time the advice took.
pub fn advice_text(advice: &Advice) -> String {
    use std::fmt::Write;
    let mut text = format!(
        "advice for {} ({}x{}x{}), transfer function {} ({}), {}x{} image, mean over {} view{}\n\
         functional model at {}x{} per view; cost model: {:.3} cycles per sample, {} rays, \
         SRAM {} bits\n\n",
        advice.dataset,
        advice.dims[0],
        advice.dims[1],
        advice.dims[2],
        advice.transfer_function,
        advice.tf,
        advice.size.0,
        advice.size.1,
        advice.views.len(),
        if advice.views.len() == 1 { "" } else { "s" },
        advice.sample_size.0,
        advice.sample_size.1,
        advice.cost_model.cycles_per_sample,
        advice.cost_model.rays,
        advice.sram_bits
    );
    let _ = writeln!(
        text,
        "| rank | configuration | mode | map bits | fits | skippable % | steps (M) | samples (M) | predicted fps | × ERT |"
    );
    let _ = writeln!(text, "|---:|---|---|---:|---|---:|---:|---:|---:|---:|");
    // Why a candidate does not fit: a numbered note per distinct reason, below the table.
    let mut reasons: Vec<&str> = Vec::new();
    for (i, c) in advice.ranking.iter().enumerate() {
        let fits = match &c.misfit {
            None => "yes".to_string(),
            Some(reason) => {
                let n = match reasons.iter().position(|r| *r == reason.as_str()) {
                    Some(n) => n + 1,
                    None => {
                        reasons.push(reason);
                        reasons.len()
                    }
                };
                format!("no ({n})")
            }
        };
        let _ = writeln!(
            text,
            "| {} | {}{}{} | {} | {} | {} | {} | {:.2} | {:.2} | {:.2} | {:.2} |",
            i + 1,
            c.label,
            if leap_value_calibrated(&c.mode) {
                " †"
            } else {
                ""
            },
            if c.mode == advice.recommended {
                " ◀ recommended"
            } else {
                ""
            },
            c.mode,
            c.map_bits
                .map(|b| b.to_string())
                .unwrap_or_else(|| "–".into()),
            fits,
            c.skippable_percent
                .map(|p| format!("{p:.1}"))
                .unwrap_or_else(|| "–".into()),
            c.steps / 1e6,
            c.samples / 1e6,
            c.predicted_fps,
            c.speedup_over_ert
        );
    }
    if !reasons.is_empty() {
        let _ = writeln!(text, "\nnot accepted by the cycle model (`sim`):");
        for (n, reason) in reasons.iter().enumerate() {
            let _ = writeln!(text, "({}) {reason}", n + 1);
        }
    }
    for c in &advice.not_predicted {
        let _ = writeln!(
            text,
            "\nnot predicted: {} (`{}`): the cycle model refuses it ({}), and its steps could not \
             be counted ({})",
            c.label, c.mode, c.reason, c.error
        );
    }
    if advice
        .ranking
        .iter()
        .any(|c| leap_value_calibrated(&c.mode))
    {
        let _ = writeln!(
            text,
            "\n† from one calibrated row-miss rate (28 %): with leap values the rays drift apart \
             and miss rows at 11–33 % on the cycle model, so this is within about ±30 % \
             (docs/advise.md, \"Leap values\")"
        );
    }
    let r = advice.recommended();
    let _ = writeln!(
        text,
        "\nrecommended: {} (`{}`): {:.2} fps predicted, {:.2}× ERT{}\nadvice took {:.2} s{}",
        r.label,
        r.mode,
        r.predicted_fps,
        r.speedup_over_ert,
        match advice.ranking.first() {
            Some(top) if !top.fits => format!(
                "; {} would be {:.0} % faster but {}",
                top.label,
                100.0 * (top.predicted_fps / r.predicted_fps - 1.0),
                top.misfit.as_deref().unwrap_or("it does not fit")
            ),
            _ => String::new(),
        },
        advice.seconds,
        advice
            .cpu_seconds
            .map(|c| format!(" ({c:.2} s of CPU time)"))
            .unwrap_or_default()
    );
    text
}

/// The validation table (Markdown) with a summary and the command that made it.
pub fn validation_markdown(validation: &Validation, command: &str) -> String {
    use std::fmt::Write;
    let rows = &validation.rows;
    let mut text = String::from(
        "| dataset | tf | frames | image | advised | fps | true best | fps | loss % | fps error mean / max % | advice s (CPU s) |\n\
         |---|---|---:|---|---|---:|---|---:|---:|---:|---:|\n",
    );
    for r in rows {
        let _ = writeln!(
            text,
            "| {}{} | {} | {} | {}x{} | {} | {:.2} | {} | {:.2} | {:.1} | {:.1} / {:.1} | {:.2} ({}) |",
            r.dataset,
            if r.axes.is_empty() {
                String::new()
            } else {
                format!(" ({})", r.axes)
            },
            r.transfer_function,
            if r.frames == 0 {
                format!("table ({} used)", r.advisor_views)
            } else {
                format!("{} ({} used)", r.frames, r.advisor_views)
            },
            r.size.0,
            r.size.1,
            r.advised,
            r.advised_fps,
            r.best,
            r.best_fps,
            r.loss_percent,
            r.fps_error_mean_percent,
            r.fps_error_max_percent,
            r.advice_seconds,
            r.advice_cpu_seconds
                .map(|c| format!("{c:.2}"))
                .unwrap_or_else(|| "–".into())
        );
    }
    let worst = rows.iter().map(|r| r.loss_percent).fold(0.0f64, f64::max);
    let exact = rows.iter().filter(|r| r.advised == r.best).count();
    let within = rows.iter().filter(|r| r.loss_percent <= 5.0).count();
    // Pairs where a mode the advisor does not rank beat its pick: the advice is the best of
    // the ranked modes at most there, and the summary says so.
    let beaten: Vec<&ValidationRow> = rows
        .iter()
        .filter(|r| !r.faster_not_ranked.is_empty())
        .collect();
    let slowest = rows.iter().map(|r| r.advice_seconds).fold(0.0f64, f64::max);
    let slowest_cpu = rows
        .iter()
        .filter_map(|r| r.advice_cpu_seconds)
        .fold(0.0f64, f64::max);
    let quality = if beaten.is_empty() {
        format!(
            "the advice is the true best in {exact}, within 5 % in {within}; worst loss \
             {worst:.1} %"
        )
    } else {
        format!(
            "the advice is the true best among the ranked modes in {exact}, within 5 % of it in \
             {within} (worst loss {worst:.1} %); a mode advise does not rank was faster in {} \
             (below), so the advice is the true best of every mode run in {} only",
            beaten.len(),
            rows.iter()
                .filter(|r| r.advised == r.best && r.faster_not_ranked.is_empty())
                .count()
        )
    };
    let _ = writeln!(
        text,
        "\n{} pairs: {quality}; slowest advice {slowest:.2} s wall, {slowest_cpu:.2} s of CPU \
         time. Predicted frame rates are {:.1} % off the cycle model's on average over the pairs \
         (per pair the mean over its configurations), {:.1} % at most.",
        rows.len(),
        rows.iter().map(|r| r.fps_error_mean_percent).sum::<f64>() / rows.len().max(1) as f64,
        rows.iter()
            .map(|r| r.fps_error_max_percent)
            .fold(0.0f64, f64::max)
    );
    if !validation.errors_by_structure.is_empty() {
        let _ = writeln!(
            text,
            "\nPrediction error by structure (predicted / cycle model − 1 over every \
             configuration of that structure in every pair; + is predicted faster):\n\n\
             | structure | configurations | pairs | mean \\|error\\| % | mean signed % | max \\|error\\| % |\n\
             |---|---:|---:|---:|---:|---:|"
        );
        for g in &validation.errors_by_structure {
            let _ = writeln!(
                text,
                "| {} | {} | {} | {:.1} | {:+.1} | {:.1} |",
                g.group,
                g.configurations,
                g.pairs,
                g.mean_abs_percent,
                g.mean_percent,
                g.max_abs_percent
            );
        }
    }
    if !beaten.is_empty() {
        let _ = writeln!(
            text,
            "\nFaster than the advice, modes advise does not rank (mean over the frames both ran):"
        );
        for r in &beaten {
            let _ = writeln!(
                text,
                "- {} {}{}: {}; the advice {} ran {:.2} fps",
                r.dataset,
                r.transfer_function,
                if r.axes.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", r.axes)
                },
                r.faster_not_ranked
                    .iter()
                    .map(FasterUnranked::describe)
                    .collect::<Vec<_>>()
                    .join("; "),
                r.advised,
                r.faster_not_ranked[0].advised_fps
            );
        }
    }
    if !validation.incomplete.is_empty() {
        let _ = writeln!(
            text,
            "\nLeft out, their runs not all there yet: {}.",
            validation.incomplete.join("; ")
        );
    }
    if !validation.sample_rates.is_empty() {
        let _ = writeln!(
            text,
            "\nThe cycle model's frame rates here are sampled estimates (sample rate {}), each \
             with a 95 % interval (docs/sampling.md): where two configurations are within a few \
             per cent of each other, the true best may be the other.",
            validation
                .sample_rates
                .iter()
                .map(|r| format!("{r}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    if !validation.not_ranked.is_empty() {
        let _ = writeln!(
            text,
            "\nLeft out of the true best, as modes the advisor does not rank: {}.",
            validation.not_ranked.join(", ")
        );
    }
    if validation.torn_last_line {
        let _ = writeln!(
            text,
            "\nThe last line of {} was incomplete (a sweep killed while writing it, or one still \
             running) and is left out.",
            crate::experiment::store::RESULTS
        );
    }
    let _ = writeln!(text, "\nMade by `{command}`.");
    text
}

/// Writes `validation.md`, `validation.csv` and `validation.json` into `dir`.
pub fn write_validation(
    dir: &std::path::Path,
    validation: &Validation,
    command: &str,
) -> Result<()> {
    use std::io::Write;
    let rows = &validation.rows;
    crate::output::write_atomically(&dir.join("validation.md"), |f| {
        f.write_all(validation_markdown(validation, command).as_bytes())
    })?;
    crate::output::write_atomically(&dir.join("validation.json"), |f| {
        f.write_all(
            serde_json::to_string_pretty(validation)
                .unwrap_or_default()
                .as_bytes(),
        )
    })?;
    crate::output::write_atomically(&dir.join("validation.csv"), |f| {
        writeln!(
            f,
            "dataset,tf,transfer_function,axes,frames,advisor_views,width,height,advised,advised_fps,best,best_fps,loss_percent,predicted_fps,ert_fps,advice_seconds,advice_cpu_seconds,fps_error_mean_percent,fps_error_max_percent,faster_not_ranked"
        )?;
        for r in rows {
            writeln!(
                f,
                "{},{},{},\"{}\",{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                r.dataset,
                r.tf,
                r.transfer_function,
                r.axes.replace('"', "'"),
                r.frames,
                r.advisor_views,
                r.size.0,
                r.size.1,
                r.advised,
                r.advised_fps,
                r.best,
                r.best_fps,
                r.loss_percent,
                r.predicted_fps,
                r.ert_fps.map(|f| f.to_string()).unwrap_or_default(),
                r.advice_seconds,
                r.advice_cpu_seconds
                    .map(|c| c.to_string())
                    .unwrap_or_default(),
                r.fps_error_mean_percent,
                r.fps_error_max_percent,
                // `mode fps` pairs, ';'-separated: no comma in the cell.
                r.faster_not_ranked
                    .iter()
                    .map(|u| format!("{} {}", u.mode, u.fps))
                    .collect::<Vec<_>>()
                    .join(";")
            )?;
        }
        Ok(())
    })
}

/// Validates against a table of mean frame rates as `vizsim table` writes it (CSV: `dataset,tf,`
/// then one column per mode labelled `ERT`, `8³`, `8³+h`; rows labelled `vessel (aneurism)`,
/// `'0'`), e.g. the protocol's `reports/paper-protocol/tables/cycle-fps.csv`, for which no
/// results folder is kept. The table does not say its image size, frames or hardware: the
/// advisor runs with `size`, `views` and `hardware`. Whether a map fits is the advisor's own
/// test (`map_bits` against `occupancy.sram_bits`).
pub fn validate_table(
    path: &std::path::Path,
    data_dir: Option<&std::path::Path>,
    hardware: &HardwareConfig,
    size: (u32, u32),
    views: &[String],
    max_rays: u64,
    mut progress: impl FnMut(&ValidationRow),
) -> Result<Validation> {
    if path.file_name().and_then(|n| n.to_str()) != Some(FPS_TABLE) {
        return Err(Error::Invalid(format!(
            "expected the cycle model's frame-rate table, `{FPS_TABLE}` as `vizsim table --model \
             cycle --metric fps` writes it (another table's cells would be read as frame rates)"
        )));
    }
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let bad = |line: usize, message: String| Error::format(path, format!("line {line}: {message}"));
    let mut lines = text.lines();
    // Labels with a comma (`no ERT, 4³`) are quoted, as `vizsim table` writes them.
    let cells_of = |number: usize, line: &str| {
        crate::tables::csv_cells(line).ok_or_else(|| bad(number, "a quote is left open".into()))
    };
    let header = cells_of(1, lines.next().ok_or_else(|| bad(1, "empty table".into()))?)?;
    if header.len() < 3 || header[0] != "dataset" || header[1] != "tf" {
        return Err(bad(1, "expected a header `dataset,tf,MODE...`".into()));
    }
    if let Some(label) = header
        .iter()
        .enumerate()
        .find_map(|(i, h)| header[..i].contains(h).then_some(h))
    {
        return Err(bad(1, format!("column `{label}` is given twice")));
    }
    // Column label -> mode: `ERT`, `N³` (leapN), `N³+h` (leapN+hier); others are ignored.
    let modes: Vec<Option<String>> = header[2..]
        .iter()
        .map(|label| {
            if label == "ERT" {
                return Some("ert".to_string());
            }
            let (n, hier) = match label.strip_suffix("+h") {
                Some(n) => (n, true),
                None => (label.as_str(), false),
            };
            let n: usize = n.strip_suffix('³')?.parse().ok()?;
            Some(format!("ert+leap{n}{}", if hier { "+hier" } else { "" }))
        })
        .collect();
    let mut rows = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    for (i, line) in lines.enumerate() {
        let number = i + 2;
        if line.trim().is_empty() {
            continue;
        }
        let cells = cells_of(number, line)?;
        if cells.len() != header.len() {
            return Err(bad(
                number,
                format!("{} cells, the header has {}", cells.len(), header.len()),
            ));
        }
        // A cell of a ranked mode is empty (not run) or a frame rate; anything else would
        // be left out or skew the loss unseen.
        for ((label, cell), mode) in header[2..].iter().zip(&cells[2..]).zip(&modes) {
            if mode.is_none() || cell.is_empty() {
                continue;
            }
            if !cell.parse::<f64>().is_ok_and(|v| v.is_finite() && v > 0.0) {
                return Err(bad(
                    number,
                    format!("column `{label}`: `{cell}` is not a frame rate (a positive number)"),
                ));
            }
        }
        let cells: Vec<&str> = cells.iter().map(String::as_str).collect();
        // `vessel (aneurism)`, `skull (stand-in: tooth)`: the published name, which the
        // dataset aliases resolve to the data (or its stand-in).
        let dataset = cells[0].split(" (").next().unwrap_or(cells[0]).trim();
        let tf = match cells[1] {
            "'0'" | "zero" => "zero",
            "class" => "class",
            other => {
                return Err(bad(
                    number,
                    format!("transfer function `{other}`: expected '0' or class"),
                ))
            }
        };
        if !seen.insert((dataset.to_string(), tf)) {
            return Err(bad(
                number,
                format!(
                    "dataset `{dataset}`, transfer function `{tf}` is a row twice (a table with \
                     more row fields than dataset and tf? validate one made with the default \
                     rows)"
                ),
            ));
        }
        let volume = crate::volume::dataset::load(dataset, data_dir)?;
        let base = RunDescription {
            size,
            ..RunDescription::new(dataset, tf, Model::Step, hardware.clone())
        };
        let advice = advise(
            &base,
            &volume,
            &AdviseOptions {
                views: views.to_vec(),
                sample_size: reduced_size(size, max_rays),
                structures: vec![Structure::Map],
            },
        )?;
        let truth: Vec<(String, f64)> = modes
            .iter()
            .zip(&cells[2..])
            .filter_map(|(m, c)| Some((m.clone()?, c.parse::<f64>().ok()?)))
            .filter(|(m, _)| advice.ranking.iter().any(|c| &c.mode == m && c.fits))
            .collect();
        let fps_of = |m: &str| truth.iter().find(|(t, _)| t == m).map(|(_, f)| *f);
        let Some(advised) = advice
            .ranking
            .iter()
            .find(|c| c.fits && fps_of(&c.mode).is_some())
        else {
            return Err(bad(
                number,
                "no frame rate in the row is of a configuration the advisor ranks that fits the \
                 SRAM (columns ERT, N³ or N³+h with a number)"
                    .into(),
            ));
        };
        let (best, best_fps) = truth
            .iter()
            .cloned()
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .expect("the advised configuration is in the table");
        let advised_fps = fps_of(&advised.mode).unwrap_or(0.0);
        let (error_mean, error_max, config_errors) = fps_errors(
            &advice,
            modes
                .iter()
                .zip(&cells[2..])
                .filter_map(|(m, c)| Some((m.as_deref()?, c.parse::<f64>().ok()?))),
        );
        // Columns of modes the advisor does not rank (`no ERT, 4³`) that beat its pick.
        let mut faster_not_ranked: Vec<FasterUnranked> = header[2..]
            .iter()
            .zip(&cells[2..])
            .zip(&modes)
            .filter(|(_, mode)| mode.is_none())
            .filter_map(|((label, cell), _)| {
                let fps = cell.parse::<f64>().ok().filter(|f| f.is_finite())?;
                FasterUnranked::if_faster(label.clone(), fps, advised_fps)
            })
            .collect();
        faster_not_ranked.sort_by(|a, b| b.fps.total_cmp(&a.fps));
        let row = ValidationRow {
            dataset: dataset.to_string(),
            tf: tf.to_string(),
            transfer_function: advice.transfer_function.clone(),
            axes: String::new(),
            frames: 0,
            advisor_views: views.len(),
            size,
            advised: advised.mode.clone(),
            advised_fps,
            best,
            best_fps,
            loss_percent: 100.0 * (1.0 - advised_fps / best_fps.max(1e-12)),
            predicted_fps: advised.predicted_fps,
            ert_fps: fps_of("ert"),
            advice_seconds: advice.seconds,
            advice_cpu_seconds: advice.cpu_seconds,
            fps_error_mean_percent: error_mean,
            fps_error_max_percent: error_max,
            faster_not_ranked,
            fps_errors: config_errors,
        };
        progress(&row);
        rows.push(row);
    }
    if rows.is_empty() {
        return Err(bad(2, "no rows: the table holds only its header".into()));
    }
    Ok(Validation {
        errors_by_structure: errors_by_group(&rows),
        rows,
        incomplete: Vec::new(),
        not_ranked: Vec::new(),
        torn_last_line: false,
        sample_rates: Vec::new(),
    })
}

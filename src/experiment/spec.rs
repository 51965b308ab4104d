//! Experiment files (`configs/experiments/*.toml`) and their expansion into runs. Everything
//! is checked before the first run: unknown field paths, empty axes, values out of range,
//! unknown modes and datasets that are not there, each error naming the axis and the value.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::camera::{parse_image_size, Projection};
use crate::config::{self, HardwareConfig};
use crate::dynamic::{MapMode, Sequence};
use crate::error::{Error, Result};
use crate::occupancy::SUBCUBE_SIZES;
use crate::run::RunDescription;
use crate::volume::{dataset, Volume};

#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ExperimentFile {
    pub name: String,
    #[serde(default)]
    pub description: String,
    /// Base hardware configuration file (default: the embedded vizard2.toml).
    pub config: Option<PathBuf>,
    /// Dataset names (`fuel`, `aneurism`, `phantom:metaballs:64`, ...).
    pub datasets: Vec<String>,
    /// Classification axis: `zero` ('0' transfer function and map) and/or `class`.
    #[serde(default = "default_tf")]
    pub tf: Vec<String>,
    /// Acceleration modes: `none`, or `+`-joined `ert`, `leapN`, `hier`, `distanceN`,
    /// `leapvalues`, `leapvalues-homogeneous`, `bricksN`, `table`, `isoN` (iso-surface mode
    /// with N refinement steps; the iso value from the configuration or an `iso.value` axis).
    pub modes: Vec<String>,
    /// `step` (functional model, counts steps) and/or `cycle` (cycle-accurate with SDRAM).
    pub models: Vec<String>,
    /// Leaping points whose map exceeds occupancy.sram_bits: run them with the SRAM raised to
    /// the next power of two that fits (marked in the results), or leave them out.
    #[serde(default)]
    pub raise_sram: bool,
    pub frames: Frames,
    /// Hardware fields by dotted path, each with its list of values.
    #[serde(default)]
    pub axes: toml::Table,
    /// Groups of axes that advance together instead of spanning a product.
    #[serde(default)]
    pub zip: Vec<Vec<String>>,
    /// Runs matching every key of one of these tables are left out.
    #[serde(default)]
    pub exclude: Vec<toml::Table>,
    /// A time axis: the datasets are sequences (`phantom:metaballs…`, `phantom:tsdf…`, a
    /// folder of time steps) and every run is one time step of one sequence's frame loop
    /// (docs/experiments.md, "Sequences"). Written out only when given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sequence: Option<SequenceAxis>,
}

/// `[sequence]`: the time axis of a dynamic experiment.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SequenceAxis {
    /// Time steps per sequence (step 0 downloads the whole volume).
    pub steps: usize,
    /// Metaballs: time between steps.
    #[serde(default = "default_dt")]
    pub dt: f64,
    /// Edge of the bricks a partial update sends.
    #[serde(default = "default_brick")]
    pub brick: usize,
    /// How the occupancy map follows the volume: `update` (built during the update, widened),
    /// `rescan` (during the update, partly written sub-cubes read back), `scan` (a separate
    /// scan pass per step), `none` (no leaping).
    #[serde(default = "default_maps")]
    pub map: Vec<String>,
}

fn default_dt() -> f64 {
    0.05
}
fn default_brick() -> usize {
    8
}
fn default_maps() -> Vec<String> {
    vec!["update".into(), "scan".into(), "none".into()]
}

/// A map strategy of `[sequence] map`: `update` (or `during-update`), `rescan`, `scan`, `none`.
pub fn parse_map_strategy(text: &str) -> std::result::Result<MapMode, String> {
    match text {
        "update" => Ok(MapMode::DuringUpdate),
        "during-update" | "rescan" | "scan" | "none" => MapMode::parse(text),
        other => Err(format!(
            "`{other}`: unknown map strategy; expected `update` (map built during the update), \
             `rescan` (during the update, partly written sub-cubes read back), `scan` (a separate \
             scan pass) or `none` (no leaping)"
        )),
    }
}

/// Where a run sits in a sequence: one time step of one frame loop.
#[derive(Clone, Debug, Serialize)]
pub struct StepSpec {
    /// The sequence's source (the dataset as listed).
    pub source: String,
    pub time_step: usize,
    pub map: MapMode,
    pub dt: f64,
    pub brick: usize,
}

fn default_tf() -> Vec<String> {
    vec!["zero".into(), "class".into()]
}

#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Frames {
    /// Frames of the full orbit about the vertical axis (72 in the published protocol).
    pub orbit: u32,
    /// Frame indices to run (default: all).
    pub select: Option<Vec<u32>>,
    /// Or every n-th frame.
    pub every: Option<u32>,
    #[serde(default = "default_size")]
    pub size: String,
    #[serde(default = "default_projection")]
    pub projection: String,
    /// A camera path file (`crate::path`): the views are then `path:FILE:K/N` with N =
    /// `orbit` frames along the path instead of the orbit. Written out only when given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<String>,
}

fn default_size() -> String {
    "256x256".into()
}
fn default_projection() -> String {
    "ortho".into()
}

/// An acceleration mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
pub struct Mode {
    pub ert: bool,
    /// 0 = no leaping.
    pub subcube: usize,
    pub hierarchy: bool,
    /// Bits of the distance volume that leaps (`distanceN`), 0 = none. Serialised only when
    /// set, so existing results keep their form.
    #[serde(skip_serializing_if = "is_zero")]
    pub distance_bits: u32,
    /// Leap values in the volume (`leapvalues`: empty regions, `leapvalues-homogeneous`),
    /// None = not this structure. Serialised only when set.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub leap_values: Option<config::LeapRegions>,
    /// Bounding-brick edge (`bricksN`), 0 = none; `table`: start and end from a per-frame table
    /// instead of the ray-setup traversal. Serialised only when set.
    #[serde(skip_serializing_if = "is_zero_usize")]
    pub bricks: usize,
    #[serde(skip_serializing_if = "is_false")]
    pub brick_table: bool,
    /// Iso-surface mode with this many refinement steps (`isoN`), None = off. Serialised only
    /// when set.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub iso: Option<u32>,
}

fn is_zero(n: &u32) -> bool {
    *n == 0
}

fn is_zero_usize(n: &usize) -> bool {
    *n == 0
}

fn is_false(b: &bool) -> bool {
    !*b
}

impl Mode {
    pub fn parse(text: &str) -> std::result::Result<Mode, String> {
        let mut mode = Mode {
            ert: false,
            subcube: 0,
            hierarchy: false,
            distance_bits: 0,
            leap_values: None,
            bricks: 0,
            brick_table: false,
            iso: None,
        };
        if text == "none" {
            return Ok(mode);
        }
        for token in text.split('+') {
            match token {
                "ert" => mode.ert = true,
                "hier" => mode.hierarchy = true,
                "leapvalues" => mode.leap_values = Some(config::LeapRegions::Empty),
                "leapvalues-homogeneous" => {
                    mode.leap_values = Some(config::LeapRegions::Homogeneous)
                }
                t if t.starts_with("distance") => {
                    let n: u32 = t[8..]
                        .parse()
                        .map_err(|_| format!("`{t}`: expected distanceN, N the distance bits"))?;
                    if !config::DISTANCE_BITS_ALLOWED.contains(&n) {
                        return Err(format!(
                            "`{t}`: distance bits must be one of {:?}",
                            config::DISTANCE_BITS_ALLOWED
                        ));
                    }
                    mode.distance_bits = n;
                }
                "table" => mode.brick_table = true,
                t if t.starts_with("iso") => {
                    let n: u32 = t[3..].parse().map_err(|_| {
                        format!("`{t}`: expected isoN, N the refinement steps (iso0 = none)")
                    })?;
                    if n > config::MAX_REFINEMENT_STEPS {
                        return Err(format!(
                            "`{t}`: refinement steps must be 0..={}",
                            config::MAX_REFINEMENT_STEPS
                        ));
                    }
                    mode.iso = Some(n);
                }
                t if t.starts_with("bricks") => {
                    let n: usize = t[6..]
                        .parse()
                        .map_err(|_| format!("`{t}`: expected bricksN, N a brick edge"))?;
                    if !config::BRICK_SIZES.contains(&n) {
                        return Err(format!(
                            "`{t}`: brick edge must be one of {:?}",
                            config::BRICK_SIZES
                        ));
                    }
                    mode.bricks = n;
                }
                t if t.starts_with("leap") => {
                    let n: usize = t[4..]
                        .parse()
                        .map_err(|_| format!("`{t}`: expected leapN, N a sub-cube edge"))?;
                    if !SUBCUBE_SIZES.contains(&n) {
                        return Err(format!(
                            "`{t}`: sub-cube edge must be one of {SUBCUBE_SIZES:?}"
                        ));
                    }
                    mode.subcube = n;
                }
                t => {
                    return Err(format!(
                    "unknown token `{t}`; modes are `none` or `+`-joined `ert`, `leapN`, `hier`, \
                         `distanceN`, `leapvalues`, `leapvalues-homogeneous`, `bricksN`, `table`, \
                         `isoN`"
                ))
                }
            }
        }
        if mode.hierarchy && mode.subcube == 0 {
            return Err("`hier` needs `leapN`".into());
        }
        let structures = (mode.subcube > 0) as u32
            + (mode.distance_bits > 0) as u32
            + mode.leap_values.is_some() as u32;
        if structures > 1 {
            return Err(
                "`leapN`, `distanceN` and `leapvalues` are different leaping structures; choose one"
                    .into(),
            );
        }
        if mode.brick_table && mode.bricks == 0 {
            return Err("`table` needs `bricksN`".into());
        }
        if mode.iso.is_some() && mode.leap_values.is_some() {
            return Err("`isoN` does not work with `leapvalues`".into());
        }
        Ok(mode)
    }

    /// Canonical text: `none`, `ert`, `ert+leap8`, `ert+leap8+hier`, `ert+distance8`.
    pub fn name(&self) -> String {
        let mut parts = Vec::new();
        if self.ert {
            parts.push("ert".to_string());
        }
        if self.subcube > 0 {
            parts.push(format!("leap{}", self.subcube));
        }
        if self.hierarchy {
            parts.push("hier".into());
        }
        if self.distance_bits > 0 {
            parts.push(format!("distance{}", self.distance_bits));
        }
        match self.leap_values {
            Some(config::LeapRegions::Empty) => parts.push("leapvalues".into()),
            Some(config::LeapRegions::Homogeneous) => parts.push("leapvalues-homogeneous".into()),
            None => {}
        }
        if self.bricks > 0 {
            parts.push(format!("bricks{}", self.bricks));
        }
        if self.brick_table {
            parts.push("table".into());
        }
        if let Some(n) = self.iso {
            parts.push(format!("iso{n}"));
        }
        if parts.is_empty() {
            "none".into()
        } else {
            parts.join("+")
        }
    }
}

/// Experiments run the step and the cycle model (`float` has no cost to sweep).
pub use crate::run::Model;

/// Datasets that stand in for unavailable published ones (brief, section 6).
pub fn dataset_label(name: &str) -> (String, bool) {
    match name {
        "foot-lossy" => ("foot (lossy stand-in)".into(), true),
        "tooth_103x94x161" => ("skull (stand-in: tooth)".into(), true),
        "aneurism" => ("vessel (aneurism)".into(), false),
        other => (other.to_string(), false),
    }
}

/// One frame-run, fully resolved: the run itself (`run`, what `run::execute` takes) and where
/// it sits in the experiment.
#[derive(Clone, Debug, Serialize)]
pub struct RunSpec {
    pub key: String,
    /// Position in the experiment's expansion (sharding uses it).
    pub index: usize,
    pub mode: Mode,
    pub frame: u32,
    /// Swept hardware fields: path → value.
    pub axes: BTreeMap<String, serde_json::Value>,
    pub fits_default_sram: bool,
    pub run: RunDescription,
    /// Sequence experiments: the time step this run is. Serialised only when set.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sequence: Option<StepSpec>,
}

impl RunSpec {
    /// Runs that are steps of one frame loop (same source, TF, configuration, view and map
    /// strategy) run together, as one sequence; None for runs without a time axis.
    pub fn sequence_group(&self) -> Option<String> {
        let s = self.sequence.as_ref()?;
        Some(format!(
            "{}|{}|{}|{}|{}|{}|{}",
            self.run.dataset,
            self.run.tf,
            self.run.view,
            s.map.name(),
            s.dt,
            s.brick,
            serde_json::to_string(&self.run.hardware).unwrap_or_default(),
        ))
    }

    /// Runs that differ only in the frame share a prepared run (same dataset, TF and config).
    pub fn group(&self) -> (String, String, String) {
        (
            self.run.dataset.clone(),
            self.run.tf.clone(),
            serde_json::to_string(&self.run.hardware).unwrap_or_default(),
        )
    }
}

/// A point left out of the expansion, and why.
#[derive(Clone, Debug, Serialize)]
pub struct Skipped {
    pub dataset: String,
    pub mode: String,
    pub reason: String,
}

pub struct Expansion {
    pub experiment: ExperimentFile,
    pub source: String,
    pub runs: Vec<RunSpec>,
    pub skipped: Vec<Skipped>,
    /// Runs listed more than once in the file, dropped (each runs once).
    pub duplicates: usize,
    pub volumes: BTreeMap<String, Arc<Volume>>,
}

/// The most runs one experiment may expand to: 10^6 runs took 2.2 GB to expand.
pub const MAX_RUNS: u64 = 200_000;
/// Memory one expanded run holds (its resolved configuration and identity), rounded up.
const BYTES_PER_RUN: u64 = 4096;

/// Configuration fields a mode or the tf axis sets.
const MODE_FIELDS: [&str; 11] = [
    "compositing.ert",
    "occupancy.subcube",
    "occupancy.hierarchy",
    "occupancy.kind",
    "occupancy.structure",
    "occupancy.distance_bits",
    "leap_values.regions",
    "bricks.size",
    "bricks.setup",
    "iso.enabled",
    "iso.refinement_steps",
];

/// Reads and expands an experiment file.
pub fn load(path: &Path, data_dir: Option<&Path>) -> Result<Expansion> {
    let text = crate::input::read_text(path)?;
    expand(&text, &path.display().to_string(), data_dir)
}

fn toml_to_json(value: &toml::Value) -> serde_json::Value {
    serde_json::to_value(value).unwrap_or(serde_json::Value::Null)
}

/// SRAM bits of a sub-cube map of a volume (as `OccupancyMap::storage_bits`).
fn map_bits(dims: [usize; 3], subcube: usize, hierarchy: bool) -> u64 {
    let cells = dims.map(|d| d.div_ceil(subcube));
    if hierarchy {
        8 * cells.iter().map(|c| c.div_ceil(2) as u64).product::<u64>()
    } else {
        cells.iter().map(|&c| c as u64).product()
    }
}

pub fn expand(text: &str, source: &str, data_dir: Option<&Path>) -> Result<Expansion> {
    let experiment: ExperimentFile = toml::from_str(text)
        .map_err(|e| Error::format(source, format!("invalid experiment: {e}")))?;
    let bad = |field: &str, message: String| Error::config(source, field, message);
    for (field, list) in [
        ("datasets", &experiment.datasets),
        ("tf", &experiment.tf),
        ("modes", &experiment.modes),
        ("models", &experiment.models),
    ] {
        if list.is_empty() {
            return Err(bad(field, "is empty; give at least one value".into()));
        }
    }
    let base_text = match &experiment.config {
        Some(p) => crate::input::read_text(p)?,
        None => config::DEFAULT_TOML.to_string(),
    };
    let base_name = experiment
        .config
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_else(|| config::DEFAULT_NAME.to_string());
    HardwareConfig::from_toml_str(&base_text, &base_name, &[])?;

    let modes = experiment
        .modes
        .iter()
        .map(|m| Mode::parse(m).map_err(|e| bad("modes", format!("`{m}`: {e}"))))
        .collect::<Result<Vec<_>>>()?;
    let models = experiment
        .models
        .iter()
        .map(|m| match m.as_str() {
            "step" => Ok(Model::Step),
            "cycle" => Ok(Model::Cycle),
            other => Err(bad(
                "models",
                format!("`{other}`: expected `step` or `cycle`"),
            )),
        })
        .collect::<Result<Vec<_>>>()?;
    for tf in &experiment.tf {
        if tf != "zero" && tf != "class" {
            return Err(bad("tf", format!("`{tf}`: expected `zero` or `class`")));
        }
    }
    // The time axis: checked before anything is loaded.
    let sequence = match &experiment.sequence {
        None => None,
        Some(seq) => {
            if seq.steps == 0 {
                return Err(bad(
                    "sequence.steps",
                    "0 is out of range; a sequence needs at least one time step".into(),
                ));
            }
            if seq.steps > crate::dynamic::MAX_STEPS {
                return Err(bad(
                    "sequence.steps",
                    format!(
                        "{} is out of range; allowed 1..={}",
                        seq.steps,
                        crate::dynamic::MAX_STEPS
                    ),
                ));
            }
            if seq.brick == 0 {
                return Err(bad(
                    "sequence.brick",
                    "0 is out of range; bricks of at least 1".into(),
                ));
            }
            if !seq.dt.is_finite() || seq.dt <= 0.0 {
                return Err(bad(
                    "sequence.dt",
                    format!("{}: must be a finite number above 0", seq.dt),
                ));
            }
            if seq.map.is_empty() {
                return Err(bad(
                    "sequence.map",
                    "is empty; give at least one map strategy (update, rescan, scan, none)".into(),
                ));
            }
            let maps = seq
                .map
                .iter()
                .map(|m| parse_map_strategy(m).map_err(|e| bad("sequence.map", e)))
                .collect::<Result<Vec<_>>>()?;
            if let Some(m) = models.iter().find(|m| **m != Model::Cycle) {
                return Err(bad(
                    "models",
                    format!(
                        "`{}`: a sequence experiment measures update, map and render cycles on \
                         the cycle model; use models = [\"cycle\"]",
                        m.name()
                    ),
                ));
            }
            for m in &modes {
                let plain = Mode {
                    ert: m.ert,
                    subcube: m.subcube,
                    ..Mode::parse("none").expect("valid")
                };
                if *m != plain {
                    return Err(bad(
                        "modes",
                        format!(
                            "`{}`: a sequence experiment takes `none`, `ert`, `leapN` and \
                             `ert+leapN` (the map follows the volume as `sequence.map` says)",
                            m.name()
                        ),
                    ));
                }
            }
            Some((seq.clone(), maps))
        }
    };
    let frames = &experiment.frames;
    if frames.orbit == 0 || frames.orbit > 3600 {
        return Err(bad(
            "frames.orbit",
            format!("{} is out of range; allowed 1..=3600", frames.orbit),
        ));
    }
    let frame_list: Vec<u32> = match (&frames.select, frames.every) {
        (Some(_), Some(_)) => {
            return Err(bad("frames", "give `select` or `every`, not both".into()))
        }
        (Some(list), None) => {
            if list.is_empty() {
                return Err(bad("frames.select", "is empty".into()));
            }
            if let Some(f) = list.iter().find(|&&f| f >= frames.orbit) {
                return Err(bad(
                    "frames.select",
                    format!("frame {f} is out of range; allowed 0..{}", frames.orbit),
                ));
            }
            list.clone()
        }
        (None, Some(0)) => {
            return Err(bad(
                "frames.every",
                "0 is out of range; allowed >= 1".into(),
            ))
        }
        (None, Some(n)) => (0..frames.orbit).step_by(n as usize).collect(),
        (None, None) => (0..frames.orbit).collect(),
    };
    let size = parse_image_size(&frames.size).map_err(|e| bad("frames.size", e.to_string()))?;
    let projection = match frames.projection.as_str() {
        "ortho" => Projection::Ortho,
        "persp" => Projection::Persp,
        other => {
            return Err(bad(
                "frames.projection",
                format!("`{other}`: expected `ortho` or `persp`"),
            ))
        }
    };

    // Axes: each a non-empty list; zipped groups advance together.
    let mut axes: Vec<(String, Vec<toml::Value>)> = Vec::new();
    for (path, values) in &experiment.axes {
        let field = format!("axes.\"{path}\"");
        // These are what `modes` and `tf` set; as axes they would be overridden silently.
        if MODE_FIELDS.contains(&path.as_str()) {
            return Err(bad(
                &field,
                "is set by `modes` / `tf`; sweep it there instead".into(),
            ));
        }
        let list = values
            .as_array()
            .ok_or_else(|| bad(&field, "expected a list of values".into()))?;
        if list.is_empty() {
            return Err(bad(&field, "is empty; give at least one value".into()));
        }
        axes.push((path.clone(), list.clone()));
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut zipped = vec![false; axes.len()];
    for group in &experiment.zip {
        if group.is_empty() {
            return Err(bad(
                "zip",
                "a zip group is empty; list the axes that advance together".into(),
            ));
        }
        let mut members = Vec::new();
        for path in group {
            let i = axes
                .iter()
                .position(|(p, _)| p == path)
                .ok_or_else(|| bad("zip", format!("`{path}` is not an axis")))?;
            if zipped[i] {
                return Err(bad("zip", format!("`{path}` is in two zip groups")));
            }
            zipped[i] = true;
            members.push(i);
        }
        let len = axes[members[0]].1.len();
        if let Some(&m) = members.iter().find(|&&m| axes[m].1.len() != len) {
            return Err(bad(
                "zip",
                format!(
                    "`{}` has {} values, `{}` has {len}; zipped axes need equal lengths",
                    axes[m].0,
                    axes[m].1.len(),
                    axes[members[0]].0
                ),
            ));
        }
        groups.push(members);
    }
    for (i, z) in zipped.iter().enumerate() {
        if !z {
            groups.push(vec![i]);
        }
    }
    groups.sort();
    // The run count, before anything is built: a product of long axes is refused with its
    // figure instead of exhausting memory (each run holds its resolved configuration).
    let count = [
        experiment.datasets.len(),
        experiment.tf.len(),
        modes.len(),
        models.len(),
        frame_list.len(),
    ]
    .into_iter()
    .chain(groups.iter().map(|g| axes[g[0]].1.len()))
    .chain(
        sequence
            .iter()
            .flat_map(|(seq, maps)| [seq.steps, maps.len()]),
    )
    .try_fold(1u64, |acc, n| acc.checked_mul(n as u64))
    .unwrap_or(u64::MAX);
    if count > MAX_RUNS {
        return Err(bad(
            "axes",
            format!(
                "the experiment expands to {count} runs, over the limit of {MAX_RUNS}; split \
                 it into several experiments (fewer axis values, datasets or frames each)"
            ),
        ));
    }
    crate::budget::check(&format!("expanding {count} runs"), count * BYTES_PER_RUN)?;
    // Cartesian product over groups.
    let mut combos: Vec<Vec<(String, toml::Value)>> = vec![Vec::new()];
    for group in &groups {
        let len = axes[group[0]].1.len();
        let mut next = Vec::with_capacity(combos.len() * len);
        for combo in &combos {
            for j in 0..len {
                let mut c = combo.clone();
                for &m in group {
                    c.push((axes[m].0.clone(), axes[m].1[j].clone()));
                }
                next.push(c);
            }
        }
        combos = next;
    }
    // Every axis value alone must be a valid setting of its field.
    for (path, values) in &axes {
        for value in values {
            HardwareConfig::from_toml_str(&base_text, &base_name, &[format!("{path}={value}")])
                .map_err(|e| bad(&format!("axes.\"{path}\""), format!("value {value}: {e}")))?;
        }
    }

    // Datasets: loaded once, here, so a missing one fails before any run.
    // A sequence's dataset is its source, and its volume the first time step (the sequence
    // is opened here, so a static dataset or a folder with too few steps fails now).
    let mut volumes = BTreeMap::new();
    for name in &experiment.datasets {
        if !volumes.contains_key(name) {
            let volume = match &sequence {
                None => dataset::load(name, data_dir)
                    .map_err(|e| bad("datasets", format!("`{name}`: {e}")))?,
                Some((seq, _)) => {
                    let memory = HardwareConfig::from_toml_str(&base_text, &base_name, &[])?.memory;
                    let first = Sequence::open(name, seq.steps, seq.dt as f32, seq.brick)
                        .and_then(|mut s| s.next_step(&memory))
                        .map_err(|e| {
                            bad(
                                "datasets",
                                format!("`{name}` is not a sequence for `[sequence]`: {e}"),
                            )
                        })?;
                    first.expect("at least one step").volume
                }
            };
            volumes.insert(name.clone(), Arc::new(volume));
        }
    }
    // Every dataset needs its transfer functions (a dataset outside the protocol has no
    // preset): checked here so that a sweep fails before it writes anything.
    for (name, volume) in &volumes {
        for tf in &experiment.tf {
            crate::transfer::resolve(tf, &volume.name)
                .map_err(|e| bad("tf", format!("`{tf}` for dataset `{name}`: {e}")))?;
        }
    }

    let view_of = |frame: u32| match &frames.path {
        Some(file) => format!("path:{file}:{frame}/{}", frames.orbit),
        None => format!("orbit:{frame}/{}", frames.orbit),
    };
    if frames.path.is_some() {
        crate::camera::View::parse(&view_of(0)).map_err(|e| bad("frames.path", e.to_string()))?;
    }
    let map_variants: Vec<Option<MapMode>> = match &sequence {
        Some((_, maps)) => maps.iter().map(|&m| Some(m)).collect(),
        None => vec![None],
    };
    let mut runs = Vec::new();
    let mut skipped = Vec::new();
    let mut configs: BTreeMap<String, HardwareConfig> = BTreeMap::new();
    for name in &experiment.datasets {
        let dims = volumes[name].dims;
        for tf in &experiment.tf {
            for given_mode in &modes {
                for &map in &map_variants {
                    // A sequence without leaping renders without a map whatever the mode says.
                    let mode = &match map {
                        Some(MapMode::None) => Mode {
                            subcube: 0,
                            hierarchy: false,
                            ..*given_mode
                        },
                        _ => *given_mode,
                    };
                    if map.is_some_and(|m| m != MapMode::None) && mode.subcube == 0 {
                        skipped.push(Skipped {
                            dataset: name.clone(),
                            mode: mode.name(),
                            reason: format!(
                                "map strategy {} needs a leaping mode (leapN)",
                                map.map(|m| m.name()).unwrap_or_default()
                            ),
                        });
                        continue;
                    }
                    for &model in &models {
                        for combo in &combos {
                            let mut overrides: Vec<String> =
                                combo.iter().map(|(p, v)| format!("{p}={v}")).collect();
                            overrides.push(format!("compositing.ert={}", mode.ert));
                            overrides.push(format!("occupancy.subcube={}", mode.subcube));
                            overrides.push(format!("occupancy.hierarchy={}", mode.hierarchy));
                            overrides.push(format!("occupancy.kind=\"{tf}\""));
                            let id = overrides.join(" ");
                            let mut config = match configs.get(&id) {
                                Some(c) => c.clone(),
                                None => {
                                    let c = HardwareConfig::from_toml_str(
                                        &base_text, &base_name, &overrides,
                                    )
                                    .map_err(|e| {
                                        bad(
                                            "axes",
                                            format!(
                                                "the combination {}: {e}",
                                                combo
                                                    .iter()
                                                    .map(|(p, v)| format!("{p}={v}"))
                                                    .collect::<Vec<_>>()
                                                    .join(", ")
                                            ),
                                        )
                                    })?;
                                    configs.insert(id, c.clone());
                                    c
                                }
                            };
                            if mode.distance_bits > 0 {
                                // Set here, not by `--set`, so a base file without the fields works.
                                config.occupancy.structure = config::LeapStructure::Distance;
                                config.occupancy.distance_bits = mode.distance_bits;
                            } else if let Some(regions) = mode.leap_values {
                                config.occupancy.structure = config::LeapStructure::LeapValues;
                                config.leap_values.regions = regions;
                            } else {
                                config.occupancy.structure = config::LeapStructure::Map;
                            }
                            // Bricks: set here (like the distance volume), so a base file without
                            // the section works and a run without bricks keeps its key.
                            config.bricks.size = mode.bricks;
                            if mode.bricks > 0 {
                                config.bricks.setup = if mode.brick_table {
                                    config::BrickSetup::Table
                                } else {
                                    config::BrickSetup::Traversal
                                };
                                if mode.bricks > *dims.iter().max().unwrap_or(&0) {
                                    skipped.push(Skipped {
                                        dataset: name.clone(),
                                        mode: mode.name(),
                                        reason: format!("brick larger than the volume {dims:?}"),
                                    });
                                    continue;
                                }
                            }
                            // Iso mode: set here too; the iso value comes from the base file or
                            // an `iso.value` axis.
                            if let Some(n) = mode.iso {
                                config.iso.enabled = true;
                                config.iso.refinement_steps = n;
                            }
                            let mut fits = true;
                            if mode.subcube > 0 {
                                if mode.subcube > *dims.iter().max().unwrap_or(&0) {
                                    skipped.push(Skipped {
                                        dataset: name.clone(),
                                        mode: mode.name(),
                                        reason: format!("sub-cube larger than the volume {dims:?}"),
                                    });
                                    continue;
                                }
                                let bits = map_bits(dims, mode.subcube, mode.hierarchy);
                                if bits > config.occupancy.sram_bits {
                                    if !experiment.raise_sram {
                                        skipped.push(Skipped {
                                            dataset: name.clone(),
                                            mode: mode.name(),
                                            reason: format!(
                                                "map needs {bits} bits > occupancy.sram_bits {}",
                                                config.occupancy.sram_bits
                                            ),
                                        });
                                        continue;
                                    }
                                    fits = false;
                                    config.occupancy.sram_bits = bits.next_power_of_two();
                                }
                            }
                            let axes_json: BTreeMap<String, serde_json::Value> = combo
                                .iter()
                                .map(|(p, v)| (p.clone(), toml_to_json(v)))
                                .collect();
                            let excluded = experiment.exclude.iter().any(|rule| {
                                rule.iter().all(|(k, v)| match k.as_str() {
                                    "dataset" => v.as_str() == Some(name),
                                    "tf" => v.as_str() == Some(tf),
                                    "mode" => v
                                        .as_str()
                                        .and_then(|m| Mode::parse(m).ok())
                                        .is_some_and(|m| m == *mode),
                                    "model" => v.as_str() == Some(model.name()),
                                    path => axes_json.get(path) == Some(&toml_to_json(v)),
                                })
                            });
                            if excluded {
                                continue;
                            }
                            for &frame in &frame_list {
                                let view = view_of(frame);
                                let run = RunDescription {
                                    view,
                                    projection,
                                    size,
                                    ..RunDescription::new(name, tf, model, config.clone())
                                };
                                let spec = RunSpec {
                                    key: run_key(&run),
                                    index: runs.len(),
                                    mode: *mode,
                                    frame,
                                    axes: axes_json.clone(),
                                    fits_default_sram: fits,
                                    run,
                                    sequence: None,
                                };
                                match (&sequence, map) {
                                    (Some((seq, _)), Some(map)) => {
                                        for time_step in 0..seq.steps {
                                            let step = StepSpec {
                                                source: name.clone(),
                                                time_step,
                                                map,
                                                dt: seq.dt,
                                                brick: seq.brick,
                                            };
                                            runs.push(RunSpec {
                                                key: step_key(&spec.run, &step),
                                                index: runs.len(),
                                                sequence: Some(step),
                                                ..spec.clone()
                                            });
                                        }
                                    }
                                    _ => runs.push(spec),
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    for rule in &experiment.exclude {
        if rule.is_empty() {
            return Err(bad(
                "exclude",
                "an empty [[exclude]] table would exclude every run; give the fields to match"
                    .into(),
            ));
        }
        for k in rule.keys() {
            let known = ["dataset", "tf", "mode", "model"].contains(&k.as_str())
                || axes.iter().any(|(p, _)| p == k);
            if !known {
                return Err(bad(
                    "exclude",
                    format!("`{k}` is neither dataset, tf, mode, model nor an axis"),
                ));
            }
        }
    }
    // The same run listed twice (a repeated dataset, frame or axis value; 12.5 and 12.50 are
    // one value) has one key: keep its first occurrence.
    let listed = runs.len();
    let mut seen = std::collections::HashSet::new();
    runs.retain(|r| seen.insert(r.key.clone()));
    for (i, run) in runs.iter_mut().enumerate() {
        run.index = i;
    }
    let duplicates = listed - runs.len();
    if runs.is_empty() {
        let why = if skipped.is_empty() {
            "every run is excluded by `exclude`".to_string()
        } else {
            format!(
                "no run is left: {} points were left out for sub-cube size or SRAM fit (first: {} {}: {}), the rest excluded",
                skipped.len(),
                skipped[0].dataset,
                skipped[0].mode,
                skipped[0].reason
            )
        };
        return Err(bad("exclude", why));
    }
    Ok(Expansion {
        experiment,
        source: source.to_string(),
        runs,
        skipped,
        duplicates,
        volumes,
    })
}

/// The run's identity: a hash of everything that decides its result (not the experiment's
/// name, so the same run in two experiments has the same key). Spacing, shading and memory
/// enter only when they differ from the defaults every experiment had before they were part
/// of a run, so keys of earlier results stay valid.
pub fn run_key(run: &RunDescription) -> String {
    hash_key(&canonical_run(run))
}

/// The key of one time step of a sequence: the run's identity (as `run_key`) and where in which
/// frame loop it is (map strategy, dt, brick, time step). The number of steps is not part of
/// it: a longer sequence repeats the shorter one's first steps.
pub fn step_key(run: &RunDescription, step: &StepSpec) -> String {
    let mut canonical = canonical_run(run);
    canonical.as_object_mut().expect("object").insert(
        "sequence".into(),
        serde_json::json!({
            "map": step.map.name(),
            "dt": step.dt,
            "brick": step.brick,
            "time_step": step.time_step,
        }),
    );
    hash_key(&canonical)
}

fn hash_key(canonical: &serde_json::Value) -> String {
    let digest = Sha256::digest(canonical.to_string().as_bytes());
    digest[..8].iter().map(|b| format!("{b:02x}")).collect()
}

fn canonical_run(run: &RunDescription) -> serde_json::Value {
    let mut canonical = serde_json::json!({
        "dataset": run.dataset,
        "tf": run.tf,
        "model": run.model,
        "view": run.view,
        "size": [run.size.0, run.size.1],
        "projection": run.projection,
        "config": run.hardware,
    });
    let defaults = RunDescription::new("", "", run.model, run.hardware.clone());
    let obj = canonical.as_object_mut().expect("object");
    if run.sample_spacing != defaults.sample_spacing {
        obj.insert(
            "sample_spacing".into(),
            serde_json::json!(run.sample_spacing),
        );
    }
    if run.shading != defaults.shading {
        obj.insert("shading".into(), serde_json::json!(run.shading));
    }
    if run.memory != defaults.memory {
        obj.insert("memory".into(), serde_json::json!(run.memory));
    }
    canonical
}

//! Experiment files (`configs/experiments/*.toml`) and their expansion into runs. Everything
//! is checked before the first run: unknown field paths, empty axes, values out of range,
//! unknown modes and datasets that are not there, each error naming the axis and the value.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::arch::sampling::Sampling;
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
    /// Classification axis, each as `--tf` takes it: `zero` ('0' transfer function and map),
    /// `class` (the dataset's own), a preset name or a transfer-function file (a class map
    /// built from it); checked against every dataset once the datasets are loaded.
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
    /// Sampled simulation of the cycle-model runs at this rate in (0, 1] (docs/sampling.md):
    /// their timing is estimated, with a 95 % interval, and their keys differ from the exact
    /// runs'. Written out only when given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample: Option<f64>,
    /// Every run's line also carries `float_reference`: its image against the float reference
    /// of the same run (max, mean error, PSNR), so that a sweep of bit widths tabulates the
    /// image error beside the cycles. The runs' keys differ from those without it. Written out
    /// only when true.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub float_reference: bool,
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
    crate::dynamic::DEFAULT_DT as f64
}
fn default_brick() -> usize {
    crate::dynamic::DEFAULT_BRICK
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
        // One token of each kind: `leap4+leap8` would keep the last without a word.
        let mut seen: Vec<&str> = Vec::new();
        for token in text.split('+') {
            let kind = if token.starts_with("leapvalues") {
                "leapvalues"
            } else {
                token.trim_end_matches(|c: char| c.is_ascii_digit())
            };
            if seen.contains(&kind) {
                return Err(format!("`{token}`: only one `{kind}` token per mode"));
            }
            seen.push(kind);
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
                    let n: usize = t[4..].parse().map_err(|_| {
                        format!(
                            "`{t}`: expected leapN, N a sub-cube edge, or `leapvalues`, \
                                 `leapvalues-homogeneous`"
                        )
                    })?;
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
    /// The line also carries the image against the float reference (the experiment's
    /// `float_reference`). Serialised only when set.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub float_reference: bool,
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
    pub volumes: Volumes,
}

/// The most runs one experiment may expand to: 10^6 runs took 2.2 GB to expand.
pub const MAX_RUNS: u64 = 200_000;
/// Memory one expanded run holds (its resolved configuration and identity), rounded up, and
/// for a cycle run what a sweep keeps to reuse its timing for twins (its timing description as
/// JSON text and its `Measurements`, about 2 KB: `experiment::TimingReuse`).
const BYTES_PER_RUN: u64 = 6144;

/// Configuration fields a mode or the tf axis sets (never an axis; `advise` leaves them out of
/// a pair's identity).
pub(crate) const MODE_FIELDS: [&str; 11] = [
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

/// Reads and validates an experiment file without expanding it (`Plan::for_each_run` streams
/// the runs: the dry run).
pub fn load_plan(path: &Path, data_dir: Option<&Path>) -> Result<Plan> {
    let text = crate::input::read_text(path)?;
    plan(&text, &path.display().to_string(), data_dir)
}

fn toml_to_json(value: &toml::Value) -> serde_json::Value {
    serde_json::to_value(value).unwrap_or(serde_json::Value::Null)
}

/// Whether an `exclude` value names an axis value: numbers by value, so that `8.0` matches an
/// axis written `8` and `10` one written `10.0` (they set the field alike); anything else as
/// written.
fn same_axis_value(a: &toml::Value, b: &toml::Value) -> bool {
    use toml::Value::{Float, Integer};
    match (a, b) {
        // Exact: a float equals an integer only when it is that whole number (no rounding of
        // large integers through f64).
        (Integer(i), Float(f)) | (Float(f), Integer(i)) => {
            f.fract() == 0.0 && f.abs() < 9.0e18 && *f as i64 == *i
        }
        (Float(x), Float(y)) => x == y,
        _ => toml_to_json(a) == toml_to_json(b),
    }
}

pub fn expand(text: &str, source: &str, data_dir: Option<&Path>) -> Result<Expansion> {
    expand_plan(plan(text, source, data_dir)?)
}

/// The experiment's datasets by name.
pub type Volumes = BTreeMap<String, Arc<Volume>>;

/// Expands a validated experiment into all its runs.
pub fn expand_plan(plan: Plan) -> Result<Expansion> {
    // Expanded runs hold their resolved configuration: refused up front when over the budget.
    crate::budget::check(
        &format!("expanding {} runs", plan.count),
        plan.count * BYTES_PER_RUN,
    )?;
    let mut runs = Vec::new();
    let omitted = plan.for_each_run(|run| {
        runs.push(run);
        Ok(())
    })?;
    Ok(Expansion {
        experiment: plan.experiment,
        source: plan.source,
        runs,
        skipped: omitted.skipped,
        duplicates: omitted.duplicates,
        volumes: plan.volumes,
    })
}

/// What is wrong with the base configuration once an experiment's values are set in it, without
/// the source the configuration names (`BASE with --set FIELD=VALUE`): the values came from the
/// experiment file, not from `--set`, and the caller's error names the file and the axis. The
/// field is named unless it is `axis` itself; the base only when the experiment gives one (the
/// check may involve its other fields).
fn setting_problem(error: Error, axis: &str, base: Option<&Path>) -> String {
    let problem = match error {
        Error::Config { field, message, .. } if field == axis => message,
        Error::Config { field, message, .. } => format!("field `{field}`: {message}"),
        Error::Format { message, .. } => message.trim_end().to_string(),
        other => other.to_string(),
    };
    match base {
        Some(base) => format!("{problem} (with the base configuration {})", base.display()),
        None => problem,
    }
}

/// Validates an experiment and loads its datasets: everything a sweep checks before it writes
/// anything. The runs themselves come from `Plan::for_each_run`, one at a time.
pub fn plan(text: &str, source: &str, data_dir: Option<&Path>) -> Result<Plan> {
    let experiment: ExperimentFile = toml::from_str(text)
        .map_err(|e| Error::format(source, format!("invalid experiment: {e}")))?;
    let bad = |field: &str, message: String| Error::config(source, field, message);
    // The name is what keeps two experiments' results out of one folder.
    if experiment.name.trim().is_empty() {
        return Err(bad("name", "is empty; give the experiment a name".into()));
    }
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
        Some(p) => crate::input::read_text(p).map_err(|e| bad("config", e.to_string()))?,
        None => config::DEFAULT_TOML.to_string(),
    };
    let base_name = experiment
        .config
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_else(|| config::DEFAULT_NAME.to_string());
    // A mistake in the base file is named with the experiment that points to it.
    HardwareConfig::from_toml_str(&base_text, &base_name, &[])
        .map_err(|e| bad("config", e.to_string()))?;

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
    let sample = experiment
        .sample
        .map(|rate| Sampling::new(rate, "value").map_err(|e| bad("sample", e.to_string())))
        .transpose()?;
    if sample.is_some() && experiment.sequence.is_some() {
        return Err(bad(
            "sample",
            "a sequence's frames are simulated exactly; sampling applies to experiments \
             without [sequence]"
                .into(),
        ));
    }
    if experiment.float_reference && experiment.sequence.is_some() {
        return Err(bad(
            "float_reference",
            "a sequence's steps are compared with nothing; the image against the float \
             reference applies to experiments without [sequence]"
                .into(),
        ));
    }
    if sample.is_some() && !models.contains(&Model::Cycle) {
        return Err(bad(
            "sample",
            "sampling times cycle-model runs; `models` has no \"cycle\"".into(),
        ));
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
            // Time steps are f32: the last one's time must be finite too.
            if !(seq.dt as f32 * (seq.steps - 1) as f32).is_finite() {
                return Err(bad(
                    "sequence.dt",
                    format!(
                        "{:e}: the time of step {} overflows; give a smaller dt or fewer steps",
                        seq.dt,
                        seq.steps - 1
                    ),
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
                // The occupancy map, with or without its hierarchy (the map's byte layout,
                // which `vizsim sequence --hierarchy` models too), is what a sequence follows;
                // bounding bricks are rebuilt from its table (`dynamic::check_modelled` leaves
                // out the runs where they cannot be).
                let plain = Mode {
                    ert: m.ert,
                    subcube: m.subcube,
                    hierarchy: m.hierarchy,
                    bricks: m.bricks,
                    brick_table: m.brick_table,
                    ..Mode::parse("none").expect("valid")
                };
                if *m != plain {
                    return Err(bad(
                        "modes",
                        format!(
                            "`{}`: a sequence experiment takes `none`, `ert`, `leapN`, \
                             `ert+leapN` and `ert+leapN+hier`, each with `+bricksN` (the map \
                             follows the volume as `sequence.map` says, the brick flags the \
                             map's table)",
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
    crate::run::check_frame_budget(size).map_err(|e| bad("frames.size", e.to_string()))?;
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
            if members.contains(&i) {
                return Err(bad(
                    "zip",
                    format!("`{path}` is given twice in one zip group"),
                ));
            }
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
    // Every axis value alone must be a valid setting of its field. A rule between fields (the
    // overtaking window within the FIFO's depth, t_rtw above cl) is checked per combination
    // when the runs are generated: another axis zipped or crossed with this one, or an
    // exclusion, may be what makes the value valid.
    for (path, values) in &axes {
        for value in values {
            match HardwareConfig::from_toml_str(
                &base_text,
                &base_name,
                &[format!("{path}={value}")],
            ) {
                Err(Error::Config { field, .. }) if field != *path => {}
                Err(e) => {
                    let problem = setting_problem(e, path, experiment.config.as_deref());
                    return Err(bad(
                        &format!("axes.\"{path}\""),
                        format!("value {value}: {problem}"),
                    ));
                }
                Ok(_) => {}
            }
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
            crate::transfer::resolve_for(tf, volume)
                .map_err(|e| bad("tf", format!("`{tf}` for dataset `{name}`: {e}")))?;
        }
    }

    if frames.path.is_some() {
        let view = format!(
            "path:{}:0/{}",
            frames.path.as_deref().unwrap_or(""),
            frames.orbit
        );
        crate::camera::View::parse(&view).map_err(|e| bad("frames.path", e.to_string()))?;
    }
    // The modes runs have: a sequence's `none` map renders each mode without its map, and an
    // exclude may name that mode (docs/experiments.md).
    let mut run_modes = modes.clone();
    if sequence
        .as_ref()
        .is_some_and(|(_, maps)| maps.contains(&MapMode::None))
    {
        run_modes.extend(modes.iter().map(|m| Mode {
            subcube: 0,
            hierarchy: false,
            ..*m
        }));
    }
    for rule in &experiment.exclude {
        if rule.is_empty() {
            return Err(bad(
                "exclude",
                "an empty [[exclude]] table would exclude every run; give the fields to match"
                    .into(),
            ));
        }
        for (k, v) in rule {
            let known = ["dataset", "tf", "mode", "model"].contains(&k.as_str())
                || axes.iter().any(|(p, _)| p == k);
            if !known {
                return Err(bad(
                    "exclude",
                    format!("`{k}` is neither dataset, tf, mode, model nor an axis"),
                ));
            }
            // A value no run has (a typo) would exclude nothing without a word.
            let text = v.as_str();
            let (matches, listed) = match k.as_str() {
                "dataset" => (
                    text.is_some_and(|t| experiment.datasets.iter().any(|d| d == t)),
                    "`datasets`".to_string(),
                ),
                "tf" => (
                    text.is_some_and(|t| experiment.tf.iter().any(|d| d == t)),
                    "`tf`".to_string(),
                ),
                "mode" => (
                    text.and_then(|t| Mode::parse(t).ok())
                        .is_some_and(|m| run_modes.contains(&m)),
                    "`modes`".to_string(),
                ),
                "model" => (
                    text.is_some_and(|t| experiment.models.iter().any(|d| d == t)),
                    "`models`".to_string(),
                ),
                path => {
                    let values = &axes.iter().find(|(p, _)| p == path).expect("known").1;
                    (
                        values.iter().any(|x| same_axis_value(x, v)),
                        format!("`axes.\"{path}\"`"),
                    )
                }
            };
            if !matches {
                return Err(bad(
                    "exclude",
                    format!("`{k} = {v}` matches no run: not among the values of {listed}"),
                ));
            }
        }
    }
    Ok(Plan {
        source: source.to_string(),
        volumes,
        base_text,
        base_name,
        modes,
        models,
        frame_list,
        size,
        projection,
        sequence,
        sample,
        axes,
        groups,
        count,
        experiment,
    })
}

/// A validated experiment with its datasets loaded, before expansion (`plan`).
pub struct Plan {
    pub experiment: ExperimentFile,
    pub source: String,
    pub volumes: Volumes,
    /// Runs the product lists, duplicates and left-out points included (at most `MAX_RUNS`).
    pub count: u64,
    base_text: String,
    base_name: String,
    modes: Vec<Mode>,
    models: Vec<Model>,
    frame_list: Vec<u32>,
    size: (u32, u32),
    projection: Projection,
    sequence: Option<(SequenceAxis, Vec<MapMode>)>,
    /// Sampled simulation of the cycle-model runs.
    sample: Option<Sampling>,
    axes: Vec<(String, Vec<toml::Value>)>,
    /// Axis indices advancing together (a zip group or one axis), in product order.
    groups: Vec<Vec<usize>>,
}

/// Resolved configurations kept for reuse during an expansion; the cache is emptied when full,
/// so a long product costs parsing time, not memory.
const CONFIG_CACHE: usize = 1024;

/// What an expansion left out or dropped.
#[derive(Default)]
pub struct Omitted {
    /// Points left out (sub-cube or brick larger than the volume, SRAM fit, a map strategy
    /// without leaping), each reason once.
    pub skipped: Vec<Skipped>,
    /// Runs listed more than once, dropped (each runs once).
    pub duplicates: usize,
}

impl Plan {
    /// Combinations of axis values: the product of the groups' lengths.
    fn combinations(&self) -> usize {
        self.groups
            .iter()
            .map(|g| self.axes[g[0]].1.len())
            .product()
    }

    /// Combination `i` of the product, the last group advancing fastest (the order the
    /// expansion always had).
    fn combination(&self, mut i: usize) -> Vec<(String, toml::Value)> {
        let mut picks = vec![0; self.groups.len()];
        for (g, group) in self.groups.iter().enumerate().rev() {
            let len = self.axes[group[0]].1.len();
            picks[g] = i % len;
            i /= len;
        }
        let mut combo = Vec::new();
        for (group, &j) in self.groups.iter().zip(&picks) {
            for &m in group {
                combo.push((self.axes[m].0.clone(), self.axes[m].1[j].clone()));
            }
        }
        combo
    }

    /// Calls `visit` with every run in expansion order, without holding them: a run listed
    /// more than once (a repeated dataset, frame or axis value; 12.5 and 12.50 are one value)
    /// is passed only the first time, with `index` its position among the runs passed. Only
    /// each run's 8-byte key is kept, to find repeats. Fails, naming why, when no run is left.
    pub fn for_each_run(&self, mut visit: impl FnMut(RunSpec) -> Result<()>) -> Result<Omitted> {
        let mut seen: std::collections::HashSet<u64> = std::collections::HashSet::new();
        let (mut passed, mut duplicates) = (0usize, 0usize);
        let mut emit = |mut run: RunSpec| -> Result<()> {
            let id = u64::from_str_radix(&run.key, 16)
                .map_err(|_| Error::Invalid(format!("run key {} is not hexadecimal", run.key)))?;
            if !seen.insert(id) {
                duplicates += 1;
                return Ok(());
            }
            run.index = passed;
            passed += 1;
            visit(run)
        };
        let mut skipped: Vec<Skipped> = Vec::new();
        let mut skip = |s: Skipped| {
            let known = skipped
                .iter()
                .any(|k| k.dataset == s.dataset && k.mode == s.mode && k.reason == s.reason);
            if !known {
                skipped.push(s);
            }
        };
        self.runs(&mut emit, &mut skip)?;
        let omitted = Omitted {
            skipped,
            duplicates,
        };
        if passed == 0 {
            // Left out for the modes' sake alone, the modes (with the datasets) are the cause;
            // `exclude` only when it took part.
            let excludes = !self.experiment.exclude.is_empty();
            let field = if excludes { "exclude" } else { "modes" };
            let why = if omitted.skipped.is_empty() {
                "every run is excluded by `exclude`".to_string()
            } else if !excludes {
                let first = &omitted.skipped[0];
                format!(
                    "no run is left: every mode's points were left out (first: {} {}: {}); \
                     check `modes` against `datasets` and `[sequence] map`",
                    first.dataset, first.mode, first.reason
                )
            } else {
                let first = &omitted.skipped[0];
                format!(
                    "no run is left: {} points were left out (first: {} {}: {}), the rest \
                     excluded",
                    omitted.skipped.len(),
                    first.dataset,
                    first.mode,
                    first.reason
                )
            };
            return Err(Error::config(&self.source, field, why));
        }
        Ok(omitted)
    }

    /// The product itself: every listed run to `emit`, every left-out point to `skip`.
    fn runs(
        &self,
        emit: &mut dyn FnMut(RunSpec) -> Result<()>,
        skip: &mut dyn FnMut(Skipped),
    ) -> Result<()> {
        let experiment = &self.experiment;
        let frames = &experiment.frames;
        let bad = |field: &str, message: String| Error::config(&self.source, field, message);
        let view_of = |frame: u32| match &frames.path {
            Some(file) => format!("path:{file}:{frame}/{}", frames.orbit),
            None => format!("orbit:{frame}/{}", frames.orbit),
        };
        let map_variants: Vec<Option<MapMode>> = match &self.sequence {
            Some((_, maps)) => maps.iter().map(|&m| Some(m)).collect(),
            None => vec![None],
        };
        // A base file that names a leaping structure: a map mode sets it back to the map
        // before validation (an occupancy map's sub-cube size is refused with another
        // structure). A file without the field keeps the default, the map.
        let base_names_structure = self
            .base_text
            .parse::<toml::Table>()
            .ok()
            .and_then(|t| t.get("occupancy")?.get("structure").cloned())
            .is_some();
        let mut configs: std::collections::HashMap<String, HardwareConfig> =
            std::collections::HashMap::new();
        let mut on_volume = VolumeChecks::default();
        for name in &experiment.datasets {
            let dims = self.volumes[name].dims;
            for tf in &experiment.tf {
                for given_mode in &self.modes {
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
                            skip(Skipped {
                                dataset: name.clone(),
                                mode: mode.name(),
                                reason: format!(
                                    "map strategy {} needs a leaping mode (leapN)",
                                    map.map(|m| m.name()).unwrap_or_default()
                                ),
                            });
                            continue;
                        }
                        for &model in &self.models {
                            for combo in (0..self.combinations()).map(|i| self.combination(i)) {
                                // Before the configuration is built: an excluded combination
                                // need not be a valid one.
                                let excluded = experiment.exclude.iter().any(|rule| {
                                    rule.iter().all(|(k, v)| match k.as_str() {
                                        "dataset" => v.as_str() == Some(name),
                                        "tf" => v.as_str() == Some(tf),
                                        "mode" => v
                                            .as_str()
                                            .and_then(|m| Mode::parse(m).ok())
                                            .is_some_and(|m| m == *mode),
                                        "model" => v.as_str() == Some(model.name()),
                                        path => combo
                                            .iter()
                                            .any(|(p, x)| p == path && same_axis_value(x, v)),
                                    })
                                });
                                if excluded {
                                    continue;
                                }
                                let mut overrides: Vec<String> =
                                    combo.iter().map(|(p, v)| format!("{p}={v}")).collect();
                                overrides.push(format!("compositing.ert={}", mode.ert));
                                overrides.push(format!("occupancy.subcube={}", mode.subcube));
                                overrides.push(format!("occupancy.hierarchy={}", mode.hierarchy));
                                overrides.push(format!(
                                    "occupancy.kind=\"{}\"",
                                    crate::occupancy::OccupancyKind::for_tf(tf).name()
                                ));
                                if base_names_structure
                                    && mode.distance_bits == 0
                                    && mode.leap_values.is_none()
                                {
                                    overrides.push("occupancy.structure=\"map\"".into());
                                }
                                let id = overrides.join(" ");
                                let mut config = match configs.get(&id) {
                                    Some(c) => c.clone(),
                                    None => {
                                        // Bounded: a long axis product must not keep every
                                        // configuration (the dry run streams).
                                        if configs.len() >= CONFIG_CACHE {
                                            configs.clear();
                                        }
                                        let c = HardwareConfig::from_toml_str(
                                            &self.base_text,
                                            &self.base_name,
                                            &overrides,
                                        )
                                        .map_err(|e| {
                                            let problem = setting_problem(
                                                e,
                                                "",
                                                self.experiment.config.as_deref(),
                                            );
                                            bad(
                                                "axes",
                                                format!(
                                                    "the combination {}: {problem}; zip the \
                                                     axes that must change together, or leave \
                                                     the combination out with [[exclude]] \
                                                     (docs/experiments.md)",
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
                                        skip(Skipped {
                                            dataset: name.clone(),
                                            mode: mode.name(),
                                            reason: format!(
                                                "brick larger than the volume {dims:?}"
                                            ),
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
                                // A sequence run the update model does not model is left out
                                // with the reason the sequence itself would refuse it.
                                if let Some(map) = map {
                                    if let Err(e) = crate::dynamic::check_modelled(
                                        &config,
                                        crate::dynamic::UpdateUse::Sequence { map },
                                    ) {
                                        skip(Skipped {
                                            dataset: name.clone(),
                                            mode: mode.name(),
                                            reason: e.to_string(),
                                        });
                                        continue;
                                    }
                                }
                                // The run, as errors name it.
                                let the_run = || {
                                    format!(
                                        "the run {name}, tf {tf}, mode {}, {} model{}",
                                        mode.name(),
                                        model.name(),
                                        combo
                                            .iter()
                                            .map(|(p, v)| format!(", {p}={v}"))
                                            .collect::<String>()
                                    )
                                };
                                let mut fits = true;
                                if mode.subcube > 0 {
                                    if mode.subcube > *dims.iter().max().unwrap_or(&0) {
                                        skip(Skipped {
                                            dataset: name.clone(),
                                            mode: mode.name(),
                                            reason: format!(
                                                "sub-cube larger than the volume {dims:?}"
                                            ),
                                        });
                                        continue;
                                    }
                                    // A hierarchy that groups nothing runs as the map alone:
                                    // left out as a sub-cube larger than the volume is.
                                    if let Some(why) = mode
                                        .hierarchy
                                        .then(|| {
                                            crate::occupancy::hierarchy_without_effect(
                                                dims,
                                                mode.subcube,
                                            )
                                        })
                                        .flatten()
                                    {
                                        skip(Skipped {
                                            dataset: name.clone(),
                                            mode: mode.name(),
                                            reason: why,
                                        });
                                        continue;
                                    }
                                    let bits = crate::occupancy::map_bits(
                                        dims,
                                        mode.subcube,
                                        mode.hierarchy,
                                    );
                                    if bits > config.occupancy.sram_bits {
                                        if !experiment.raise_sram {
                                            skip(Skipped {
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
                                for (f, &frame) in self.frame_list.iter().enumerate() {
                                    let first_frame = f == 0;
                                    let view = view_of(frame);
                                    let run = RunDescription {
                                        view,
                                        projection: self.projection,
                                        size: self.size,
                                        sample: self.sample.filter(|_| model == Model::Cycle),
                                        ..RunDescription::new(name, tf, model, config.clone())
                                    };
                                    // What the run path would refuse (sampling with leap
                                    // values, a frame over the budget...), refused before any
                                    // run rather than when the run comes up.
                                    run.validate().map_err(|e| {
                                        bad(
                                            "modes",
                                            format!(
                                                "{}: {e}; leave such runs out with [[exclude]] \
                                                 (docs/experiments.md)",
                                                the_run()
                                            ),
                                        )
                                    })?;
                                    // What preparing the run would refuse on its dataset,
                                    // refused here, before the sweep writes anything (after the
                                    // runs left out above, which are not errors); once per
                                    // configuration, the frames share it.
                                    if first_frame {
                                        on_volume.check(&run, &self.volumes[name]).map_err(
                                            |(field, e)| {
                                                let axis = combo.iter().any(|(p, _)| *p == field);
                                                let problem = match e {
                                                    Error::Config {
                                                        field: f, message, ..
                                                    } if f == field && axis => message,
                                                    Error::Config {
                                                        field: f, message, ..
                                                    } => format!("field `{f}`: {message}"),
                                                    other => other.to_string(),
                                                };
                                                // Not the field itself but axes of its
                                                // section (`memory.banks` for the rows a
                                                // volume needs): named as the likely cause.
                                                let section = field.split('.').next();
                                                let related: Vec<String> = combo
                                                    .iter()
                                                    .filter(|(p, _)| {
                                                        !field.is_empty()
                                                            && p.split('.').next() == section
                                                    })
                                                    .map(|(p, _)| format!("axes.\"{p}\""))
                                                    .collect();
                                                bad(
                                                    &if axis {
                                                        format!("axes.\"{field}\"")
                                                    } else if !related.is_empty() {
                                                        related.join(", ")
                                                    } else if experiment.config.is_some() {
                                                        "config".to_string()
                                                    } else {
                                                        "datasets".to_string()
                                                    },
                                                    format!(
                                                        "{}: {problem}; leave such runs out with \
                                                     [[exclude]] (docs/experiments.md)",
                                                        the_run()
                                                    ),
                                                )
                                            },
                                        )?;
                                    }
                                    let float_reference = experiment.float_reference;
                                    let spec = RunSpec {
                                        key: match float_reference {
                                            true => float_reference_key(&run),
                                            false => run_key(&run),
                                        },
                                        float_reference,
                                        index: 0,
                                        mode: *mode,
                                        frame,
                                        axes: axes_json.clone(),
                                        fits_default_sram: fits,
                                        run,
                                        sequence: None,
                                    };
                                    match (&self.sequence, map) {
                                        (Some((seq, _)), Some(map)) => {
                                            for time_step in 0..seq.steps {
                                                let step = StepSpec {
                                                    source: name.clone(),
                                                    time_step,
                                                    map,
                                                    dt: seq.dt,
                                                    brick: seq.brick,
                                                };
                                                emit(RunSpec {
                                                    key: step_key(&spec.run, &step),
                                                    sequence: Some(step),
                                                    ..spec.clone()
                                                })?;
                                            }
                                        }
                                        _ => emit(spec)?,
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
        Ok(())
    }
}

/// What preparing a run refuses on its dataset that the configuration alone cannot tell
/// (`run::prepare`), checked when the runs are generated so that a sweep (and its dry run)
/// refuses them before it writes anything: the iso value within the volume's densities
/// (`IsoSurface::from_config`), the block size dividing its dimensions
/// (`blocking::check_block_size`), the depth file (there, a regular file of the length its
/// header announces, within the memory budget, of the frames' size:
/// `Scene::check_depth_file`, which reads only its header), the memory budget, the voxel word
/// and the rows the volume needs in SDRAM (`run::check_on_volume`), and with blocking the
/// active blocks fitting the memory (`run::blocked_fit_table`, `run::check_blocked_fit`). What
/// costs a pass over the volume or a file is kept, so each costs once per dataset and value.
#[derive(Default)]
struct VolumeChecks {
    /// (dataset, iso value's bits) found inside the dataset's densities.
    iso: std::collections::HashSet<(String, u64)>,
    /// Depth files found valid for the frames' size.
    depth_files: std::collections::HashSet<String>,
    /// Block tables by what decides them (dataset, transfer function, block size, map kind,
    /// table width, spacing): a memory axis reuses its table, only the fit is checked again.
    block_tables: std::collections::HashMap<String, Arc<crate::blocking::BlockTable>>,
}

impl VolumeChecks {
    /// Checks `run` on `volume` (its dataset); an error with the field it is about.
    fn check(
        &mut self,
        run: &RunDescription,
        volume: &Volume,
    ) -> std::result::Result<(), (String, Error)> {
        let config = &run.hardware;
        fn at(field: &'static str) -> impl Fn(Error) -> (String, Error) {
            move |e| (field.to_string(), e)
        }
        if config.iso.enabled {
            let key = (run.dataset.clone(), config.iso.value.to_bits());
            if !self.iso.contains(&key) {
                crate::iso::IsoSurface::from_config(config, volume).map_err(at("iso.value"))?;
                self.iso.insert(key);
            }
        }
        if config.blocking.enabled {
            crate::blocking::check_block_size(config.blocking.block_size, volume.dims)
                .map_err(at("blocking.block_size"))?;
        }
        if config.geometry.shape == config::GeometryShape::DepthFile
            && !self.depth_files.contains(&config.geometry.file)
        {
            crate::clip::Scene::check_depth_file(config, run.size).map_err(at("geometry.file"))?;
            self.depth_files.insert(config.geometry.file.clone());
        }
        // The field these name is in the error itself (memory.rows, shading.gradient_bits).
        let own_field = |e: Error| match &e {
            Error::Config { field, .. } => (field.clone(), e),
            _ => (String::new(), e),
        };
        crate::run::check_on_volume(run, volume).map_err(own_field)?;
        if config.blocking.enabled {
            let key = format!(
                "{}\0{}\0{}\0{:?}\0{}\0{}",
                run.dataset,
                run.tf,
                config.blocking.block_size,
                config.occupancy.kind,
                config.classification.lut_bits,
                run.sample_spacing.to_bits(),
            );
            let table = match self.block_tables.get(&key) {
                Some(table) => Some(table.clone()),
                None => crate::run::blocked_fit_table(run, volume)
                    .map_err(own_field)?
                    .map(Arc::new),
            };
            if let Some(table) = table {
                crate::run::check_blocked_fit(run, volume.dims, &table).map_err(own_field)?;
                self.block_tables.insert(key, table);
            }
        }
        Ok(())
    }
}

/// The run's identity: a hash of everything that decides its result (not the experiment's
/// name, so the same run in two experiments has the same key). Spacing, shading and memory
/// enter only when they differ from the defaults every experiment had before they were part
/// of a run, so keys of earlier results stay valid.
pub fn run_key(run: &RunDescription) -> String {
    hash_key(&canonical_run(run))
}

/// The key of a run whose line also carries its image against the float reference: the run's
/// identity (as `run_key`) and that, so that its line and the line without it never share a
/// key.
pub fn float_reference_key(run: &RunDescription) -> String {
    let mut canonical = canonical_run(run);
    canonical
        .as_object_mut()
        .expect("object")
        .insert("float_reference".into(), serde_json::Value::Bool(true));
    hash_key(&canonical)
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
    // Sampled runs are other runs than the exact ones: they never share a key.
    if let Some(sampling) = &run.sample {
        obj.insert("sample".into(), serde_json::json!(sampling));
    }
    canonical
}

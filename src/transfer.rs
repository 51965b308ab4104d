//! Transfer functions: piecewise-linear maps from density to colour and opacity, read from
//! TOML (`configs/transfer/*.toml`) and sampled into lookup tables.
//!
//! Opacity convention: a point's `rgba[3]` is the opacity of a slab **one voxel thick**.
//! Renderers correct it for their sample spacing S (in voxels): `alpha_S = 1 - (1 - alpha)^S`.
//! Colours are not premultiplied; a sample contributes `alpha * colour`.

use std::path::Path;

use serde::Deserialize;

use crate::error::{Error, Result};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TransferFile {
    name: Option<String>,
    description: Option<String>,
    points: Vec<PointFile>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PointFile {
    value: f64,
    rgba: [f64; 4],
}

#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ControlPoint {
    /// Density in voxel units (0..=255 for 8-bit data, 0..=65535 for 16-bit).
    pub value: f32,
    /// Colour and opacity, each in 0..=1.
    pub rgba: [f32; 4],
}

#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TransferFunction {
    pub name: String,
    pub description: String,
    /// Strictly increasing in `value`; constant extension before the first and after the last.
    pub points: Vec<ControlPoint>,
}

impl TransferFunction {
    pub fn load(path: &Path) -> Result<Self> {
        let text = crate::input::read_text(path)?;
        let stem = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        Self::from_toml(&text, &path.display().to_string(), &stem)
    }

    /// Parses TOML text; `source` names it in errors, `default_name` is used without `name`.
    pub fn from_toml(text: &str, source: &str, default_name: &str) -> Result<Self> {
        let file: TransferFile = toml::from_str(text)
            .map_err(|e| Error::format(source, format!("invalid transfer function: {e}")))?;
        let points = file
            .points
            .iter()
            .map(|p| ControlPoint {
                value: p.value as f32,
                rgba: p.rgba.map(|c| c as f32),
            })
            .collect();
        Self::new(
            file.name.unwrap_or_else(|| default_name.to_string()),
            file.description.unwrap_or_default(),
            points,
            source,
        )
    }

    /// Validates the points: at least one, values finite in 0..=65535 and strictly increasing,
    /// colour and opacity in 0..=1. `source` names where they came from in error messages.
    pub fn new(
        name: String,
        description: String,
        points: Vec<ControlPoint>,
        source: &str,
    ) -> Result<Self> {
        if points.is_empty() {
            return Err(Error::config(source, "points", "needs at least one point"));
        }
        for (i, p) in points.iter().enumerate() {
            let field = format!("points[{i}]");
            if !p.value.is_finite() || !(0.0..=65535.0).contains(&p.value) {
                return Err(Error::config(
                    source,
                    format!("{field}.value"),
                    format!("{} is out of range; allowed 0..=65535", p.value),
                ));
            }
            if p.rgba
                .iter()
                .any(|c| !c.is_finite() || !(0.0..=1.0).contains(c))
            {
                return Err(Error::config(
                    source,
                    format!("{field}.rgba"),
                    format!("{:?} is out of range; each component allowed 0..=1", p.rgba),
                ));
            }
            if i > 0 && p.value <= points[i - 1].value {
                return Err(Error::config(
                    source,
                    format!("{field}.value"),
                    format!(
                        "points must be sorted by strictly increasing value: {} follows {}",
                        p.value,
                        points[i - 1].value
                    ),
                ));
            }
        }
        Ok(TransferFunction {
            name,
            description,
            points,
        })
    }

    /// The piecewise-linear function at density `v`.
    pub fn eval(&self, v: f32) -> [f32; 4] {
        let pts = &self.points;
        let first = &pts[0];
        if v <= first.value {
            return first.rgba;
        }
        for w in pts.windows(2) {
            let (a, b) = (&w[0], &w[1]);
            if v <= b.value {
                let t = (v - a.value) / (b.value - a.value);
                return [0, 1, 2, 3].map(|c| a.rgba[c] + t * (b.rgba[c] - a.rgba[c]));
            }
        }
        pts[pts.len() - 1].rgba
    }

    /// One entry per integer density 0..entries (per-voxel-thickness opacity, not corrected).
    pub fn sample_table(&self, entries: usize) -> Vec<[f32; 4]> {
        (0..entries).map(|i| self.eval(i as f32)).collect()
    }

    /// Whether any density in [lo, hi] has non-zero opacity (exact for piecewise-linear
    /// functions: checks both ends and every control point inside the interval). This is the
    /// safe emptiness test of class occupancy maps.
    pub fn any_opacity_in(&self, lo: f32, hi: f32) -> bool {
        if self.eval(lo)[3] > 0.0 || self.eval(hi)[3] > 0.0 {
            return true;
        }
        self.points
            .iter()
            .any(|p| p.value >= lo && p.value <= hi && p.rgba[3] > 0.0)
    }
}

/// The '0' classification for a volume without a preset of its own: zero transparent, every
/// non-zero voxel visible, colour and opacity rising over the voxel type's range (0..=255 or
/// 0..=65535), as the datasets' own `*-zero` presets do.
pub fn generic_zero(volume: &crate::volume::Volume) -> TransferFunction {
    let max = if volume.bits == 16 { 65535.0 } else { 255.0 };
    let point = |value: f32, rgba: [f32; 4]| ControlPoint { value, rgba };
    TransferFunction {
        name: format!("{}-zero", preset_key(&volume.name)),
        description: "'0' classification (generic, the volume has no preset): every non-zero \
                      voxel is visible, zero is transparent."
            .into(),
        points: vec![
            point(0.0, [0.0, 0.0, 0.0, 0.0]),
            point(1.0, [0.35, 0.45, 0.8, 0.05]),
            point(max, [1.0, 0.9, 0.6, 0.6]),
        ],
    }
}

/// Opacity of a slab `spacing` voxels thick, from the opacity of a one-voxel slab.
#[inline]
pub fn correct_opacity(alpha_per_voxel: f32, spacing: f32) -> f32 {
    if alpha_per_voxel >= 1.0 {
        1.0
    } else {
        1.0 - (1.0 - alpha_per_voxel).powf(spacing)
    }
}

mod presets {
    include!(concat!(env!("OUT_DIR"), "/transfer_presets.rs"));
}

/// The transfer-function key of a volume: its name with `phantom:KIND:...` turned into
/// `phantom-KIND`. Presets are named `KEY-zero` and `KEY-class`.
pub fn preset_key(volume_name: &str) -> String {
    match volume_name.strip_prefix("phantom:") {
        Some(rest) => format!("phantom-{}", rest.split(':').next().unwrap_or(rest)),
        None => volume_name.to_string(),
    }
}

/// Names of the embedded transfer functions (file stems of configs/transfer/*.toml).
pub fn preset_names() -> Vec<&'static str> {
    presets::EMBEDDED.iter().map(|(n, _)| *n).collect()
}

/// Resolves a `--tf` argument for a volume: `zero` or `class` pick the volume's own preset, a
/// path loads that file, any other word names an embedded preset; a volume without presets (a
/// file of your own) takes `zero` as the generic '0' classification (`generic_zero`).
pub fn resolve_for(arg: &str, volume: &crate::volume::Volume) -> Result<TransferFunction> {
    let own = format!("{}-zero", preset_key(&volume.name));
    if arg == "zero" && !Path::new(arg).is_file() && !preset_names().contains(&own.as_str()) {
        return Ok(generic_zero(volume));
    }
    resolve(arg, &volume.name)
}

/// Resolves a `--tf` argument for the volume named `volume_name` (`resolve_for`, without the
/// generic `zero`).
pub fn resolve(arg: &str, volume_name: &str) -> Result<TransferFunction> {
    let path = Path::new(arg);
    if path.is_file() {
        return TransferFunction::load(path);
    }
    let wanted = match arg {
        "zero" | "class" => format!("{}-{arg}", preset_key(volume_name)),
        other => other.to_string(),
    };
    let Some((name, text)) = presets::EMBEDDED.iter().find(|(n, _)| *n == wanted) else {
        if path.exists() {
            // A directory or a device (`/dev/zero` would never end): not read. (A preset of
            // the same name wins: a folder `class/` does not hide `--tf class`.)
            return Err(Error::Invalid(format!(
                "transfer function `{arg}`: `{arg}` is not a regular file (a directory or a \
                 device); give a transfer function file (TOML, docs/config.md) or a preset name"
            )));
        }
        if arg == "class" {
            return Err(Error::Invalid(format!(
                "transfer function `class` for dataset `{volume_name}`: there is no preset \
                     `{wanted}` (a classification is made for a dataset); give `--tf zero` (every \
                     non-zero voxel visible) or a transfer function file (docs/config.md, \
                     \"Transfer functions and volumes of your own\")"
            )));
        }
        // The dataset's own presets when it has some (the whole list is some 70 names).
        let key = format!("{}-", preset_key(volume_name));
        let own: Vec<&str> = preset_names()
            .into_iter()
            .filter(|n| n.starts_with(&key))
            .collect();
        let listed = if own.is_empty() {
            format!("presets: {}", preset_names().join(", "))
        } else {
            format!(
                "this dataset's presets: {} (`zero` and `class` name its own); the others are \
                 in configs/transfer/",
                own.join(", ")
            )
        };
        return Err(Error::Invalid(format!(
            "transfer function `{arg}` for dataset `{volume_name}`: no file `{arg}` and no \
             preset `{wanted}`; {listed}"
        )));
    };
    TransferFunction::from_toml(text, &format!("configs/transfer/{name}.toml"), name)
}

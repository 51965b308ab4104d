//! Camera paths for fly-throughs (issue 15, part 3): a TOML file of key positions (eye,
//! look-at, up), interpolated into N frames; the view `path:FILE:K/N` is frame K.
//!
//! ```toml
//! units = "extent"              # "extent" (default): fractions of the volume's extent per
//!                               # axis; "world": world units (voxel index × spacing)
//! interpolation = "catmull-rom" # or "linear"
//! fov_y_deg = 60.0              # perspective field of view (default 60)
//! near = 0.0                    # near plane distance from the eye (units of the largest
//!                               # extent with "extent", else world units; default 0)
//! view_width = 0.25             # orthographic image width (same units; default the volume's
//!                               # largest extent, i.e. 1 with "extent")
//!
//! [[key]]
//! eye = [0.5, 0.05, 0.5]
//! look_at = [0.5, 0.5, 0.5]
//! up = [0.0, 0.0, 1.0]
//! ```
//!
//! Interpolation: frame K of N sits at parameter u = K·(keys − 1)/(N − 1) along the keys (N = 1:
//! u = 0), so key i is frame i·(N − 1)/(keys − 1) whenever that is whole, and such frames take the
//! key exactly. Between keys i and i + 1 (local t = u − i) eye and look-at follow a uniform
//! Catmull-Rom spline through the keys (the end keys repeated as outer control points; with
//! "linear", straight lines); up is interpolated linearly, then re-orthogonalised against the
//! frame's view direction (its component along the direction removed). A frame whose up is
//! parallel to its view direction, or whose eye equals its look-at, is an error naming the file
//! and the frame.

use std::path::Path;

use glam::Vec3;
use serde::Deserialize;

use crate::camera::{Camera, Projection};
use crate::error::{Error, Result};

/// Largest accepted frame count N of a path view.
pub const MAX_PATH_FRAMES: u32 = 1_000_000;

/// Largest coordinate magnitude of a key's eye and look-at, in the path's units. Poses are
/// computed in f32 (a 24-bit mantissa): a million units from the origin a sixteenth of a unit
/// is still resolved; much farther, eye and look-at merge.
pub const MAX_COORDINATE: f32 = 1e6;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Units {
    #[default]
    Extent,
    World,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Interpolation {
    #[default]
    CatmullRom,
    Linear,
}

#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Key {
    pub eye: [f32; 3],
    pub look_at: [f32; 3],
    pub up: [f32; 3],
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
struct PathFile {
    #[serde(default)]
    units: Units,
    #[serde(default)]
    interpolation: Interpolation,
    #[serde(default = "default_fov")]
    fov_y_deg: f32,
    #[serde(default)]
    near: f32,
    view_width: Option<f32>,
    #[serde(default)]
    key: Vec<Key>,
}

fn default_fov() -> f32 {
    60.0
}

/// A loaded, validated camera path.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraPath {
    /// The file it came from (for error messages).
    pub file: String,
    pub units: Units,
    pub interpolation: Interpolation,
    pub fov_y_deg: f32,
    pub near: f32,
    /// None: the volume's largest extent, in either unit (a world-unit path used to default to
    /// 1, one voxel: an orthographic fly-through showed a single voxel's width).
    pub view_width: Option<f32>,
    pub keys: Vec<Key>,
}

/// One frame of a path, in the path's units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    pub eye: Vec3,
    pub look_at: Vec3,
    /// Re-orthogonalised: unit length, perpendicular to the view direction.
    pub up: Vec3,
}

impl CameraPath {
    /// Reads and validates a path file.
    pub fn load(file: &Path) -> Result<CameraPath> {
        let name = file.display().to_string();
        // Only a regular file of bounded size: a FIFO would block, /dev/zero never end.
        let text = crate::input::read_text(file)
            .map_err(|e| Error::Invalid(format!("camera path {name}: cannot read: {e}")))?;
        Self::parse(&text, &name)
    }

    /// Parses and validates a path from TOML text; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<CameraPath> {
        let bad = |msg: String| Error::Invalid(format!("camera path {file}: {msg}"));
        let raw: PathFile = toml::from_str(text).map_err(|e| bad(e.to_string()))?;
        if raw.key.len() < 2 {
            return Err(bad(format!(
                "`key`: {} key(s) given; a path needs at least two [[key]] entries",
                raw.key.len()
            )));
        }
        if !(raw.fov_y_deg.is_finite() && raw.fov_y_deg > 0.0 && raw.fov_y_deg < 180.0) {
            return Err(bad(format!(
                "`fov_y_deg` = {}: allowed (0, 180) degrees",
                raw.fov_y_deg
            )));
        }
        if !(raw.near.is_finite() && raw.near >= 0.0) {
            return Err(bad(format!(
                "`near` = {}: must be finite and >= 0",
                raw.near
            )));
        }
        if let Some(width) = raw.view_width.filter(|w| !(w.is_finite() && *w > 0.0)) {
            return Err(bad(format!(
                "`view_width` = {width}: must be finite and > 0"
            )));
        }
        for (i, k) in raw.key.iter().enumerate() {
            for (field, v) in [("eye", k.eye), ("look_at", k.look_at), ("up", k.up)] {
                if v.iter().any(|c| !c.is_finite()) {
                    return Err(bad(format!("`key[{i}].{field}` = {v:?}: must be finite")));
                }
                // Poses are computed in f32: far beyond the volume, eye and look-at merge (up is
                // a direction, normalised: any length will do).
                if field != "up" && v.iter().any(|c| c.abs() > MAX_COORDINATE) {
                    return Err(bad(format!(
                        "`key[{i}].{field}` = {v:?}: coordinates allowed within \
                         ±{MAX_COORDINATE:e} (in the path's units)"
                    )));
                }
            }
            if Vec3::from(k.up).length() == 0.0 {
                return Err(bad(format!("`key[{i}].up` is the zero vector")));
            }
        }
        let path = CameraPath {
            file: file.to_string(),
            units: raw.units,
            interpolation: raw.interpolation,
            fov_y_deg: raw.fov_y_deg,
            near: raw.near,
            view_width: raw.view_width,
            keys: raw.key,
        };
        // Every key must give a valid camera on its own.
        for i in 0..path.keys.len() {
            path.pose_at(i as f64, &format!("`key[{i}]`"))?;
        }
        Ok(path)
    }

    /// Checks that frames 0..n all give valid cameras (up not parallel to the direction).
    pub fn check_frames(&self, n: u32) -> Result<()> {
        for k in 0..n {
            self.pose(k, n)?;
        }
        Ok(())
    }

    /// Frame k of n (0 <= k < n).
    pub fn pose(&self, k: u32, n: u32) -> Result<Pose> {
        if n == 0 || k >= n || n > MAX_PATH_FRAMES {
            return Err(Error::Invalid(format!(
                "camera path {}: frame {k} of {n}: expected 0 <= K < N <= {MAX_PATH_FRAMES}",
                self.file
            )));
        }
        let segments = (self.keys.len() - 1) as u64;
        let what = format!("frame {k} of {n}");
        if n == 1 {
            return self.pose_at(0.0, &what);
        }
        let num = k as u64 * segments;
        let den = (n - 1) as u64;
        if num.is_multiple_of(den) {
            // Exactly on a key.
            return self.pose_at((num / den) as f64, &what);
        }
        self.pose_at(num as f64 / den as f64, &what)
    }

    /// The pose at parameter u in [0, keys − 1].
    fn pose_at(&self, u: f64, what: &str) -> Result<Pose> {
        let last = self.keys.len() - 1;
        let i = (u.floor() as usize).min(last);
        let (eye, look_at, up) = if u == i as f64 {
            let k = &self.keys[i];
            (Vec3::from(k.eye), Vec3::from(k.look_at), Vec3::from(k.up))
        } else {
            let t = (u - i as f64) as f32;
            let key = |j: isize| &self.keys[j.clamp(0, last as isize) as usize];
            let j = i as isize;
            let (k0, k1, k2, k3) = (key(j - 1), key(j), key(j + 1), key(j + 2));
            let curve = |f: fn(&Key) -> [f32; 3]| -> Vec3 {
                let (p0, p1, p2, p3) = (
                    Vec3::from(f(k0)),
                    Vec3::from(f(k1)),
                    Vec3::from(f(k2)),
                    Vec3::from(f(k3)),
                );
                match self.interpolation {
                    Interpolation::Linear => p1.lerp(p2, t),
                    Interpolation::CatmullRom => {
                        0.5 * (2.0 * p1
                            + (p2 - p0) * t
                            + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * (t * t)
                            + (3.0 * p1 - p0 - 3.0 * p2 + p3) * (t * t * t))
                    }
                }
            };
            let up = Vec3::from(k1.up)
                .normalize()
                .lerp(Vec3::from(k2.up).normalize(), t);
            (curve(|k| k.eye), curve(|k| k.look_at), up)
        };
        let bad = |msg: String| Error::Invalid(format!("camera path {}: {what}: {msg}", self.file));
        let dir = look_at - eye;
        if dir.length() <= 1e-6 * eye.length().max(look_at.length()).max(1e-30) {
            return Err(bad(format!(
                "eye {eye} and look_at {look_at} coincide; no view direction"
            )));
        }
        let dir = dir.normalize();
        // Two keys whose up vectors point opposite ways interpolate to zero between them.
        if up.length() < 1e-6 {
            let i = u.floor() as usize;
            return Err(bad(format!(
                "the up vectors of key[{i}] and key[{}] point opposite ways, so up interpolated \
                 between them is zero here; turn one of them, or add a key between them",
                i + 1
            )));
        }
        let ortho = up - dir * up.dot(dir);
        if ortho.length() < 1e-3 * up.length() || !ortho.is_finite() {
            return Err(bad(format!(
                "up {up} is parallel to the view direction {dir}"
            )));
        }
        Ok(Pose {
            eye,
            look_at,
            up: ortho.normalize(),
        })
    }

    /// The camera of frame k of n for a volume of this world extent.
    pub fn camera(
        &self,
        extent: Vec3,
        k: u32,
        n: u32,
        projection: Projection,
        width: u32,
        height: u32,
    ) -> Result<Camera> {
        let pose = self.pose(k, n)?;
        let (scale, length) = match self.units {
            Units::Extent => (extent, extent.max_element().max(1.0)),
            Units::World => (Vec3::ONE, 1.0),
        };
        let mut camera = Camera::new(
            pose.eye * scale,
            pose.look_at * scale,
            pose.up,
            projection,
            width,
            height,
        )
        .map_err(|e| Error::Invalid(format!("camera path {}: frame {k} of {n}: {e}", self.file)))?;
        camera.fov_y_deg = self.fov_y_deg;
        camera.near = self.near * length;
        camera.view_width = match self.view_width {
            Some(width) => width * length,
            None => extent.max_element().max(1.0),
        };
        Ok(camera)
    }
}

//! Cameras and views. World space is the volume's physical space: voxel (x, y, z) sits at
//! (x·sx, y·sy, z·sz) for spacing (sx, sy, sz). Renderers map each world ray into voxel index
//! space (divide by the spacing) and march there.

use glam::{Vec3, Vec3A};

use crate::error::{Error, Result};

/// Largest accepted image extent along one axis.
pub const MAX_IMAGE_SIDE: u32 = 16384;

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Projection {
    /// Parallel rays; `Camera::view_width` world units span the image width.
    Ortho,
    /// Rays from the eye; `Camera::fov_y_deg` is the vertical field of view.
    Persp,
}

/// A ray in voxel index space: `origin + t·dir`, `dir` of unit length (in voxels), `t` in voxels.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub origin: Vec3A,
    pub dir: Vec3A,
    /// Samples are taken only at t >= t_min (the near plane).
    pub t_min: f32,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Camera {
    pub eye: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    pub projection: Projection,
    pub width: u32,
    pub height: u32,
    /// Orthographic: world units across the image width.
    pub view_width: f32,
    /// Perspective: vertical field of view in degrees.
    pub fov_y_deg: f32,
    /// Distance from the eye (perspective) or the view plane (orthographic) to the near plane.
    pub near: f32,
    // Derived orthonormal frame.
    forward: Vec3,
    right: Vec3,
    true_up: Vec3,
}

/// A named view of a volume: which side the camera looks from, and the orbit position.
#[derive(Clone, Debug, PartialEq)]
pub enum View {
    /// Looking along +y with +z up (the dataset's front).
    Front,
    /// Frame `k` of an `n`-frame orbit about the vertical (z) axis through the volume centre,
    /// starting at the front view; 360/n degrees per frame.
    Orbit { k: u32, n: u32 },
    /// Frame `k` of `n` along a camera path file (`crate::path`): `path:FILE:K/N`.
    Path {
        path: std::sync::Arc<crate::path::CameraPath>,
        k: u32,
        n: u32,
    },
}

impl View {
    pub fn parse(text: &str) -> Result<View> {
        if text == "front" {
            return Ok(View::Front);
        }
        let bad = || {
            Error::Invalid(format!(
                "view `{text}`: expected `front`, `orbit:K/N` or `path:FILE:K/N` with 0 <= K < N \
                 (e.g. orbit:3/72)"
            ))
        };
        if let Some(rest) = text.strip_prefix("path:") {
            return View::parse_path(text, rest);
        }
        let rest = text.strip_prefix("orbit:").ok_or_else(bad)?;
        let (k, n) = rest.split_once('/').ok_or_else(bad)?;
        let k: u32 = k.parse().map_err(|_| bad())?;
        let n: u32 = n.parse().map_err(|_| bad())?;
        if n == 0 || k >= n {
            return Err(bad());
        }
        Ok(View::Orbit { k, n })
    }

    /// `path:FILE:K/N`: loads and checks the file (every one of the N frames).
    fn parse_path(text: &str, rest: &str) -> Result<View> {
        let bad = |msg: &str| {
            Error::Invalid(format!(
                "view `{text}`: {msg}; expected `path:FILE:K/N` with 0 <= K < N (e.g. \
                 path:configs/paths/tube.toml:10/120)"
            ))
        };
        let (file, frame) = rest.rsplit_once(':').ok_or_else(|| bad("no `:K/N`"))?;
        let (k, n) = frame.split_once('/').ok_or_else(|| bad("no `/` in K/N"))?;
        // A whole number too large is out of range, not malformed.
        let whole = |text: &str, what: &str| -> Result<u64> {
            if text.is_empty() || !text.bytes().all(|b| b.is_ascii_digit()) {
                return Err(bad(&format!("{what} is not a whole number")));
            }
            Ok(text.parse().unwrap_or(u64::MAX))
        };
        let (k, n) = (whole(k, "K")?, whole(n, "N")?);
        if n == 0 || k >= n || n > crate::path::MAX_PATH_FRAMES as u64 {
            return Err(bad(&format!(
                "frame {k} of {n} out of range (N at most {})",
                crate::path::MAX_PATH_FRAMES
            )));
        }
        if file.is_empty() {
            return Err(bad("empty file name"));
        }
        let (k, n) = (k as u32, n as u32);
        let path = crate::path::CameraPath::load(std::path::Path::new(file))?;
        path.check_frames(n)?;
        Ok(View::Path {
            path: std::sync::Arc::new(path),
            k,
            n,
        })
    }

    /// Rotation angle about the vertical axis, in degrees (0 for a path view).
    pub fn angle_deg(&self) -> f64 {
        match *self {
            View::Front | View::Path { .. } => 0.0,
            View::Orbit { k, n } => 360.0 * k as f64 / n as f64,
        }
    }
}

impl Camera {
    pub fn new(
        eye: Vec3,
        look_at: Vec3,
        up: Vec3,
        projection: Projection,
        width: u32,
        height: u32,
    ) -> Result<Camera> {
        check_image_size(width, height)?;
        let forward = (look_at - eye).normalize_or_zero();
        if forward == Vec3::ZERO || !forward.is_finite() {
            return Err(Error::Invalid(format!(
                "camera: eye {eye} and look-at {look_at} must be distinct finite points"
            )));
        }
        let right = forward.cross(up);
        if right.length() < 1e-6 * up.length().max(1e-30) || !right.is_finite() {
            return Err(Error::Invalid(format!(
                "camera: up vector {up} is parallel to the view direction {forward}"
            )));
        }
        let right = right.normalize();
        let true_up = right.cross(forward);
        Ok(Camera {
            eye,
            look_at,
            up,
            projection,
            width,
            height,
            view_width: 1.0,
            fov_y_deg: 30.0,
            near: 0.0,
            forward,
            right,
            true_up,
        })
    }

    /// The published default: the camera orbits the volume centre about the vertical (z) axis;
    /// the volume's largest extent spans the image width (for perspective: fits the frustum).
    pub fn for_volume(
        extent: Vec3,
        view: View,
        projection: Projection,
        width: u32,
        height: u32,
    ) -> Result<Camera> {
        if let View::Path { path, k, n } = &view {
            return path.camera(extent, *k, *n, projection, width, height);
        }
        let centre = extent * 0.5;
        let largest = extent.max_element().max(1.0);
        let angle = (view.angle_deg()).to_radians();
        // Front view looks along +y; orbit frames rotate the eye counter-clockwise about +z.
        let to_eye = Vec3::new(-(angle.sin() as f32), -(angle.cos() as f32), 0.0);
        let fov_y_deg = 30.0f32;
        let aspect = width as f32 / height.max(1) as f32;
        let distance = match projection {
            // Far enough that the whole volume is in front of the view plane.
            Projection::Ortho => extent.length(),
            Projection::Persp => {
                let half_fov_x = ((fov_y_deg.to_radians() * 0.5).tan() * aspect).atan();
                0.5 * largest / half_fov_x.tan() + 0.5 * extent.length()
            }
        };
        let mut camera = Camera::new(
            centre + to_eye * distance,
            centre,
            Vec3::Z,
            projection,
            width,
            height,
        )?;
        camera.view_width = largest;
        camera.fov_y_deg = fov_y_deg;
        Ok(camera)
    }

    /// The world-space ray through the centre of pixel (px, py); py = 0 is the top row.
    pub fn world_ray(&self, px: u32, py: u32) -> (Vec3, Vec3) {
        let u = (px as f32 + 0.5) / self.width as f32 * 2.0 - 1.0;
        let v = 1.0 - (py as f32 + 0.5) / self.height as f32 * 2.0;
        let aspect = self.height as f32 / self.width as f32;
        match self.projection {
            Projection::Ortho => {
                let half_w = 0.5 * self.view_width;
                let origin =
                    self.eye + self.right * (u * half_w) + self.true_up * (v * half_w * aspect);
                (origin, self.forward)
            }
            Projection::Persp => {
                let half_h = (self.fov_y_deg.to_radians() * 0.5).tan();
                let half_w = half_h / aspect;
                let dir = (self.forward + self.right * (u * half_w) + self.true_up * (v * half_h))
                    .normalize();
                (self.eye, dir)
            }
        }
    }

    /// The ray through pixel (px, py) in voxel index space, for a volume of the given spacing.
    /// `t` is measured in voxels from the eye (perspective) or the view plane (orthographic), so
    /// samples at t = k·S lie on planes (or spheres) fixed to the camera, not to the volume.
    pub fn voxel_ray(&self, px: u32, py: u32, spacing: [f32; 3]) -> Ray {
        let (origin, dir) = self.world_ray(px, py);
        let inv = Vec3::new(1.0 / spacing[0], 1.0 / spacing[1], 1.0 / spacing[2]);
        let dir_v = dir * inv;
        let len = dir_v.length();
        // Near plane distance converted with the same scale as the direction.
        Ray {
            origin: Vec3A::from(origin * inv),
            dir: Vec3A::from(dir_v / len),
            t_min: self.near * len,
        }
    }
}

pub fn check_image_size(width: u32, height: u32) -> Result<()> {
    if width == 0 || height == 0 || width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
        return Err(Error::Invalid(format!(
            "image size {width}x{height}: each side must be 1..={MAX_IMAGE_SIDE}"
        )));
    }
    Ok(())
}

/// Parses `WxH`, e.g. `256x256`.
pub fn parse_image_size(text: &str) -> Result<(u32, u32)> {
    let bad = || Error::Invalid(format!("image size `{text}`: expected WxH, e.g. 256x256"));
    let (w, h) = text.split_once(['x', 'X']).ok_or_else(bad)?;
    // A side of digits too large for u32 is out of range, not malformed.
    let side = |s: &str| match s.trim().parse::<u32>() {
        Ok(v) => Ok(v),
        Err(e) if *e.kind() == std::num::IntErrorKind::PosOverflow => Ok(u32::MAX),
        Err(_) => Err(bad()),
    };
    let (w, h) = (side(w)?, side(h)?);
    check_image_size(w, h).map_err(|_| {
        Error::Invalid(format!(
            "image size `{text}`: each side must be 1..={MAX_IMAGE_SIDE}"
        ))
    })?;
    Ok((w, h))
}

/// Largest accepted interleaving pattern side N (`ray.interleave`).
pub const MAX_INTERLEAVE: u32 = 64;

/// Interleaved sampling (issue 15, part 4): the first-sample offset of pixel (px, py), in
/// sample steps, from an N×N pattern. The pattern holds each of 0, 1/N², ..., (N²−1)/N² once:
/// cell (i, j) = (px mod N, py mod N) gets rank ((i·N + j)·g) mod N², g the smallest integer
/// at least 0.618·N² that is coprime with N (a permutation that spreads neighbouring ranks
/// apart). N = 1 gives 0 everywhere.
pub fn interleave_offset(px: u32, py: u32, n: u32) -> f32 {
    if n <= 1 {
        return 0.0;
    }
    let n = n as u64;
    let cells = n * n;
    let mut g = ((cells as f64) * 0.618_034).ceil() as u64;
    while gcd(g, n) != 1 {
        g += 1;
    }
    let (i, j) = (px as u64 % n, py as u64 % n);
    let rank = ((i * n + j) * g) % cells;
    (rank as f64 / cells as f64) as f32
}

fn gcd(mut a: u64, mut b: u64) -> u64 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

/// The ray of pixel (px, py) with interleaved sampling (`settings.interleave`): samples sit at
/// t = (k − o)·S instead of k·S, o = `interleave_offset`. Realised by moving the origin back
/// by o·S along the ray (and the near plane forward by as much, so it stays in place): every
/// model keeps its convention of samples at t' = k·S on the shifted ray, so the float
/// reference, the fixed-point setup and the cycle model (which uses that setup) place the same
/// samples. Off (N = 1): the ray unchanged, bit for bit.
pub fn interleave_ray(ray: Ray, px: u32, py: u32, settings: &crate::render::RenderSettings) -> Ray {
    let o = interleave_offset(px, py, settings.interleave);
    if o == 0.0 {
        return ray;
    }
    let shift = o * settings.sample_spacing;
    Ray {
        origin: ray.origin - ray.dir * shift,
        dir: ray.dir,
        t_min: ray.t_min + shift,
    }
}

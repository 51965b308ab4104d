//! Clipping and opaque geometry: what ends or starts a ray besides the volume's box.
//!
//! Everything here is computed per ray from the float camera ray (`camera::Ray`, voxel space)
//! and turned into a range of global sample indices k (samples at t = k·S): every model takes
//! the same range, so clipping and geometry cut exactly the same samples in the float
//! reference, the functional model and the cycle model.
//!
//! - **Clip planes** (`[clip] planes`): a sample at x is kept when (x - point)·normal >= 0.
//! - **Clip box** (`[clip] box_min`, `box_max`): a sample is kept inside [min, max].
//! - **Opaque geometry** (`[geometry]`): per pixel the ray parameter t of the first opaque
//!   surface; samples with t >= that depth are not taken, and the surface's colour (opaque)
//!   replaces the background behind the volume. Shapes: an analytic sphere or capped cylinder
//!   "pointer" (lit by the headlight), or a depth image file (below) with one colour.
//!
//! **Depth file format** (`geometry.shape = "depth-file"`): the ASCII line `VIZDEPTH W H\n`
//! (W, H the image size in pixels, which must equal the rendered image's), then W·H
//! little-endian f32 values, row-major, top row first: the ray parameter t (voxels, the
//! renderers' t along the pixel's voxel-space ray) of the first opaque surface. A negative or
//! non-finite value means no surface in that pixel. `write_depth_file` writes one.

use std::path::Path;

use crate::camera::Ray;
use crate::config::{ClipPlane, GeometryShape, HardwareConfig};
use crate::error::{Error, Result};

/// An opaque surface colour, RGBA in 0..=1 (alpha 1).
pub type SurfaceColour = [f32; 4];

/// What the scene leaves of one ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// Samples with global index k in [k_lo, k_end) are kept (before box and bricks).
    pub k_lo: i64,
    pub k_end: i64,
    /// The opaque surface behind the volume in this pixel.
    pub surface: Option<SurfaceColour>,
}

/// A depth image: per pixel the t of the first opaque surface (None: no surface).
#[derive(Clone, Debug)]
pub struct DepthImage {
    pub width: u32,
    pub height: u32,
    pub depth: Vec<f32>,
}

const DEPTH_MAGIC: &str = "VIZDEPTH";

/// Longest header line read: `VIZDEPTH`, two numbers and the newline fit with room to spare.
const HEADER_MAX: u64 = 64;

impl DepthImage {
    /// Reads a depth file: only a regular file (a FIFO or a device such as `/dev/zero` is
    /// refused before it is read, as every input is: `input::open_regular`), and only after its
    /// header is checked against the file's length and the memory budget
    /// (`DepthImage::check_file`); then exactly the values the header announces.
    pub fn read(path: &Path) -> Result<DepthImage> {
        let (file, width, height) = Self::open_checked(path)?;
        let expected = Self::values_bytes(width, height);
        let mut body = Vec::with_capacity(expected as usize);
        use std::io::Read;
        file.take(expected)
            .read_to_end(&mut body)
            .map_err(|e| Error::io(path, e))?;
        if body.len() as u64 != expected {
            // The file shrank after its length was checked.
            return Err(Error::format(
                path,
                format!(
                    "{} bytes of depth values; a {width}x{height} image needs {expected} (4 per \
                     pixel)",
                    body.len()
                ),
            ));
        }
        let depth = body
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        Ok(DepthImage {
            width,
            height,
            depth,
        })
    }

    /// Checks a depth file without reading its values, and returns its image size (W, H):
    /// a regular file whose header is valid, whose length is the header line and exactly
    /// the W·H values it announces, and whose values fit the memory budget.
    pub fn check_file(path: &Path) -> Result<(u32, u32)> {
        Self::open_checked(path).map(|(_, w, h)| (w, h))
    }

    /// Bytes of the values of a W×H image (4 per pixel).
    fn values_bytes(width: u32, height: u32) -> u64 {
        width as u64 * height as u64 * 4
    }

    /// Opens a depth file, checks it as `check_file` says, and leaves it positioned at the
    /// first value.
    fn open_checked(path: &Path) -> Result<(std::fs::File, u32, u32)> {
        use std::io::{Read, Seek};
        let mut file = crate::input::open_regular(path)?;
        let length = file.metadata().map_err(|e| Error::io(path, e))?.len();
        let mut head = Vec::with_capacity(HEADER_MAX as usize);
        (&mut file)
            .take(HEADER_MAX)
            .read_to_end(&mut head)
            .map_err(|e| Error::io(path, e))?;
        let bad = |m: String| Error::format(path, m);
        let line_end = head
            .iter()
            .position(|&b| b == b'\n')
            .ok_or_else(|| bad(format!("no `{DEPTH_MAGIC} W H` header line")))?;
        let header =
            std::str::from_utf8(&head[..line_end]).map_err(|_| bad("header is not text".into()))?;
        let fields: Vec<&str> = header.split_whitespace().collect();
        let (w, h) = match fields.as_slice() {
            [magic, w, h] if *magic == DEPTH_MAGIC => (w.parse::<u32>(), h.parse::<u32>()),
            _ => {
                return Err(bad(format!(
                    "header `{header}`: expected `{DEPTH_MAGIC} W H`"
                )))
            }
        };
        let (Ok(width), Ok(height)) = (w, h) else {
            return Err(bad(format!("header `{header}`: W and H must be integers")));
        };
        crate::camera::check_image_size(width, height).map_err(|e| bad(format!("header: {e}")))?;
        // The length the header announces, against the file's: a file of another length
        // (truncated, padded, a huge sparse file) is refused before any value is read.
        let values_at = line_end as u64 + 1;
        let expected = Self::values_bytes(width, height);
        let body = length.saturating_sub(values_at);
        if body != expected {
            return Err(bad(format!(
                "{body} bytes of depth values; a {width}x{height} image needs {expected} (4 per \
                 pixel)"
            )));
        }
        crate::budget::check(
            &format!("the {width}x{height} depth image {}", path.display()),
            expected,
        )?;
        file.seek(std::io::SeekFrom::Start(values_at))
            .map_err(|e| Error::io(path, e))?;
        Ok((file, width, height))
    }

    /// Writes the format `read` accepts, atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        crate::output::write_atomically(path, |w| {
            use std::io::Write;
            writeln!(w, "{DEPTH_MAGIC} {} {}", self.width, self.height)?;
            for d in &self.depth {
                w.write_all(&d.to_le_bytes())?;
            }
            Ok(())
        })
    }

    fn at(&self, px: u32, py: u32) -> Option<f32> {
        if px >= self.width || py >= self.height {
            return None;
        }
        let d = self.depth[(py * self.width + px) as usize];
        (d.is_finite() && d >= 0.0).then_some(d)
    }
}

#[derive(Clone, Debug)]
enum Geometry {
    Sphere {
        centre: [f64; 3],
        radius: f64,
        colour: [f32; 3],
    },
    Cylinder {
        base: [f64; 3],
        /// Unit axis from `base`, and the length along it.
        axis: [f64; 3],
        length: f64,
        radius: f64,
        colour: [f32; 3],
    },
    Depth {
        image: DepthImage,
        colour: [f32; 3],
    },
}

/// Clip planes, clip box and opaque geometry of a frame.
#[derive(Clone, Debug)]
pub struct Scene {
    planes: Vec<ClipPlane>,
    clip_box: Option<([f32; 3], [f32; 3])>,
    geometry: Option<Geometry>,
}

impl Scene {
    /// The scene of a configuration (reads a depth file); None when nothing is set.
    pub fn from_config(config: &HardwareConfig) -> Result<Option<Scene>> {
        let clip = &config.clip;
        let g = &config.geometry;
        if clip.is_off() && g.is_off() {
            return Ok(None);
        }
        let geometry = match g.shape {
            GeometryShape::None => None,
            GeometryShape::Sphere => Some(Geometry::Sphere {
                centre: g.centre.map(|x| x as f64),
                radius: g.radius as f64,
                colour: g.colour,
            }),
            GeometryShape::Cylinder => {
                let base = g.centre.map(|x| x as f64);
                let a = [0, 1, 2].map(|i| g.end[i] as f64 - base[i]);
                let length = dot(&a, &a).sqrt();
                Some(Geometry::Cylinder {
                    base,
                    axis: a.map(|x| x / length),
                    length,
                    radius: g.radius as f64,
                    colour: g.colour,
                })
            }
            GeometryShape::DepthFile => Some(Geometry::Depth {
                image: DepthImage::read(Path::new(&g.file)).map_err(depth_file_error)?,
                colour: g.colour,
            }),
        };
        Ok(Some(Scene {
            planes: clip.planes.clone(),
            clip_box: clip.box_corners(),
            geometry,
        }))
    }

    /// An error when a depth image does not match the rendered image's size.
    pub fn check_image_size(&self, width: u32, height: u32) -> Result<()> {
        if let Some(Geometry::Depth { image, .. }) = &self.geometry {
            check_depth_size((image.width, image.height), (width, height))?;
        }
        Ok(())
    }

    /// What `from_config` and `check_image_size` would refuse in a configuration's depth file
    /// (`geometry.shape = "depth-file"`), checked without reading its values: the file is
    /// there, a regular file, of the length its header announces, within the memory budget,
    /// and of the rendered image's size. Nothing to check for other shapes.
    pub fn check_depth_file(config: &HardwareConfig, size: (u32, u32)) -> Result<()> {
        let g = &config.geometry;
        if g.shape != GeometryShape::DepthFile {
            return Ok(());
        }
        let image = DepthImage::check_file(Path::new(&g.file)).map_err(depth_file_error)?;
        check_depth_size(image, size)
    }

    /// The kept sample range and the surface of the ray through pixel (px, py).
    pub fn limits(&self, ray: &Ray, px: u32, py: u32, spacing: f32) -> Limits {
        let o = [0, 1, 2].map(|a| ray.origin[a] as f64);
        let d = [0, 1, 2].map(|a| ray.dir[a] as f64);
        let s = spacing as f64;
        let (mut t_lo, mut t_hi) = (f64::NEG_INFINITY, f64::INFINITY);
        let mut none = false;
        for plane in &self.planes {
            let n = plane.normal.map(|x| x as f64);
            let num: f64 = (0..3).map(|a| (plane.point[a] as f64 - o[a]) * n[a]).sum();
            let den: f64 = (0..3).map(|a| d[a] * n[a]).sum();
            if den == 0.0 {
                // Parallel: kept everywhere or nowhere ((o - p)·n >= 0 keeps).
                none |= num > 0.0;
            } else if den > 0.0 {
                t_lo = t_lo.max(num / den);
            } else {
                t_hi = t_hi.min(num / den);
            }
        }
        if let Some((lo, hi)) = self.clip_box {
            for a in 0..3 {
                let (l, h) = (lo[a] as f64, hi[a] as f64);
                if d[a] == 0.0 {
                    none |= o[a] < l || o[a] > h;
                    continue;
                }
                let (mut ta, mut tb) = ((l - o[a]) / d[a], (h - o[a]) / d[a]);
                if ta > tb {
                    std::mem::swap(&mut ta, &mut tb);
                }
                t_lo = t_lo.max(ta);
                t_hi = t_hi.min(tb);
            }
        }
        // Samples at t = k·S with t_lo <= t <= t_hi.
        let to_k = |x: f64| x.clamp(-1e15, 1e15) as i64;
        let k_lo = to_k((t_lo / s).ceil());
        let mut k_end = to_k((t_hi / s).floor()).saturating_add(1);
        if none || t_lo > t_hi {
            k_end = k_lo;
        }
        let mut surface = None;
        if let Some((t_surface, colour)) = self.surface(ray, &o, &d, px, py) {
            // Samples strictly in front of the surface: k·S < t.
            k_end = k_end.min(to_k((t_surface / s).ceil()));
            surface = Some(colour);
        }
        Limits {
            k_lo,
            k_end: k_end.max(k_lo),
            surface,
        }
    }

    /// The first opaque surface along the ray (t >= the near plane) and its colour.
    fn surface(
        &self,
        ray: &Ray,
        o: &[f64; 3],
        d: &[f64; 3],
        px: u32,
        py: u32,
    ) -> Option<(f64, SurfaceColour)> {
        match self.geometry.as_ref()? {
            Geometry::Sphere {
                centre,
                radius,
                colour,
            } => {
                let oc = [0, 1, 2].map(|a| o[a] - centre[a]);
                let b: f64 = (0..3).map(|a| oc[a] * d[a]).sum();
                let c: f64 = (0..3).map(|a| oc[a] * oc[a]).sum::<f64>() - radius * radius;
                let disc = b * b - c;
                if disc < 0.0 {
                    return None;
                }
                let root = disc.sqrt();
                let (t0, t1) = (-b - root, -b + root);
                let t_min = ray.t_min as f64;
                if t1 < t_min {
                    return None;
                }
                let t = t0.max(t_min);
                // Headlight: ambient plus diffuse by the angle between normal and ray.
                let normal = [0, 1, 2].map(|a| (o[a] + t * d[a] - centre[a]) / radius);
                let cos = (0..3).map(|a| normal[a] * d[a]).sum::<f64>().abs().min(1.0);
                let light = (0.25 + 0.75 * cos) as f32;
                Some((
                    t,
                    [colour[0] * light, colour[1] * light, colour[2] * light, 1.0],
                ))
            }
            Geometry::Cylinder {
                base,
                axis,
                length,
                radius,
                colour,
            } => {
                let (t, normal) =
                    cylinder_hit(o, d, ray.t_min as f64, base, axis, *length, *radius)?;
                Some((t, lit(*colour, &normal, d)))
            }
            Geometry::Depth { image, colour } => {
                let t = image.at(px, py)? as f64;
                Some((t, [colour[0], colour[1], colour[2], 1.0]))
            }
        }
    }
}

/// An error when a depth image of `image` (W, H) does not match the rendered image's `size`.
fn check_depth_size(image: (u32, u32), size: (u32, u32)) -> Result<()> {
    if image != size {
        return Err(Error::config(
            "hardware configuration",
            "geometry.file",
            format!(
                "the depth image is {}x{}, the rendered image {}x{}; they must match",
                image.0, image.1, size.0, size.1
            ),
        ));
    }
    Ok(())
}

/// An error reading the depth file of `geometry.file`, naming the field: a file that is not
/// there (or not readable) and a file over the memory budget as errors of the field, a file
/// that is no depth image as an error of the file that says which field names it.
fn depth_file_error(error: Error) -> Error {
    let field = "geometry.file";
    match error {
        Error::Io { path, cause } => Error::config(
            "hardware configuration",
            field,
            format!(
                "{}: {cause}; give the path of a depth image (`{DEPTH_MAGIC} W H` header line, \
                 then W·H little-endian f32 values)",
                path.display()
            ),
        ),
        Error::Format { path, message } => Error::format(
            path,
            format!("the depth image of field `{field}`: {message}"),
        ),
        other => Error::config("hardware configuration", field, other.to_string()),
    }
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Headlight: ambient plus diffuse by the angle between the unit normal and the ray.
fn lit(colour: [f32; 3], normal: &[f64; 3], d: &[f64; 3]) -> SurfaceColour {
    let light = (0.25 + 0.75 * dot(normal, d).abs().min(1.0)) as f32;
    [colour[0] * light, colour[1] * light, colour[2] * light, 1.0]
}

/// The first t >= t_min where the ray o + t·d (d unit) meets the capped cylinder of the given
/// base point, unit axis, length and radius, and the unit normal there. A ray starting inside
/// meets it at t_min. Candidates: the two roots of the side (the radial part w + t·v of the
/// ray, with w, v the components of o - base and d normal to the axis, has length r) within
/// the axial range [0, length], and the two cap planes within the radius.
fn cylinder_hit(
    o: &[f64; 3],
    d: &[f64; 3],
    t_min: f64,
    base: &[f64; 3],
    axis: &[f64; 3],
    length: f64,
    radius: f64,
) -> Option<(f64, [f64; 3])> {
    let oc = [0, 1, 2].map(|i| o[i] - base[i]);
    let (oc_a, d_a) = (dot(&oc, axis), dot(d, axis));
    let w = [0, 1, 2].map(|i| oc[i] - oc_a * axis[i]);
    let v = [0, 1, 2].map(|i| d[i] - d_a * axis[i]);
    let inside = |t: f64| {
        let s = oc_a + t * d_a;
        let r = [0, 1, 2].map(|i| w[i] + t * v[i]);
        (0.0..=length).contains(&s) && dot(&r, &r) <= radius * radius
    };
    if inside(t_min) {
        return Some((t_min, d.map(|x| -x)));
    }
    let mut best: Option<(f64, [f64; 3])> = None;
    let mut consider = |t: f64, normal: [f64; 3]| {
        if t >= t_min && best.is_none_or(|(b, _)| t < b) {
            best = Some((t, normal));
        }
    };
    let a = dot(&v, &v);
    if a > 1e-12 {
        let b = dot(&w, &v);
        let disc = b * b - a * (dot(&w, &w) - radius * radius);
        if disc >= 0.0 {
            let root = disc.sqrt();
            for t in [(-b - root) / a, (-b + root) / a] {
                let s = oc_a + t * d_a;
                if (0.0..=length).contains(&s) {
                    consider(t, [0, 1, 2].map(|i| (w[i] + t * v[i]) / radius));
                }
            }
        }
    }
    if d_a.abs() > 1e-12 {
        for (s, sign) in [(0.0, -1.0), (length, 1.0)] {
            let t = (s - oc_a) / d_a;
            let r = [0, 1, 2].map(|i| w[i] + t * v[i]);
            if dot(&r, &r) <= radius * radius {
                consider(t, axis.map(|x| sign * x));
            }
        }
    }
    best
}

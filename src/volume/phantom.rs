//! Phantoms generated in code, deterministic from a seed.
//!
//! A spec `KIND[:SIZE][:seed=N][:t=F]` fully determines the bytes of the volume, on any machine
//! and with any number of threads: every voxel is computed on its own (slices in parallel) from
//! IEEE basic arithmetic and `sqrt`, which are correctly rounded everywhere. Library `sin`/`exp`
//! are avoided because they may differ in the last bit between platforms, which could flip a
//! rounded voxel value; the metaball trajectories use a fixed polynomial sine instead.
//!
//! Every phantom is 8-bit, `size`^3 voxels with spacing 1, voxel (x, y, z) at integer position
//! (x, y, z). The documentation of each [`PhantomKind`] lists which structures sit at which
//! values, for writing transfer functions that reveal them.

use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::ops::RangeInclusive;

use glam::DVec3;
use rayon::prelude::*;

use super::Volume;
use crate::error::{Error, Result};

/// Accepted edge lengths of a phantom.
pub const SIZE_RANGE: RangeInclusive<usize> = 8..=512;
pub const DEFAULT_SIZE: usize = 64;
pub const DEFAULT_SEED: u64 = 1;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PhantomKind {
    /// Ball of radius R = 0.4*size centred in the volume: value 250*(1 - (r/R)^2), i.e. 250 at
    /// the centre falling smoothly to 0 at the surface, so the iso-surface of value v is the
    /// sphere of radius R*sqrt(1 - v/250). Exactly 0 outside (~27 % occupied). Ignores the seed.
    Sphere,
    /// Three concentric spherical shells, (size/32 + 1) voxels thick, with hard edges: value 220
    /// at radius 0.14*size, 130 at 0.27*size, 60 at 0.40*size. Every voxel is exactly one of
    /// 0, 60, 130, 220 (11 % occupied at size 256 up to 20 % at 32). Ignores the seed.
    Shells,
    /// Fuel-injection-like plume entering at the centre of the z = 0 face and widening as a cone
    /// along +z (radius ~0.035*size, at least 2 voxels, at the nozzle; ~0.235*size at the far
    /// face) with a noisy, turbulent-looking boundary. On the axis the value is
    /// 240*(1 - 0.75*z/(size-1)) times a ±15 % texture: the nozzle slice peaks at 200..=255,
    /// the far face at ~60-70; across the plume it falls as 1 - (r/r_local)^2 to 0 at the edge.
    /// Exactly 0 elsewhere: 6.5-7.5 % occupied from size 64 up, ~9-10 % at 32 (the `fuel`
    /// dataset has 5.24 %).
    Jet,
    /// 20 blobs of radius 0.09..0.15*size, each centre moving on its own Lissajous path within
    /// the middle 60 % of the volume (time `t`, periods ~6-13 time units). Compactly supported
    /// kernels are summed and mapped to 255*F/(F + 0.5): 170 at an isolated blob's centre,
    /// ~190-220 where blobs overlap, smoothly down to 0 at a blob's edge; exactly 0 away from
    /// all blobs (11-12.5 % occupied).
    Metaballs,
    /// Industrial-CT-like cast part: an L-shaped metal block (a slab and an upright wall within
    /// the middle 60 % of the volume along each axis) with a vertical through-bore. Metal is
    /// 180 with ±6 noise (174..=186). A ~1.5-voxel partial-volume ramp (values rising from 0 to
    /// the metal's) lines its surface and the walls of 8-20 spherical blowholes (radius 2-4
    /// voxels, enclosed in the metal, cores exactly 0; small sizes fit fewer, ~2-3 at 32).
    /// Air and bore are exactly 0 (18-20 % occupied).
    Cast,
    /// Depth-camera fusion: a truncated signed distance volume (TSDF) with per-voxel weights,
    /// as a depth-camera reconstruction builds it. The scene (a sphere and a box moving in front
    /// of a back wall at z = 0.85·(size − 1), [`tsdf_scene_depth`]) is seen by a pinhole depth
    /// camera on the −z side; one depth image per time unit, at times t − ⌊t⌋, …, t − 1, t, is
    /// integrated ([`TsdfFusion`]): only voxels within the truncation distance μ =
    /// max(2, size/32) voxels of the observed surface are touched (running average of sdf/μ,
    /// weight capped at [`TSDF_MAX_WEIGHT`]). Voxel value: 0 where never observed, else
    /// round(128 − 127·tsdf) in 1..=255: 1 at μ in front of the surface, 128 on it, 255 at μ
    /// behind it (the iso-surface is value 128). The seed sets the phases of the motion;
    /// t ≤ 1000 (at t < 0 only the image at t is integrated).
    Tsdf,
    /// Virtual-endoscopy tube: a hollow tube along +y (from face to face) whose centreline
    /// bends sideways, x = (size−1)·(0.5 + 0.2·sin(π·y/(size−1))), z = (size−1)/2. Within
    /// each y-slice the wall spans radii 0.14..0.22·(size−1) from the centreline, value 200
    /// ±10 noise (seeded), with a ~1.5-voxel partial-volume ramp at both surfaces; the lumen
    /// and the outside are exactly 0. Fly through it with `configs/paths/tube.toml`.
    Tube,
}

impl PhantomKind {
    pub const ALL: [PhantomKind; 7] = [
        PhantomKind::Sphere,
        PhantomKind::Shells,
        PhantomKind::Jet,
        PhantomKind::Metaballs,
        PhantomKind::Cast,
        PhantomKind::Tsdf,
        PhantomKind::Tube,
    ];

    /// Name used in specs (`sphere`, `shells`, ...).
    pub fn name(self) -> &'static str {
        match self {
            PhantomKind::Sphere => "sphere",
            PhantomKind::Shells => "shells",
            PhantomKind::Jet => "jet",
            PhantomKind::Metaballs => "metaballs",
            PhantomKind::Cast => "cast",
            PhantomKind::Tsdf => "tsdf",
            PhantomKind::Tube => "tube",
        }
    }

    /// Inverse of [`PhantomKind::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|kind| kind.name() == name)
    }

    /// Whether the seed changes the volume (all but the sphere and the shells).
    pub fn uses_seed(self) -> bool {
        !matches!(self, PhantomKind::Sphere | PhantomKind::Shells)
    }

    /// Whether the time changes the volume (metaballs, TSDF).
    pub fn uses_time(self) -> bool {
        matches!(self, PhantomKind::Metaballs | PhantomKind::Tsdf)
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct PhantomSpec {
    pub kind: PhantomKind,
    pub size: usize,
    pub seed: u64,
    /// Animation time for the metaballs and the TSDF (other phantoms ignore it).
    pub time: f32,
}

impl PhantomSpec {
    /// The kind with the defaults: size 64, seed 1, t 0.
    pub fn default_for(kind: PhantomKind) -> Self {
        PhantomSpec {
            kind,
            size: DEFAULT_SIZE,
            seed: DEFAULT_SEED,
            time: 0.0,
        }
    }

    /// Canonical volume name, e.g. `phantom:sphere:64` or `phantom:metaballs:64:seed=3:t=0.5`.
    /// Only options that change the volume are listed: the seed when it is not the default and
    /// the kind uses it, the time for metaballs and TSDF when not 0. `parse_spec` of the part after
    /// `phantom:` gives a spec generating the same volume.
    pub fn name(&self) -> String {
        let mut name = format!("phantom:{}:{}", self.kind.name(), self.size);
        if self.kind.uses_seed() && self.seed != DEFAULT_SEED {
            name += &format!(":seed={}", self.seed);
        }
        if self.kind.uses_time() && self.time != 0.0 {
            // `{}` prints the shortest text that parses back to the same f32.
            name += &format!(":t={}", self.time);
        }
        name
    }

    fn check(&self) -> std::result::Result<(), String> {
        if !SIZE_RANGE.contains(&self.size) {
            return Err(format!(
                "size {} out of range: must be {}..={}",
                self.size,
                SIZE_RANGE.start(),
                SIZE_RANGE.end()
            ));
        }
        if !self.time.is_finite() {
            return Err(format!("time {} must be finite", self.time));
        }
        if self.kind == PhantomKind::Tsdf && self.time > TSDF_MAX_TIME {
            return Err(format!(
                "time step t={} out of range: the TSDF phantom integrates one depth image per \
                 time unit up to t, so t must be at most {TSDF_MAX_TIME}",
                self.time
            ));
        }
        Ok(())
    }
}

/// Parses the part after `phantom:`, e.g. `sphere:64`, `metaballs:64:t=0.5`, `cast:128:seed=7`.
/// Syntax `KIND[:SIZE][:seed=N][:t=F]`; defaults: size 64, seed 1, t 0. The size, if given,
/// comes right after the kind; `seed=` and `t=` may follow in any order, each at most once.
pub fn parse_spec(text: &str) -> Result<PhantomSpec> {
    let bad = |message: String| Error::Invalid(format!("phantom spec `{text}`: {message}"));
    let mut parts = text.split(':');
    let kind_name = parts.next().unwrap_or_default();
    let kind = PhantomKind::from_name(kind_name).ok_or_else(|| {
        let kinds: Vec<_> = PhantomKind::ALL.iter().map(|k| k.name()).collect();
        bad(format!(
            "unknown kind `{kind_name}`; available: {}",
            kinds.join(", ")
        ))
    })?;
    let mut spec = PhantomSpec::default_for(kind);
    let (mut seed_given, mut time_given) = (false, false);
    for (position, part) in parts.enumerate() {
        match part.split_once('=') {
            None if position == 0 => {
                spec.size = part.parse().map_err(|_| {
                    bad(
                        if !part.is_empty() && part.bytes().all(|b| b.is_ascii_digit()) {
                            format!("size `{part}` is too large")
                        } else {
                            format!("size `{part}` is not a whole number")
                        },
                    )
                })?;
            }
            None => {
                return Err(bad(format!(
                    "unexpected `{part}`: the size comes right after the kind, \
                     then only `seed=N` or `t=F`"
                )))
            }
            // An option the kind ignores would name a second dataset of the same bytes.
            Some(("seed", _)) if !kind.uses_seed() => {
                return Err(bad(format!(
                    "`{part}`: a {kind_name} has no random part; seed= applies to {}",
                    kinds_where(PhantomKind::uses_seed)
                )));
            }
            Some(("t", _)) if !kind.uses_time() => {
                return Err(bad(format!(
                    "`{part}`: a {kind_name} does not change over time; t= applies to {}",
                    kinds_where(PhantomKind::uses_time)
                )));
            }
            Some(("seed", value)) if !seed_given => {
                seed_given = true;
                spec.seed = value
                    .parse()
                    .map_err(|_| bad(format!("`{part}`: seed must be a whole number >= 0")))?;
            }
            Some(("t", value)) if !time_given => {
                time_given = true;
                spec.time = value
                    .parse::<f32>()
                    .ok()
                    .filter(|t| t.is_finite())
                    .ok_or_else(|| bad(format!("`{part}`: t must be a finite number")))?;
            }
            Some((key @ ("seed" | "t"), _)) => {
                return Err(bad(format!("`{key}` given twice")));
            }
            Some((key, _)) => {
                return Err(bad(format!(
                    "unknown option `{key}` in `{part}`; allowed: seed, t"
                )));
            }
        }
    }
    spec.check().map_err(bad)?;
    let voxels = (spec.size as u64).pow(3);
    crate::budget::check(&format!("phantom `{text}`"), voxels * 2)?;
    Ok(spec)
}

/// The kinds for which `uses` holds, for messages.
fn kinds_where(uses: fn(PhantomKind) -> bool) -> String {
    let kinds: Vec<&str> = PhantomKind::ALL
        .into_iter()
        .filter(|&k| uses(k))
        .map(PhantomKind::name)
        .collect();
    kinds.join(", ")
}

/// Generates the phantom. Panics if the size is outside [`SIZE_RANGE`] or the time is not
/// finite (`parse_spec` rejects both).
pub fn generate(spec: &PhantomSpec) -> Volume {
    if let Err(message) = spec.check() {
        panic!("{}: {message}", spec.name());
    }
    let n = spec.size;
    let data = match spec.kind {
        PhantomKind::Sphere => sphere(n),
        PhantomKind::Shells => shells(n),
        PhantomKind::Jet => jet(n, spec.seed),
        PhantomKind::Metaballs => metaballs(n, spec.seed, spec.time as f64),
        PhantomKind::Cast => cast(n, spec.seed),
        PhantomKind::Tsdf => TsdfFusion::at(n, spec.seed, spec.time as f64).values(),
        PhantomKind::Tube => tube(n, spec.seed),
    };
    Volume::new(spec.name(), [n; 3], [1.0; 3], 8, data)
        .expect("generated phantoms have valid dims and 8-bit values")
}

fn sphere(n: usize) -> Vec<u16> {
    let centre = centre(n);
    let radius = 0.4 * n as f64;
    fill_voxels(n, |p| {
        let s = p.distance_squared(centre) / (radius * radius);
        if s < 1.0 {
            to_voxel(250.0 * (1.0 - s))
        } else {
            0
        }
    })
}

/// (radius as a fraction of the size, value), innermost first.
const SHELLS: [(f64, u16); 3] = [(0.14, 220), (0.27, 130), (0.40, 60)];

fn shells(n: usize) -> Vec<u16> {
    let centre = centre(n);
    let half_thickness = (n / 32 + 1) as f64 / 2.0;
    fill_voxels(n, |p| {
        let distance = p.distance(centre);
        SHELLS
            .iter()
            .find(|(fraction, _)| (distance - fraction * n as f64).abs() < half_thickness)
            .map_or(0, |&(_, value)| value)
    })
}

/// Relative amplitude of the noise on the jet's radius.
const JET_WOBBLE: f64 = 0.35;

fn jet(n: usize, seed: u64) -> Vec<u16> {
    let nf = n as f64;
    let axis = centre(n);
    // Floor of 2 voxels so small volumes still have a resolvable nozzle.
    let nozzle_radius = (0.035 * nf).max(2.0);
    // Radius gained from the nozzle to the far face.
    let spread = 0.2 * nf;
    let wobble_key = splitmix64(seed);
    let texture_key = splitmix64(wobble_key);
    fill_slices(n, |z, slice| {
        let u = z as f64 / (nf - 1.0);
        let radius = nozzle_radius + spread * u;
        let reach = radius * (1.0 + JET_WOBBLE);
        let density = 240.0 * (1.0 - 0.75 * u);
        for (y, row) in slice.chunks_mut(n).enumerate() {
            for (x, voxel) in row.iter_mut().enumerate() {
                let p = DVec3::new(x as f64, y as f64, z as f64);
                let rho2 = (p.x - axis.x) * (p.x - axis.x) + (p.y - axis.y) * (p.y - axis.y);
                // Cheap reject: the noise is only worth evaluating near the plume.
                if rho2 >= reach * reach {
                    continue;
                }
                // Noise in fractions of the size, so the plume looks alike at every size.
                let q = p / nf;
                let local_radius = radius * (1.0 + JET_WOBBLE * fbm(wobble_key, q * 6.0));
                let profile = 1.0 - rho2 / (local_radius * local_radius);
                if profile > 0.0 {
                    let texture = 1.0 + 0.15 * fbm(texture_key, q * 14.0);
                    *voxel = to_voxel(density * profile * texture);
                }
            }
        }
    })
}

/// Largest time of the TSDF phantom (one depth image integrated per time unit).
pub const TSDF_MAX_TIME: f32 = 1000.0;
/// Cap of a TSDF voxel's weight: the running average follows a moving surface with a memory
/// of about this many depth images.
pub const TSDF_MAX_WEIGHT: u8 = 8;

/// The TSDF phantom's truncation distance μ in voxels: max(2, size/32).
pub fn tsdf_truncation(n: usize) -> f64 {
    (n as f64 / 32.0).max(2.0)
}

/// The pinhole depth camera of the TSDF phantom: eye at ((n−1)/2, (n−1)/2, −0.75·n) looking
/// along +z, an n×n image with a focal length of 0.75·n pixels (the front face fills it).
fn tsdf_camera(n: usize) -> (DVec3, f64) {
    let s = (n - 1) as f64 / 2.0;
    (DVec3::new(s, s, -0.75 * n as f64), 0.75 * n as f64)
}

/// Sphere (centre, radius) and box (centre, half extents) of the TSDF scene at `time`.
fn tsdf_scene(n: usize, seed: u64, time: f64) -> ((DVec3, f64), (DVec3, DVec3)) {
    let (nf, s) = (n as f64, (n - 1) as f64);
    let mut rng = Rng(seed);
    let phase: [f64; 5] = [(); 5].map(|_| rng.range(0.0, TAU));
    let sphere = DVec3::new(
        s * (0.5 + 0.22 * sin(0.11 * time + phase[0])),
        s * (0.42 + 0.08 * sin(0.07 * time + phase[1])),
        s * (0.45 + 0.1 * sin(0.05 * time + phase[2])),
    );
    let cube = DVec3::new(
        s * (0.5 - 0.2 * sin(0.09 * time + phase[3])),
        s * (0.62 + 0.06 * sin(0.13 * time + phase[4])),
        s * 0.55,
    );
    (
        (sphere, 0.15 * nf),
        (cube, DVec3::new(0.12 * nf, 0.1 * nf, 0.12 * nf)),
    )
}

/// The depth image of the TSDF scene (motion phases from `seed`) at `time`: per pixel (x fastest, n×n) the depth along the
/// camera axis (z − eye.z) of the nearest surface: the sphere, the box or the back wall at
/// z = 0.85·(n − 1), which every ray hits.
pub fn tsdf_scene_depth(n: usize, seed: u64, time: f64) -> Vec<f64> {
    let (eye, focal) = tsdf_camera(n);
    let ((centre, radius), (cube, half)) = tsdf_scene(n, seed, time);
    let wall = 0.85 * (n - 1) as f64 - eye.z;
    let half_image = n as f64 / 2.0;
    let mut depth = vec![0.0; n * n];
    depth.par_chunks_mut(n).enumerate().for_each(|(v, row)| {
        for (u, d) in row.iter_mut().enumerate() {
            // z component 1: the ray parameter is the depth along the axis.
            let dir = DVec3::new(
                (u as f64 + 0.5 - half_image) / focal,
                (v as f64 + 0.5 - half_image) / focal,
                1.0,
            );
            let mut nearest = wall;
            let oc = eye - centre;
            let (a, b, c) = (
                dir.dot(dir),
                2.0 * dir.dot(oc),
                oc.dot(oc) - radius * radius,
            );
            let disc = b * b - 4.0 * a * c;
            if disc >= 0.0 {
                let t = (-b - disc.sqrt()) / (2.0 * a);
                if t > 0.0 && t < nearest {
                    nearest = t;
                }
            }
            let (lo, hi) = (cube - half, cube + half);
            let (mut enter, mut exit) = (0.0f64, f64::INFINITY);
            for axis in 0..3 {
                let (o, dd) = (eye[axis], dir[axis]);
                if dd == 0.0 {
                    if o < lo[axis] || o > hi[axis] {
                        exit = -1.0;
                    }
                } else {
                    let (t1, t2) = ((lo[axis] - o) / dd, (hi[axis] - o) / dd);
                    enter = enter.max(t1.min(t2));
                    exit = exit.min(t1.max(t2));
                }
            }
            if enter <= exit && enter > 0.0 && enter < nearest {
                nearest = enter;
            }
            *d = nearest;
        }
    });
    depth
}

/// Where voxel `p` projects in the TSDF phantom's depth image: the pixel (x fastest) and the
/// voxel's depth along the camera axis; None outside the image.
pub fn tsdf_project(n: usize, p: [usize; 3]) -> Option<(usize, f64)> {
    let (eye, focal) = tsdf_camera(n);
    let depth = p[2] as f64 - eye.z;
    let half_image = n as f64 / 2.0;
    let u = (focal * (p[0] as f64 - eye.x) / depth + half_image).floor();
    let v = (focal * (p[1] as f64 - eye.y) / depth + half_image).floor();
    let inside = |c: f64| c >= 0.0 && c < n as f64;
    (inside(u) && inside(v)).then(|| (v as usize * n + u as usize, depth))
}

/// A depth-camera reconstruction in progress: per voxel a truncated signed distance (in units
/// of μ, positive in front of the surface) and a weight (0: never observed).
#[derive(Clone, Debug)]
pub struct TsdfFusion {
    pub size: usize,
    pub seed: u64,
    tsdf: Vec<f32>,
    weight: Vec<u8>,
}

impl TsdfFusion {
    /// An empty reconstruction (every weight 0).
    pub fn new(n: usize, seed: u64) -> TsdfFusion {
        TsdfFusion {
            size: n,
            seed,
            tsdf: vec![0.0; n * n * n],
            weight: vec![0; n * n * n],
        }
    }

    /// The reconstruction the `phantom:tsdf:N:seed=S:t=T` spec describes: the depth images at
    /// t − ⌊t⌋, …, t − 1, t integrated in that order (only t's when t < 1).
    pub fn at(n: usize, seed: u64, time: f64) -> TsdfFusion {
        let mut fusion = TsdfFusion::new(n, seed);
        let whole = time.floor().max(0.0) as usize;
        for k in (0..=whole).rev() {
            fusion.integrate(time - k as f64);
        }
        fusion
    }

    /// Integrates the depth image of the scene at `time`: every voxel whose projective signed
    /// distance to the observed surface (image depth − voxel depth) lies within ±μ is averaged
    /// in; no other voxel is touched. Returns the touched voxels' indices (x fastest), sorted.
    pub fn integrate(&mut self, time: f64) -> Vec<usize> {
        let n = self.size;
        let depth = tsdf_scene_depth(n, self.seed, time);
        let mu = tsdf_truncation(n);
        let touched: Vec<Vec<usize>> = self
            .tsdf
            .par_chunks_mut(n * n)
            .zip(self.weight.par_chunks_mut(n * n))
            .enumerate()
            .map(|(z, (tsdf, weight))| {
                let mut touched = Vec::new();
                for y in 0..n {
                    for x in 0..n {
                        let Some((pixel, voxel_depth)) = tsdf_project(n, [x, y, z]) else {
                            continue;
                        };
                        let sdf = depth[pixel] - voxel_depth;
                        if sdf.abs() > mu {
                            continue;
                        }
                        let i = y * n + x;
                        let w = weight[i] as f64;
                        let value = (tsdf[i] as f64 * w + sdf / mu) / (w + 1.0);
                        tsdf[i] = value as f32;
                        weight[i] = (weight[i] + 1).min(TSDF_MAX_WEIGHT);
                        touched.push(z * n * n + i);
                    }
                }
                touched
            })
            .collect();
        touched.concat()
    }

    /// The 8-bit voxel of entry `i`: 0 never observed, else round(128 − 127·tsdf).
    pub fn value(&self, i: usize) -> u16 {
        if self.weight[i] == 0 {
            0
        } else {
            to_voxel(128.0 - 127.0 * self.tsdf[i] as f64).max(1)
        }
    }

    /// Every voxel's 8-bit value, x fastest.
    pub fn values(&self) -> Vec<u16> {
        (0..self.tsdf.len()).map(|i| self.value(i)).collect()
    }

    pub fn weight(&self, i: usize) -> u8 {
        self.weight[i]
    }
}

const METABALLS: usize = 20;

fn metaballs(n: usize, seed: u64, time: f64) -> Vec<u16> {
    let balls = metaball_positions(n, seed, time);
    fill_slices(n, |z, slice| {
        let z = z as f64;
        let in_slice: Vec<&Ball> = balls
            .iter()
            .filter(|b| (z - b.centre.z).abs() < b.radius)
            .collect();
        // (squared distance in y and z, ball) for the balls reaching the current row.
        let mut in_row: Vec<(f64, &Ball)> = Vec::with_capacity(METABALLS);
        for (y, row) in slice.chunks_mut(n).enumerate() {
            let y = y as f64;
            in_row.clear();
            in_row.extend(in_slice.iter().filter_map(|&b| {
                let d2 = (y - b.centre.y) * (y - b.centre.y) + (z - b.centre.z) * (z - b.centre.z);
                (d2 < b.radius * b.radius).then_some((d2, b))
            }));
            if in_row.is_empty() {
                continue;
            }
            for (x, voxel) in row.iter_mut().enumerate() {
                let mut field = 0.0;
                for &(d2_yz, b) in &in_row {
                    let dx = x as f64 - b.centre.x;
                    let s = (dx * dx + d2_yz) / (b.radius * b.radius);
                    if s < 1.0 {
                        field += (1.0 - s) * (1.0 - s);
                    }
                }
                // Saturating map: overlaps get brighter but never clip.
                *voxel = to_voxel(255.0 * field / (field + 0.5));
            }
        }
    })
}

/// Ball centres and radii at `time`. The paths depend only on the seed: each coordinate is
/// 0.5 + 0.3*sin(w*t + phase) of the box, with w in 0.5..1 rad per time unit.
fn metaball_positions(n: usize, seed: u64, time: f64) -> Vec<Ball> {
    let scale = (n - 1) as f64;
    let mut rng = Rng(seed);
    (0..METABALLS)
        .map(|_| {
            let radius = rng.range(0.09, 0.15) * n as f64;
            let [x, y, z] = [(); 3].map(|_| {
                let frequency = rng.range(0.5, 1.0);
                let phase = rng.range(0.0, TAU);
                0.5 + 0.3 * sin(frequency * time + phase)
            });
            Ball {
                centre: DVec3::new(x, y, z) * scale,
                radius,
            }
        })
        .collect()
}

/// A sphere in voxel units.
struct Ball {
    centre: DVec3,
    radius: f64,
}

/// Width of the partial-volume ramp at the cast's surfaces, in voxels.
const CAST_EDGE: f64 = 1.5;
/// Fully dense metal kept between a blowhole's ramp and the part's ramp, in voxels.
const CAST_MIN_WALL: f64 = 0.5;

fn cast(n: usize, seed: u64) -> Vec<u16> {
    let part = CastPart::new(n, seed);
    let noise_key = splitmix64(seed);
    fill_voxels(n, |p| {
        let metal = part.metal_fraction(p);
        if metal == 0.0 {
            return 0;
        }
        // Triangular noise in -6..=6, independent per voxel like CT quantum noise.
        let h = hash(noise_key, [p.x as i64, p.y as i64, p.z as i64]);
        let noise = ((h & 0xffff) % 7 + (h >> 16 & 0xffff) % 7) as f64 - 6.0;
        to_voxel(metal * (180.0 + noise))
    })
}

/// The L-shaped part in voxel units: a base slab and an upright wall, minus a vertical bore
/// through the slab and the blowholes.
struct CastPart {
    base: (DVec3, DVec3),
    upright: (DVec3, DVec3),
    bore_axis: (f64, f64),
    bore_radius: f64,
    /// Bounding box (min corner, max corner).
    bounds: (DVec3, DVec3),
    blowholes: Vec<Ball>,
}

impl CastPart {
    fn new(n: usize, seed: u64) -> Self {
        let scale = (n - 1) as f64;
        let at = |x: f64, y: f64, z: f64| DVec3::new(x, y, z) * scale;
        let base = (at(0.2, 0.2, 0.2), at(0.8, 0.8, 0.55));
        let upright = (at(0.2, 0.2, 0.2), at(0.55, 0.8, 0.8));
        let mut part = CastPart {
            base,
            upright,
            bore_axis: (0.65 * scale, 0.5 * scale),
            bore_radius: 0.06 * scale,
            bounds: (base.0.min(upright.0), base.1.max(upright.1)),
            blowholes: Vec::new(),
        };
        // Rejection sampling: a hole is kept only if its ramp ends at least CAST_MIN_WALL
        // inside the part's ramp and it keeps clear of earlier holes, so every hole is a void
        // enclosed in metal. Small volumes may fit fewer holes than drawn.
        let mut rng = Rng(seed);
        let wanted = 8 + (rng.next_u64() % 13) as usize;
        let (low, high) = part.bounds;
        for _ in 0..200 * wanted {
            if part.blowholes.len() == wanted {
                break;
            }
            let radius = rng.range(2.0, 4.0);
            let centre = DVec3::new(
                rng.range(low.x, high.x),
                rng.range(low.y, high.y),
                rng.range(low.z, high.z),
            );
            let enclosed = part.solid_distance(centre) <= -(radius + CAST_EDGE + CAST_MIN_WALL);
            let clear = part
                .blowholes
                .iter()
                .all(|h| h.centre.distance(centre) >= h.radius + radius + 2.0 * CAST_EDGE);
            if enclosed && clear {
                part.blowholes.push(Ball { centre, radius });
            }
        }
        part
    }

    /// Fraction of the voxel at `p` that is metal, with a CAST_EDGE-wide ramp at the part's
    /// surface and at the blowholes' walls.
    fn metal_fraction(&self, p: DVec3) -> f64 {
        // Cheap reject: the ramp ends within CAST_EDGE of the bounding box.
        let (low, high) = self.bounds;
        if (p - low).min_element() < -CAST_EDGE || (p - high).max_element() > CAST_EDGE {
            return 0.0;
        }
        let mut distance = self.solid_distance(p);
        // A hole matters only where its ramp reaches: deeper than CAST_EDGE/2 inside the
        // metal the fraction is 1 anyway.
        for hole in &self.blowholes {
            let reach = hole.radius + CAST_EDGE / 2.0;
            let d2 = p.distance_squared(hole.centre);
            if d2 < reach * reach {
                distance = distance.max(hole.radius - d2.sqrt());
            }
        }
        inside_fraction(distance, CAST_EDGE)
    }

    /// Signed distance to the part without its blowholes. Unions (min) and differences (max)
    /// of exact distances under-estimate the depth inside, which keeps the blowhole placement
    /// conservative.
    fn solid_distance(&self, p: DVec3) -> f64 {
        let block = box_distance(p, self.base).min(box_distance(p, self.upright));
        let (dx, dy) = (p.x - self.bore_axis.0, p.y - self.bore_axis.1);
        let bore = (dx * dx + dy * dy).sqrt() - self.bore_radius;
        block.max(-bore)
    }
}

/// Signed Euclidean distance to the box (min corner, max corner).
fn box_distance(p: DVec3, (min, max): (DVec3, DVec3)) -> f64 {
    let q = (p - (min + max) * 0.5).abs() - (max - min) * 0.5;
    q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
}

/// The tube's centreline x at slice y, and its wall radii, as fractions of size − 1.
pub const TUBE_BEND: f64 = 0.2;
pub const TUBE_RADII: (f64, f64) = (0.14, 0.22);

/// Centreline of the tube phantom at y (fractions of size − 1): (x, z).
pub fn tube_centre(y: f64) -> (f64, f64) {
    (0.5 + TUBE_BEND * (std::f64::consts::PI * y).sin(), 0.5)
}

fn tube(n: usize, seed: u64) -> Vec<u16> {
    let m = (n - 1) as f64;
    let key = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ 0x7475_6265;
    fill_voxels(n, |p| {
        let (cx, cz) = tube_centre(p.y / m);
        let d = ((p.x - cx * m).powi(2) + (p.z - cz * m).powi(2)).sqrt();
        let sd = (TUBE_RADII.0 * m - d).max(d - TUBE_RADII.1 * m);
        let inside = inside_fraction(sd, 1.5);
        if inside <= 0.0 {
            return 0;
        }
        let noise = 10.0 * value_noise(key, p * 0.5);
        to_voxel(((200.0 + noise) * inside).max(1.0))
    })
}

/// How much of a voxel at signed distance `sd` lies inside: 1 deep inside, 0 outside, a linear
/// ramp `width` wide across the surface (partial-volume blur).
fn inside_fraction(sd: f64, width: f64) -> f64 {
    (0.5 - sd / width).clamp(0.0, 1.0)
}

fn centre(n: usize) -> DVec3 {
    DVec3::splat((n - 1) as f64 / 2.0)
}

fn to_voxel(value: f64) -> u16 {
    value.round().clamp(0.0, 255.0) as u16
}

/// Allocates an n^3 volume and lets `fill(z, slice)` write each z-slice (x fastest), slices
/// in parallel. Each slice is computed on its own, so the result is thread-count independent.
fn fill_slices(n: usize, fill: impl Fn(usize, &mut [u16]) + Sync) -> Vec<u16> {
    let mut data = vec![0u16; n * n * n];
    data.par_chunks_mut(n * n)
        .enumerate()
        .for_each(|(z, slice)| fill(z, slice));
    data
}

/// `fill_slices` with one function per voxel position.
fn fill_voxels(n: usize, voxel: impl Fn(DVec3) -> u16 + Sync) -> Vec<u16> {
    fill_slices(n, |z, slice| {
        for (y, row) in slice.chunks_mut(n).enumerate() {
            for (x, value) in row.iter_mut().enumerate() {
                *value = voxel(DVec3::new(x as f64, y as f64, z as f64));
            }
        }
    })
}

/// Three octaves of value noise, in [-1, 1].
fn fbm(key: u64, p: DVec3) -> f64 {
    let octaves = value_noise(key, p) + 0.5 * value_noise(key, p * 2.0);
    (octaves + 0.25 * value_noise(key, p * 4.0)) / 1.75
}

/// Smooth noise in [-1, 1]: seeded random values at integer lattice points, blended
/// trilinearly with smoothstep weights.
fn value_noise(key: u64, p: DVec3) -> f64 {
    let cell = p.floor();
    let (x, y, z) = (cell.x as i64, cell.y as i64, cell.z as i64);
    let f = p - cell;
    let w = f * f * (DVec3::splat(3.0) - 2.0 * f);
    let corner = |dx, dy, dz| unit(hash(key, [x + dx, y + dy, z + dz])) * 2.0 - 1.0;
    let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
    let along_x = |dy, dz| lerp(corner(0, dy, dz), corner(1, dy, dz), w.x);
    let near = lerp(along_x(0, 0), along_x(1, 0), w.y);
    let far = lerp(along_x(0, 1), along_x(1, 1), w.y);
    lerp(near, far, w.z)
}

/// sin(x) from a fixed polynomial (reduction to [-pi/2, pi/2], Taylor series to x^11, error
/// < 1e-7), identical on every platform unlike libm's.
fn sin(x: f64) -> f64 {
    let mut r = x - TAU * (x / TAU).round();
    if r > FRAC_PI_2 {
        r = PI - r;
    } else if r < -FRAC_PI_2 {
        r = -PI - r;
    }
    let r2 = r * r;
    r * (1.0
        + r2 * (-1.0 / 6.0
            + r2 * (1.0 / 120.0
                + r2 * (-1.0 / 5040.0 + r2 * (1.0 / 362_880.0 - r2 / 39_916_800.0)))))
}

const GOLDEN_GAMMA: u64 = 0x9e37_79b9_7f4a_7c15;

/// SplitMix64's output function: a strong 64-bit mix of `x`.
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(GOLDEN_GAMMA);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Hash of a key and a lattice / voxel position: the coordinates are combined with distinct
/// large odd multipliers, then mixed once (one mix per call keeps the jet's noise cheap).
fn hash(key: u64, [x, y, z]: [i64; 3]) -> u64 {
    let combined = (x as u64)
        .wrapping_mul(0x9e37_79b1_85eb_ca87)
        .wrapping_add((y as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f))
        .wrapping_add((z as u64).wrapping_mul(0x1656_67b1_9e37_79f9));
    splitmix64(key ^ combined)
}

/// Uniform in [0, 1) from the top 53 bits.
fn unit(bits: u64) -> f64 {
    (bits >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Sequential SplitMix64 generator for per-phantom parameters (ball paths, blowholes).
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(GOLDEN_GAMMA);
        splitmix64(self.0)
    }

    fn range(&mut self, low: f64, high: f64) -> f64 {
        low + (high - low) * unit(self.next_u64())
    }
}

//! Renderers that produce a frame: the float reference (`float`) and, later, the functional
//! fixed-point model. Both place samples by the same convention (see `sample_range`) so that
//! they sample the same points up to quantisation.

pub mod float;

use std::path::Path;

use crate::camera::Ray;
use crate::error::{Error, Result};

/// Settings shared by every renderer.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RenderSettings {
    /// Distance between samples along a ray, in voxels (1.0 = one sample per voxel distance).
    pub sample_spacing: f32,
    /// Early ray termination: stop a ray once its accumulated opacity reaches this; None = off.
    pub ert_threshold: Option<f32>,
    /// Phong shading from gradients (one headlight).
    pub shading: bool,
    /// Background colour and opacity, composited behind every ray.
    pub background: [f32; 4],
    /// Interleaved sampling: the N of the N×N pattern of first-sample offsets
    /// (`camera::interleave_ray`); 1 = off. Written out only when not 1.
    #[serde(skip_serializing_if = "is_one")]
    pub interleave: u32,
}

fn is_one(n: &u32) -> bool {
    *n == 1
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            sample_spacing: 1.0,
            ert_threshold: Some(0.95),
            shading: false,
            background: [0.0, 0.0, 0.0, 1.0],
            interleave: 1,
        }
    }
}

impl RenderSettings {
    pub fn validate(&self) -> Result<()> {
        if !(self.sample_spacing.is_finite() && (1.0 / 64.0..=16.0).contains(&self.sample_spacing))
        {
            return Err(Error::Invalid(format!(
                "sample spacing {}: allowed 1/64..=16 voxels",
                self.sample_spacing
            )));
        }
        if let Some(t) = self.ert_threshold {
            if !(t > 0.0 && t <= 1.0) {
                return Err(Error::Invalid(format!("ERT threshold {t}: allowed (0, 1]")));
            }
        }
        if !(1..=crate::camera::MAX_INTERLEAVE).contains(&self.interleave) {
            return Err(Error::Invalid(format!(
                "interleave {}: the pattern is N×N with N in 1..={} (1 = off)",
                self.interleave,
                crate::camera::MAX_INTERLEAVE
            )));
        }
        if self.background.iter().any(|c| !(0.0..=1.0).contains(c)) {
            return Err(Error::Invalid(format!(
                "background {:?}: each component allowed 0..=1",
                self.background
            )));
        }
        Ok(())
    }
}

/// What happened to one ray.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct RayRecord {
    /// The ray meets the volume's sampling box and has at least one sample inside it (between
    /// its start and end, when bricks, clipping or geometry set them).
    pub hit: bool,
    /// Samples taken (interpolated, classified and composited), leap samples included.
    pub samples: u32,
    /// Leap steps: issue slots in which the ray took no sample and jumped ahead (fixed-point
    /// model, `skip.policy = "leap-only"`; always 0 with "sample-then-leap").
    pub leaps: u32,
    /// Sample positions passed over by leaps (never sampled).
    pub skipped: u32,
    /// Samples followed by a leap (`skip.policy = "sample-then-leap"`: the sample taken in an
    /// empty sub-cube before leaping on); included in `samples`.
    pub leap_samples: u32,
    /// Index k of the first sample (t = k·S) and one past the last; equal when no sample.
    pub first_sample: i64,
    pub end_sample: i64,
    /// Ray parameter (voxels) where the ray enters and leaves the box (clipped to the near plane).
    pub t_enter: f32,
    pub t_exit: f32,
    /// Stopped by early ray termination before its last sample.
    pub terminated_early: bool,
    /// Sample positions inside the box that the ray's start and end (bricks, clipping,
    /// geometry) removed; `first_sample..end_sample` is what remains. Not written when 0.
    #[serde(skip_serializing_if = "is_zero")]
    pub positions_cut: u32,
    /// Iso mode: bisection samples refining the ray's hit (included in `samples`). Not
    /// written when 0.
    #[serde(skip_serializing_if = "is_zero")]
    pub refinement_samples: u32,
}

fn is_zero(n: &u32) -> bool {
    *n == 0
}

/// Totals over a frame.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct FrameStats {
    pub rays: u64,
    pub rays_hit: u64,
    pub samples: u64,
    pub leaps: u64,
    /// Sample positions passed over by leaps.
    pub skipped: u64,
    /// Samples followed by a leap (sample-then-leap); included in `samples`.
    pub leap_samples: u64,
    pub rays_terminated_early: u64,
    /// Iso mode: refinement samples (included in `samples`). Not written when 0.
    #[serde(skip_serializing_if = "is_zero_u64")]
    pub refinement_samples: u64,
}

fn is_zero_u64(n: &u64) -> bool {
    *n == 0
}

impl FrameStats {
    /// Issue steps: one per sample and one per leap (the published cost unit). A leap that
    /// follows a sample (sample-then-leap) costs no slot of its own.
    pub fn steps(&self) -> u64 {
        self.samples + self.leaps
    }

    pub fn from_records(records: &[RayRecord]) -> Self {
        let mut s = FrameStats {
            rays: records.len() as u64,
            ..Default::default()
        };
        for r in records {
            s.rays_hit += r.hit as u64;
            s.samples += r.samples as u64;
            s.leaps += r.leaps as u64;
            s.skipped += r.skipped as u64;
            s.leap_samples += r.leap_samples as u64;
            s.rays_terminated_early += r.terminated_early as u64;
            s.refinement_samples += r.refinement_samples as u64;
        }
        s
    }
}

/// An RGBA8 image with one record per ray (row-major, top row first).
#[derive(Clone, Debug)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[u8; 4]>,
    pub rays: Vec<RayRecord>,
}

impl Frame {
    pub fn stats(&self) -> FrameStats {
        FrameStats::from_records(&self.rays)
    }

    pub fn rgba_bytes(&self) -> Vec<u8> {
        self.pixels.iter().flatten().copied().collect()
    }

    /// Writes one CSV row per ray (row-major pixels), atomically.
    pub fn write_rays_csv(&self, path: &Path) -> Result<()> {
        crate::output::write_atomically(path, |w| {
            use std::io::Write;
            writeln!(
                w,
                "px,py,hit,samples,leaps,skipped,first_sample,end_sample,t_enter,t_exit,terminated_early,leap_samples,positions_cut,refinement_samples"
            )?;
            for (i, r) in self.rays.iter().enumerate() {
                let (px, py) = (i as u32 % self.width, i as u32 / self.width);
                writeln!(
                    w,
                    "{px},{py},{},{},{},{},{},{},{},{},{},{},{},{}",
                    r.hit as u8,
                    r.samples,
                    r.leaps,
                    r.skipped,
                    r.first_sample,
                    r.end_sample,
                    r.t_enter,
                    r.t_exit,
                    r.terminated_early as u8,
                    r.leap_samples,
                    r.positions_cut,
                    r.refinement_samples
                )?;
            }
            Ok(())
        })
    }

    /// Writes a PNG atomically: to a temporary file beside `path`, then renamed, so a failure
    /// never leaves a half-written image.
    pub fn write_png(&self, path: &Path) -> Result<()> {
        let img = image::RgbaImage::from_raw(self.width, self.height, self.rgba_bytes())
            .ok_or_else(|| {
                Error::Invalid("frame buffer size does not match its dimensions".into())
            })?;
        crate::output::write_atomically(path, |file| {
            img.write_to(file, image::ImageFormat::Png)
                .map_err(std::io::Error::other)
        })
    }
}

/// Renders a frame by calling `cast(px, py)` for every pixel, rows in parallel (rayon). Each
/// pixel depends only on its own inputs, so the frame is bit-identical for any thread count.
pub fn render_frame(
    width: u32,
    height: u32,
    cast: impl Fn(u32, u32) -> ([u8; 4], RayRecord) + Sync,
) -> Frame {
    render_rows(width, height, |py, pixels, rays| {
        for (px, (pixel, ray)) in pixels.iter_mut().zip(rays).enumerate() {
            (*pixel, *ray) = cast(px as u32, py);
        }
    })
}

/// Renders a frame by calling `cast_row(py, pixels, records)` for every row, rows in parallel
/// (rayon); for renderers that cast several pixels of a row together.
pub fn render_rows(
    width: u32,
    height: u32,
    cast_row: impl Fn(u32, &mut [[u8; 4]], &mut [RayRecord]) + Sync,
) -> Frame {
    use rayon::prelude::*;
    let mut pixels = vec![[0u8; 4]; (width * height) as usize];
    let mut rays = vec![RayRecord::default(); (width * height) as usize];
    pixels
        .par_chunks_mut(width as usize)
        .zip(rays.par_chunks_mut(width as usize))
        .enumerate()
        .for_each(|(py, (pixel_row, ray_row))| cast_row(py as u32, pixel_row, ray_row));
    Frame {
        width,
        height,
        pixels,
        rays,
    }
}

/// Where a ray meets the box [0, dims-1]^3 (slab method), clipped to `ray.t_min`.
/// Returns (t_enter, t_exit) with t_enter <= t_exit, or None when it misses.
pub fn clip_to_box(ray: &Ray, dims: [usize; 3]) -> Option<(f32, f32)> {
    let mut t0 = ray.t_min;
    let mut t1 = f32::INFINITY;
    for axis in 0..3 {
        let o = ray.origin[axis];
        let d = ray.dir[axis];
        let hi = (dims[axis] - 1) as f32;
        if d == 0.0 {
            if o < 0.0 || o > hi {
                return None;
            }
            continue;
        }
        let (mut a, mut b) = ((0.0 - o) / d, (hi - o) / d);
        if a > b {
            std::mem::swap(&mut a, &mut b);
        }
        t0 = t0.max(a);
        t1 = t1.min(b);
    }
    (t0 <= t1).then_some((t0, t1))
}

/// Sample placement convention: samples sit at t = k·S for integer k (S the sample spacing),
/// i.e. on a grid fixed to the camera, and a ray takes every such sample inside the box.
/// Returns the half-open range of k for [t_enter, t_exit].
pub fn sample_range(t_enter: f32, t_exit: f32, spacing: f32) -> (i64, i64) {
    let first = (t_enter / spacing).ceil() as i64;
    let last = (t_exit / spacing).floor() as i64;
    (first, (last + 1).max(first))
}

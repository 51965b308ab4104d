//! The float reference ray caster: the mathematically intended image.
//!
//! Per ray: clip to the box [0, dims-1]^3, take the samples t = k·S inside it (see
//! `super::sample_range`), and per sample: trilinear interpolation of the 8 neighbouring voxels,
//! classification by the transfer function (linear between table entries at integer
//! densities), opacity corrected for the spacing, optional Phong shading, front-to-back
//! compositing `C += (1-A)·a·c, A += (1-A)·a`, and early ray termination once A >= threshold.
//! Finally the background is composited behind: `out = C + (1-A)·bg`.
//!
//! Each pixel is computed independently, so the image is bit-identical whatever the number of
//! rayon threads.

use std::borrow::Cow;

use glam::{Vec3A, Vec4};

use super::{clip_to_box, render_frame, sample_range, Frame, RayRecord, RenderSettings};
use crate::bricks::FloatRange;
use crate::camera::interleave_ray;
use crate::camera::{Camera, Ray};
use crate::config::{HardwareConfig, LeapRegions};
use crate::error::Result;
use crate::iso::IsoSurface;
use crate::leapvalues::LeapValueVolume;
use crate::shading::{phong_float, voxel_gradient};
use crate::transfer::{correct_opacity, TransferFunction};
use crate::volume::Volume;

/// Everything a ray needs, prepared once per frame.
pub struct FloatRenderer<'a> {
    /// The volume sampled: the dataset, or with homogeneous leap values its density fields.
    volume: Cow<'a, Volume>,
    /// Transfer function at every integer density, plus one extra copy of the last entry so
    /// that interpolation at the top density needs no branch.
    table: Vec<Vec4>,
    settings: RenderSettings,
    /// Ray start and end (bricks, clipping, geometry); None when off.
    ray_range: Option<Box<FloatRange>>,
    /// Homogeneous leap values: the ray follows the same region protocol as the fixed-point
    /// model (lossy by design). Empty-region leaping only skips zero-opacity samples, so the
    /// reference does not need it.
    leap_values: Option<LeapValueVolume>,
    /// Iso-surface mode (`[iso]`): first hit, f32 bisection, shaded surface.
    iso: Option<IsoSurface>,
}

impl<'a> FloatRenderer<'a> {
    pub fn new(
        volume: &'a Volume,
        tf: &TransferFunction,
        settings: &RenderSettings,
    ) -> Result<Self> {
        settings.validate()?;
        let entries = volume.max_value() as usize + 1;
        let mut table: Vec<Vec4> = tf
            .sample_table(entries)
            .into_iter()
            .map(Vec4::from_array)
            .collect();
        table.push(table[entries - 1]);
        Ok(FloatRenderer {
            volume: Cow::Borrowed(volume),
            table,
            settings: settings.clone(),
            ray_range: None,
            leap_values: None,
            iso: None,
        })
    }

    /// Adds the configuration's iso-surface mode (`[iso]`), when on; before
    /// `with_ray_range`, so that bricks see the iso table (opacity 0 below the iso value, 1 at
    /// and above it).
    pub fn with_iso(mut self, config: &HardwareConfig) -> Result<Self> {
        self.iso = IsoSurface::from_config(config, &self.volume)?;
        if let Some(iso) = &self.iso {
            let first = iso.first_opaque();
            let c = iso.colour;
            for (i, e) in self.table.iter_mut().enumerate() {
                *e = if i >= first {
                    Vec4::new(c[0], c[1], c[2], 1.0)
                } else {
                    Vec4::ZERO
                };
            }
        }
        Ok(self)
    }

    /// Adds the configuration's ray start and end (`[bricks]`, `[clip]`, `[geometry]`); after
    /// `with_leap_values`, so that bricks see the densities the reference samples.
    pub fn with_ray_range(mut self, config: &HardwareConfig) -> Result<Self> {
        self.ray_range = FloatRange::from_config(&self.volume, config, &self.table)?.map(Box::new);
        Ok(self)
    }

    /// The reference with homogeneous leap values (`leap_values.regions = "homogeneous"`):
    /// it samples the density fields and follows the region protocol of the fixed-point model
    /// (docs/model.md). Other leap-value volumes are ignored: they change no image.
    pub fn with_leap_values(mut self, leap_values: LeapValueVolume) -> Self {
        if leap_values.regions == LeapRegions::Homogeneous {
            if let Some(densities) = leap_values.densities.clone() {
                self.volume = Cow::Owned(densities);
            }
            self.leap_values = Some(leap_values);
        }
        self
    }

    /// Homogeneous leap values: what preprocessing found.
    pub fn leap_value_stats(&self) -> Option<crate::leapvalues::LeapValueStats> {
        self.leap_values.as_ref().map(|l| l.stats)
    }

    pub fn render(&self, camera: &Camera) -> Frame {
        render_frame(camera.width, camera.height, |px, py| {
            let ray = camera.voxel_ray(px, py, self.volume.spacing);
            let ray = interleave_ray(ray, px, py, &self.settings);
            self.cast_pixel(&ray, (px, py))
        })
    }

    /// Casts one ray; returns the final pixel and what the ray did.
    pub fn cast(&self, ray: &Ray) -> ([u8; 4], RayRecord) {
        self.cast_pixel(ray, (0, 0))
    }

    /// Casts the ray of pixel (px, py) (the pixel matters only for a depth image).
    pub fn cast_pixel(&self, ray: &Ray, pixel: (u32, u32)) -> ([u8; 4], RayRecord) {
        let mut record = RayRecord::default();
        // Accumulated (R, G, B, A): a sample of colour c and opacity a adds (1 - A)·a·(c, 1).
        let mut acc = Vec4::ZERO;
        let mut surface = None;
        if let Some((t_enter, t_exit)) = clip_to_box(ray, self.volume.dims) {
            let s = self.settings.sample_spacing;
            let (mut first, mut end) = sample_range(t_enter, t_exit, s);
            // Iso refinement reaches back to first - 1 when only bricks cut it.
            let mut refine_from = first;
            if let Some(range) = &self.ray_range {
                // The same positions as the loop below computes.
                let l = range.limits(ray, pixel, s, first, end, |k| {
                    ray.origin + ray.dir * (k as f32 * s)
                });
                record.positions_cut = ((end - first) - (l.end - l.first)) as u32;
                (first, end, surface) = (l.first, l.end, l.surface);
                refine_from = l.scene_first;
            }
            record.t_enter = t_enter;
            record.t_exit = t_exit;
            record.first_sample = first;
            record.end_sample = end;
            record.hit = end > first;
            let threshold = self.settings.ert_threshold.unwrap_or(f32::INFINITY);
            if let Some(iso) = &self.iso {
                self.march_iso(ray, iso, (first, refine_from), end, &mut acc, &mut record);
                return self.finish(acc, record, ray, pixel, surface);
            }
            if let Some(words) = &self.leap_values {
                self.march_regions(ray, words, first, end, &mut acc, &mut record);
                return self.finish(acc, record, ray, pixel, surface);
            }
            for k in first..end {
                let p = ray.origin + ray.dir * (k as f32 * s);
                let rgba = self.classify(p, ray.dir);
                record.samples += 1;
                let a = if s == 1.0 {
                    rgba.w
                } else {
                    correct_opacity(rgba.w, s)
                };
                acc += (1.0 - acc.w) * a * rgba.truncate().extend(1.0);
                if acc.w >= threshold {
                    record.terminated_early = k + 1 < end;
                    break;
                }
            }
        }
        self.finish(acc, record, ray, pixel, surface)
    }

    /// The pixel: the opaque surface (geometry) or the background composited behind the
    /// accumulated colour.
    fn finish(
        &self,
        acc: Vec4,
        record: RayRecord,
        ray: &Ray,
        pixel: (u32, u32),
        mut surface: Option<[f32; 4]>,
    ) -> ([u8; 4], RayRecord) {
        if let (None, Some(scene)) = (surface, self.ray_range.as_ref().and_then(|r| r.scene())) {
            // A ray that misses the volume (or has no sample in it) still meets the geometry.
            surface = scene
                .limits(ray, pixel.0, pixel.1, self.settings.sample_spacing)
                .surface;
        }
        let bg = Vec4::from_array(surface.unwrap_or(self.settings.background));
        let out = acc + (1.0 - acc.w) * bg;
        (
            [to_u8(out.x), to_u8(out.y), to_u8(out.z), to_u8(out.w)],
            record,
        )
    }

    /// Iso mode: samples k in first..end until the first whose density is at least the iso
    /// value; when k > refine_from (k - 1 is in the box and not cut by clipping or geometry;
    /// bricks may have cut it), `refinement_steps` f32 bisections of t between the sample before
    /// and the hit; the surface colour shaded at the upper end of the interval, opaque.
    fn march_iso(
        &self,
        ray: &Ray,
        iso: &IsoSurface,
        (first, refine_from): (i64, i64),
        end: i64,
        acc: &mut Vec4,
        record: &mut RayRecord,
    ) {
        let s = self.settings.sample_spacing;
        let v = iso.value as f32;
        let at = |t: f32| ray.origin + ray.dir * t;
        for k in first..end {
            let mut hi = k as f32 * s;
            record.samples += 1;
            if self.interpolate(at(hi)) < v {
                continue;
            }
            if k > refine_from {
                let mut lo = (k - 1) as f32 * s;
                for _ in 0..iso.refinement_steps {
                    let mid = 0.5 * (lo + hi);
                    record.samples += 1;
                    record.refinement_samples += 1;
                    if self.interpolate(at(mid)) >= v {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                }
            }
            let (diffuse, specular) = self.phong(at(hi), ray.dir);
            let lit = (glam::Vec3::from_array(iso.colour) * diffuse + glam::Vec3::splat(specular))
                .min(glam::Vec3::ONE);
            *acc = lit.extend(1.0);
            record.terminated_early = self.settings.ert_threshold.is_some() && k + 1 < end;
            return;
        }
    }

    /// The iso hit of a ray at sample index `k` refined as `march_iso` does: its ray parameter
    /// t (for tests: it lies in [(k - 1)·S, k·S]). None when the sample at k is below the value.
    pub fn iso_hit_t(&self, ray: &Ray, k: i64, first: i64) -> Option<f32> {
        let iso = self.iso.as_ref()?;
        let s = self.settings.sample_spacing;
        let v = iso.value as f32;
        let at = |t: f32| ray.origin + ray.dir * t;
        let mut hi = k as f32 * s;
        if self.interpolate(at(hi)) < v {
            return None;
        }
        if k > first {
            let mut lo = (k - 1) as f32 * s;
            for _ in 0..iso.refinement_steps {
                let mid = 0.5 * (lo + hi);
                if self.interpolate(at(mid)) >= v {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
        }
        Some(hi)
    }

    /// Samples k in first..end with homogeneous leap values: the fixed-point model's region
    /// protocol (`functional::leaping::LeapValueLeaping`) on float positions. A region value
    /// standing for j positions composites with opacity 1 - (1 - a_S)^j.
    fn march_regions(
        &self,
        ray: &Ray,
        words: &LeapValueVolume,
        first: i64,
        end: i64,
        acc: &mut Vec4,
        record: &mut RayRecord,
    ) {
        let s = self.settings.sample_spacing;
        let threshold = self.settings.ert_threshold.unwrap_or(f32::INFINITY);
        let d = words.dims;
        let word_at = |v: [usize; 3]| words.layout.decode(words.words[words.index(v)]);
        let mut region: Option<u16> = None;
        let mut k = first;
        while k < end {
            let p = ray.origin + ray.dir * (k as f32 * s);
            let nearest = [0, 1, 2].map(|a| {
                let x = p[a].clamp(0.0, (d[a] - 1) as f32);
                ((x + 0.5).floor() as usize).min(d[a] - 1)
            });
            let w = word_at(nearest);
            let in_region = match (region, w.leap) {
                (Some(_), Some(l)) => Some((w.density, l.max(1))),
                (Some(m), None) if w.density == m => Some((m, 1)),
                _ => None,
            };
            let (rgba, steps) = match in_region {
                Some((m, steps)) => {
                    region = Some(m);
                    (self.classify_density(m as f32, p, ray.dir), steps)
                }
                None => {
                    // Trilinear mode: enter region mode at a flagged nearest word or eight
                    // identical unflagged words.
                    region = if w.leap.is_some() {
                        Some(w.density)
                    } else {
                        let base = [0, 1, 2]
                            .map(|a| (p[a].clamp(0.0, (d[a] - 1) as f32) as usize).min(d[a] - 2));
                        let first_word = words.words[words.index(base)];
                        (0..8)
                            .all(|c| {
                                let v = [
                                    base[0] + (c & 1),
                                    base[1] + ((c >> 1) & 1),
                                    base[2] + (c >> 2),
                                ];
                                words.words[words.index(v)] == first_word
                            })
                            .then_some(w.density)
                    };
                    (self.classify(p, ray.dir), 1)
                }
            };
            let steps = (steps as i64).min(end - k);
            record.samples += 1;
            record.skipped += steps as u32 - 1;
            let a = if s == 1.0 {
                rgba.w
            } else {
                correct_opacity(rgba.w, s)
            };
            let a = if steps > 1 {
                1.0 - (1.0 - a).powi(steps as i32)
            } else {
                a
            };
            *acc += (1.0 - acc.w) * a * rgba.truncate().extend(1.0);
            if acc.w >= threshold {
                record.terminated_early = k + steps < end;
                break;
            }
            k += steps;
        }
    }

    /// Colour and per-voxel opacity of the sample at `p` (voxel space, inside the box).
    #[inline(always)]
    fn classify(&self, p: Vec3A, dir: Vec3A) -> Vec4 {
        self.classify_density(self.interpolate(p), p, dir)
    }

    /// Colour and per-voxel opacity of density `v` at `p`; shading uses the gradient at `p`.
    #[inline(always)]
    fn classify_density(&self, v: f32, p: Vec3A, dir: Vec3A) -> Vec4 {
        let i = v as usize; // v >= 0: truncation is floor
        let f = v - i as f32;
        let (a, b) = (self.table[i], self.table[i + 1]);
        let rgba = a + (b - a) * f;
        if self.settings.shading && rgba.w > 0.0 {
            let (diffuse, specular) = self.phong(p, dir);
            let lit =
                (rgba.truncate() * diffuse + glam::Vec3::splat(specular)).min(glam::Vec3::ONE);
            return lit.extend(rgba.w);
        }
        rgba
    }

    /// Trilinear interpolation; positions are clamped into the box so that rounding at its
    /// faces cannot read outside the volume.
    #[inline(always)]
    pub fn interpolate(&self, p: Vec3A) -> f32 {
        let d = self.volume.dims;
        let mut base = [0usize; 3];
        let mut frac = [0f32; 3];
        for axis in 0..3 {
            let hi = (d[axis] - 1) as f32;
            let x = p[axis].clamp(0.0, hi);
            // The lower corner stays <= dim-2 so the +1 neighbour exists; at x = dim-1, frac = 1.
            let b = (x as usize).min(d[axis] - 2);
            base[axis] = b;
            frac[axis] = x - b as f32;
        }
        let data = &self.volume.data;
        let sx = 1;
        let sy = d[0];
        let sz = d[0] * d[1];
        let i0 = base[0] + sy * base[1] + sz * base[2];
        let v = |i: usize| data[i] as f32;
        let c00 = lerp(v(i0), v(i0 + sx), frac[0]);
        let c10 = lerp(v(i0 + sy), v(i0 + sy + sx), frac[0]);
        let c01 = lerp(v(i0 + sz), v(i0 + sz + sx), frac[0]);
        let c11 = lerp(v(i0 + sz + sy), v(i0 + sz + sy + sx), frac[0]);
        lerp(lerp(c00, c10, frac[1]), lerp(c01, c11, frac[1]), frac[2])
    }

    /// (diffuse factor, specular term): the per-voxel gradients of the 8 neighbours,
    /// interpolated with the sample's weights (see `shading`).
    fn phong(&self, p: Vec3A, dir: Vec3A) -> (f32, f32) {
        let d = self.volume.dims;
        let mut base = [0usize; 3];
        let mut frac = [0f32; 3];
        for axis in 0..3 {
            let x = p[axis].clamp(0.0, (d[axis] - 1) as f32);
            base[axis] = (x as usize).min(d[axis] - 2);
            frac[axis] = x - base[axis] as f32;
        }
        let mut g = Vec3A::ZERO;
        for corner in 0..8 {
            let offset = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
            let weight: f32 = (0..3)
                .map(|a| {
                    if offset[a] == 1 {
                        frac[a]
                    } else {
                        1.0 - frac[a]
                    }
                })
                .product();
            let v = voxel_gradient(
                &self.volume,
                base[0] + offset[0],
                base[1] + offset[1],
                base[2] + offset[2],
            );
            g += weight * Vec3A::from_array(v);
        }
        phong_float(g, dir)
    }
}

#[inline(always)]
fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + t * (b - a)
}

#[inline]
fn to_u8(x: f32) -> u8 {
    (x.clamp(0.0, 1.0) * 255.0).round() as u8
}

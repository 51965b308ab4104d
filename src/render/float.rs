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
//! rayon threads. Rays of neighbouring pixels are marched in packets (`PACKET_WIDTHS`): one ray
//! per lane, every lane performing the scalar code's f32 operations in the same order, so the
//! image is also bit-identical whatever the packet width.

use std::borrow::Cow;

use glam::{Vec3A, Vec4};

use super::{clip_to_box, render_rows, sample_range, Frame, RayRecord, RenderSettings};
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
    /// The volume's lattice, prepared once: what every sample's cell lookup needs.
    grid: Grid,
    /// Rays marched together (one of `PACKET_WIDTHS`).
    packet: usize,
}

/// Packet widths `with_packet_width` accepts; the image is the same for each.
pub const PACKET_WIDTHS: [usize; 3] = [1, 4, 8];

/// The packet width `render` uses unless told otherwise.
pub const DEFAULT_PACKET_WIDTH: usize = 4;

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
            grid: Grid::new(volume.dims),
            packet: DEFAULT_PACKET_WIDTH,
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
                self.grid = Grid::new(self.volume.dims);
            }
            self.leap_values = Some(leap_values);
        }
        self
    }

    /// Marches `width` rays together (one of `PACKET_WIDTHS`); the image does not change.
    pub fn with_packet_width(mut self, width: usize) -> Result<Self> {
        if !PACKET_WIDTHS.contains(&width) {
            return Err(crate::error::Error::Invalid(format!(
                "packet width {width}: allowed {PACKET_WIDTHS:?}"
            )));
        }
        self.packet = width;
        Ok(self)
    }

    /// Homogeneous leap values: what preprocessing found.
    pub fn leap_value_stats(&self) -> Option<crate::leapvalues::LeapValueStats> {
        self.leap_values.as_ref().map(|l| l.stats)
    }

    pub fn render(&self, camera: &Camera) -> Frame {
        match self.packet {
            8 => self.render_packets::<8>(camera),
            4 => self.render_packets::<4>(camera),
            _ => self.render_packets::<1>(camera),
        }
    }

    /// Each row in packets of N neighbouring pixels (the last one padded with idle lanes).
    fn render_packets<const N: usize>(&self, camera: &Camera) -> Frame {
        render_rows(camera.width, camera.height, |py, pixels, records| {
            for (chunk, (pixels, records)) in
                pixels.chunks_mut(N).zip(records.chunks_mut(N)).enumerate()
            {
                let mut lanes: [Lane; N] = std::array::from_fn(|l| {
                    let px = (chunk * N + l) as u32;
                    if l < pixels.len() {
                        let ray = camera.voxel_ray(px, py, self.volume.spacing);
                        self.begin(interleave_ray(ray, px, py, &self.settings), (px, py))
                    } else {
                        Lane::idle()
                    }
                });
                self.march(&mut lanes);
                for ((pixel, record), lane) in pixels.iter_mut().zip(records).zip(&lanes) {
                    (*pixel, *record) = self.finish(lane);
                }
            }
        })
    }

    /// Casts one ray; returns the final pixel and what the ray did.
    pub fn cast(&self, ray: &Ray) -> ([u8; 4], RayRecord) {
        self.cast_pixel(ray, (0, 0))
    }

    /// Casts the ray of pixel (px, py) (the pixel matters only for a depth image).
    pub fn cast_pixel(&self, ray: &Ray, pixel: (u32, u32)) -> ([u8; 4], RayRecord) {
        let mut lanes = [self.begin(*ray, pixel)];
        self.march(&mut lanes);
        self.finish(&lanes[0])
    }

    /// Sets a ray up: its samples in the box, cut to its start and end (bricks, clipping,
    /// geometry). Iso mode and homogeneous leap values march the whole ray here (their own
    /// protocols); otherwise the lane's samples `first..end` are left to `march`.
    fn begin(&self, ray: Ray, pixel: (u32, u32)) -> Lane {
        let mut lane = Lane {
            ray,
            pixel,
            first: 0,
            end: 0,
            acc: Vec4::ZERO,
            record: RayRecord::default(),
            surface: None,
        };
        let Some((t_enter, t_exit)) = clip_to_box(&ray, self.volume.dims) else {
            return lane;
        };
        let record = &mut lane.record;
        let s = self.settings.sample_spacing;
        let (mut first, mut end) = sample_range(t_enter, t_exit, s);
        // Iso refinement reaches back to first - 1 when only bricks cut it.
        let mut refine_from = first;
        if let Some(range) = &self.ray_range {
            // The same positions as `march` computes.
            let l = range.limits(&ray, pixel, s, first, end, |k| position(&ray, k, s));
            record.positions_cut = ((end - first) - (l.end - l.first)) as u32;
            (first, end, lane.surface) = (l.first, l.end, l.surface);
            refine_from = l.scene_first;
        }
        record.t_enter = t_enter;
        record.t_exit = t_exit;
        record.first_sample = first;
        record.end_sample = end;
        record.hit = end > first;
        if let Some(iso) = &self.iso {
            self.march_iso(&ray, iso, (first, refine_from), end, &mut lane.acc, record);
        } else if let Some(words) = &self.leap_values {
            self.march_regions(&ray, words, first, end, &mut lane.acc, record);
        } else {
            (lane.first, lane.end) = (first, end);
        }
        lane
    }

    /// Samples each lane's `first..end` (until early ray termination), the lanes in step: one
    /// sample of every lane per iteration. Lanes that are done compute a position in the box
    /// and discard it, so the loop has no per-lane control flow before classification.
    fn march<const N: usize>(&self, lanes: &mut [Lane; N]) {
        let s = self.settings.sample_spacing;
        let threshold = self.settings.ert_threshold.unwrap_or(f32::INFINITY);
        let mut k: [i64; N] = std::array::from_fn(|l| lanes[l].first);
        let mut end: [i64; N] = std::array::from_fn(|l| lanes[l].end);
        let o: [[f32; N]; 3] =
            std::array::from_fn(|a| std::array::from_fn(|l| lanes[l].ray.origin[a]));
        let d: [[f32; N]; 3] =
            std::array::from_fn(|a| std::array::from_fn(|l| lanes[l].ray.dir[a]));
        // Local copies of what every sample reads: the renderer is shared with the other
        // threads, so the compiler would read its fields again at every sample.
        let (grid, data) = (self.grid, &self.volume.data[..]);
        while (0..N).any(|l| k[l] < end[l]) {
            let p = positions(&o, &d, std::array::from_fn(|l| k[l].min(end[l])), s);
            let (entry, f) = table_position(grid.interpolate(data, &p));
            for (l, lane) in lanes.iter_mut().enumerate() {
                if k[l] >= end[l] {
                    continue;
                }
                let q = Vec3A::new(p[0][l], p[1][l], p[2][l]);
                let rgba = self.classify_entry(entry[l], f[l], q, lane.ray.dir);
                lane.record.samples += 1;
                composite(&mut lane.acc, self.opacity(rgba.w), rgba);
                if lane.acc.w >= threshold {
                    lane.record.terminated_early = k[l] + 1 < end[l];
                    end[l] = k[l];
                } else {
                    k[l] += 1;
                }
            }
        }
    }

    /// The pixel: the opaque surface (geometry) or the background composited behind the
    /// accumulated colour.
    fn finish(&self, lane: &Lane) -> ([u8; 4], RayRecord) {
        let Lane {
            ray,
            pixel,
            acc,
            record,
            mut surface,
            ..
        } = *lane;
        if let (None, Some(scene)) = (surface, self.ray_range.as_ref().and_then(|r| r.scene())) {
            // A ray that misses the volume (or has no sample in it) still meets the geometry.
            surface = scene
                .limits(&ray, pixel.0, pixel.1, self.settings.sample_spacing)
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
            let p = position(ray, k, s);
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
            let a = self.opacity(rgba.w);
            let a = if steps > 1 {
                1.0 - (1.0 - a).powi(steps as i32)
            } else {
                a
            };
            composite(acc, a, rgba);
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
        let ([i], [f]) = table_position([v]);
        self.classify_entry(i, f, p, dir)
    }

    /// Colour and per-voxel opacity between table entries i and i + 1 at fraction f.
    #[inline(always)]
    fn classify_entry(&self, i: usize, f: f32, p: Vec3A, dir: Vec3A) -> Vec4 {
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

    /// Trilinear interpolation at `p` (see `Grid::interpolate`).
    #[inline(always)]
    pub fn interpolate(&self, p: Vec3A) -> f32 {
        self.grid
            .interpolate(&self.volume.data, &[[p.x], [p.y], [p.z]])[0]
    }

    /// Opacity of a sample per sample spacing S, from its opacity per voxel.
    #[inline(always)]
    fn opacity(&self, alpha_per_voxel: f32) -> f32 {
        let s = self.settings.sample_spacing;
        if s == 1.0 {
            alpha_per_voxel
        } else {
            correct_opacity(alpha_per_voxel, s)
        }
    }

    /// (diffuse factor, specular term): the per-voxel gradients of the 8 neighbours,
    /// interpolated with the sample's weights (see `shading`).
    fn phong(&self, p: Vec3A, dir: Vec3A) -> (f32, f32) {
        let (base, frac) = self.grid.cell(&[[p.x], [p.y], [p.z]]);
        let (base, frac) = (base.map(|b| b[0] as usize), frac.map(|f| f[0]));
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

/// One ray of a packet.
#[derive(Clone, Copy)]
struct Lane {
    ray: Ray,
    pixel: (u32, u32),
    /// The samples `march` takes: `first..end` (empty when `begin` marched the ray).
    first: i64,
    end: i64,
    /// Accumulated (R, G, B, A).
    acc: Vec4,
    record: RayRecord,
    /// The opaque surface composited behind instead of the background (geometry).
    surface: Option<[f32; 4]>,
}

impl Lane {
    /// A lane padding the last packet of a row: no samples, never written out.
    fn idle() -> Lane {
        Lane {
            ray: Ray {
                origin: Vec3A::ZERO,
                dir: Vec3A::X,
                t_min: 0.0,
            },
            pixel: (0, 0),
            first: 0,
            end: 0,
            acc: Vec4::ZERO,
            record: RayRecord::default(),
            surface: None,
        }
    }
}

/// The positions (axis, lane) of samples k (t = k·S) on rays of origins `o` and directions
/// `d` (axis, lane): o + d·t per component, the one definition every path uses.
#[inline(always)]
fn positions<const N: usize>(
    o: &[[f32; N]; 3],
    d: &[[f32; N]; 3],
    k: [i64; N],
    s: f32,
) -> [[f32; N]; 3] {
    let t: [f32; N] = std::array::from_fn(|l| k[l] as f32 * s);
    std::array::from_fn(|a| std::array::from_fn(|l| o[a][l] + d[a][l] * t[l]))
}

/// The position of sample k on `ray` (`positions` with one lane).
#[inline(always)]
fn position(ray: &Ray, k: i64, s: f32) -> Vec3A {
    let lane = |v: Vec3A| [[v.x], [v.y], [v.z]];
    let [[x], [y], [z]] = positions(&lane(ray.origin), &lane(ray.dir), [k], s);
    Vec3A::new(x, y, z)
}

/// Table entries and fractions of densities v (per lane, v >= 0).
#[inline(always)]
fn table_position<const N: usize>(v: [f32; N]) -> ([usize; N], [f32; N]) {
    let i = floor(v);
    (
        i.map(|i| i as usize),
        std::array::from_fn(|l| v[l] - i[l] as f32),
    )
}

/// floor(x) per lane, for lanes in [0, 2^23) (positions and densities are). Written with a float
/// add and bit casts, which the compiler does for a whole packet per instruction (`x as i32`
/// saturates, which it converts lane by lane): x + 2^23 rounds x to the integer n held in its
/// low mantissa bits; floor is n, or n - 1 when n rounded up.
#[inline(always)]
fn floor<const N: usize>(x: [f32; N]) -> [i32; N] {
    const TWO_23: f32 = 8_388_608.0;
    std::array::from_fn(|l| {
        let n = (x[l] + TWO_23).to_bits() as i32 - TWO_23.to_bits() as i32;
        n - ((n as f32) > x[l]) as i32
    })
}

/// Front-to-back compositing: a sample of colour c and opacity a adds (1 - A)·a·(c, 1).
#[inline(always)]
fn composite(acc: &mut Vec4, a: f32, rgba: Vec4) {
    *acc += (1.0 - acc.w) * a * rgba.truncate().extend(1.0);
}

/// The volume's lattice: per axis the largest coordinate, the largest lower corner of a cell
/// (dim - 2, so that its +1 neighbour exists) and the stride; the offsets of a cell's four
/// x-pairs of voxels from its lower corner (rows y, y + 1 at z, then at z + 1) and the span of
/// voxels a cell covers.
#[derive(Clone, Copy, Debug)]
struct Grid {
    hi: [f32; 3],
    top: [i32; 3],
    stride: [usize; 3],
    rows: [usize; 4],
    span: usize,
}

impl Grid {
    fn new(dims: [usize; 3]) -> Grid {
        let stride = [1, dims[0], dims[0] * dims[1]];
        Grid {
            // Dims are 2..=MAX_DIM (`volume::check_dims`): exact in f32 and i32.
            hi: dims.map(|d| (d - 1) as f32),
            top: dims.map(|d| (d - 2) as i32),
            stride,
            rows: [0, stride[1], stride[2], stride[2] + stride[1]],
            span: stride[2] + stride[1] + 2,
        }
    }

    /// Lower corners and fractions of the cells holding the positions `p` (axis, lane).
    /// Positions are clamped into the box so that rounding at its faces cannot read outside
    /// the volume; at x = dim - 1 the corner stays dim - 2 with fraction 1.
    #[inline(always)]
    fn cell<const N: usize>(&self, p: &[[f32; N]; 3]) -> ([[i32; N]; 3], [[f32; N]; 3]) {
        let mut base = [[0i32; N]; 3];
        let mut frac = [[0f32; N]; 3];
        for axis in 0..3 {
            let x: [f32; N] = std::array::from_fn(|l| p[axis][l].clamp(0.0, self.hi[axis]));
            base[axis] = floor(x).map(|b| b.min(self.top[axis]));
            frac[axis] = std::array::from_fn(|l| x[l] - base[axis][l] as f32);
        }
        (base, frac)
    }

    /// Trilinear interpolation of `data` at the positions `p` (axis, lane): x, then y, then z.
    #[inline(always)]
    fn interpolate<const N: usize>(&self, data: &[u16], p: &[[f32; N]; 3]) -> [f32; N] {
        let (base, [fx, fy, fz]) = self.cell(p);
        // Lane by lane: each cell's four x-pairs are adjacent voxels, which the compiler loads
        // and interpolates as vectors within the lane.
        std::array::from_fn(|l| {
            let i0 = base[0][l] as usize
                + base[1][l] as usize * self.stride[1]
                + base[2][l] as usize * self.stride[2];
            let cube = &data[i0..i0 + self.span];
            let [c00, c10, c01, c11] = self
                .rows
                .map(|r| lerp(cube[r] as f32, cube[r + 1] as f32, fx[l]));
            lerp(lerp(c00, c10, fy[l]), lerp(c01, c11, fy[l]), fz[l])
        })
    }
}

#[inline]
fn to_u8(x: f32) -> u8 {
    (x.clamp(0.0, 1.0) * 255.0).round() as u8
}

#[cfg(test)]
mod tests {
    use super::floor;

    /// `floor` equals truncation for integers, halves and their neighbours one ulp away, up to
    /// the largest density.
    #[test]
    fn floor_matches_truncation() {
        let mut xs = vec![0.0f32, -0.0];
        for n in 0..=65535u32 {
            for x in [n as f32, n as f32 + 0.5] {
                xs.extend([x, f32::from_bits(x.to_bits() + 1)]);
                if x > 0.0 {
                    xs.push(f32::from_bits(x.to_bits() - 1));
                }
            }
        }
        for chunk in xs.chunks(4) {
            let lanes: [f32; 4] = std::array::from_fn(|l| chunk[l % chunk.len()]);
            assert_eq!(floor(lanes), lanes.map(|x| x as i32), "{lanes:?}");
            assert_eq!(floor([chunk[0]]), [chunk[0] as i32]);
        }
    }
}

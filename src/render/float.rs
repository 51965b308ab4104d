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

use std::ops::{Add, Mul, Sub};

use glam::{BVec4A, Vec3A, Vec4};

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
    /// Per integer density i: table[i] and table[i + 1] - table[i], so that classification
    /// loads one pair and does one multiply-add (the same f32 operations as a lerp).
    steps: Vec<[Vec4; 2]>,
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
            steps: steps(&table),
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
            self.steps = steps(&self.table);
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
            8 => self.render_packets::<2>(camera),
            _ => self.render_packets::<1>(camera),
        }
    }

    /// Each row in packets of `self.packet` neighbouring pixels, marched as G groups of four
    /// lanes (lanes past the packet's pixels, and past the row's end, are idle).
    fn render_packets<const G: usize>(&self, camera: &Camera) -> Frame {
        let width = self.packet;
        render_rows(camera.width, camera.height, |py, pixels, records| {
            for (chunk, (pixels, records)) in pixels
                .chunks_mut(width)
                .zip(records.chunks_mut(width))
                .enumerate()
            {
                let mut lanes: [[Lane; 4]; G] = std::array::from_fn(|g| {
                    std::array::from_fn(|l| {
                        let i = g * 4 + l;
                        let px = (chunk * width + i) as u32;
                        if i < pixels.len() {
                            let ray = camera.voxel_ray(px, py, self.volume.spacing);
                            self.begin(interleave_ray(ray, px, py, &self.settings), (px, py))
                        } else {
                            Lane::idle()
                        }
                    })
                });
                self.march(&mut lanes);
                for ((pixel, record), lane) in
                    pixels.iter_mut().zip(records).zip(lanes.iter().flatten())
                {
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
        let mut lanes = [[Lane::idle(); 4]];
        lanes[0][0] = self.begin(*ray, pixel);
        self.march(&mut lanes);
        self.finish(&lanes[0][0])
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
    /// sample of every lane per iteration, each group of four lanes as SIMD vectors (`Lanes`
    /// for `Vec4`), the accumulated colours and opacities as structure of arrays. Lanes that
    /// are done (or had nothing to march) compute a position in the box and discard it: in a
    /// run of iterations in which the same lanes are live nothing is decided per lane.
    fn march<const G: usize>(&self, lanes: &mut [[Lane; 4]; G]) {
        // Samples each lane takes; early ray termination cuts it.
        let mut count: [[i64; 4]; G] = lanes.map(|g| g.map(|lane| lane.end - lane.first));
        let mut acc: [[Vec4; 4]; G] = lanes.map(|g| {
            let a = g.map(|lane| lane.acc);
            [0, 1, 2, 3].map(|c| Vec4::new(a[0][c], a[1][c], a[2][c], a[3][c]))
        });
        let groups: [Group; G] = lanes.map(|g| Group {
            first: g.map(|lane| lane.first),
            o: [0, 1, 2].map(|a| Vec4::from_array(g.map(|lane| lane.ray.origin[a]))),
            d: [0, 1, 2].map(|a| Vec4::from_array(g.map(|lane| lane.ray.dir[a]))),
            dirs: g.map(|lane| lane.ray.dir),
        });
        let mut i = 0;
        loop {
            let live: [[bool; 4]; G] = count.map(|g| g.map(|n| n > i));
            // Every live lane takes samples until the first of them has taken all.
            let Some(stop) = (0..G * 4)
                .filter(|&j| live[j / 4][j % 4])
                .map(|j| count[j / 4][j % 4])
                .min()
            else {
                break;
            };
            let ended = if live.iter().flatten().all(|&b| b) {
                self.run::<G, false>(&groups, i..stop, live, &mut acc)
            } else {
                self.run::<G, true>(&groups, i..stop, live, &mut acc)
            };
            i = match ended {
                Some((at, full)) => {
                    for j in (0..G * 4).filter(|&j| full[j / 4][j % 4]) {
                        let n = &mut count[j / 4][j % 4];
                        lanes[j / 4][j % 4].record.terminated_early = at + 1 < *n;
                        *n = at + 1;
                    }
                    at + 1
                }
                None => stop,
            };
        }
        for (g, group) in lanes.iter_mut().enumerate() {
            for (l, lane) in group.iter_mut().enumerate() {
                lane.acc = Vec4::from_array(acc[g].map(|c| c.lane(l)));
                lane.record.samples += count[g][l] as u32;
            }
        }
    }

    /// Iterations `iters` of `march`: sample i of every lane. Only the lanes in `live` (all of
    /// them unless `MASKED`) composite. Returns the iteration and the live lanes whose opacity
    /// reached the threshold there, if any did.
    #[inline(always)]
    fn run<const G: usize, const MASKED: bool>(
        &self,
        groups: &[Group; G],
        iters: std::ops::Range<i64>,
        live: [[bool; 4]; G],
        acc: &mut [[Vec4; 4]; G],
    ) -> Option<(i64, [[bool; 4]; G])> {
        let s = self.settings.sample_spacing;
        let threshold = Vec4::splat(self.settings.ert_threshold.unwrap_or(f32::INFINITY));
        // Local copies of what every sample reads: the renderer is shared with the other
        // threads, so the compiler would read its fields again at every sample.
        let (grid, steps) = (self.grid, &self.steps[..]);
        let voxels = grid.voxels(&self.volume.data);
        let live_mask = live.map(|g| BVec4A::new(g[0], g[1], g[2], g[3]));
        for i in iters {
            let mut full = [[false; 4]; G];
            for g in 0..G {
                let group = &groups[g];
                let t = Vec4::from_array(group.first.map(|k| (k + i) as f32)) * s;
                let p = positions(group.o, group.d, t);
                let (entry, f) = table_position(grid.interpolate(&voxels, p));
                let rgba: [Vec4; 4] = std::array::from_fn(|l| {
                    let q = Vec3A::new(p[0].lane(l), p[1].lane(l), p[2].lane(l));
                    self.classify_step(steps, entry(l), f.lane(l), q, group.dirs[l])
                });
                let [r, gr, b, a] = glam::Mat4::from_cols(rgba[0], rgba[1], rgba[2], rgba[3])
                    .transpose()
                    .to_cols_array_2d()
                    .map(Vec4::from_array);
                let alpha = if s == 1.0 {
                    a
                } else {
                    Vec4::from_array(std::array::from_fn(|l| correct_opacity(a.lane(l), s)))
                };
                let acc = &mut acc[g];
                let w = (Vec4::ONE - acc[3]) * alpha;
                for (c, colour) in [r, gr, b, Vec4::ONE].into_iter().enumerate() {
                    let sum = acc[c] + w * colour;
                    acc[c] = if MASKED {
                        Vec4::select(live_mask[g], sum, acc[c])
                    } else {
                        sum
                    };
                }
                let reached = acc[3].cmpge(threshold);
                let reached = if MASKED {
                    reached & live_mask[g]
                } else {
                    reached
                };
                if reached.any() {
                    full[g] = [0, 1, 2, 3].map(|l| reached.test(l));
                }
            }
            if full.iter().flatten().any(|&b| b) {
                return Some((i, full));
            }
        }
        None
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
        let (i, f) = table_position(v);
        self.classify_entry(i(0), f, p, dir)
    }

    /// Colour and per-voxel opacity between table entries i and i + 1 at fraction f.
    #[inline(always)]
    fn classify_entry(&self, i: usize, f: f32, p: Vec3A, dir: Vec3A) -> Vec4 {
        self.classify_step(&self.steps, i, f, p, dir)
    }

    /// `classify_entry` with the renderer's `steps` passed in (a local copy in the ray loop).
    #[inline(always)]
    fn classify_step(&self, steps: &[[Vec4; 2]], i: usize, f: f32, p: Vec3A, dir: Vec3A) -> Vec4 {
        let [a, slope] = steps[i];
        let rgba = a + slope * f;
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
        let voxels = self.grid.voxels(&self.volume.data);
        self.grid.interpolate(&voxels, [p.x, p.y, p.z])
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
        let (base, frac) = self.grid.cell([p.x, p.y, p.z]);
        let base = base.map(|b| b as usize);
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
fn lerp<L: Lanes>(a: L, b: L, t: L) -> L {
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

/// One group of four rays of a packet: first samples, origins and directions (axis, lane).
struct Group {
    first: [i64; 4],
    o: [Vec4; 3],
    d: [Vec4; 3],
    dirs: [Vec3A; 4],
}

/// The lanes of a packet step as one value: `f32` (one ray or one sample) or `Vec4` (four
/// rays, one SIMD instruction per operation). Every step of a sample is written once, generic
/// over `Lanes`, so that each lane performs the same f32 operations in the same order whatever
/// its packet; the comparisons are the ones SSE does in one instruction.
trait Lanes: Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> {
    fn splat(x: f32) -> Self;
    /// Lane l is `f(l)`.
    fn from_fn(f: impl FnMut(usize) -> f32) -> Self;
    fn lane(self, l: usize) -> f32;
    /// Per lane `if self > other { self } else { other }` (SSE's `maxps`).
    fn max_first(self, other: Self) -> Self;
    /// Per lane `if self < other { self } else { other }` (SSE's `minps`).
    fn min_first(self, other: Self) -> Self;
    /// Per lane `if self > other { 1.0 } else { 0.0 }`.
    fn gt_one(self, other: Self) -> Self;
}

impl Lanes for f32 {
    #[inline(always)]
    fn splat(x: f32) -> f32 {
        x
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> f32) -> f32 {
        f(0)
    }
    #[inline(always)]
    fn lane(self, _: usize) -> f32 {
        self
    }
    #[inline(always)]
    fn max_first(self, other: f32) -> f32 {
        if self > other {
            self
        } else {
            other
        }
    }
    #[inline(always)]
    fn min_first(self, other: f32) -> f32 {
        if self < other {
            self
        } else {
            other
        }
    }
    #[inline(always)]
    fn gt_one(self, other: f32) -> f32 {
        if self > other {
            1.0
        } else {
            0.0
        }
    }
}

impl Lanes for Vec4 {
    #[inline(always)]
    fn splat(x: f32) -> Vec4 {
        Vec4::splat(x)
    }
    #[inline(always)]
    fn from_fn(f: impl FnMut(usize) -> f32) -> Vec4 {
        Vec4::from_array(std::array::from_fn(f))
    }
    #[inline(always)]
    fn lane(self, l: usize) -> f32 {
        self[l]
    }
    #[inline(always)]
    fn max_first(self, other: Vec4) -> Vec4 {
        // glam's `max` is `maxps` with SSE2; elsewhere say it per lane.
        if cfg!(target_feature = "sse2") {
            self.max(other)
        } else {
            Vec4::select(self.cmpgt(other), self, other)
        }
    }
    #[inline(always)]
    fn min_first(self, other: Vec4) -> Vec4 {
        if cfg!(target_feature = "sse2") {
            self.min(other)
        } else {
            Vec4::select(self.cmplt(other), self, other)
        }
    }
    #[inline(always)]
    fn gt_one(self, other: Vec4) -> Vec4 {
        Vec4::select(self.cmpgt(other), Vec4::ONE, Vec4::ZERO)
    }
}

/// The positions (axis) of the samples at ray parameters t on rays of origins `o` and
/// directions `d` (axis): o + d·t per component, the one definition every path uses.
#[inline(always)]
fn positions<L: Lanes>(o: [L; 3], d: [L; 3], t: L) -> [L; 3] {
    [0, 1, 2].map(|a| o[a] + d[a] * t)
}

/// The position of sample k (t = k·S) on `ray` (`positions` with one lane).
#[inline(always)]
fn position(ray: &Ray, k: i64, s: f32) -> Vec3A {
    let lane = |v: Vec3A| [v.x, v.y, v.z];
    Vec3A::from_array(positions(lane(ray.origin), lane(ray.dir), k as f32 * s))
}

/// Table entries (per lane) and fractions of densities v (v >= 0).
#[inline(always)]
fn table_position<L: Lanes>(v: L) -> (impl Fn(usize) -> usize, L) {
    let i = floor(v);
    (index(i), v - i)
}

const TWO_23: f32 = 8_388_608.0;

/// floor(x) per lane, for lanes in [0, 2^23) (positions and densities are), as floats: x + 2^23
/// rounds x to the integer n held in its low mantissa bits (exact, as is n - 2^23); floor is n,
/// or n - 1 when n rounded up.
#[inline(always)]
fn floor<L: Lanes>(x: L) -> L {
    let two_23 = L::splat(TWO_23);
    let n = (x + two_23) - two_23;
    n - n.gt_one(x)
}

/// Integers n in [0, 2^23) held as floats (from `floor`), as indices per lane: the bits of
/// n + 2^23 less those of 2^23 (`as usize` would saturate, which the compiler does lane by
/// lane).
#[inline(always)]
fn index<L: Lanes>(n: L) -> impl Fn(usize) -> usize {
    let biased = n + L::splat(TWO_23);
    move |l| (biased.lane(l).to_bits() - TWO_23.to_bits()) as usize
}

/// Front-to-back compositing: a sample of colour c and opacity a adds (1 - A)·a·(c, 1).
#[inline(always)]
fn composite(acc: &mut Vec4, a: f32, rgba: Vec4) {
    *acc += (1.0 - acc.w) * a * rgba.truncate().extend(1.0);
}

/// The volume's lattice: per axis the largest coordinate and the largest lower corner of a
/// cell (dim - 2, so that its +1 neighbour exists), as floats; the strides; the offsets of a
/// cell's four x-pairs of voxels from its lower corner (rows y, y + 1 at z, then at z + 1).
#[derive(Clone, Copy, Debug)]
struct Grid {
    hi: [f32; 3],
    top: [f32; 3],
    stride: [usize; 3],
    rows: [usize; 4],
}

/// The volume's voxels seen from each of a cell's four x-pairs: `rows[r]` is the data from
/// `Grid::rows[r]` on, all four of the same length, so that one bounds check of a lower corner
/// covers the cell's eight voxels.
struct Voxels<'d> {
    rows: [&'d [u16]; 4],
}

impl Grid {
    fn new(dims: [usize; 3]) -> Grid {
        let stride = [1, dims[0], dims[0] * dims[1]];
        Grid {
            // Dims are 2..=MAX_DIM (`volume::check_dims`): exact in f32.
            hi: dims.map(|d| (d - 1) as f32),
            top: dims.map(|d| (d - 2) as f32),
            stride,
            rows: [0, stride[1], stride[2], stride[2] + stride[1]],
        }
    }

    /// `data` (the volume's voxels) as `Voxels`: the largest lower corner plus one is the last
    /// index of each row view.
    #[inline(always)]
    fn voxels<'d>(&self, data: &'d [u16]) -> Voxels<'d> {
        let len = data.len() - self.rows[3];
        Voxels {
            rows: self.rows.map(|r| &data[r..r + len]),
        }
    }

    /// Lower corners and fractions (axis) of the cells holding the positions `p` (axis).
    /// Positions are clamped into the box so that rounding at its faces cannot read outside
    /// the volume; at x = dim - 1 the corner stays dim - 2 with fraction 1.
    #[inline(always)]
    fn cell<L: Lanes>(&self, p: [L; 3]) -> ([L; 3], [L; 3]) {
        let x: [L; 3] = std::array::from_fn(|a| {
            // `f32::clamp(0.0, hi)`, lane by lane.
            L::splat(self.hi[a]).min_first(L::splat(0.0).max_first(p[a]))
        });
        let base: [L; 3] = std::array::from_fn(|a| L::splat(self.top[a]).min_first(floor(x[a])));
        (base, std::array::from_fn(|a| x[a] - base[a]))
    }

    /// Trilinear interpolation of the voxels at the positions `p` (axis): x, then y, then z.
    #[inline(always)]
    fn interpolate<L: Lanes>(&self, voxels: &Voxels, p: [L; 3]) -> L {
        let (base, [fx, fy, fz]) = self.cell(p);
        let [bx, by, bz] = base.map(index);
        let corner = |l: usize| bx(l) + by(l) * self.stride[1] + bz(l) * self.stride[2];
        // Row r's pair of voxels in each lane.
        let pair = |r: usize| {
            let row = voxels.rows[r];
            let at = |l: usize| {
                let i = corner(l);
                let pair = &row[i..i + 2];
                (pair[0] as f32, pair[1] as f32)
            };
            (L::from_fn(|l| at(l).0), L::from_fn(|l| at(l).1))
        };
        let [c00, c10, c01, c11] = [0, 1, 2, 3].map(|r| {
            let (a, b) = pair(r);
            lerp(a, b, fx)
        });
        lerp(lerp(c00, c10, fy), lerp(c01, c11, fy), fz)
    }
}

/// Per integer density: the table's entry and its difference to the next (see
/// `FloatRenderer::steps`).
fn steps(table: &[Vec4]) -> Vec<[Vec4; 2]> {
    table.windows(2).map(|w| [w[0], w[1] - w[0]]).collect()
}

#[inline]
fn to_u8(x: f32) -> u8 {
    (x.clamp(0.0, 1.0) * 255.0).round() as u8
}

#[cfg(test)]
mod tests {
    use super::{floor, index};

    /// `floor` equals truncation for integers, halves and their neighbours one ulp away, up to
    /// the largest density, and `to_index` of it equals the integer.
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
            let n = floor(glam::Vec4::from_array(lanes));
            assert_eq!(n.to_array(), lanes.map(|x| x.trunc()), "{lanes:?}");
            let i = index(n);
            assert_eq!([0, 1, 2, 3].map(i), lanes.map(|x| x as usize), "{lanes:?}");
            assert_eq!(floor(chunk[0]), chunk[0].trunc());
            assert_eq!(index(floor(chunk[0]))(0), chunk[0] as usize);
        }
    }
}

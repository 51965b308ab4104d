//! Invariant (c) of the brief (section 5): the fixed-point image stays within the error its bit
//! widths predict, against the float reference.
//!
//! The prediction is an interval per ray that provably holds both models' values: for each
//! sample k of the float ray, every position either model can sample is inside a box around the
//! exact position (the fixed start rounded to `position_frac_bits`, the increment to
//! `increment_frac_bits` and so drifting by k half-units, the trilinear weights truncated to
//! `weight_bits`, the float reference's f32 rounding). The box gives a density interval (the
//! trilinear interpolant's range over it, exact: the interpolant is multilinear between lattice
//! planes, so its extremes lie on the corners of the box cut at those planes), and the density
//! interval an interval of colour and opacity that holds the float classification (the
//! transfer function, linear between entries, over the interval) and the fixed one (the entries
//! its rounded density can index, as rounded to `lut_bits` and widened to the accumulators). Front-to-back
//! compositing is monotone in each input, so the intervals carry through it, each fixed-point
//! product widening them by its rounding (`accumulator_bits`). Two events make a model's
//! sample set uncertain, and the interval takes both outcomes: a sample near a box face that
//! the fixed ray may not have (its positions are rounded; it never has one the float ray lacks),
//! and early ray termination that one model may reach before the other (the lower bound stops
//! accumulating while the upper goes on). The pixel's bound is the width of the final interval
//! in 8-bit levels, after both models' output rounding.
//!
//! So the bound depends on the widths and on the frame (the data's gradients and the transfer
//! function's slopes where the rays go); nothing of the fixed-point model's result enters it.
//! With shading, the colour interval is shaded by the gradients' range over the same box (the
//! fixed model's quantised to half a unit), n·l over that range (any value where the gradient
//! may vanish) and every rounding of the fixed model's Phong arithmetic.
//!
//! It covers classified direct volume rendering, shaded or not, with any leaping structure that
//! keeps the image (occupancy maps, distance volumes, blocking, bricks), ERT, perspective,
//! interleaved sampling, leap values over empty regions, clipping and opaque geometry (which
//! cut the same sample indices in both models) and the iso surface (`iso_ray`); homogeneous
//! leap values, lossy by design, are outside it (`unsupported`). docs/precision.md gives the
//! figures.

use rayon::prelude::*;
use serde::Serialize;

use crate::camera::{interleave_ray, Camera, Ray};
use crate::config::{HardwareConfig, LeapRegions, LeapStructure};
use crate::error::{Error, Result};
use crate::functional::arith::{to_accumulator, ClassificationTable, Compositor};
use crate::functional::Widths;
use crate::render::{clip_to_box, sample_range, Frame, RenderSettings};
use crate::transfer::{correct_opacity, TransferFunction};
use crate::volume::Volume;

/// Slack for the float reference's f32 arithmetic in one compositing step (its sums and
/// products of values in [0, 1] round by at most a few units of 2^-24).
const FLOAT_STEP_SLACK: f64 = 1.0 / (1u64 << 20) as f64;

/// Why a run's fixed-point image has no predicted bound, if it has none.
pub fn unsupported(config: &HardwareConfig) -> Option<String> {
    let reason = if config.occupancy.structure == LeapStructure::LeapValues
        && config.leap_values.regions == LeapRegions::Homogeneous
    {
        "homogeneous leap values (lossy by design: both models composite a region's mean \
         under their own protocol)"
    } else {
        return None;
    };
    Some(format!("no predicted error bound with {reason}"))
}

/// Per table entry and channel (R, G, B, A), a value range, with blocks of `BLOCK` entries
/// summarised so that the range over many entries is found in a few dozen reads even in a
/// 16-bit table.
struct EntryRanges {
    lo: Vec<[f64; 4]>,
    hi: Vec<[f64; 4]>,
    block_lo: Vec<[f64; 4]>,
    block_hi: Vec<[f64; 4]>,
}

const BLOCK: usize = 64;

/// Widens the range lo..hi (per channel) to include l..h.
fn include(lo: &mut [f64; 4], hi: &mut [f64; 4], l: [f64; 4], h: [f64; 4]) {
    for c in 0..4 {
        lo[c] = lo[c].min(l[c]);
        hi[c] = hi[c].max(h[c]);
    }
}

impl EntryRanges {
    fn new(lo: Vec<[f64; 4]>, hi: Vec<[f64; 4]>) -> Self {
        let fold = |values: &[[f64; 4]], pick: fn(f64, f64) -> f64, start: f64| {
            values
                .chunks(BLOCK)
                .map(|chunk| {
                    chunk.iter().fold([start; 4], |acc, v| {
                        std::array::from_fn(|c| pick(acc[c], v[c]))
                    })
                })
                .collect::<Vec<_>>()
        };
        let block_lo = fold(&lo, f64::min, f64::INFINITY);
        let block_hi = fold(&hi, f64::max, f64::NEG_INFINITY);
        EntryRanges {
            lo,
            hi,
            block_lo,
            block_hi,
        }
    }

    /// The lowest and highest values over entries first..=last.
    fn range(&self, first: usize, last: usize) -> ([f64; 4], [f64; 4]) {
        let mut lo = [f64::INFINITY; 4];
        let mut hi = [f64::NEG_INFINITY; 4];
        let mut take = |l: &[f64; 4], h: &[f64; 4]| include(&mut lo, &mut hi, *l, *h);
        let mut i = first;
        while i <= last {
            if i.is_multiple_of(BLOCK) && i + BLOCK - 1 <= last {
                take(&self.block_lo[i / BLOCK], &self.block_hi[i / BLOCK]);
                i += BLOCK;
            } else {
                take(&self.lo[i], &self.hi[i]);
                i += 1;
            }
        }
        (lo, hi)
    }
}

/// A frame's predicted bound: per pixel and channel (R, G, B, A), the largest difference in
/// 8-bit levels the widths allow between the fixed-point and the float pixel.
#[derive(Clone, Debug)]
pub struct BoundFrame {
    pub width: u32,
    pub height: u32,
    pub levels: Vec<[u8; 4]>,
}

/// The error bound of one run's frames.
pub struct ErrorBound<'a> {
    volume: &'a Volume,
    widths: Widths,
    settings: RenderSettings,
    /// The fixed model's entries as it composites them (widened to the accumulators).
    fixed_entries: EntryRanges,
    /// The float reference's table (the transfer function at integer densities, opacity not
    /// yet corrected), one extra copy of the last entry, as it interpolates it.
    float_table: Vec<[f64; 4]>,
    float_entries: EntryRanges,
    /// One accumulator unit (1 / (2^accumulator_bits − 1)): a fixed-point product's rounding
    /// is at most half of it.
    unit: f64,
    /// The two models' ERT thresholds, lower and higher (fixed: rounded up to a unit).
    thresholds: Option<(f64, f64)>,
    /// The background per channel as each model composites it (lower, higher).
    background: [(f64, f64); 4],
    /// Clip planes, clip box and opaque geometry, when set.
    scene: Option<crate::clip::Scene>,
    /// Iso-surface mode: the surface and its colour as each model holds it (lower, higher).
    iso: Option<(crate::iso::IsoSurface, [(f64, f64); 3])>,
    /// With shading: the fixed model's gradient scale (quantised units per density unit) and
    /// its table unit, in which it shades.
    shading: Option<Shading>,
}

#[derive(Clone, Copy, Debug)]
struct Shading {
    gradient_scale: f64,
    lut_unit: f64,
}

impl<'a> ErrorBound<'a> {
    /// The bound for frames of `volume` with this transfer function, settings and hardware
    /// (its widths); an error naming the reason when the configuration is outside it.
    pub fn new(
        volume: &'a Volume,
        tf: &TransferFunction,
        settings: &RenderSettings,
        config: &HardwareConfig,
    ) -> Result<Self> {
        if let Some(reason) = unsupported(config) {
            return Err(Error::Invalid(reason));
        }
        let widths = Widths::from_config(config);
        let entries = volume.max_value() as usize + 1;
        // The fixed model's own table and compositor: the values it composites.
        let table =
            ClassificationTable::build(tf, entries, widths.lut_bits, settings.sample_spacing);
        let compositor = Compositor::new(
            widths.accumulator_bits,
            widths.lut_bits,
            settings.ert_threshold,
            settings.background,
        );
        let unit = compositor.unit as f64;
        let fixed: Vec<[f64; 4]> = (0..entries)
            .map(|i| {
                table
                    .lookup(i as u16)
                    .map(|x| compositor.widen(x) as f64 / unit)
            })
            .collect();
        let mut float_table: Vec<[f64; 4]> = tf
            .sample_table(entries)
            .into_iter()
            .map(|rgba| rgba.map(|x| x as f64))
            .collect();
        float_table.push(float_table[entries - 1]);
        let thresholds = settings.ert_threshold.map(|t| {
            let fixed = compositor.threshold() as f64 / unit;
            let t = t as f64;
            (t.min(fixed), t.max(fixed))
        });
        let fixed_background = compositor.background().map(|b| b as f64 / unit);
        let background = std::array::from_fn(|c| {
            let float = settings.background[c] as f64;
            (
                float.min(fixed_background[c]),
                float.max(fixed_background[c]),
            )
        });
        let iso = crate::iso::IsoSurface::from_config(config, volume)?.map(|iso| {
            let fixed = crate::functional::arith::iso_entry(iso.colour, widths.lut_bits);
            let lut_unit = ((1u32 << widths.lut_bits) - 1) as f64;
            let colour = std::array::from_fn(|c| {
                let (float, fixed) = (iso.colour[c] as f64, fixed[c] as f64 / lut_unit);
                (float.min(fixed), float.max(fixed))
            });
            (iso, colour)
        });
        // The iso surface is always shaded.
        let shading = (settings.shading || iso.is_some()).then(|| {
            // As `GradientVolume::build` scales, in f32.
            let max_component = ((1i32 << (config.shading.gradient_bits - 1)) - 1) as f32;
            Shading {
                gradient_scale: (max_component / (volume.max_value() as f32 * 0.5)) as f64,
                lut_unit: ((1u32 << widths.lut_bits) - 1) as f64,
            }
        });
        Ok(ErrorBound {
            iso,
            scene: crate::clip::Scene::from_config(config)?,
            shading,
            volume,
            widths,
            settings: settings.clone(),
            fixed_entries: EntryRanges::new(fixed.clone(), fixed),
            float_entries: EntryRanges::new(float_table.clone(), float_table.clone()),
            float_table,
            unit,
            thresholds,
            background,
        })
    }

    /// The bound of every pixel of the camera's frame (rows in parallel; the same for any
    /// thread count).
    pub fn predict(&self, camera: &Camera) -> BoundFrame {
        let (width, height) = (camera.width, camera.height);
        let mut levels = vec![[0u8; 4]; (width * height) as usize];
        levels
            .par_chunks_mut(width as usize)
            .enumerate()
            .for_each(|(py, row)| {
                for (px, level) in row.iter_mut().enumerate() {
                    let (px, py) = (px as u32, py as u32);
                    let ray = camera.voxel_ray(px, py, self.volume.spacing);
                    *level = self.ray(&interleave_ray(ray, px, py, &self.settings), (px, py));
                }
            });
        BoundFrame {
            width,
            height,
            levels,
        }
    }

    /// The bound of one ray's pixel, per channel, in 8-bit levels.
    pub fn ray(&self, ray: &Ray, (px, py): (u32, u32)) -> [u8; 4] {
        let dims = self.volume.dims;
        let s = self.settings.sample_spacing as f64;
        let w = &self.widths;
        // A product's rounding in the fixed model, and the float's own per step.
        let r = 0.5 / self.unit + FLOAT_STEP_SLACK;
        let (mut a_lo, mut a_hi) = (0.0f64, 0.0f64);
        let (mut c_lo, mut c_hi) = ([0.0f64; 3], [0.0f64; 3]);
        // Clipping and geometry cut the same sample indices k in both models (`clip`), and an
        // opaque surface replaces the background, each model's colour rounded its own way.
        let limits = self
            .scene
            .as_ref()
            .map(|scene| scene.limits(ray, px, py, self.settings.sample_spacing));
        let mut background = self.background;
        if let Some(surface) = limits.and_then(|l| l.surface) {
            background = std::array::from_fn(|c| {
                let float = surface[c] as f64;
                let fixed = to_accumulator(surface[c], self.unit as u32) as f64 / self.unit;
                (float.min(fixed), float.max(fixed))
            });
        }
        if let Some((t_enter, t_exit)) = clip_to_box(ray, dims) {
            let (first, end) = sample_range(t_enter, t_exit, self.settings.sample_spacing);
            // Drift counts from the box entry, where the fixed start was rounded.
            let (kept_first, kept_end) = match limits {
                Some(l) => (first.max(l.k_lo), end.min(l.k_end)),
                None => (first, end),
            };
            let origin = [ray.origin.x, ray.origin.y, ray.origin.z].map(|x| x as f64);
            let dir = [ray.dir.x, ray.dir.y, ray.dir.z].map(|x| x as f64);
            // The fixed start is the exact position rounded to half a position unit; each
            // increment adds at most half an increment unit per axis.
            let start_error = 0.5 / (1u64 << w.position_frac_bits) as f64 + 1e-9;
            let step_error = 0.5 / (1u64 << w.increment_frac_bits) as f64;
            // Truncating the position to the weights' bits moves the interpolated position
            // towards the cell's lower corner by less than one weight unit.
            let weight_error = if w.position_frac_bits > w.weight_bits {
                1.0 / (1u64 << w.weight_bits) as f64
            } else {
                0.0
            };
            let max_value = self.volume.max_value() as f64;
            // The float's three nested f32 lerps round by up to 8 half-ulps of the largest value;
            // twice that leaves room for the table lerp's own rounding.
            let density_slack = max_value * 16.0 / (1u64 << 24) as f64 + 1e-9;
            // Every position either model can sample (or interpolate at) for sample k, and
            // whether the fixed ray surely has that sample.
            let sample_box = |k: i64| {
                let t = k as f64 * s;
                let exact: [f64; 3] = std::array::from_fn(|a| origin[a] + dir[a] * t);
                let fixed_error = start_error + (k - first).max(0) as f64 * step_error;
                // The float position: f32 products and sums of magnitudes up to |o| + |d·t|.
                let float_error: [f64; 3] = std::array::from_fn(|a| {
                    (origin[a].abs() + (dir[a] * t).abs() + 1.0) * 4.0 / (1u64 << 24) as f64
                });
                let mut lo = [0.0; 3];
                let mut hi = [0.0; 3];
                let mut certain = true;
                for a in 0..3 {
                    let top = (dims[a] - 1) as f64;
                    // The fixed ray lacks a sample whose rounded position left the box.
                    if exact[a] - fixed_error < 0.0 || exact[a] + fixed_error > top {
                        certain = false;
                    }
                    let below = (fixed_error + weight_error).max(float_error[a]);
                    let above = fixed_error.max(float_error[a]);
                    lo[a] = (exact[a] - below).clamp(0.0, top);
                    hi[a] = (exact[a] + above).clamp(0.0, top);
                }
                (lo, hi, certain)
            };
            if let Some((iso, colour)) = &self.iso {
                return self.iso_ray(
                    iso,
                    colour,
                    (kept_first, kept_end),
                    sample_box,
                    dir,
                    background,
                );
            }
            for k in kept_first..kept_end {
                let (lo, hi, certain) = sample_box(k);
                let (d_lo, d_hi) = self.density_range(lo, hi);
                let (mut v_lo, mut v_hi) = self.classification_range(d_lo, d_hi, density_slack);
                if v_hi[3] == 0.0 {
                    // Transparent in both models: the fixed model composites nothing (no
                    // rounding), the float adds zero.
                    continue;
                }
                if let Some(shading) = &self.shading {
                    (v_lo, v_hi) = self.shaded(shading, (lo, hi), dir, (v_lo, v_hi));
                }
                // ERT: once either model may have stopped, the lower bound takes nothing more;
                // once both surely have, the ray is done.
                let (maybe_stopped, both_stopped) = match self.thresholds {
                    Some((low, high)) => (a_hi + 1e-9 >= low, a_lo - 1e-9 >= high),
                    None => (false, false),
                };
                if both_stopped {
                    break;
                }
                // Opacity and colour per step: A' = A + (1 − A)·a, C' = C + (1 − A)·a·c, each
                // increasing in a, c and A's own term, C's decreasing in A.
                let (new_a_hi, weight_hi) = (
                    a_hi + ((1.0 - a_hi) * v_hi[3] + r),
                    (1.0 - a_lo) * v_hi[3] + r,
                );
                for c in 0..3 {
                    // A colour's increment is at most its weight (c <= 1) in either model.
                    c_hi[c] = (c_hi[c] + (weight_hi * v_hi[c] + r).min(weight_hi)).min(1.0);
                }
                if certain && !maybe_stopped {
                    let weight_lo = ((1.0 - a_hi) * v_lo[3] - r).max(0.0);
                    for c in 0..3 {
                        c_lo[c] += (weight_lo * v_lo[c] - r).max(0.0);
                    }
                    a_lo += ((1.0 - a_lo) * v_lo[3] - r).max(0.0);
                }
                a_hi = new_a_hi.min(1.0);
            }
        }
        // The background behind: out = C + (1 − A)·bg, one more rounded product.
        let out = |c: usize, lo: f64, hi: f64| -> (f64, f64) {
            let (b_lo, b_hi) = background[c];
            (
                lo + ((1.0 - a_hi) * b_lo - r).max(0.0),
                hi + (1.0 - a_lo) * b_hi + r,
            )
        };
        let mut levels = [0u8; 4];
        for (c, level) in levels.iter_mut().enumerate() {
            let (lo, hi) = if c < 3 {
                out(c, c_lo[c], c_hi[c])
            } else {
                // A + (1 − A)·bg is increasing in A.
                let (b_lo, b_hi) = background[3];
                (
                    a_lo + ((1.0 - a_lo) * b_lo - r).max(0.0),
                    a_hi + (1.0 - a_hi) * b_hi + r,
                )
            };
            *level = self.levels_between(lo, hi);
        }
        levels
    }

    /// Iso mode: the pixel is the shaded surface colour (opaque) of the first sample at or above
    /// the iso value, refined between it and the sample before, or the background when none
    /// is. Each sample whose density range reaches the iso value may be the hit, until one
    /// surely is (in both models: its whole range at or above the value, and surely on the
    /// fixed ray); the pixel's range is the union of those outcomes' ranges, the surface's
    /// shaded over the positions between the two samples (any refinement lands there in both
    /// models: the fixed midpoints floor, the float bisects t).
    fn iso_ray(
        &self,
        iso: &crate::iso::IsoSurface,
        colour: &[(f64, f64); 3],
        (kept_first, kept_end): (i64, i64),
        sample_box: impl Fn(i64) -> ([f64; 3], [f64; 3], bool),
        dir: [f64; 3],
        background: [(f64, f64); 4],
    ) -> [u8; 4] {
        let shading = self.shading.as_ref().expect("the iso surface is shaded");
        let slack = self.volume.max_value() as f64 * 16.0 / (1u64 << 24) as f64 + 1e-9;
        let (mut lo, mut hi) = ([f64::INFINITY; 4], [f64::NEG_INFINITY; 4]);
        let mut take = |l: [f64; 4], h: [f64; 4]| include(&mut lo, &mut hi, l, h);
        let mut surely_hit = false;
        for k in kept_first..kept_end {
            let (box_lo, box_hi, certain) = sample_box(k);
            let (d_lo, d_hi) = self.density_range(box_lo, box_hi);
            if d_hi + slack < iso.value {
                continue;
            }
            let (before_lo, before_hi, _) = sample_box(k - 1);
            let hull_lo = std::array::from_fn(|a| box_lo[a].min(before_lo[a]));
            let hull_hi = std::array::from_fn(|a| box_hi[a].max(before_hi[a]));
            let v_lo = [colour[0].0, colour[1].0, colour[2].0, 1.0];
            let v_hi = [colour[0].1, colour[1].1, colour[2].1, 1.0];
            let (s_lo, s_hi) = self.shaded(shading, (hull_lo, hull_hi), dir, (v_lo, v_hi));
            take(s_lo, s_hi);
            if certain && d_lo - slack >= iso.value {
                surely_hit = true;
                break;
            }
        }
        if !surely_hit {
            take(background.map(|b| b.0), background.map(|b| b.1));
        }
        // The fixed model's finish rounds once more (a product with the background's share).
        let r = 0.5 / self.unit + FLOAT_STEP_SLACK;
        std::array::from_fn(|c| self.levels_between(lo[c] - r, hi[c] + r))
    }

    /// The lowest and highest colour and opacity either model classifies a density in
    /// [d_lo, d_hi] to: the fixed model the entries its rounded density can index, the float
    /// reference its table interpolated linearly over [d_lo − slack, d_hi + slack] (its own
    /// interpolation's rounding), opacity corrected for the spacing after interpolation.
    fn classification_range(&self, d_lo: f64, d_hi: f64, slack: f64) -> ([f64; 4], [f64; 4]) {
        let max_value = self.volume.max_value() as f64;
        // The fixed index rounds half up the exact interpolated density.
        let index = |d: f64| (d + 0.5).floor().clamp(0.0, max_value) as usize;
        let (mut lo, mut hi) = self
            .fixed_entries
            .range(index(d_lo - 1e-9), index(d_hi + 1e-9));
        let (d_lo, d_hi) = (
            (d_lo - slack).clamp(0.0, max_value),
            (d_hi + slack).clamp(0.0, max_value),
        );
        let lerp = |d: f64| -> [f64; 4] {
            let i = d.floor() as usize;
            let f = d - i as f64;
            let (a, b) = (self.float_table[i], self.float_table[i + 1]);
            std::array::from_fn(|c| a[c] + (b[c] - a[c]) * f)
        };
        let mut float_lo = lerp(d_lo);
        let mut float_hi = float_lo;
        let mut take = |l: [f64; 4], h: [f64; 4]| include(&mut float_lo, &mut float_hi, l, h);
        let end = lerp(d_hi);
        take(end, end);
        // Between the ends the interpolated table is linear from one entry to the next: its
        // extremes are the entries inside.
        let (first_inside, last_inside) = (d_lo.floor() as usize + 1, d_hi.ceil() as usize);
        if first_inside < last_inside {
            let (l, h) = self.float_entries.range(first_inside, last_inside - 1);
            take(l, h);
        }
        let spacing = self.settings.sample_spacing;
        // f32 rounding of the float's interpolation (before the correction, whose slope has no
        // bound near opacity 1 when the spacing is below 1) and of the correction itself. A
        // value that is exactly 0 (every entry in reach transparent) stays 0 in f32: such a
        // sample composites nothing in either model.
        let slack = 1e-6;
        let widen = |lo: f64, hi: f64| {
            (
                (lo - slack).max(0.0),
                if hi > 0.0 { (hi + slack).min(1.0) } else { 0.0 },
            )
        };
        if spacing != 1.0 {
            // The float reference's own correction (f32) of the widened ends; the loop below
            // widens its result for the correction's rounding.
            let (a_lo, a_hi) = widen(float_lo[3], float_hi[3]);
            float_lo[3] = correct_opacity(a_lo as f32, spacing) as f64;
            float_hi[3] = correct_opacity(a_hi as f32, spacing) as f64;
        }
        for c in 0..4 {
            let (f_lo, f_hi) = widen(float_lo[c], float_hi[c]);
            lo[c] = lo[c].min(f_lo);
            hi[c] = hi[c].max(f_hi);
        }
        (lo, hi)
    }

    /// The colour range `v` after Phong shading (`shading::phong_fixed`, `phong_float`) at any
    /// position in the box: the gradient's range per component over the box (the float's
    /// gradients, and the fixed model's quantised to half a unit), n·l over that range of
    /// gradients (any direction when it comes near zero), and every rounding of the fixed
    /// model's shading in table units (n·l floored, the constants rounded, each product and
    /// squaring rounded, the light direction rounded to `LIGHT_FRAC_BITS`). Opacity unchanged.
    fn shaded(
        &self,
        shading: &Shading,
        (lo, hi): ([f64; 3], [f64; 3]),
        dir: [f64; 3],
        (v_lo, v_hi): ([f64; 4], [f64; 4]),
    ) -> ([f64; 4], [f64; 4]) {
        use crate::shading::{voxel_gradient, AMBIENT, DIFFUSE, LIGHT_FRAC_BITS, SPECULAR};
        let scale = shading.gradient_scale;
        // The gradient box in quantised units; f32 slack for the float's interpolation.
        let mut g_lo = [0.0; 3];
        let mut g_hi = [0.0; 3];
        for c in 0..3 {
            let (l, h) = self.field_range(lo, hi, |x, y, z| {
                voxel_gradient(self.volume, x, y, z)[c] as f64
            });
            let slack = 0.5 + 1e-4 * (1.0 + h.abs().max(l.abs()) * scale);
            g_lo[c] = l * scale - slack;
            g_hi[c] = h * scale + slack;
        }
        let nearest = |c: usize| {
            if g_lo[c] > 0.0 {
                g_lo[c]
            } else if g_hi[c] < 0.0 {
                -g_hi[c]
            } else {
                0.0
            }
        };
        let farthest = |c: usize| g_lo[c].abs().max(g_hi[c].abs());
        let norm_min = (0..3).map(|c| nearest(c).powi(2)).sum::<f64>().sqrt();
        let norm_max = (0..3).map(|c| farthest(c).powi(2)).sum::<f64>().sqrt();
        // g·d over the box, widened by the fixed light direction's rounding.
        let light_error = 0.5 / (1u64 << LIGHT_FRAC_BITS) as f64;
        let widen: f64 = (0..3).map(|c| farthest(c) * light_error).sum::<f64>() + 1e-9;
        let dot_lo: f64 = (0..3)
            .map(|c| (g_lo[c] * dir[c]).min(g_hi[c] * dir[c]))
            .sum::<f64>()
            - widen;
        let dot_hi: f64 = (0..3)
            .map(|c| (g_lo[c] * dir[c]).max(g_hi[c] * dir[c]))
            .sum::<f64>()
            + widen;
        let (abs_lo, abs_hi) = if dot_lo <= 0.0 && dot_hi >= 0.0 {
            (0.0, dot_lo.abs().max(dot_hi.abs()))
        } else {
            (
                dot_lo.abs().min(dot_hi.abs()),
                dot_lo.abs().max(dot_hi.abs()),
            )
        };
        let u = shading.lut_unit;
        let r = 0.5 / u;
        // The fixed norm is floored in units of 2^-3wb of a quantised unit; a zero norm (fixed)
        // or a length under 1e-3 (float) shades with n·l = 1.
        let norm_floor = 1.0 / (1u64 << (3 * self.widths.weight_bits)) as f64;
        let zero_possible = norm_min <= (1e-3 * scale).max(norm_floor) * 2.0;
        let nl_hi = if zero_possible {
            1.0
        } else {
            (abs_hi / (norm_min - norm_floor)).min(1.0)
        };
        let nl_lo = if norm_max > 0.0 {
            (abs_lo / norm_max - 1.0 / u - 1e-6).max(0.0)
        } else {
            0.0
        };
        let constant = |x: f32| {
            let fixed = crate::functional::arith::to_unit(x, u as u32) as f64 / u;
            (fixed.min(x as f64), fixed.max(x as f64))
        };
        let (ambient, diffuse, specular) =
            (constant(AMBIENT), constant(DIFFUSE), constant(SPECULAR));
        let factor = (
            ambient.0 + diffuse.0 * nl_lo - r - 1e-6,
            ambient.1 + diffuse.1 * nl_hi + r + 1e-6,
        );
        let (mut p_lo, mut p_hi) = (nl_lo, nl_hi);
        for _ in 0..crate::shading::SHININESS_LOG2 {
            p_lo = (p_lo * p_lo - r).max(0.0);
            p_hi = (p_hi * p_hi + r).min(1.0);
        }
        let spec = (
            (specular.0 * p_lo - r - 1e-6).max(0.0),
            specular.1 * p_hi + r + 1e-6,
        );
        // The fixed model shades the table value (table units), then widens it to the
        // accumulators: half an accumulator unit each way around the widened value.
        let a = 0.5 / self.unit;
        let mut out = (v_lo, v_hi);
        for c in 0..3 {
            let (c_lo, c_hi) = ((v_lo[c] - a).max(0.0), (v_hi[c] + a).min(1.0));
            out.0[c] = ((c_lo * factor.0 - r + spec.0).min(1.0) - a).max(0.0);
            out.1[c] = ((c_hi * factor.1 + r + spec.1).min(1.0) + a).min(1.0);
        }
        out
    }

    /// The most two 8-bit outputs can differ when both come from values in [lo, hi]: the fixed
    /// model's floor(255·x + 1/2 − 1/(2U)) and the float's round(255·x), both monotone.
    fn levels_between(&self, lo: f64, hi: f64) -> u8 {
        let low = (255.0 * lo.clamp(0.0, 1.0) + 0.5 - 0.5 / self.unit - 1e-6).floor();
        let high = (255.0 * hi.clamp(0.0, 1.0) + 0.5 + 1e-6).floor();
        (high.min(255.0) - low.max(0.0)).max(0.0) as u8
    }

    /// The trilinear interpolant's lowest and highest value over the box lo..hi (voxel
    /// coordinates inside the volume). Between lattice planes the interpolant is multilinear,
    /// so its extremes over each piece of the box are at the piece's corners: evaluated at
    /// every combination of the box's ends and the planes inside it. A box crossing more than
    /// a few planes (very narrow widths) takes its voxels' range instead, also a bound.
    fn density_range(&self, lo: [f64; 3], hi: [f64; 3]) -> (f64, f64) {
        let data = &self.volume.data;
        let dims = self.volume.dims;
        self.field_range(lo, hi, |x, y, z| {
            data[x + dims[0] * (y + dims[1] * z)] as f64
        })
    }

    /// `density_range` of any per-voxel field (`value(x, y, z)`): the density, a gradient
    /// component.
    fn field_range<F: Fn(usize, usize, usize) -> f64>(
        &self,
        lo: [f64; 3],
        hi: [f64; 3],
        value: F,
    ) -> (f64, f64) {
        const MAX_POINTS: usize = 6;
        let mut points: [[f64; MAX_POINTS]; 3] = [[0.0; MAX_POINTS]; 3];
        let mut counts = [0usize; 3];
        for a in 0..3 {
            let mut n = 0;
            points[a][n] = lo[a];
            n += 1;
            let mut plane = lo[a].floor() + 1.0;
            while plane < hi[a] {
                if n == MAX_POINTS - 1 {
                    return self.voxel_range(lo, hi, value);
                }
                points[a][n] = plane;
                n += 1;
                plane += 1.0;
            }
            if hi[a] > lo[a] {
                points[a][n] = hi[a];
                n += 1;
            }
            counts[a] = n;
        }
        let (mut d_lo, mut d_hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for &z in &points[2][..counts[2]] {
            for &y in &points[1][..counts[1]] {
                for &x in &points[0][..counts[0]] {
                    let d = self.interpolate([x, y, z], &value);
                    d_lo = d_lo.min(d);
                    d_hi = d_hi.max(d);
                }
            }
        }
        (d_lo, d_hi)
    }

    /// The exact trilinear interpolant of the field at p (inside the box), in f64.
    fn interpolate<F: Fn(usize, usize, usize) -> f64>(&self, p: [f64; 3], value: &F) -> f64 {
        let dims = self.volume.dims;
        let base: [usize; 3] = std::array::from_fn(|a| (p[a].floor() as usize).min(dims[a] - 2));
        let f: [f64; 3] = std::array::from_fn(|a| p[a] - base[a] as f64);
        let at = |x: usize, y: usize, z: usize| value(base[0] + x, base[1] + y, base[2] + z);
        let lerp = |a: f64, b: f64, t: f64| a + (b - a) * t;
        let y0 = lerp(
            lerp(at(0, 0, 0), at(1, 0, 0), f[0]),
            lerp(at(0, 1, 0), at(1, 1, 0), f[0]),
            f[1],
        );
        let y1 = lerp(
            lerp(at(0, 0, 1), at(1, 0, 1), f[0]),
            lerp(at(0, 1, 1), at(1, 1, 1), f[0]),
            f[1],
        );
        lerp(y0, y1, f[2])
    }

    /// The range of the field's voxels over every cell the box lo..hi touches.
    fn voxel_range<F: Fn(usize, usize, usize) -> f64>(
        &self,
        lo: [f64; 3],
        hi: [f64; 3],
        value: F,
    ) -> (f64, f64) {
        let dims = self.volume.dims;
        let first: [usize; 3] = std::array::from_fn(|a| (lo[a].floor() as usize).min(dims[a] - 1));
        let last: [usize; 3] = std::array::from_fn(|a| (hi[a].ceil() as usize).min(dims[a] - 1));
        let (mut d_lo, mut d_hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for z in first[2]..=last[2] {
            for y in first[1]..=last[1] {
                for x in first[0]..=last[0] {
                    let v = value(x, y, z);
                    d_lo = d_lo.min(v);
                    d_hi = d_hi.max(v);
                }
            }
        }
        (d_lo, d_hi)
    }
}

/// One pixel over its bound: a broken invariant.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Violation {
    pub pixel: (u32, u32),
    /// 0..4: R, G, B, A.
    pub channel: usize,
    pub error: u8,
    pub bound: u8,
}

/// The fixed-point image against the float image and the bound.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BoundCheck {
    pub pixels: u64,
    /// Pixel channels whose error exceeds their bound (0 when the invariant holds).
    pub violations: u64,
    /// The first violation in row order, if any.
    pub first_violation: Option<Violation>,
    /// The largest error and the largest bound over every pixel, per channel (R, G, B, A).
    pub max_error: [u8; 4],
    pub max_bound: [u8; 4],
    /// Means over the pixels and the colour channels R, G, B, in 8-bit levels.
    pub mean_error: f64,
    pub mean_bound: f64,
    /// Pixel channels whose bound is full scale (255 levels): there any error is within it,
    /// so the check says nothing about them.
    pub full_scale_channels: u64,
}

impl BoundCheck {
    pub fn holds(&self) -> bool {
        self.violations == 0
    }

    /// One line: the measured error against the bound, and whether every pixel is within it.
    pub fn describe(&self) -> String {
        let verdict = match self.first_violation {
            None => format!("every pixel within its bound ({} pixels)", self.pixels),
            Some(v) => format!(
                "{} pixel channels OVER their bound, the first at pixel ({}, {}) channel {}: \
                 error {} > bound {}",
                self.violations,
                v.pixel.0,
                v.pixel.1,
                ["R", "G", "B", "A"][v.channel],
                v.error,
                v.bound
            ),
        };
        let vacuous = match self.full_scale_channels {
            0 => String::new(),
            n => format!(
                " (at {n} of the {} pixel channels the bound is full scale, 255 levels, and \
                 any error passes)",
                4 * self.pixels
            ),
        };
        format!(
            "fixed vs float: max error (R, G, B, A) {} {} {} {}, mean (R, G, B) {:.3}; predicted \
             bound max {} {} {} {}, mean (R, G, B) {:.3} levels; {verdict}{vacuous}",
            self.max_error[0],
            self.max_error[1],
            self.max_error[2],
            self.max_error[3],
            self.mean_error,
            self.max_bound[0],
            self.max_bound[1],
            self.max_bound[2],
            self.max_bound[3],
            self.mean_bound
        )
    }
}

/// Checks every pixel of `fixed` against `float` and its bound.
pub fn check(fixed: &Frame, float: &Frame, bound: &BoundFrame) -> Result<BoundCheck> {
    if (fixed.width, fixed.height) != (float.width, float.height)
        || (fixed.width, fixed.height) != (bound.width, bound.height)
    {
        return Err(Error::Invalid(format!(
            "frames of different sizes: fixed {}x{}, float {}x{}, bound {}x{}",
            fixed.width, fixed.height, float.width, float.height, bound.width, bound.height
        )));
    }
    let mut result = BoundCheck {
        pixels: fixed.pixels.len() as u64,
        violations: 0,
        first_violation: None,
        max_error: [0; 4],
        max_bound: [0; 4],
        mean_error: 0.0,
        mean_bound: 0.0,
        full_scale_channels: 0,
    };
    let (mut error_sum, mut bound_sum) = (0u64, 0u64);
    for (i, ((x, f), b)) in fixed
        .pixels
        .iter()
        .zip(&float.pixels)
        .zip(&bound.levels)
        .enumerate()
    {
        for c in 0..4 {
            let error = x[c].abs_diff(f[c]);
            result.max_error[c] = result.max_error[c].max(error);
            result.max_bound[c] = result.max_bound[c].max(b[c]);
            result.full_scale_channels += u64::from(b[c] == u8::MAX);
            if c < 3 {
                error_sum += error as u64;
                bound_sum += b[c] as u64;
            }
            if error > b[c] {
                result.violations += 1;
                result.first_violation.get_or_insert(Violation {
                    pixel: (i as u32 % fixed.width, i as u32 / fixed.width),
                    channel: c,
                    error,
                    bound: b[c],
                });
            }
        }
    }
    let channels = (3 * fixed.pixels.len()).max(1) as f64;
    result.mean_error = error_sum as f64 / channels;
    result.mean_bound = bound_sum as f64 / channels;
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise_volume(dims: [usize; 3]) -> Volume {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let data = (0..dims.iter().product::<usize>())
            .map(|_| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (state >> 56) as u16
            })
            .collect();
        Volume {
            name: "noise".into(),
            dims,
            spacing: [1.0; 3],
            bits: 8,
            data,
        }
    }

    /// The interpolant's range over a box contains its value at every point of a fine grid in
    /// the box, and is attained there (within the grid's resolution): boxes inside a cell, across
    /// planes, at the faces, and wide enough for the voxel-range fallback.
    #[test]
    fn density_range_bounds_the_interpolant_over_the_box() {
        let volume = noise_volume([6, 5, 7]);
        let point = |value: f32, a: f32| crate::transfer::ControlPoint {
            value,
            rgba: [a, a, a, a],
        };
        let tf = TransferFunction::new(
            "ramp".into(),
            String::new(),
            vec![point(0.0, 0.0), point(255.0, 1.0)],
            "test",
        )
        .expect("valid");
        let config = HardwareConfig::default_config();
        let bound =
            ErrorBound::new(&volume, &tf, &RenderSettings::default(), &config).expect("bound");
        let boxes = [
            ([1.2, 2.3, 3.1], [1.4, 2.35, 3.6]),
            ([0.5, 1.9, 2.75], [2.0, 2.05, 4.25]),
            ([0.0, 0.0, 0.0], [0.3, 4.0, 0.1]),
            ([4.5, 3.5, 5.5], [5.0, 4.0, 6.0]),
            ([0.0, 0.2, 0.0], [5.0, 4.0, 6.0]),
        ];
        for (lo, hi) in boxes {
            let (d_lo, d_hi) = bound.density_range(lo, hi);
            let n = 24;
            let (mut seen_lo, mut seen_hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for i in 0..=n {
                for j in 0..=n {
                    for k in 0..=n {
                        let t = [i, j, k].map(|x| x as f64 / n as f64);
                        let p = std::array::from_fn(|a| lo[a] + (hi[a] - lo[a]) * t[a]);
                        let d = bound.interpolate(p, &|x, y, z| volume.get(x, y, z) as f64);
                        assert!(
                            d >= d_lo - 1e-9 && d <= d_hi + 1e-9,
                            "{p:?}: {d} not in {d_lo}..{d_hi}"
                        );
                        seen_lo = seen_lo.min(d);
                        seen_hi = seen_hi.max(d);
                    }
                }
            }
            let wide = (0..3).any(|a| hi[a] - lo[a] > 3.0);
            if !wide {
                // Exact: the extremes are at the box's corners and planes, which these boxes
                // put on the fine grid.
                assert!(
                    (seen_lo - d_lo).abs() < 1e-9 && (seen_hi - d_hi).abs() < 1e-9,
                    "{lo:?}..{hi:?}: {d_lo}..{d_hi} against {seen_lo}..{seen_hi}"
                );
            }
        }
    }

    /// A range over many entries (blocks and ends) equals the element-wise fold.
    #[test]
    fn entry_ranges_equal_the_fold_over_the_entries() {
        let values: Vec<[f64; 4]> = (0..300)
            .map(|i| {
                [
                    (i * 37 % 101) as f64,
                    (i * 13 % 7) as f64,
                    i as f64,
                    (300 - i) as f64,
                ]
            })
            .collect();
        let ranges = EntryRanges::new(values.clone(), values.clone());
        for (first, last) in [
            (0, 0),
            (0, 63),
            (1, 64),
            (5, 299),
            (64, 127),
            (63, 200),
            (299, 299),
        ] {
            let (lo, hi) = ranges.range(first, last);
            for c in 0..4 {
                let slice = values[first..=last].iter().map(|v| v[c]);
                assert_eq!(lo[c], slice.clone().fold(f64::INFINITY, f64::min));
                assert_eq!(hi[c], slice.fold(f64::NEG_INFINITY, f64::max));
            }
        }
    }

    /// The check counts the channels whose bound is full scale (any error passes there) and says
    /// so, shows alpha's maximum too (it checks alpha), and finds a violation in any channel.
    #[test]
    fn check_counts_full_scale_bounds_and_reports_alpha() {
        let frame = |pixels: Vec<[u8; 4]>| Frame {
            width: 2,
            height: 1,
            pixels,
            rays: Vec::new(),
        };
        let fixed = frame(vec![[10, 10, 10, 200], [0, 0, 0, 0]]);
        let float = frame(vec![[0, 10, 10, 197], [0, 0, 0, 0]]);
        let bound = BoundFrame {
            width: 2,
            height: 1,
            levels: vec![[255, 3, 3, 3], [1, 1, 1, 255]],
        };
        let c = check(&fixed, &float, &bound).unwrap();
        assert!(c.holds());
        assert_eq!(c.full_scale_channels, 2);
        assert_eq!(c.max_error, [10, 0, 0, 3]);
        let text = c.describe();
        assert!(text.contains("max error (R, G, B, A) 10 0 0 3"), "{text}");
        assert!(
            text.contains("at 2 of the 8 pixel channels the bound is full scale"),
            "{text}"
        );
        let tight = BoundFrame {
            levels: vec![[10, 3, 3, 2], [1, 1, 1, 1]],
            ..bound
        };
        let c = check(&fixed, &float, &tight).unwrap();
        assert_eq!((c.violations, c.full_scale_channels), (1, 0));
        assert_eq!(c.first_violation.unwrap().channel, 3);
        assert!(!c.describe().contains("full scale"), "{}", c.describe());
    }
}

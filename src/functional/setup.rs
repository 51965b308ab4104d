//! Fixed-point ray setup (brief, section 4, "ray setup"): from the float camera ray, per ray the
//! start position P0, the increment V, the reciprocals 1/|V_i| and the number of samples.
//!
//! - V_i = round_nearest(dir_i · S · 2^increment_frac_bits), then shifted left into position
//!   units (exact): every later position is P0 + k·V in exact integer arithmetic.
//! - P0 is the float position of the ray's first grid sample (t = k·S, the convention of
//!   `render::sample_range`) rounded to nearest in position units.
//! - The sample count is exact: the samples are the k >= 0 (up to the float model's count) for
//!   which P0 + k·V lies inside the box [0, dim-1] on every axis, found by integer division. So
//!   the fixed model never takes a sample outside the box, and never one the float model lacks.
//! - Reciprocals come from the quantised V, rounded down (`skip::ray_reciprocals`).

use super::Widths;
use crate::camera::Ray;
use crate::error::{Error, Result};
use crate::render::{clip_to_box, sample_range};
use crate::shading::LIGHT_FRAC_BITS;
use crate::skip::{ray_reciprocals, Reciprocal, ReciprocalRounding};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FixedRay {
    /// Position of the first sample, in units of 2^-position_frac_bits voxels.
    pub start: [i64; 3],
    /// Increment per sample, in position units (a multiple of 2^(pos_frac - inc_frac)).
    pub step: [i64; 3],
    pub reciprocals: [Option<Reciprocal>; 3],
    /// Number of sample positions along the ray (0 = the ray misses the volume).
    pub samples: u32,
    /// Grid index k (t = k·S) of the first sample, for reporting.
    pub first_k: i64,
    /// The ray direction for the headlight, rounded to nearest with
    /// `shading::LIGHT_FRAC_BITS` fraction bits.
    pub light: [i32; 3],
    /// Positions inside the box that the ray's start and end (bricks, clipping, geometry;
    /// `crate::bricks`) removed; 0 without them.
    pub cut: u32,
    /// Bricks the ray-setup traversal visited (`bricks::fixed_span`); 0 without bricks.
    pub bricks_visited: u32,
    /// The opaque surface behind the volume in this pixel (accumulator units, composited
    /// instead of the background); None without geometry there.
    pub surface: Option<[u32; 4]>,
    /// The position before `start` is a position of the ray that only bricks cut (so below
    /// any iso value): an iso hit at `start` refines back to it as it would without bricks.
    pub refinable_start: bool,
    /// Ray parameter (voxels) where the ray enters and leaves the box, as the float
    /// reference's `RayRecord` has them; 0, 0 when it misses the box. For reports only.
    pub t_range: [f32; 2],
}

/// Checks that the widths can represent positions inside this volume and increments at this
/// sample spacing.
pub fn check_widths(widths: &Widths, dims: [usize; 3], spacing: f32) -> Result<()> {
    let largest = *dims.iter().max().unwrap_or(&0) as u64;
    if largest > 1u64 << widths.position_int_bits {
        return Err(Error::Invalid(format!(
            "ray.position_int_bits = {} cannot represent positions up to {} in a volume of {dims:?}; \
             need at least {} bits",
            widths.position_int_bits,
            largest - 1,
            64 - (largest - 1).leading_zeros()
        )));
    }
    // The largest component of a unit direction is >= 1/sqrt(3); it must not round to zero.
    let smallest_major = spacing as f64 / 3f64.sqrt() * (1u64 << widths.increment_frac_bits) as f64;
    if smallest_major < 1.0 {
        return Err(Error::Invalid(format!(
            "ray.increment_frac_bits = {} is too narrow for sample spacing {spacing}: increments round to zero",
            widths.increment_frac_bits
        )));
    }
    Ok(())
}

/// Sets up one ray. `widths` must have passed `check_widths` for these dims and spacing.
pub fn setup_ray(ray: &Ray, dims: [usize; 3], spacing: f32, widths: &Widths) -> FixedRay {
    let pf = widths.position_frac_bits;
    let inc_shift = pf - widths.increment_frac_bits;
    let inc_scale = (1u64 << widths.increment_frac_bits) as f64;
    let step: [i64; 3] = [0, 1, 2].map(|a| {
        let v = (ray.dir[a] as f64 * spacing as f64 * inc_scale).round() as i64;
        v << inc_shift
    });
    let reciprocals = ray_reciprocals(step, &widths.skip(), ReciprocalRounding::Down);
    let light_scale = (1u32 << LIGHT_FRAC_BITS) as f32;
    let light = [0, 1, 2].map(|a| (ray.dir[a] * light_scale).round() as i32);
    let miss = FixedRay {
        start: [0; 3],
        step,
        reciprocals,
        samples: 0,
        first_k: 0,
        light,
        cut: 0,
        bricks_visited: 0,
        surface: None,
        refinable_start: false,
        t_range: [0.0; 2],
    };
    let Some((t_enter, t_exit)) = clip_to_box(ray, dims) else {
        return miss;
    };
    // From here on the ray enters the box, sampled or not.
    let miss = FixedRay {
        t_range: [t_enter, t_exit],
        ..miss
    };
    let (first, end) = sample_range(t_enter, t_exit, spacing);
    if end <= first {
        return miss;
    }
    let pos_scale = (1u64 << pf) as f64;
    let t_first = first as f64 * spacing as f64;
    let p0: [i64; 3] = [0, 1, 2]
        .map(|a| ((ray.origin[a] as f64 + ray.dir[a] as f64 * t_first) * pos_scale).round() as i64);
    // Exact range of k with lo <= p0 + k·v <= hi on every axis.
    let mut k_lo: i64 = 0;
    let mut k_hi: i64 = end - first - 1;
    for a in 0..3 {
        let hi = ((dims[a] - 1) as i64) << pf;
        let (p, v) = (p0[a], step[a]);
        if v == 0 {
            if p < 0 || p > hi {
                return miss;
            }
            continue;
        }
        let (lo_k, hi_k) = if v > 0 {
            (div_ceil(-p, v), (hi - p).div_euclid(v))
        } else {
            (div_ceil(p - hi, -v), p.div_euclid(-v))
        };
        k_lo = k_lo.max(lo_k);
        k_hi = k_hi.min(hi_k);
    }
    if k_hi < k_lo {
        return miss;
    }
    FixedRay {
        start: [0, 1, 2].map(|a| p0[a] + k_lo * step[a]),
        step,
        reciprocals,
        samples: (k_hi - k_lo + 1) as u32,
        first_k: first + k_lo,
        light,
        ..miss
    }
}

/// ceil(a / b) for b > 0.
#[inline]
fn div_ceil(a: i64, b: i64) -> i64 {
    -((-a).div_euclid(b))
}

//! Phong shading with one headlight, shared by the float reference and the fixed-point model.
//!
//! Gradients are stored per voxel, as VIZARD II stores a precalculated gradient with each voxel
//! so that shading needs only the sample's own 8-voxel neighbourhood: the central difference
//! g_i = (v[x_i + 1] - v[x_i - 1]) / 2 (indices clamped at the faces), interpolated trilinearly
//! with the sample's weights. Shading changes colour only, never opacity, so occupancy maps need
//! no wider dilation for it: a sample the map skips has opacity 0 whatever its colour.
//!
//! With n·l = |g·d| / |g| (two-sided; light and eye both along the ray d):
//! `c' = min(1, c · (AMBIENT + DIFFUSE · n·l) + SPECULAR · (n·l)^16)`, alpha unchanged. Where
//! the gradient is zero there is no surface and n·l is taken as 1.

use glam::Vec3A;

use crate::functional::arith::{mul_unit, to_unit};
use crate::volume::Volume;

pub const AMBIENT: f32 = 0.3;
pub const DIFFUSE: f32 = 0.7;
pub const SPECULAR: f32 = 0.3;
/// The specular exponent; a power of two so the fixed-point model squares four times.
pub const SHININESS_LOG2: u32 = 4;

/// The central-difference gradient of voxel (x, y, z), in density units per voxel.
#[inline]
pub fn voxel_gradient(volume: &Volume, x: usize, y: usize, z: usize) -> [f32; 3] {
    let d = volume.dims;
    let at = |x: usize, y: usize, z: usize| volume.get(x, y, z) as f32;
    [
        (at((x + 1).min(d[0] - 1), y, z) - at(x.saturating_sub(1), y, z)) * 0.5,
        (at(x, (y + 1).min(d[1] - 1), z) - at(x, y.saturating_sub(1), z)) * 0.5,
        (at(x, y, (z + 1).min(d[2] - 1)) - at(x, y, z.saturating_sub(1))) * 0.5,
    ]
}

/// Float shading factors (diffuse multiplier, specular term) for gradient `g` and direction `d`.
#[inline]
pub fn phong_float(g: Vec3A, d: Vec3A) -> (f32, f32) {
    let len = g.length();
    let n_dot_l = if len < 1e-3 {
        1.0
    } else {
        (g.dot(d) / len).abs().min(1.0)
    };
    (
        AMBIENT + DIFFUSE * n_dot_l,
        SPECULAR * n_dot_l.powi(1 << SHININESS_LOG2),
    )
}

/// Fraction bits of the per-ray light direction in the fixed-point model.
pub const LIGHT_FRAC_BITS: u32 = 14;

/// Per-voxel gradients quantised to signed `bits`-bit components (the voxel word's gradient
/// field): round(g · scale), clamped, where scale maps the largest possible central difference
/// (half the value range) to the largest component.
pub struct GradientVolume {
    pub bits: u32,
    data: Vec<[i16; 3]>,
}

impl GradientVolume {
    pub fn build(volume: &Volume, bits: u32) -> GradientVolume {
        let max_component = ((1i32 << (bits - 1)) - 1) as f32;
        let scale = max_component / (volume.max_value() as f32 * 0.5);
        let d = volume.dims;
        let mut data = Vec::with_capacity(volume.voxel_count());
        for z in 0..d[2] {
            for y in 0..d[1] {
                for x in 0..d[0] {
                    let g = voxel_gradient(volume, x, y, z);
                    data.push(
                        g.map(|c| (c * scale).round().clamp(-max_component, max_component) as i16),
                    );
                }
            }
        }
        GradientVolume { bits, data }
    }

    #[inline(always)]
    pub fn at(&self, index: usize) -> [i16; 3] {
        self.data[index]
    }
}

/// Fixed-point Phong: shades an RGBA table entry (`unit` = 2^lut_bits - 1) with the interpolated
/// gradient `g` (any consistent scale) and the ray's light direction `light` (LIGHT_FRAC_BITS).
///
/// n·l = min(U, floor(|g·l| · U / (|g| · 2^LIGHT_FRAC_BITS))) with |g| = floor(sqrt(g·g));
/// factor = round(0.3·U) + mul(round(0.7·U), n·l); spec = mul(round(0.3·U), (n·l)^16) by four
/// rounded squarings; c' = min(U, mul(c, factor) + spec), mul(x, y) = round(x·y / U).
#[inline]
pub fn phong_fixed(rgba: [u16; 4], g: [i64; 3], light: [i32; 3], unit: u32) -> [u16; 4] {
    let u = unit as u64;
    let mul = |x: u64, y: u64| mul_unit(x, y, u);
    let norm_sq: u128 = g.iter().map(|&c| (c as i128 * c as i128) as u128).sum();
    let norm = norm_sq.isqrt();
    let n_dot_l = if norm == 0 {
        u
    } else {
        let dot: i128 = (0..3).map(|i| g[i] as i128 * light[i] as i128).sum();
        let value = dot.unsigned_abs() * u as u128 / (norm << LIGHT_FRAC_BITS);
        (value as u64).min(u)
    };
    let to_unit = |x: f32| to_unit(x, unit) as u64;
    let factor = to_unit(AMBIENT) + mul(to_unit(DIFFUSE), n_dot_l);
    let mut power = n_dot_l;
    for _ in 0..SHININESS_LOG2 {
        power = mul(power, power);
    }
    let spec = mul(to_unit(SPECULAR), power);
    let shade = |c: u16| (mul(c as u64, factor) + spec).min(u) as u16;
    [shade(rgba[0]), shade(rgba[1]), shade(rgba[2]), rgba[3]]
}

//! The per-sample arithmetic of the pipeline in fixed point: trilinear interpolation,
//! classification table, front-to-back compositing and early ray termination. Every rounding
//! is stated where it happens; docs/model.md lists them all.

use crate::transfer::{correct_opacity, TransferFunction};
use crate::volume::Volume;

/// A fraction in [0, 1] in units of `unit` (2^bits − 1: a table entry, an accumulator),
/// rounded to nearest. The one conversion of a float colour or weight into a fixed-point unit:
/// table entries, the iso surface's colour and the shading constants (`to_accumulator` for the
/// accumulators' background and surface colours).
#[inline]
pub fn to_unit(x: f32, unit: u32) -> u32 {
    (x * unit as f32).round() as u32
}

/// A colour in [0, 1] in accumulator units `unit`, rounded to nearest (in double precision, as
/// the accumulators are up to 30 bits wide): the background and an opaque surface's colour.
#[inline]
pub fn to_accumulator(x: f32, unit: u32) -> u32 {
    (x as f64 * unit as f64).round() as u32
}

/// x·y / U rounded to nearest, floor((x·y + U/2) / U): the product of two values in units of
/// U. `Compositor` computes the same with shifts for U = 2^k − 1 (tested against this).
#[inline]
pub fn mul_unit(x: u64, y: u64, unit: u64) -> u64 {
    (x * y + unit / 2) / unit
}

/// The table-format RGBA of the iso surface (`lut_bits` wide): its colour, full opacity.
pub fn iso_entry(colour: [f32; 3], lut_bits: u32) -> [u16; 4] {
    let unit = (1u32 << lut_bits) - 1;
    let c = colour.map(|c| to_unit(c, unit) as u16);
    [c[0], c[1], c[2], unit as u16]
}

/// The lower corner voxel of the 2×2×2 cell a sample at the fixed-point position `pos` (units
/// of 2^-pf voxels, inside the box) interpolates in, clamped to dim − 2 at the upper face. The
/// one definition: the interpolation, the cycle model's memory addresses and the leaping
/// structures' cell tests all use it.
#[inline(always)]
pub fn base_voxel(dims: [usize; 3], pos: [i64; 3], pf: u32) -> [usize; 3] {
    [0, 1, 2].map(|a| ((pos[a] >> pf) as usize).min(dims[a] - 2))
}

/// The 2×2×2 neighbourhood of a fixed-point position (units of 2^-pf voxels, inside the box)
/// and its trilinear weights: the position's fraction truncated to `wb` bits, w in [0, 2^wb]
/// (2^wb only at the upper face, where the lower corner is dim-2).
#[derive(Clone, Copy, Debug)]
pub struct Neighbourhood {
    /// Index of the lower corner voxel.
    pub base: usize,
    pub weights: [u64; 3],
    stride_y: usize,
    stride_z: usize,
    weight_bits: u32,
}

impl Neighbourhood {
    #[inline(always)]
    pub fn new(dims: [usize; 3], pos: [i64; 3], pf: u32, wb: u32) -> Self {
        let base = base_voxel(dims, pos, pf);
        let mut weights = [0u64; 3];
        for a in 0..3 {
            let p = pos[a] as u64;
            let frac = p - ((base[a] as u64) << pf);
            weights[a] = if pf >= wb {
                frac >> (pf - wb)
            } else {
                frac << (wb - pf)
            };
        }
        let (stride_y, stride_z) = (dims[0], dims[0] * dims[1]);
        Neighbourhood {
            base: base[0] + stride_y * base[1] + stride_z * base[2],
            weights,
            stride_y,
            stride_z,
            weight_bits: wb,
        }
    }

    /// Σ weight · value over the 8 corners, exact, with 3·wb fraction bits. Three lerps, each
    /// keeping every bit; `value(i)` reads the voxel at index i.
    #[inline(always)]
    pub fn weighted_sum(&self, value: impl Fn(usize) -> i64) -> i64 {
        let one = 1i64 << self.weight_bits;
        let w = self.weights.map(|w| w as i64);
        let lerp = |a: i64, b: i64, t: i64| a * (one - t) + b * t;
        let (i0, sy, sz) = (self.base, self.stride_y, self.stride_z);
        let c00 = lerp(value(i0), value(i0 + 1), w[0]);
        let c10 = lerp(value(i0 + sy), value(i0 + sy + 1), w[0]);
        let c01 = lerp(value(i0 + sz), value(i0 + sz + 1), w[0]);
        let c11 = lerp(value(i0 + sz + sy), value(i0 + sz + sy + 1), w[0]);
        lerp(lerp(c00, c10, w[1]), lerp(c01, c11, w[1]), w[2])
    }
}

/// Trilinear interpolation of the density at a fixed-point position: the exact weighted sum,
/// rounded to nearest once at the end — the classification table's index.
#[inline(always)]
pub fn interpolate(volume: &Volume, pos: [i64; 3], pf: u32, wb: u32) -> u16 {
    round_sum(interpolate_exact(volume, pos, pf, wb), wb)
}

/// `interpolate` over cells that hold an 8-bit density in their low byte (leap values' packed
/// cells, `LeapCells::Packed`): the same sum and rounding.
#[inline(always)]
pub fn interpolate_low_bytes(
    cells: &[u16],
    dims: [usize; 3],
    pos: [i64; 3],
    pf: u32,
    wb: u32,
) -> u16 {
    let n = Neighbourhood::new(dims, pos, pf, wb);
    round_sum(n.weighted_sum(|i| (cells[i] & 0xFF) as i64), wb)
}

/// The exact weighted sum (3·wb fraction bits) rounded to nearest once: the table index.
#[inline(always)]
fn round_sum(sum: i64, wb: u32) -> u16 {
    let shift = 3 * wb;
    ((sum + (1i64 << (shift - 1))) >> shift) as u16
}

/// The exact trilinear weighted sum at a fixed-point position (3·wb fraction bits), before
/// `interpolate` rounds it: what the iso comparator tests.
#[inline(always)]
pub fn interpolate_exact(volume: &Volume, pos: [i64; 3], pf: u32, wb: u32) -> i64 {
    let n = Neighbourhood::new(volume.dims, pos, pf, wb);
    let data = &volume.data;
    n.weighted_sum(|i| data[i] as i64)
}

/// The iso comparator's threshold for iso value `value` (density units): ceil(value·2^(3·wb)),
/// so that `interpolate_exact(..) >= threshold` exactly when the exact interpolated density
/// is at least `value` (the weighted sum is an integer).
pub fn iso_threshold(value: f64, wb: u32) -> i64 {
    (value * (1u64 << (3 * wb)) as f64).ceil() as i64
}

/// The bisection midpoint of two fixed-point positions: floor((a + b) / 2) per component (an
/// arithmetic shift). It lies between a and b on every axis (inclusive), so a refined hit
/// never leaves the box spanned by the two samples it refines.
#[inline(always)]
pub fn midpoint(a: [i64; 3], b: [i64; 3]) -> [i64; 3] {
    [0, 1, 2].map(|i| (a[i] + b[i]) >> 1)
}

/// The classification lookup table: one RGBA entry per density, each component `bits` wide,
/// an unsigned fraction with 2^bits - 1 = 1.0. Built from the transfer function at integer
/// densities, opacity corrected for the sample spacing, rounded to nearest.
#[derive(Clone, Debug)]
pub struct ClassificationTable {
    pub bits: u32,
    entries: Vec<[u16; 4]>,
    /// visible_prefix[i] = number of entries below i with non-zero opacity.
    visible_prefix: Vec<u32>,
}

impl ClassificationTable {
    pub fn build(tf: &TransferFunction, densities: usize, bits: u32, spacing: f32) -> Self {
        let unit = ((1u32 << bits) - 1) as f32;
        let entries: Vec<[u16; 4]> = (0..densities)
            .map(|i| {
                let mut rgba = tf.eval(i as f32);
                rgba[3] = correct_opacity(rgba[3], spacing);
                rgba.map(|c| (c * unit).round() as u16)
            })
            .collect();
        Self::from_entries(entries, bits)
    }

    /// The table of these entries, with its prefix count of visible entries.
    fn from_entries(entries: Vec<[u16; 4]>, bits: u32) -> Self {
        let mut visible_prefix = Vec::with_capacity(entries.len() + 1);
        let mut count = 0u32;
        visible_prefix.push(0);
        for e in &entries {
            count += (e[3] > 0) as u32;
            visible_prefix.push(count);
        }
        ClassificationTable {
            bits,
            entries,
            visible_prefix,
        }
    }

    #[inline(always)]
    pub fn lookup(&self, density: u16) -> [u16; 4] {
        self.entries[density as usize]
    }

    /// The iso mode's table: opacity 0 below density `first_opaque`, full opacity (colour
    /// `colour`) from it on. Only the leaping structures and the bricks read it (their
    /// emptiness test: a cell whose largest voxel is below the iso value is empty); the
    /// iso comparator and the surface colour do not go through the table.
    pub fn iso(first_opaque: usize, colour: [f32; 3], densities: usize, bits: u32) -> Self {
        let opaque = iso_entry(colour, bits);
        let entries: Vec<[u16; 4]> = (0..densities)
            .map(|i| if i >= first_opaque { opaque } else { [0; 4] })
            .collect();
        Self::from_entries(entries, bits)
    }

    /// Whether any density in [lo, hi] has non-zero opacity in the table: the exact emptiness
    /// test for class occupancy maps, since an interpolated density rounds into [min, max] of
    /// its neighbours.
    pub fn any_visible(&self, lo: u16, hi: u16) -> bool {
        self.visible_prefix[hi as usize + 1] > self.visible_prefix[lo as usize]
    }
}

/// Colour and opacity accumulated along a ray, `bits`-wide unsigned fractions.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Accumulator {
    pub colour: [u32; 3],
    pub alpha: u32,
}

/// Front-to-back compositing in fixed point.
///
/// With unit U = 2^accumulator_bits - 1 (= 1.0), table entries widened to U by
/// `widen(x) = round(x·U / (2^lut_bits - 1))`, and `mul(x, y) = round(x·y / U)` (to nearest;
/// U is odd, so there are no ties):
///
/// ```text
/// w  = mul(U - A, a)        contribution weight
/// A += w
/// C += mul(w, c)            per colour channel
/// ```
///
/// A never exceeds U and each C never exceeds A. ERT: the ray terminates once A >= ceil(t·U).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Compositor {
    pub unit: u32,
    /// log2(U + 1): the accumulator width.
    unit_bits: u32,
    /// `widen` of every table value 0..=2^lut_bits - 1 (a division each, done once here).
    widened: std::sync::Arc<[u32]>,
    /// Raw ERT threshold; without ERT a value A can never reach.
    threshold: u64,
    background: [u32; 4],
}

impl Compositor {
    pub fn new(
        accumulator_bits: u32,
        lut_bits: u32,
        ert_threshold: Option<f32>,
        background: [f32; 4],
    ) -> Self {
        let unit = (1u32 << accumulator_bits) - 1;
        let threshold = match ert_threshold {
            Some(t) => (t as f64 * unit as f64).ceil() as u64,
            None => u64::MAX,
        };
        let lut_unit = (1u32 << lut_bits) - 1;
        let l = lut_unit as u64;
        let widened = (0..=l)
            .map(|x| ((x * unit as u64 + l / 2) / l) as u32)
            .collect();
        Compositor {
            unit,
            unit_bits: accumulator_bits,
            widened,
            threshold,
            background: background.map(|c| to_accumulator(c, unit)),
        }
    }

    /// x·y / U rounded to nearest: floor((x·y + U/2) / U). U = 2^k - 1, and floor(v / U) =
    /// (v + (v >> k) + 1) >> k exactly for every v < 2^2k - 1 (here v <= U² + U/2): two
    /// shifts and two adds instead of a 64-bit division on the ray's critical path (the
    /// accumulated opacity of one sample is an input of the next). `tests` check it against the
    /// division.
    #[inline(always)]
    fn mul(&self, x: u32, y: u32) -> u32 {
        let v = x as u64 * y as u64 + (self.unit as u64 >> 1);
        ((v + (v >> self.unit_bits) + 1) >> self.unit_bits) as u32
    }

    /// A table value (lut_bits) in accumulator units, rounded to nearest.
    #[inline(always)]
    pub fn widen(&self, x: u16) -> u32 {
        self.widened[x as usize]
    }

    /// The raw ERT threshold (accumulator units): the ray stops once A reaches it; `u64::MAX`
    /// without ERT.
    pub fn threshold(&self) -> u64 {
        self.threshold
    }

    /// The background in accumulator units, as `finish` composites it.
    pub fn background(&self) -> [u32; 4] {
        self.background
    }

    /// Composites one classified sample; returns true when the ray has reached the ERT threshold.
    #[inline(always)]
    pub fn composite(&self, acc: &mut Accumulator, rgba: [u16; 4]) -> bool {
        if rgba[3] != 0 {
            let w = self.mul(self.unit - acc.alpha, self.widen(rgba[3]));
            acc.alpha += w;
            for c in 0..3 {
                acc.colour[c] += self.mul(w, self.widen(rgba[c]));
            }
        }
        acc.alpha as u64 >= self.threshold
    }

    /// Composites a sample that stands for `steps` consecutive positions of the same colour and
    /// opacity a (a leap over a homogeneous region): opacity `U - (U - widen(a))^steps`, the
    /// power by squaring over the bits of `steps` from the lowest, each product a `mul`. One
    /// step is exactly `composite`. Returns true at the ERT threshold.
    #[inline(always)]
    pub fn composite_steps(&self, acc: &mut Accumulator, rgba: [u16; 4], steps: u32) -> bool {
        if steps <= 1 || rgba[3] == 0 {
            return self.composite(acc, rgba);
        }
        let a = self.unit - self.power(self.unit - self.widen(rgba[3]), steps);
        let w = self.mul(self.unit - acc.alpha, a);
        acc.alpha += w;
        for c in 0..3 {
            acc.colour[c] += self.mul(w, self.widen(rgba[c]));
        }
        acc.alpha as u64 >= self.threshold
    }

    /// x^k in units of U (x <= U), by squaring: each product rounded by `mul`.
    #[inline(always)]
    fn power(&self, mut x: u32, mut k: u32) -> u32 {
        let mut result = self.unit;
        while k > 0 {
            if k & 1 == 1 {
                result = self.mul(result, x);
            }
            k >>= 1;
            if k > 0 {
                x = self.mul(x, x);
            }
        }
        result
    }

    /// The final pixel: background composited behind, each channel rounded to 8 bits.
    pub fn finish(&self, acc: &Accumulator) -> [u8; 4] {
        self.finish_over(acc, self.background)
    }

    /// The final pixel of a ray: its opaque surface (`FixedRay::surface`, accumulator units)
    /// composited behind when it has one, else the background.
    pub fn finish_ray(&self, acc: &Accumulator, surface: Option<[u32; 4]>) -> [u8; 4] {
        self.finish_over(acc, surface.unwrap_or(self.background))
    }

    /// The final pixel with `background` (accumulator units) composited behind.
    pub fn finish_over(&self, acc: &Accumulator, background: [u32; 4]) -> [u8; 4] {
        let rest = self.unit - acc.alpha;
        let u = self.unit as u64;
        let to8 = |x: u32| ((x as u64 * 255 + u / 2) / u) as u8;
        [
            to8(acc.colour[0] + self.mul(rest, background[0])),
            to8(acc.colour[1] + self.mul(rest, background[1])),
            to8(acc.colour[2] + self.mul(rest, background[2])),
            to8(acc.alpha + self.mul(rest, background[3])),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `mul` and `widen` equal the divisions they replace, for every input at small widths
    /// and for the extremes and a sweep of inputs at every width up to the largest allowed.
    #[test]
    fn mul_and_widen_equal_the_divisions() {
        for acc_bits in 2..=30u32 {
            let unit = (1u64 << acc_bits) - 1;
            for lut_bits in [2u32, 8, 12, 16] {
                let c = Compositor::new(acc_bits, lut_bits, None, [0.0; 4]);
                let l = (1u64 << lut_bits) - 1;
                for x in 0..=l {
                    let expected = (x * unit + l / 2) / l;
                    assert_eq!(
                        c.widen(x as u16) as u64,
                        expected,
                        "widen {x} ({acc_bits}, {lut_bits})"
                    );
                }
            }
            let c = Compositor::new(acc_bits, 8, None, [0.0; 4]);
            let check = |x: u64, y: u64| {
                let expected = mul_unit(x, y, unit);
                assert_eq!(
                    c.mul(x as u32, y as u32) as u64,
                    expected,
                    "mul {x} {y} at {acc_bits} bits"
                );
            };
            if acc_bits <= 8 {
                for x in 0..=unit {
                    for y in 0..=unit {
                        check(x, y);
                    }
                }
            } else {
                let step = (unit / 997).max(1);
                for x in (0..=unit).step_by(step as usize).chain([unit - 1, unit]) {
                    for y in [0, 1, 2, unit / 2, unit - 1, unit, x] {
                        check(x, y);
                    }
                }
            }
        }
    }
}

//! The skip calculator of occupancy-map space leaping (hardware brief §2–3), bit-accurate.
//!
//! These functions are the arithmetic of the hardware unit; the functional model and the cycle
//! model both call them, so the two cannot disagree on a leap.
//!
//! # Conventions
//!
//! - **Positions** `P` (one per axis) are raw `i64` in units of `2^-pos_frac_bits` voxels,
//!   non-negative inside the volume.
//! - **Increments** `V` are stored with `inc_frac_bits ≤ pos_frac_bits` fraction bits and shifted
//!   left exactly into position units ([`SkipWidths::increment_to_pos_units`]). `P + n·V` is then
//!   exact integer arithmetic and equals `n` single steps bit for bit, which is what makes the
//!   leaping image identical to the non-leaping one.
//! - **Sub-cubes** have `s = 2^k` voxels a side (`k = cube_log2`); the occupancy bit of `P` is
//!   indexed by `P_i >> (k + pos_frac_bits)` per axis. The two-level hierarchy calls the same
//!   functions with `k + 1`: a zero byte is an empty `2s` group aligned at even sub-cube addresses,
//!   i.e. at the `(k+1)` sub-cube addresses.
//! - **Distance** per axis ([`exit_distance`]): the position bits below the sub-cube size,
//!   `o = P_i & mask` with `mask = 2^(k + pos_frac_bits) - 1`. For `V_i > 0`, `D'_i = mask - o`,
//!   the distance to the *last* position still inside the sub-cube (a position exactly on the
//!   upper boundary is already in the next one). For `V_i < 0`, `D'_i = o` (the lower boundary
//!   still belongs to the current sub-cube). In both directions the exact number of steps to the
//!   first sample outside the sub-cube is `floor(D'_i / |V_i|) + 1`: for `V_i < 0` the first
//!   position strictly below the lower boundary; for `V_i > 0`,
//!   `floor((mask - o)/V_i) + 1 = ceil((s - o)/V_i)`. This is the brief's `ceil(D/V)` with both
//!   directions handled exactly.
//! - `D'_i` is **narrowed** to `distance_frac_bits` fraction bits by truncation (`D''_i`): rounding
//!   the distance down only shortens the leap, which is safe.
//! - **Reciprocals** `1/a_i`, `a_i = |V_i|` in increment LSBs, are computed once per ray
//!   ([`ray_reciprocals`]) from the quantised increment, not from a float, as an
//!   adaptive-division-table value `R = m · 2^-e` with `m` in `[2^(b-1), 2^b)`,
//!   `b = reciprocal_bits`. The shipped rounding is [`ReciprocalRounding::Down`], so `R ≤ 1/a`
//!   exactly. An axis with `V_i = 0` has no reciprocal and is excluded from the minimum (it never
//!   reaches a boundary).
//! - **Steps** per axis ([`axis_steps`]): `n_i = floor(D''_i · R_i) + 1` (with the units scaled
//!   to voxels), computed exactly in integers. Since `D'' ≤ D'` and `R ≤ 1/a`, `n_i` never exceeds
//!   the exact count.
//!   `n_s = min` over the moving axes ([`leap_steps`]). Every `n_i ≥ 1`, so the brief's
//!   `max(1, ·)` holds by construction: a leap is always at least one step.

use serde::{Deserialize, Serialize};

/// Largest `pos_frac_bits`. Together with [`MAX_CUBE_LOG2`] and `reciprocal_bits ≤ 32` it keeps
/// the exact product `D'' · m · 2^inc_frac_bits` below `2^103`, inside `u128`.
pub const MAX_POS_FRAC_BITS: u32 = 32;
/// Largest sub-cube size `2^7`: sub-cubes go up to 64 voxels (brief §2), and the hierarchy
/// doubles that.
pub const MAX_CUBE_LOG2: u32 = 7;
/// Reciprocal mantissa widths: at least 2 bits to be a table value, at most 32 to fit a `u32`.
pub const RECIPROCAL_BITS: std::ops::RangeInclusive<u32> = 2..=32;

/// A configuration value of the skip calculator outside its allowed range.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "skip calculator: `{field}` = {value} is outside its allowed range {min}..={max}{}",
    max_set_by.map(|f| format!(", at most `{f}`")).unwrap_or_default()
)]
pub struct SkipConfigError {
    pub field: &'static str,
    pub value: u64,
    pub min: u64,
    pub max: u64,
    /// The field whose value is `max`, when the bound is not a constant.
    pub max_set_by: Option<&'static str>,
}

fn check_range(field: &'static str, value: u64, min: u64, max: u64) -> Result<(), SkipConfigError> {
    check_range_up_to(field, value, min, max, None)
}

fn check_range_up_to(
    field: &'static str,
    value: u64,
    min: u64,
    max: u64,
    max_set_by: Option<&'static str>,
) -> Result<(), SkipConfigError> {
    if (min..=max).contains(&value) {
        Ok(())
    } else {
        Err(SkipConfigError {
            field,
            value,
            min,
            max,
            max_set_by,
        })
    }
}

/// The bit widths of the skip calculator's datapath.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SkipWidths {
    /// Fraction bits of a sample position, `0..=MAX_POS_FRAC_BITS`.
    pub pos_frac_bits: u32,
    /// Fraction bits of the stored increment, `0..=pos_frac_bits`.
    pub inc_frac_bits: u32,
    /// Significant bits of the reciprocal mantissa, `2..=32`.
    pub reciprocal_bits: u32,
    /// Fraction bits the distance keeps before the multiplier, `0..=pos_frac_bits`.
    pub distance_frac_bits: u32,
}

impl SkipWidths {
    pub fn new(
        pos_frac_bits: u32,
        inc_frac_bits: u32,
        reciprocal_bits: u32,
        distance_frac_bits: u32,
    ) -> Result<SkipWidths, SkipConfigError> {
        let widths = SkipWidths {
            pos_frac_bits,
            inc_frac_bits,
            reciprocal_bits,
            distance_frac_bits,
        };
        widths.validate()?;
        Ok(widths)
    }

    /// Checks every field against its range; the hot-loop functions assume valid widths.
    pub fn validate(&self) -> Result<(), SkipConfigError> {
        let pos = u64::from(self.pos_frac_bits);
        check_range("pos_frac_bits", pos, 0, MAX_POS_FRAC_BITS.into())?;
        let up_to_pos = Some("pos_frac_bits");
        check_range_up_to(
            "inc_frac_bits",
            self.inc_frac_bits.into(),
            0,
            pos,
            up_to_pos,
        )?;
        check_range(
            "reciprocal_bits",
            self.reciprocal_bits.into(),
            (*RECIPROCAL_BITS.start()).into(),
            (*RECIPROCAL_BITS.end()).into(),
        )?;
        check_range_up_to(
            "distance_frac_bits",
            self.distance_frac_bits.into(),
            0,
            pos,
            up_to_pos,
        )
    }

    /// An increment stored with `inc_frac_bits` fraction bits, in position units (exact).
    #[inline]
    pub fn increment_to_pos_units(&self, v_inc: i64) -> i64 {
        v_inc << (self.pos_frac_bits - self.inc_frac_bits)
    }
}

/// How the per-ray reciprocal is rounded to its mantissa.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ReciprocalRounding {
    /// Toward zero, so `R ≤ 1/a` and no leap overshoots. What the hardware ships.
    Down,
    /// To nearest (a tie up). Unsafe: `R` may exceed `1/a`. It exists so the verifier can show
    /// that it catches the resulting overshoot.
    Nearest,
}

/// `R = mantissa · 2^-exponent ≈ 1/a` for an increment magnitude `a` in increment LSBs;
/// `mantissa` has exactly `reciprocal_bits` significant bits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub struct Reciprocal {
    pub mantissa: u32,
    pub exponent: u32,
}

impl Reciprocal {
    /// The value `mantissa · 2^-exponent` (exact: at most 32 significant bits).
    pub fn value(&self) -> f64 {
        f64::from(self.mantissa) * (-f64::from(self.exponent)).exp2()
    }
}

/// The reciprocal of an increment magnitude `v_abs` given in increment LSBs
/// (`2^-inc_frac_bits` voxels); `None` for 0, an axis that does not move.
#[inline]
pub fn reciprocal(
    v_abs: u64,
    widths: &SkipWidths,
    rounding: ReciprocalRounding,
) -> Option<Reciprocal> {
    if v_abs == 0 {
        return None;
    }
    let bits = widths.reciprocal_bits;
    // With e = b - 1 + ceil(log2 a), 2^e / a lies in [2^(b-1), 2^b): the mantissa is normalised.
    let ceil_log2 = u64::BITS - (v_abs - 1).leading_zeros();
    let exponent = bits - 1 + ceil_log2;
    let a = u128::from(v_abs);
    let mantissa = match rounding {
        ReciprocalRounding::Down => (1u128 << exponent) / a,
        ReciprocalRounding::Nearest => ((1u128 << (exponent + 1)) / a + 1) >> 1,
    };
    // Rounding to nearest may carry into 2^b: renormalise (same value, one bit less exponent).
    let (mantissa, exponent) = if mantissa >> bits != 0 {
        (mantissa >> 1, exponent - 1)
    } else {
        (mantissa, exponent)
    };
    Some(Reciprocal {
        mantissa: mantissa as u32,
        exponent,
    })
}

/// The per-ray reciprocals for an increment `v` in position units (each component a multiple of
/// `2^(pos_frac_bits - inc_frac_bits)`, as [`SkipWidths::increment_to_pos_units`] makes it).
#[inline]
pub fn ray_reciprocals(
    v: [i64; 3],
    widths: &SkipWidths,
    rounding: ReciprocalRounding,
) -> [Option<Reciprocal>; 3] {
    let shift = widths.pos_frac_bits - widths.inc_frac_bits;
    v.map(|v_i| {
        let v_abs = v_i.unsigned_abs();
        debug_assert_eq!(
            v_abs & ((1 << shift) - 1),
            0,
            "increment {v_i} is not quantised to {} fraction bits",
            widths.inc_frac_bits
        );
        reciprocal(v_abs >> shift, widths, rounding)
    })
}

/// `D'_i`, in position units: how far `p_i` can move in the direction of `v_i` and still be in its
/// sub-cube (see the module conventions). Only the position bits below the sub-cube size matter.
#[inline]
pub fn exit_distance(p_i: i64, v_i: i64, cube_log2: u32, pos_frac_bits: u32) -> u64 {
    let mask = (1u64 << (cube_log2 + pos_frac_bits)) - 1;
    let offset = p_i as u64 & mask;
    if v_i > 0 {
        mask - offset
    } else {
        offset
    }
}

/// The skip calculator's step count for one moving axis, `floor(D''_i · R_i) + 1`: never more
/// than [`exact_axis_steps`] when `recip` was rounded down.
#[inline]
pub fn axis_steps(
    p_i: i64,
    v_i: i64,
    recip: &Reciprocal,
    cube_log2: u32,
    widths: &SkipWidths,
) -> u64 {
    let distance = exit_distance(p_i, v_i, cube_log2, widths.pos_frac_bits);
    // Truncation: a shorter distance only shortens the leap.
    let narrowed = distance >> (widths.pos_frac_bits - widths.distance_frac_bits);
    // Steps = (D'' · 2^-dist_frac voxels) / (a · 2^-inc_frac voxels)
    //       ≈ D'' · m · 2^(inc_frac - e - dist_frac); shifting left first keeps both shifts
    //       non-negative.
    let scaled = (u128::from(narrowed) * u128::from(recip.mantissa)) << widths.inc_frac_bits;
    (scaled >> (recip.exponent + widths.distance_frac_bits)) as u64 + 1
}

/// The exact number of steps after which a sample on this axis first lies outside the sub-cube
/// of `p_i`, by integer division. `v_i` must be non-zero. Written from the boundaries themselves,
/// not from [`exit_distance`], so that it checks the calculator instead of repeating it.
#[inline]
pub fn exact_axis_steps(p_i: i64, v_i: i64, cube_log2: u32, pos_frac_bits: u32) -> u64 {
    let size = 1u64 << (cube_log2 + pos_frac_bits);
    let offset = p_i as u64 & (size - 1);
    let magnitude = v_i.unsigned_abs();
    if v_i > 0 {
        // The first position at or above the upper boundary `size`.
        (size - offset).div_ceil(magnitude)
    } else {
        // The first position strictly below the lower boundary 0.
        offset / magnitude + 1
    }
}

/// The leap `n_s` of a ray at `p` with increment `v` (position units) whose current sub-cube
/// (`2^cube_log2` voxels) is empty: the minimum of [`axis_steps`] over the axes that have a
/// reciprocal. `None` when no axis moves.
#[inline]
pub fn leap_steps(
    p: [i64; 3],
    v: [i64; 3],
    recips: &[Option<Reciprocal>; 3],
    cube_log2: u32,
    widths: &SkipWidths,
) -> Option<u64> {
    // An axis without a reciprocal does not move: it never limits the leap. (The minimum of
    // three, not an iterator's: the leap is on the ray's critical path.)
    let steps = [0, 1, 2].map(|axis| match &recips[axis] {
        Some(recip) => axis_steps(p[axis], v[axis], recip, cube_log2, widths),
        None => u64::MAX,
    });
    let n = steps[0].min(steps[1]).min(steps[2]);
    (n != u64::MAX).then_some(n)
}

/// The exact reference for [`leap_steps`]: the number of steps after which `p + n·v` first lies
/// outside the sub-cube of `p`. `None` when `v` is zero.
#[inline]
pub fn exact_steps_to_leave(
    p: [i64; 3],
    v: [i64; 3],
    cube_log2: u32,
    pos_frac_bits: u32,
) -> Option<u64> {
    (0..3)
        .filter(|&axis| v[axis] != 0)
        .map(|axis| exact_axis_steps(p[axis], v[axis], cube_log2, pos_frac_bits))
        .min()
}

/// What [`verify_exhaustive`] checks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VerifyParams {
    pub widths: SkipWidths,
    /// Sub-cube size `2^cube_log2` voxels, `1..=MAX_CUBE_LOG2`.
    pub cube_log2: u32,
    pub rounding: ReciprocalRounding,
    /// Largest increment magnitude enumerated, in increment LSBs.
    pub max_increment: u64,
}

impl VerifyParams {
    /// The cases `verify_skip` enumerates: every position offset in the sub-cube for every
    /// increment magnitude, in both directions.
    pub fn cases(&self) -> u128 {
        (1u128 << (self.cube_log2 + self.widths.pos_frac_bits)) * u128::from(self.max_increment) * 2
    }

    /// Parameters enumerating increments up to one voxel (`2^inc_frac_bits` LSBs).
    pub fn new(widths: SkipWidths, cube_log2: u32, rounding: ReciprocalRounding) -> VerifyParams {
        VerifyParams {
            widths,
            cube_log2,
            rounding,
            max_increment: 1 << widths.inc_frac_bits,
        }
    }

    pub fn validate(&self) -> Result<(), SkipConfigError> {
        self.widths.validate()?;
        check_range("cube_log2", self.cube_log2.into(), 1, MAX_CUBE_LOG2.into())?;
        // The increment must still fit an i64 once shifted into position units.
        let shift = self.widths.pos_frac_bits - self.widths.inc_frac_bits;
        check_range(
            "max_increment",
            self.max_increment,
            1,
            i64::MAX as u64 >> shift,
        )
    }
}

/// The first overshooting case [`verify_exhaustive`] met.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Violation {
    /// Position within the sub-cube, `0..=mask`, in position LSBs.
    pub offset: u64,
    /// Signed increment, in increment LSBs.
    pub increment: i64,
    pub computed_steps: u64,
    pub exact_steps: u64,
}

/// The outcome of [`verify_exhaustive`], with the parameters it ran with.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VerifyReport {
    pub params: VerifyParams,
    /// Cases enumerated: positions × increment magnitudes × 2 directions.
    pub cases: u64,
    /// Cases where the calculator's leap exceeds the exact count (an overshoot).
    pub violations: u64,
    /// Largest `exact - computed` over all cases (an overshooting case counts as 0).
    pub worst_wasted_steps: u64,
    /// Mean of `exact - computed` over all cases (an overshooting case counts as 0).
    pub mean_wasted_steps: f64,
    pub first_violation: Option<Violation>,
}

/// Proves (or refutes) for one set of widths that no leap overshoots, by enumerating every
/// representable case of one axis: every position within a sub-cube (`o` in `0..=mask`; the bits
/// above do not enter the computation), every increment magnitude `1..=max_increment` and both
/// directions.
///
/// One axis is exhaustive for 3D. The 3D leap is `n_s = min_i n_i`, and the first sample outside
/// the sub-cube is at `min_i exact_i` (a sub-cube is a product of intervals). If `n_i ≤ exact_i`
/// on every axis then `n_s ≤ min_i exact_i`: no overshoot per axis means none in 3D. With `j` the
/// axis attaining `n_s`, the 3D waste `min_i exact_i - n_j ≤ exact_j - n_j` is at most the worst
/// single-axis waste, and a ray moving along one axis only attains it: the worst 3D waste equals
/// the worst single-axis waste. (The mean is over uniformly enumerated single-axis cases; a 3D
/// mean depends on the ray distribution.)
pub fn verify_exhaustive(params: &VerifyParams) -> Result<VerifyReport, SkipConfigError> {
    params.validate()?;
    let widths = &params.widths;
    let mask = (1u64 << (params.cube_log2 + widths.pos_frac_bits)) - 1;
    let mut violations = 0u64;
    let mut worst_wasted_steps = 0u64;
    let mut total_wasted_steps = 0u128;
    let mut first_violation = None;
    for magnitude in 1..=params.max_increment {
        let recip = reciprocal(magnitude, widths, params.rounding)
            .expect("a non-zero increment has a reciprocal");
        for increment in [magnitude as i64, -(magnitude as i64)] {
            let v = widths.increment_to_pos_units(increment);
            for offset in 0..=mask {
                let p = offset as i64;
                let computed = axis_steps(p, v, &recip, params.cube_log2, widths);
                let exact = exact_axis_steps(p, v, params.cube_log2, widths.pos_frac_bits);
                if computed > exact {
                    violations += 1;
                    first_violation.get_or_insert(Violation {
                        offset,
                        increment,
                        computed_steps: computed,
                        exact_steps: exact,
                    });
                } else {
                    let wasted = exact - computed;
                    worst_wasted_steps = worst_wasted_steps.max(wasted);
                    total_wasted_steps += u128::from(wasted);
                }
            }
        }
    }
    let cases = params.cases() as u64;
    Ok(VerifyReport {
        params: *params,
        cases,
        violations,
        worst_wasted_steps,
        mean_wasted_steps: total_wasted_steps as f64 / cases as f64,
        first_violation,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn widths(reciprocal_bits: u32) -> SkipWidths {
        SkipWidths::new(8, 8, reciprocal_bits, 8).unwrap()
    }

    #[test]
    fn reciprocal_is_normalised_and_rounded_as_asked() {
        let w = widths(4);
        // 1/3 with 4 bits: 2^5/3 = 10.67 -> 10/32 down, 11/32 to nearest.
        let down = reciprocal(3, &w, ReciprocalRounding::Down).unwrap();
        assert_eq!((down.mantissa, down.exponent), (10, 5));
        let nearest = reciprocal(3, &w, ReciprocalRounding::Nearest).unwrap();
        assert_eq!((nearest.mantissa, nearest.exponent), (11, 5));
        // Powers of two are exact.
        let one = reciprocal(1, &w, ReciprocalRounding::Down).unwrap();
        assert_eq!(one.value(), 1.0);
        assert_eq!(
            reciprocal(256, &w, ReciprocalRounding::Down)
                .unwrap()
                .value(),
            1.0 / 256.0
        );
        // 1/17 with 4 bits: 2^8/17 = 15.06 -> 15, and 1/31: 2^8/31 = 8.26 -> 8.
        assert_eq!(
            reciprocal(17, &w, ReciprocalRounding::Down)
                .unwrap()
                .mantissa,
            15
        );
        assert_eq!(
            reciprocal(31, &w, ReciprocalRounding::Down)
                .unwrap()
                .mantissa,
            8
        );
        // 1/33 to nearest: 2^9/33 = 15.52 -> 16 carries out of 4 bits, renormalised to 8/2^8.
        let carried = reciprocal(33, &w, ReciprocalRounding::Nearest).unwrap();
        assert_eq!((carried.mantissa, carried.exponent), (8, 8));
        assert_eq!(reciprocal(0, &w, ReciprocalRounding::Down), None);
    }

    #[test]
    fn reciprocal_down_never_exceeds_the_true_value() {
        for bits in RECIPROCAL_BITS {
            let w = widths(bits);
            for a in (1..=4096).chain([u64::MAX, u64::MAX - 1, 1 << 63]) {
                let r = reciprocal(a, &w, ReciprocalRounding::Down).unwrap();
                assert!(r.mantissa >> (bits - 1) == 1, "not normalised: {r:?}");
                // m · 2^-e ≤ 1/a  <=>  m · a ≤ 2^e.
                let product = u128::from(r.mantissa) * u128::from(a);
                assert!(
                    product <= 1u128 << r.exponent,
                    "1/{a} at {bits} bits: {r:?}"
                );
            }
        }
    }

    #[test]
    fn widths_validation_names_the_field_and_range() {
        let err = SkipWidths::new(8, 9, 8, 8).unwrap_err();
        assert_eq!(
            err.to_string(),
            "skip calculator: `inc_frac_bits` = 9 is outside its allowed range 0..=8, \
             at most `pos_frac_bits`"
        );
        assert_eq!(
            SkipWidths::new(8, 8, 1, 8).unwrap_err().field,
            "reciprocal_bits"
        );
        assert_eq!(
            SkipWidths::new(8, 8, 33, 8).unwrap_err().field,
            "reciprocal_bits"
        );
        assert_eq!(
            SkipWidths::new(8, 8, 8, 9).unwrap_err().field,
            "distance_frac_bits"
        );
        assert_eq!(
            SkipWidths::new(33, 8, 8, 8).unwrap_err().field,
            "pos_frac_bits"
        );
        let mut params = VerifyParams::new(widths(8), 0, ReciprocalRounding::Down);
        assert_eq!(verify_exhaustive(&params).unwrap_err().field, "cube_log2");
        params.cube_log2 = 4;
        params.max_increment = 0;
        assert_eq!(
            verify_exhaustive(&params).unwrap_err().field,
            "max_increment"
        );
    }
}

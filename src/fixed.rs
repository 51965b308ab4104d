//! Fixed-point numbers whose bit widths are run-time data.
//!
//! Architects sweep bit widths, so a width is a value ([`Format`]), not a type parameter.
//! A [`Fixed`] is a raw two's-complement integer plus its format; its value is
//! `raw · 2^-frac_bits`. Every operation is exact up to one explicit [`Rounding`], and every
//! overflow is an error: nothing wraps or saturates silently.
//!
//! Hot loops work on raw `i64`s with [`shift_right_rounded`], which is exact for every rounding
//! mode and every sign.

use serde::{Deserialize, Serialize};
use std::fmt;

/// Largest total width (integer + fraction + sign bits) of a [`Format`]. 62 rather than 64 so that
/// a sum or difference of two in-range raws never overflows `i64`, and a product fits `i128`.
pub const MAX_TOTAL_BITS: u32 = 62;

/// A fixed-point format: `int_bits` integer bits, `frac_bits` fraction bits, plus one sign bit when
/// `signed`. Raw values range over `[-2^(int+frac), 2^(int+frac) - 1]` (signed) or
/// `[0, 2^(int+frac) - 1]` (unsigned). Fields are private so every `Format` is valid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub struct Format {
    int_bits: u32,
    frac_bits: u32,
    signed: bool,
}

impl Format {
    /// A format of `1..=MAX_TOTAL_BITS` bits in total (the sign bit included).
    pub fn new(int_bits: u32, frac_bits: u32, signed: bool) -> Result<Format, FixedError> {
        let total = u64::from(int_bits) + u64::from(frac_bits) + u64::from(signed);
        if !(1..=u64::from(MAX_TOTAL_BITS)).contains(&total) {
            return Err(FixedError::InvalidFormat {
                int_bits,
                frac_bits,
                signed,
                total,
            });
        }
        Ok(Format {
            int_bits,
            frac_bits,
            signed,
        })
    }

    pub fn int_bits(self) -> u32 {
        self.int_bits
    }

    pub fn frac_bits(self) -> u32 {
        self.frac_bits
    }

    pub fn signed(self) -> bool {
        self.signed
    }

    /// Total width in bits, the sign bit included.
    pub fn total_bits(self) -> u32 {
        self.int_bits + self.frac_bits + u32::from(self.signed)
    }

    pub fn min_raw(self) -> i64 {
        if self.signed {
            -(1i64 << (self.int_bits + self.frac_bits))
        } else {
            0
        }
    }

    pub fn max_raw(self) -> i64 {
        (1i64 << (self.int_bits + self.frac_bits)) - 1
    }

    /// The value of one raw LSB, `2^-frac_bits`.
    pub fn ulp(self) -> f64 {
        1.0 / pow2(self.frac_bits)
    }

    pub fn min_value(self) -> f64 {
        self.min_raw() as f64 * self.ulp()
    }

    /// Nearest `f64` to the largest value (exact up to 53 significant bits).
    pub fn max_value(self) -> f64 {
        self.max_raw() as f64 * self.ulp()
    }

    fn contains_raw(self, raw: i128) -> bool {
        (i128::from(self.min_raw())..=i128::from(self.max_raw())).contains(&raw)
    }
}

impl fmt::Display for Format {
    /// `signed Q3.8` = sign bit, 3 integer bits, 8 fraction bits.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let sign = if self.signed { "signed" } else { "unsigned" };
        write!(f, "{sign} Q{}.{}", self.int_bits, self.frac_bits)
    }
}

/// How a value that falls between two representable values is rounded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Rounding {
    /// Toward minus infinity: what truncating a two's-complement number does.
    Floor,
    /// Toward zero: rounds down in magnitude.
    TowardZero,
    /// To the nearest value, a tie away from zero.
    Nearest,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FixedError {
    #[error(
        "invalid fixed-point format: {int_bits} integer + {frac_bits} fraction bits{} = \
         {total} bits; the total must be in 1..={MAX_TOTAL_BITS}",
        if *signed { " + 1 sign bit" } else { "" }
    )]
    InvalidFormat {
        int_bits: u32,
        frac_bits: u32,
        signed: bool,
        total: u64,
    },
    #[error("{operation}: {value} is not a finite number")]
    NotFinite { operation: &'static str, value: f64 },
    /// `value` is the result that did not fit, as the nearest `f64`.
    #[error(
        "{operation} overflows {format}: {value} is outside its range [{}, {}]",
        .format.min_value(),
        .format.max_value()
    )]
    Overflow {
        operation: &'static str,
        value: f64,
        format: Format,
    },
    #[error("{operation}: operands have different formats ({left} and {right})")]
    FormatMismatch {
        operation: &'static str,
        left: Format,
        right: Format,
    },
}

/// A fixed-point value, `raw · 2^-format.frac_bits()`, with `raw` always inside the format's
/// range.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub struct Fixed {
    raw: i64,
    format: Format,
}

impl Fixed {
    /// The value with this raw integer, if it is inside the format's range.
    pub fn from_raw(raw: i64, format: Format) -> Result<Fixed, FixedError> {
        fit(i128::from(raw), format, "from_raw")
    }

    /// `x` rounded to `format`. NaN, infinities and out-of-range results are errors.
    pub fn from_f64(x: f64, format: Format, rounding: Rounding) -> Result<Fixed, FixedError> {
        const OPERATION: &str = "from_f64";
        if !x.is_finite() {
            return Err(FixedError::NotFinite {
                operation: OPERATION,
                value: x,
            });
        }
        // Scaling by a power of two is exact (it only moves the exponent), so the only rounding
        // is the one asked for. A scaled value too large for f64 becomes inf and fails the range
        // test.
        let scaled = x * pow2(format.frac_bits);
        let rounded = match rounding {
            Rounding::Floor => scaled.floor(),
            Rounding::TowardZero => scaled.trunc(),
            Rounding::Nearest => scaled.round(),
        };
        // min_raw and max_raw + 1 are 0 or powers of two, hence exact in f64; `rounded` is
        // integral.
        let in_range = rounded >= format.min_raw() as f64
            && rounded < pow2(format.int_bits + format.frac_bits);
        if !in_range {
            return Err(FixedError::Overflow {
                operation: OPERATION,
                value: x,
                format,
            });
        }
        Ok(Fixed {
            raw: rounded as i64,
            format,
        })
    }

    pub fn raw(self) -> i64 {
        self.raw
    }

    pub fn format(self) -> Format {
        self.format
    }

    /// The nearest `f64` (exact while `raw` has at most 53 significant bits).
    pub fn to_f64(self) -> f64 {
        self.raw as f64 * self.format.ulp()
    }

    /// This value in `new_format`: fraction bits dropped with `rounding` (or appended exactly),
    /// then the range of `new_format` checked.
    pub fn requantize(self, new_format: Format, rounding: Rounding) -> Result<Fixed, FixedError> {
        let raw = rescale(
            i128::from(self.raw),
            self.format.frac_bits,
            new_format.frac_bits,
            rounding,
        );
        fit_rescaled(raw, self.to_f64(), new_format, "requantize")
    }

    /// `self + other`, both in the same format; the sum must fit that format.
    pub fn checked_add(self, other: Fixed) -> Result<Fixed, FixedError> {
        let format = self.same_format(other, "checked_add")?;
        fit(
            i128::from(self.raw) + i128::from(other.raw),
            format,
            "checked_add",
        )
    }

    /// `self - other`, both in the same format; the difference must fit that format.
    pub fn checked_sub(self, other: Fixed) -> Result<Fixed, FixedError> {
        let format = self.same_format(other, "checked_sub")?;
        fit(
            i128::from(self.raw) - i128::from(other.raw),
            format,
            "checked_sub",
        )
    }

    /// `self · other`: the exact product (in `i128`), rounded once to `result_format`'s fraction
    /// bits with `rounding`, then range-checked.
    pub fn checked_mul(
        self,
        other: Fixed,
        result_format: Format,
        rounding: Rounding,
    ) -> Result<Fixed, FixedError> {
        let product_frac = self.format.frac_bits + other.format.frac_bits;
        let product = i128::from(self.raw) * i128::from(other.raw);
        let raw = rescale(product, product_frac, result_format.frac_bits, rounding);
        fit_rescaled(
            raw,
            self.to_f64() * other.to_f64(),
            result_format,
            "checked_mul",
        )
    }

    fn same_format(self, other: Fixed, operation: &'static str) -> Result<Format, FixedError> {
        if self.format == other.format {
            Ok(self.format)
        } else {
            Err(FixedError::FormatMismatch {
                operation,
                left: self.format,
                right: other.format,
            })
        }
    }
}

impl fmt::Display for Fixed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} ({})", self.to_f64(), self.format)
    }
}

/// Generates `shift_right_rounded` for one integer width, so the i64 hot-loop version and the
/// i128 version used for exact products share one implementation.
macro_rules! shift_right_rounded_impl {
    ($(#[$doc:meta])* $vis:vis fn $name:ident($int:ty, $uint:ty)) => {
        $(#[$doc])*
        #[inline]
        $vis fn $name(raw: $int, shift: u32, rounding: Rounding) -> $int {
            debug_assert!(shift < <$int>::BITS, "shift {shift} out of range");
            if shift == 0 {
                return raw;
            }
            // raw = quotient · 2^shift + remainder, remainder in [0, 2^shift): the quotient is the
            // floor, and the other modes add at most one. No intermediate can overflow.
            let quotient = raw >> shift;
            let remainder = raw & (((1 as $uint) << shift) - 1) as $int;
            let round_up = match rounding {
                Rounding::Floor => false,
                Rounding::TowardZero => raw < 0 && remainder != 0,
                Rounding::Nearest => {
                    let half: $int = 1 << (shift - 1);
                    remainder > half || (remainder == half && raw >= 0)
                }
            };
            quotient + <$int>::from(round_up)
        }
    };
}

shift_right_rounded_impl!(
    /// `raw / 2^shift` rounded with `rounding`, exact for every `raw` (negatives included) and
    /// every `shift` in `0..64`.
    pub fn shift_right_rounded(i64, u64)
);

shift_right_rounded_impl!(
    /// [`shift_right_rounded`] for exact products; `shift` in `0..128`.
    fn shift_right_rounded_wide(i128, u128)
);

/// `2^exponent` as an exact `f64` (exponent ≤ 62).
fn pow2(exponent: u32) -> f64 {
    (1u64 << exponent) as f64
}

/// `raw` (with `from_frac` fraction bits) in units of `2^-to_frac`, or `None` when appending
/// fraction bits would not fit `i128` (then it does not fit any format either).
fn rescale(raw: i128, from_frac: u32, to_frac: u32, rounding: Rounding) -> Option<i128> {
    if to_frac >= from_frac {
        let shift = to_frac - from_frac;
        let shifted = raw << shift;
        (shifted >> shift == raw).then_some(shifted)
    } else {
        Some(shift_right_rounded_wide(raw, from_frac - to_frac, rounding))
    }
}

fn fit_rescaled(
    raw: Option<i128>,
    value: f64,
    format: Format,
    operation: &'static str,
) -> Result<Fixed, FixedError> {
    match raw {
        Some(raw) => fit(raw, format, operation),
        None => Err(FixedError::Overflow {
            operation,
            value,
            format,
        }),
    }
}

/// `raw` (in units of `format`'s LSB) as a `Fixed` if it is in range, else an overflow error.
fn fit(raw: i128, format: Format, operation: &'static str) -> Result<Fixed, FixedError> {
    if format.contains_raw(raw) {
        Ok(Fixed {
            raw: raw as i64,
            format,
        })
    } else {
        Err(FixedError::Overflow {
            operation,
            value: raw as f64 * format.ulp(),
            format,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn format(int_bits: u32, frac_bits: u32, signed: bool) -> Format {
        Format::new(int_bits, frac_bits, signed).unwrap()
    }

    #[test]
    fn format_range_and_validation() {
        let f = format(3, 8, true);
        assert_eq!(
            (f.min_raw(), f.max_raw(), f.total_bits()),
            (-2048, 2047, 12)
        );
        assert_eq!(f.ulp(), 1.0 / 256.0);
        assert_eq!(f.to_string(), "signed Q3.8");
        let u = format(3, 8, false);
        assert_eq!((u.min_raw(), u.max_raw()), (0, 2047));
        assert!(Format::new(31, 31, false).is_ok());
        assert!(Format::new(31, 31, true).is_err());
        assert!(Format::new(0, 0, false).is_err());
        assert!(Format::new(u32::MAX, u32::MAX, true).is_err());
        let widest = format(0, 61, true);
        assert_eq!(widest.min_raw(), -(1 << 61));
    }

    #[test]
    fn shift_right_rounded_each_mode_positive_negative_tie() {
        use Rounding::*;
        // (raw, shift, floor, toward zero, nearest): ±2.75, ties ±2.5 and ±0.5, ±2.25, exact -3.
        let cases: [(i64, u32, i64, i64, i64); 9] = [
            (11, 2, 2, 2, 3),
            (-11, 2, -3, -2, -3),
            (10, 2, 2, 2, 3),
            (-10, 2, -3, -2, -3),
            (1, 1, 0, 0, 1),
            (-1, 1, -1, 0, -1),
            (9, 2, 2, 2, 2),
            (-9, 2, -3, -2, -2),
            (-12, 2, -3, -3, -3),
        ];
        for (raw, shift, floor, toward_zero, nearest) in cases {
            assert_eq!(shift_right_rounded(raw, shift, Floor), floor, "{raw} floor");
            assert_eq!(
                shift_right_rounded(raw, shift, TowardZero),
                toward_zero,
                "{raw} toward zero"
            );
            assert_eq!(
                shift_right_rounded(raw, shift, Nearest),
                nearest,
                "{raw} nearest"
            );
        }
        for rounding in [Floor, TowardZero, Nearest] {
            assert_eq!(shift_right_rounded(-7, 0, rounding), -7);
        }
        // Extremes: no intermediate overflow.
        assert_eq!(shift_right_rounded(i64::MAX, 63, Nearest), 1);
        assert_eq!(shift_right_rounded(i64::MAX, 1, Nearest), 1 << 62);
        assert_eq!(shift_right_rounded(i64::MIN, 63, TowardZero), -1);
        assert_eq!(shift_right_rounded(i64::MIN + 1, 63, TowardZero), 0);
        assert_eq!(shift_right_rounded(i64::MIN + 1, 63, Nearest), -1);
    }

    #[test]
    fn from_f64_each_mode_positive_negative_tie() {
        use Rounding::*;
        let f = format(4, 2, true); // ulp 0.25
        let raw = |x: f64, r: Rounding| Fixed::from_f64(x, f, r).unwrap().raw();
        assert_eq!(
            [raw(0.3, Floor), raw(0.3, TowardZero), raw(0.3, Nearest)],
            [1, 1, 1]
        );
        assert_eq!(
            [raw(0.45, Floor), raw(0.45, TowardZero), raw(0.45, Nearest)],
            [1, 1, 2]
        );
        assert_eq!(
            [raw(-0.3, Floor), raw(-0.3, TowardZero), raw(-0.3, Nearest)],
            [-2, -1, -1]
        );
        // Ties: 0.375 = 1.5 ulp, -0.375 = -1.5 ulp.
        assert_eq!(
            [
                raw(0.375, Floor),
                raw(0.375, TowardZero),
                raw(0.375, Nearest)
            ],
            [1, 1, 2]
        );
        assert_eq!(
            [
                raw(-0.375, Floor),
                raw(-0.375, TowardZero),
                raw(-0.375, Nearest)
            ],
            [-2, -1, -2]
        );
        assert_eq!(Fixed::from_f64(-0.375, f, Nearest).unwrap().to_f64(), -0.5);
    }

    #[test]
    fn from_f64_rejects_non_finite_and_out_of_range() {
        let f = format(4, 2, true);
        for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let err = Fixed::from_f64(x, f, Rounding::Floor).unwrap_err();
            assert!(matches!(err, FixedError::NotFinite { .. }), "{err}");
        }
        // max_raw = 63 (15.75); max_raw + 1 is 16.0.
        assert_eq!(
            Fixed::from_f64(15.75, f, Rounding::Nearest).unwrap().raw(),
            63
        );
        let err = Fixed::from_f64(16.0, f, Rounding::Floor).unwrap_err();
        assert_eq!(
            err.to_string(),
            "from_f64 overflows signed Q4.2: 16 is outside its range [-16, 15.75]"
        );
        // Rounding itself can overflow: 15.9 rounds to 16.0 only with Nearest.
        assert!(Fixed::from_f64(15.9, f, Rounding::Floor).is_ok());
        assert!(Fixed::from_f64(15.9, f, Rounding::Nearest).is_err());
        assert!(Fixed::from_f64(-16.0, f, Rounding::Floor).is_ok());
        assert!(Fixed::from_f64(-16.1, f, Rounding::TowardZero).is_ok());
        assert!(Fixed::from_f64(-16.1, f, Rounding::Floor).is_err());
        assert!(Fixed::from_f64(-0.25, format(4, 2, false), Rounding::Floor).is_err());
        assert!(Fixed::from_f64(1e300, f, Rounding::Floor).is_err());
    }

    #[test]
    fn overflow_detected_at_exactly_max_raw_plus_one() {
        for f in [
            format(4, 2, true),
            format(0, 62, false),
            format(30, 31, true),
        ] {
            let max = Fixed::from_raw(f.max_raw(), f).unwrap();
            let min = Fixed::from_raw(f.min_raw(), f).unwrap();
            let one_ulp = Fixed::from_raw(1, f).unwrap();
            assert!(Fixed::from_raw(f.max_raw() + 1, f).is_err());
            assert!(Fixed::from_raw(f.min_raw() - 1, f).is_err());
            assert!(max.checked_add(one_ulp).is_err());
            assert_eq!(max.checked_sub(one_ulp).unwrap().raw(), f.max_raw() - 1);
            assert!(min.checked_sub(one_ulp).is_err());
            // One more fraction bit, one fewer integer bit: max_raw no longer fits.
            if f.int_bits() > 0 {
                let narrower = format(f.int_bits() - 1, f.frac_bits() + 1, f.signed());
                assert!(max.requantize(narrower, Rounding::Floor).is_err());
                let half_max = Fixed::from_raw(f.max_raw() / 2, f).unwrap();
                assert!(half_max.requantize(narrower, Rounding::Floor).is_ok());
            }
        }
    }

    #[test]
    fn add_sub_require_equal_formats() {
        let a = Fixed::from_raw(1, format(4, 2, true)).unwrap();
        let b = Fixed::from_raw(1, format(4, 3, true)).unwrap();
        assert!(matches!(
            a.checked_add(b),
            Err(FixedError::FormatMismatch { .. })
        ));
        assert!(a.checked_sub(b).is_err());
    }

    #[test]
    fn requantize_rounds_in_each_mode() {
        use Rounding::*;
        let fine = format(4, 4, true);
        let coarse = format(4, 1, true);
        // -1.4375 = -23/16 -> halves: floor -1.5, toward zero -1.0, nearest -1.5.
        let x = Fixed::from_raw(-23, fine).unwrap();
        assert_eq!(x.requantize(coarse, Floor).unwrap().to_f64(), -1.5);
        assert_eq!(x.requantize(coarse, TowardZero).unwrap().to_f64(), -1.0);
        assert_eq!(x.requantize(coarse, Nearest).unwrap().to_f64(), -1.5);
        // Appending fraction bits is exact.
        let back = x.requantize(format(4, 10, true), Floor).unwrap();
        assert_eq!(back.to_f64(), x.to_f64());
    }

    #[test]
    fn mul_rounds_the_exact_product_once() {
        use Rounding::*;
        let f = format(3, 2, true);
        let a = Fixed::from_f64(1.25, f, Floor).unwrap();
        let b = Fixed::from_f64(-1.75, f, Floor).unwrap();
        // Exact product -2.1875 rounded to quarters.
        assert_eq!(a.checked_mul(b, f, Floor).unwrap().to_f64(), -2.25);
        assert_eq!(a.checked_mul(b, f, TowardZero).unwrap().to_f64(), -2.0);
        assert_eq!(a.checked_mul(b, f, Nearest).unwrap().to_f64(), -2.25);
        assert_eq!(
            a.checked_mul(b, format(3, 4, true), Floor)
                .unwrap()
                .to_f64(),
            -2.1875
        );
        // 7.75² = 60.0625 does not fit 3 integer bits; the widest formats stay exact in i128.
        let big = Fixed::from_raw(f.max_raw(), f).unwrap();
        assert!(big.checked_mul(big, f, Floor).is_err());
        let wide = format(30, 31, true);
        let w = Fixed::from_raw(wide.max_raw(), wide).unwrap();
        assert!(w.checked_mul(w, wide, Floor).is_err());
        // (2^61 - 1) · 2^-62, exact with 62 fraction bits, a tie away from zero with 61.
        let tiny = Fixed::from_raw(1, wide).unwrap();
        let exact = w.checked_mul(tiny, format(0, 62, false), Floor).unwrap();
        assert_eq!(exact.raw(), (1 << 61) - 1);
        let halved = w.checked_mul(tiny, format(0, 61, true), Nearest).unwrap();
        assert_eq!(halved.raw(), 1 << 60);
        // A ~2^122 integer product given 62 fraction bits leaves even i128: still an error.
        let integer = format(61, 0, false);
        let n = Fixed::from_raw(integer.max_raw(), integer).unwrap();
        assert!(n.checked_mul(n, format(0, 62, false), Floor).is_err());
    }

    fn any_format() -> impl Strategy<Value = Format> {
        (0u32..=30, 0u32..=30, any::<bool>())
            .prop_filter("non-empty", |&(i, f, s)| i + f + u32::from(s) > 0)
            .prop_map(|(i, f, s)| format(i, f, s))
    }

    proptest! {
        #[test]
        fn from_f64_floor_is_below_and_within_one_ulp(
            (f, x) in any_format().prop_flat_map(|f| (Just(f), f.min_value()..f.max_value()))
        ) {
            let fixed = Fixed::from_f64(x, f, Rounding::Floor).unwrap();
            // Both sides are exact: to_f64 of a raw that came from an f64, and the difference of
            // two values that share the power-of-two grid.
            let below = x - fixed.to_f64();
            prop_assert!(below >= 0.0, "{fixed} exceeds {x}");
            prop_assert!(below < f.ulp(), "{fixed} is more than one ulp below {x}");
        }

        #[test]
        fn shift_right_rounded_matches_integer_division(raw in any::<i64>(), shift in 0u32..63) {
            let divisor = 1i128 << shift;
            let wide = i128::from(raw);
            let floor = wide.div_euclid(divisor);
            let toward_zero = wide / divisor;
            let magnitude = (wide.abs() + divisor / 2) / divisor;
            let nearest = magnitude * wide.signum();
            prop_assert_eq!(i128::from(shift_right_rounded(raw, shift, Rounding::Floor)), floor);
            prop_assert_eq!(
                i128::from(shift_right_rounded(raw, shift, Rounding::TowardZero)),
                toward_zero
            );
            prop_assert_eq!(
                i128::from(shift_right_rounded(raw, shift, Rounding::Nearest)),
                nearest
            );
        }
    }
}

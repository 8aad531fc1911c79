//! Decimal numbers for the protocol and for messages, without core's float parsing and
//! formatting, whose tables and big-number code would take most of the firmware's flash.
//!
//! [`split_decimal`] reads what `str::parse::<f64>` reads: `[+-]` then digits with an optional
//! fraction (`50`, `62.5`, `.6`, `5.`) and an optional exponent (`1e2`, `2.5E-3`), or `inf`,
//! `infinity` or `nan` in any case. It keeps the first 19 significant digits as an integer `m` and
//! scales it by exact powers of ten up to `10^22`, each step rounded once. With `m` (less any
//! trailing zeros that are fraction digits) and the decimal exponent `e` of its last digit:
//! * `m < 2^53` (always true for 15 significant digits) and `|e| ≤ 22`, which covers every number
//!   an operator types: correctly rounded, the same `f64` as `str::parse`;
//! * otherwise one rounding for `m` and one per step, each within 2^-53 relative: a relative error
//!   of at most 2^-52 for `|e| ≤ 22` and 17·2^-53 for the most extreme exponents (results below
//!   `f64::MIN_POSITIVE` lose precision gradually, as subnormals do, and values within that error
//!   of `f64::MAX` may overflow).
//!
//! Values that overflow are infinite; those below half the smallest subnormal are zero.
//!
//! [`parse_length`] reads a length with its unit (`2.5mm`, `0.0025 m`, `2500um`, `2500µm`), the
//! unit's power of ten applied to the decimal exponent before that one rounding.
//!
//! [`Fixed`] and [`Significant`] print numbers with integer arithmetic: a fixed number of
//! decimals for replies, and 15 significant digits for explanations.

use core::fmt;

/// Significant digits kept while reading a number: `10^19 − 1` still fits a `u64`.
const MAX_DIGITS_VALUE: u64 = 1_000_000_000_000_000_000;
/// Largest power of ten an `f64` holds exactly.
const MAX_EXACT_POWER: i32 = 22;
/// Digits printed by [`Significant`]: any decimal with this many digits reads back as written.
const SIGNIFICANT_DIGITS: i32 = 15;
/// Scaled values from `2^53` on, where an `f64` no longer holds every integer, print as
/// [`Significant`] in [`Fixed`].
const MAX_FIXED_SCALED: f64 = 9_007_199_254_740_992.0;

/// Splits `text` into its longest prefix that is a decimal number and the rest (see the module
/// documentation); `None` if no prefix is a number.
pub fn split_decimal(text: &str) -> Option<(f64, &str)> {
    split_scaled_decimal(text, 0)
}

/// A unit of length a typed number may carry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LengthUnit {
    Metre,
    Millimetre,
    Micrometre,
}

impl LengthUnit {
    /// The words that name each unit, ASCII case ignored: `um` and `µm` with the micro sign
    /// (U+00B5) or the Greek mu (U+03BC) for the micrometre.
    const WORDS: [(&'static str, LengthUnit); 5] = [
        ("m", LengthUnit::Metre),
        ("mm", LengthUnit::Millimetre),
        ("um", LengthUnit::Micrometre),
        ("\u{b5}m", LengthUnit::Micrometre),
        ("\u{3bc}m", LengthUnit::Micrometre),
    ];

    /// The unit `word` names, if any.
    pub fn from_word(word: &str) -> Option<Self> {
        Self::WORDS
            .iter()
            .find(|(name, _)| name.eq_ignore_ascii_case(word))
            .map(|&(_, unit)| unit)
    }

    /// The unit's symbol.
    pub const fn symbol(self) -> &'static str {
        match self {
            LengthUnit::Metre => "m",
            LengthUnit::Millimetre => "mm",
            LengthUnit::Micrometre => "µm",
        }
    }

    /// One unit is `10^power` metres.
    const fn metre_power(self) -> i32 {
        match self {
            LengthUnit::Metre => 0,
            LengthUnit::Millimetre => -3,
            LengthUnit::Micrometre => -6,
        }
    }
}

/// Why [`parse_length`] refused a text.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LengthError {
    /// The text does not begin with a decimal number.
    NotANumber,
    /// The number is infinite or NaN.
    NotFinite,
    /// What follows the number is not a unit of length.
    UnknownUnit,
}

impl fmt::Display for LengthError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            LengthError::NotANumber => "a length must begin with a decimal number",
            LengthError::NotFinite => "a length must be finite",
            LengthError::UnknownUnit => "the unit of a length must be m, mm, um or µm",
        })
    }
}

impl core::error::Error for LengthError {}

/// Reads a length in `unit`: a decimal number (as [`split_decimal`] reads it) with an optional
/// unit of length, attached or after blanks (`2.5mm`, `2.5 mm`, `0.0025m`, `2500um`, `2500µm`);
/// a number without one is in `bare`. The units' ratio is a power of ten applied before the one
/// rounding, so `2500um` in millimetres is exactly `2.5`.
pub fn parse_length(text: &str, bare: LengthUnit, unit: LengthUnit) -> Result<f64, LengthError> {
    let (_, rest) = split_decimal(text).ok_or(LengthError::NotANumber)?;
    let word = rest.trim_start_matches([' ', '\t']);
    let typed = if word.is_empty() {
        bare
    } else {
        LengthUnit::from_word(word).ok_or(LengthError::UnknownUnit)?
    };
    let (length, _) = split_scaled_decimal(text, typed.metre_power() - unit.metre_power())
        .ok_or(LengthError::NotANumber)?;
    if length.is_finite() {
        Ok(length)
    } else {
        Err(LengthError::NotFinite)
    }
}

/// [`split_decimal`] of the number times `10^power`, the power added to its decimal exponent.
fn split_scaled_decimal(text: &str, power: i32) -> Option<(f64, &str)> {
    let bytes = text.as_bytes();
    let negative = bytes.first() == Some(&b'-');
    let mut at = usize::from(matches!(bytes.first(), Some(b'-' | b'+')));
    let signed = |magnitude: f64| if negative { -magnitude } else { magnitude };
    for (word, value) in [
        ("infinity", f64::INFINITY),
        ("inf", f64::INFINITY),
        ("nan", f64::NAN),
    ] {
        let end = at + word.len();
        if bytes
            .get(at..end)
            .is_some_and(|head| head.eq_ignore_ascii_case(word.as_bytes()))
        {
            return Some((signed(value), text.get(end..)?));
        }
    }

    let mut mantissa = 0u64;
    let mut exponent = 0i32;
    let mut any_digit = false;
    let mut in_fraction = false;
    while let Some(&byte) = bytes.get(at) {
        match byte {
            b'0'..=b'9' => {
                any_digit = true;
                if mantissa < MAX_DIGITS_VALUE {
                    mantissa = mantissa * 10 + u64::from(byte - b'0');
                    exponent -= i32::from(in_fraction);
                } else {
                    exponent += i32::from(!in_fraction);
                }
            }
            b'.' if !in_fraction => in_fraction = true,
            _ => break,
        }
        at += 1;
    }
    if !any_digit {
        return None;
    }
    if let Some((typed, end)) = exponent_part(bytes, at) {
        exponent = exponent.saturating_add(typed);
        at = end;
    }
    exponent = exponent.saturating_add(power);
    Some((signed(scaled_integer(mantissa, exponent)), text.get(at..)?))
}

/// The exponent `e[+-]digits` starting at `at`, saturated far beyond `f64`'s range, and where it
/// ends; `None` if there is none.
fn exponent_part(bytes: &[u8], at: usize) -> Option<(i32, usize)> {
    if !matches!(bytes.get(at), Some(b'e' | b'E')) {
        return None;
    }
    let mut end = at + 1;
    let negative = bytes.get(end) == Some(&b'-');
    end += usize::from(matches!(bytes.get(end), Some(b'-' | b'+')));
    let start = end;
    let mut power = 0i32;
    while let Some(&digit @ b'0'..=b'9') = bytes.get(end) {
        power = (power * 10 + i32::from(digit - b'0')).min(100_000);
        end += 1;
    }
    (end > start).then_some((if negative { -power } else { power }, end))
}

/// `mantissa · 10^exponent` as the nearest `f64` within the accuracy of the module documentation.
fn scaled_integer(mut mantissa: u64, mut exponent: i32) -> f64 {
    if mantissa == 0 {
        return 0.0;
    }
    // Dropping trailing zeros towards a zero exponent saves steps and keeps `mantissa` exact.
    while exponent < 0 && mantissa % 10 == 0 {
        mantissa /= 10;
        exponent += 1;
    }
    // 10^309 already overflows; below 10^-344 even 19 digits stay under half the least subnormal.
    if exponent > 308 {
        f64::INFINITY
    } else if exponent < -344 {
        0.0
    } else {
        scale(mantissa as f64, exponent)
    }
}

/// `value · 10^power`, the remainder power first and then whole steps of `10^22`, so that an
/// intermediate result only overflows or underflows if the final one does.
fn scale(value: f64, power: i32) -> f64 {
    let steps = power / MAX_EXACT_POWER;
    let mut scaled = multiply_by_power(value, power % MAX_EXACT_POWER);
    for _ in 0..steps.unsigned_abs() {
        scaled = multiply_by_power(scaled, steps.signum() * MAX_EXACT_POWER);
    }
    scaled
}

/// `value · 10^power` with one rounding, for `|power| ≤ 22`.
fn multiply_by_power(value: f64, power: i32) -> f64 {
    let factor = power_of_ten(power.unsigned_abs());
    if power < 0 {
        value / factor
    } else {
        value * factor
    }
}

/// `10^power`, exact for `power ≤ 22`.
fn power_of_ten(power: u32) -> f64 {
    (0..power).fold(1.0, |product, _| product * 10.0)
}

/// `value` rounded to `decimals` places (at most 22), without trailing zeros or a sign on zero:
/// `Fixed { value: 2.50, decimals: 3 }` prints `2.5`.
///
/// Rounding follows the exact binary value, ties to even, as core's `{:.*}` does. Values of
/// `2^53 / 10^decimals` and more (and non-finite ones) print as [`Significant`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fixed {
    pub value: f64,
    pub decimals: u32,
}

impl fmt::Display for Fixed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let factor = power_of_ten(self.decimals);
        let scaled = self.value.abs() * factor;
        if scaled.is_nan() || scaled >= MAX_FIXED_SCALED {
            return Significant(self.value).fmt(f);
        }
        let whole = round_ties_even(scaled, product_error(self.value.abs(), factor, scaled));
        if whole == 0 {
            return f.write_str("0");
        }
        let digits = Digits::new(whole);
        let integer_digits = digits.all().len() as i32 - self.decimals as i32;
        write_plain(f, self.value < 0.0, digits.trimmed(), integer_digits)
    }
}

/// `value` to 15 significant digits, without trailing zeros: plain from `0.00001` up to below
/// `10^15` (`0.333333333333333`, `1500`), scientific beyond (`1.5e-7`, `6.02214076e23`); `NaN`,
/// `inf` and `-inf` as core prints them, and zero as `0`.
///
/// From `10^-8` to below `10^37` the value is scaled to 15 integer digits with one rounding, then
/// rounded to an integer: the last digit is the exact value's unless the scaled value lay within
/// that first rounding of a tie (about 3 % of values), when it may be one off; beyond, scaling
/// takes several roundings and the last digit may be one off too.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Significant(pub f64);

impl fmt::Display for Significant {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let value = self.0;
        if value.is_nan() {
            return f.write_str("NaN");
        }
        if value < 0.0 {
            f.write_str("-")?;
        }
        let magnitude = value.abs();
        if magnitude.is_infinite() {
            return f.write_str("inf");
        }
        if magnitude == 0.0 {
            return f.write_str("0");
        }
        let (whole, exponent) = significant_digits(magnitude);
        let digits = Digits::new(whole);
        if (-5..SIGNIFICANT_DIGITS).contains(&exponent) {
            return write_plain(f, false, digits.trimmed(), exponent + 1);
        }
        write_plain(f, false, digits.trimmed(), 1)?;
        f.write_str("e")?;
        let exponent_digits = Digits::new(exponent.unsigned_abs().into());
        let all = exponent_digits.all();
        write_plain(f, exponent < 0, all, all.len() as i32)
    }
}

/// The 15 significant digits of a finite `magnitude > 0` as an integer in `10^14..10^15`, and the
/// decimal exponent of the first one.
fn significant_digits(magnitude: f64) -> (u64, i32) {
    let lowest = power_of_ten(SIGNIFICANT_DIGITS as u32 - 1) as u64;
    // ⌊log10 2^e⌋ from the binary exponent: the decimal exponent or one less.
    let (normal, binary_shift) = if magnitude < f64::MIN_POSITIVE {
        (magnitude * 18_014_398_509_481_984.0, 54)
    } else {
        (magnitude, 0)
    };
    let binary_exponent = ((normal.to_bits() >> 52) as i32) - 1023 - binary_shift;
    let mut exponent = (binary_exponent * 78_913) >> 18;
    let digits = |exponent: i32| {
        let scaled = scale(magnitude, SIGNIFICANT_DIGITS - 1 - exponent);
        round_ties_even(scaled, 0.0)
    };
    let mut whole = digits(exponent);
    if whole >= 10 * lowest {
        exponent += 1;
        whole = digits(exponent);
    }
    (whole.max(lowest), exponent)
}

/// `a · b − product` exactly, for the rounded `product = a · b` (Dekker's two-product).
fn product_error(a: f64, b: f64, product: f64) -> f64 {
    let split = |x: f64| {
        let spread = x * 134_217_729.0;
        let high = spread - (spread - x);
        (high, x - high)
    };
    let (a_high, a_low) = split(a);
    let (b_high, b_low) = split(b);
    (((a_high * b_high - product) + a_high * b_low) + a_low * b_high) + a_low * b_low
}

/// The integer nearest to `scaled + error` (`0 ≤ scaled < 2^53`, `|error|` at most half an ulp of
/// `scaled`), ties to even.
fn round_ties_even(scaled: f64, error: f64) -> u64 {
    let whole = scaled as u64;
    let fraction = scaled - whole as f64;
    let up =
        fraction > 0.5 || (fraction == 0.5 && (error > 0.0 || (error == 0.0 && whole % 2 == 1)));
    whole + u64::from(up)
}

/// The decimal digits of an integer, most significant first.
struct Digits {
    buffer: [u8; 20],
    start: usize,
}

impl Digits {
    fn new(mut value: u64) -> Self {
        let mut digits = Digits {
            buffer: [b'0'; 20],
            start: 20,
        };
        loop {
            digits.start -= 1;
            digits.buffer[digits.start] = b'0' + (value % 10) as u8;
            value /= 10;
            if value == 0 {
                return digits;
            }
        }
    }

    /// Every digit, from the most significant one.
    fn all(&self) -> &[u8] {
        &self.buffer[self.start..]
    }

    /// The digits without trailing zeros (`0` stays `0`).
    fn trimmed(&self) -> &[u8] {
        let digits = self.all();
        let end = digits
            .iter()
            .rposition(|&d| d != b'0')
            .map_or(1, |last| last + 1);
        &digits[..end]
    }
}

/// `digits` (ASCII, no trailing zeros) with the decimal point after `integer_digits` of them,
/// padded with zeros on either side as needed: `("25", 1)` is `2.5`, `("5", 3)` is `500` and
/// `("5", -2)` is `0.005`.
fn write_plain(
    f: &mut fmt::Formatter<'_>,
    negative: bool,
    digits: &[u8],
    integer_digits: i32,
) -> fmt::Result {
    if negative {
        f.write_str("-")?;
    }
    let split = integer_digits.clamp(0, digits.len() as i32) as usize;
    let (integer, fraction) = digits.split_at(split);
    if integer.is_empty() {
        f.write_str("0")?;
    }
    f.write_str(ascii(integer)?)?;
    for _ in digits.len() as i32..integer_digits {
        f.write_str("0")?;
    }
    if !fraction.is_empty() {
        f.write_str(".")?;
        for _ in integer_digits..0 {
            f.write_str("0")?;
        }
        f.write_str(ascii(fraction)?)?;
    }
    Ok(())
}

fn ascii(digits: &[u8]) -> Result<&str, fmt::Error> {
    core::str::from_utf8(digits).map_err(|_| fmt::Error)
}

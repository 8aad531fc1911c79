//! `{=f64}` as defmt's decoder prints it (the `ryu` crate's layout): the shortest digits that
//! read back as the same value, positional from `1e-5` to below `1e16` with at least one decimal
//! (`50.0`, `0.00005`), scientific outside (`1e-7`, `8.611636210880064e-7`, `1e16`). The digits
//! are Rust's (`{:e}`), read byte by byte (see [`super`] on the generic string code the firmware
//! also uses).

use core::fmt::{self, Write};

/// Writes `value` as the decoder prints an `{=f64}`.
pub(super) fn write(f: &mut fmt::Formatter<'_>, value: f64) -> fmt::Result {
    if !value.is_finite() {
        return write!(f, "{value}");
    }
    let decimal = Decimal::of(value.abs())?;
    let (digits, length) = (decimal.digits(), decimal.length);
    // The value is 0.`digits` × 10^`point`.
    let point = decimal.exponent + 1;
    if value.is_sign_negative() {
        f.write_char('-')?;
    }
    if (length..=16).contains(&point) {
        write_chars(f, digits)?;
        write_chars(f, (length..point).map(|_| '0'))?;
        f.write_str(".0")
    } else if (1..=16).contains(&point) {
        write_chars(f, digits.clone().take(point as usize))?;
        f.write_char('.')?;
        write_chars(f, digits.skip(point as usize))
    } else if (-4..=0).contains(&point) {
        f.write_str("0.")?;
        write_chars(f, (point..0).map(|_| '0'))?;
        write_chars(f, digits)
    } else {
        write_chars(f, digits.clone().take(1))?;
        if length > 1 {
            f.write_char('.')?;
            write_chars(f, digits.skip(1))?;
        }
        write!(f, "e{}", decimal.exponent)
    }
}

fn write_chars(f: &mut fmt::Formatter<'_>, mut chars: impl Iterator<Item = char>) -> fmt::Result {
    chars.try_for_each(|c| f.write_char(c))
}

/// A positive finite `f64` as `d.ddd × 10^exponent` with the shortest digits that read back as
/// it, which Rust's `{:e}` gives (`8.611636210880064e-7`).
struct Decimal {
    /// ASCII digits; an `f64` needs at most 17.
    digits: [u8; 17],
    length: i32,
    exponent: i32,
}

impl Decimal {
    fn of(value: f64) -> Result<Self, fmt::Error> {
        let mut decimal = Decimal {
            digits: [0; 17],
            length: 0,
            exponent: 0,
        };
        let mut reader = ScientificReader {
            decimal: &mut decimal,
            in_exponent: false,
            negative_exponent: false,
        };
        write!(reader, "{value:e}")?;
        if reader.negative_exponent {
            decimal.exponent = -decimal.exponent;
        }
        decimal.round_ties_to_even(value);
        Ok(decimal)
    }

    /// Where `value` lies exactly halfway between two shortest candidates, Rust's digits round
    /// up and the decoder's round to the even one (`1969900000000000.25` gives `….3` and `….2`):
    /// this takes the even one. Only values above 1e12 can have such a tie.
    fn round_ties_to_even(&mut self, value: f64) {
        let Some(last) = self.length.checked_sub(1).map(|last| last as usize) else {
            return;
        };
        let digit = self.digits[last];
        if (digit - b'0') % 2 == 0 {
            return;
        }
        let candidate = self
            .digits
            .iter()
            .take(last + 1)
            .fold(0u64, |number, &digit| number * 10 + u64::from(digit - b'0'));
        let halfway = candidate * 10 - 5;
        if is_exactly(value, halfway, self.exponent - self.length) {
            self.digits[last] = digit - 1;
        }
    }

    fn digits(&self) -> impl Iterator<Item = char> + Clone + '_ {
        self.digits
            .iter()
            .take(self.length as usize)
            .map(|&digit| char::from(digit))
    }
}

/// Takes the text of `{:e}` apart into a [`Decimal`].
struct ScientificReader<'a> {
    decimal: &'a mut Decimal,
    in_exponent: bool,
    negative_exponent: bool,
}

impl Write for ScientificReader<'_> {
    fn write_str(&mut self, text: &str) -> fmt::Result {
        for byte in text.bytes() {
            let decimal = &mut *self.decimal;
            match byte {
                b'e' => self.in_exponent = true,
                b'-' => self.negative_exponent = true,
                b'0'..=b'9' if self.in_exponent => {
                    decimal.exponent = decimal.exponent * 10 + i32::from(byte - b'0')
                }
                b'0'..=b'9' => {
                    let slot = decimal.digits.get_mut(decimal.length as usize);
                    *slot.ok_or(fmt::Error)? = byte;
                    decimal.length += 1;
                }
                _ => {}
            }
        }
        Ok(())
    }
}

/// Whether `value` (positive, finite) is exactly `number × 10^power`.
fn is_exactly(value: f64, number: u64, power: i32) -> bool {
    let bits = value.to_bits();
    let biased_exponent = ((bits >> 52) & 0x7ff) as i32;
    let fraction = bits & ((1 << 52) - 1);
    // value = mantissa × 2^exponent
    let (mantissa, exponent) = match biased_exponent {
        0 => (fraction, -1074),
        _ => (fraction | 1 << 52, biased_exponent - 1075),
    };
    let (mantissa, number) = (u128::from(mantissa), u128::from(number));
    let fives = |times: u32| 5u128.checked_pow(times);
    // mantissa × 2^exponent = number × 5^power × 2^power, as left × 2^shift = right
    let sides = if power < 0 {
        fives(power.unsigned_abs())
            .and_then(|five| mantissa.checked_mul(five))
            .map(|left| (left, number, exponent - power))
    } else {
        fives(power.unsigned_abs())
            .and_then(|five| number.checked_mul(five))
            .map(|right| (mantissa, right, exponent - power))
    };
    let Some((left, right, shift)) = sides else {
        return false;
    };
    let places = shift.unsigned_abs();
    if places >= 128 {
        return false;
    }
    if shift >= 0 {
        left.checked_mul(1 << places) == Some(right)
    } else {
        left % (1 << places) == 0 && left >> places == right
    }
}

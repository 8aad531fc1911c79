//! Decimal numbers without core's float code: reading (`split_decimal`, also through a command
//! line), fixed places (`Fixed`) and significant digits (`Significant`), by table and property.

use std::fmt::Write as _;

use feeder_shared::number::{split_decimal, Fixed, Significant};
use feeder_shared::protocol;
use feeder_shared::{Command, Error, Quantity, ReplyError, Setting};
use proptest::prelude::*;

/// The parser's documented worst case, one rounding for the digits and one per `10^22` step (17
/// in all), plus core's own rounding.
const WORST_RELATIVE_ERROR: f64 = 18.0 * f64::EPSILON / 2.0;

/// `read` is within the parser's worst-case error of `exact` (plus half the least subnormal).
fn close_to_parser_bound(read: f64, exact: f64) -> bool {
    (read - exact).abs() <= exact.abs() * WORST_RELATIVE_ERROR + f64::from_bits(1)
}

/// The longest prefix of `text` that core reads as a number, and the rest: the reference for
/// `split_decimal`.
fn longest_parsed_prefix(text: &str) -> Option<(f64, &str)> {
    (1..=text.len())
        .rev()
        .filter(|&end| text.is_char_boundary(end))
        .find_map(|end| Some((text[..end].parse::<f64>().ok()?, &text[end..])))
}

#[test]
fn decimal_prefixes_by_table() {
    let table: &[(&str, Option<(f64, &str)>)] = &[
        ("0", Some((0.0, ""))),
        ("50", Some((50.0, ""))),
        ("+50", Some((50.0, ""))),
        ("-3", Some((-3.0, ""))),
        ("62.5Hz", Some((62.5, "Hz"))),
        (".6", Some((0.6, ""))),
        ("5.", Some((5.0, ""))),
        ("1.e3x", Some((1000.0, "x"))),
        ("1e2", Some((100.0, ""))),
        ("2.5E-3mm", Some((0.0025, "mm"))),
        ("1e+2", Some((100.0, ""))),
        ("5e", Some((5.0, "e"))),
        ("5e+", Some((5.0, "e+"))),
        ("5e-x", Some((5.0, "e-x"))),
        ("1.2.3", Some((1.2, ".3"))),
        ("0x10", Some((0.0, "x10"))),
        ("1_000", Some((1.0, "_000"))),
        ("150m/s²", Some((150.0, "m/s²"))),
        ("007", Some((7.0, ""))),
        ("0.000001", Some((1e-6, ""))),
        (
            "123456789012345678901234567890",
            Some((1.2345678901234568e29, "")),
        ),
        ("0.30000000000000004", Some((0.30000000000000004, ""))),
        ("9007199254740993", Some((9007199254740992.0, ""))),
        ("1e308", Some((1e308, ""))),
        ("1e-320", Some((1e-320, ""))),
        ("1e309", Some((f64::INFINITY, ""))),
        ("-1e999999999999", Some((f64::NEG_INFINITY, ""))),
        ("1e-400", Some((0.0, ""))),
        ("0e999999", Some((0.0, ""))),
        ("inf", Some((f64::INFINITY, ""))),
        ("-Infinity", Some((f64::NEG_INFINITY, ""))),
        ("+INFhz", Some((f64::INFINITY, "hz"))),
        ("infinit", Some((f64::INFINITY, "init"))),
        ("", None),
        ("-", None),
        (".", None),
        ("+.e1", None),
        ("e5", None),
        ("hz", None),
        ("in", None),
        ("²", None),
    ];
    for &(text, expected) in table {
        assert_eq!(
            longest_parsed_prefix(text),
            expected,
            "core reads {text:?} otherwise"
        );
        let read = split_decimal(text);
        assert_eq!(
            read.map(|(_, rest)| rest),
            expected.map(|(_, rest)| rest),
            "{text:?}"
        );
        if let (Some((read, _)), Some((expected, _))) = (read, expected) {
            let close = read == expected || close_to_parser_bound(read, expected);
            assert!(close, "{text:?} read as {read:e}");
        }
    }
    for text in ["nan", "-NaN", "+nanometre"] {
        let (value, rest) = split_decimal(text).unwrap();
        assert!(value.is_nan(), "{text:?}");
        assert_eq!(rest, &text[text.len() - rest.len()..]);
        assert_eq!(text.len() - rest.len(), text.find(['n', 'N']).unwrap() + 3);
    }
    assert!(split_decimal("-0").unwrap().0.is_sign_negative());
}

#[test]
fn fixed_by_table() {
    let table: &[(f64, u32, &str)] = &[
        (50.0, 3, "50"),
        (0.6, 4, "0.6"),
        (2.0 - 2f64.sqrt(), 4, "0.5858"),
        (156.25, 2, "156.25"),
        (73.1234, 3, "73.123"),
        (29.99999997, 3, "30"),
        (0.005, 3, "0.005"),
        (1500.0, 0, "1500"),
        (-3.25, 1, "-3.2"),
        (-0.00001, 3, "0"),
        (-0.0, 2, "0"),
        (0.0, 0, "0"),
        // Ties go to even on the exact binary value: 0.125 is exact, 0.35 lies just below.
        (0.125, 2, "0.12"),
        (0.375, 2, "0.38"),
        (2.5, 0, "2"),
        (0.35, 1, "0.3"),
        (1e20, 2, "1e20"),
        (f64::NAN, 2, "NaN"),
        (f64::NEG_INFINITY, 2, "-inf"),
    ];
    for &(value, decimals, expected) in table {
        let text = Fixed { value, decimals }.to_string();
        assert_eq!(text, expected, "{value} to {decimals} decimals");
    }
}

#[test]
fn significant_by_table() {
    let table: &[(f64, &str)] = &[
        (0.0, "0"),
        (-0.0, "0"),
        (0.4, "0.4"),
        (1.0, "1"),
        (500.0, "500"),
        (-2.5, "-2.5"),
        (0.1 + 0.2, "0.3"),
        (1.0 / 3.0, "0.333333333333333"),
        (2.0 / 3.0, "0.666666666666667"),
        (0.99999999, "0.99999999"),
        (0.00001, "0.00001"),
        (0.000001, "1e-6"),
        (1.5e-7, "1.5e-7"),
        (123456789012345.0, "123456789012345"),
        (999999999999999.9, "1e15"),
        (1e15, "1e15"),
        (6.02214076e23, "6.02214076e23"),
        (f64::MAX, "1.79769313486232e308"),
        (f64::MIN_POSITIVE, "2.2250738585072e-308"),
        (f64::from_bits(1), "4.94065645841247e-324"),
        (f64::NAN, "NaN"),
        (f64::INFINITY, "inf"),
        (f64::NEG_INFINITY, "-inf"),
    ];
    for &(value, expected) in table {
        assert_eq!(Significant(value).to_string(), expected, "{value:e}");
    }
}

#[test]
fn explanations_print_values_without_core_float_formatting() {
    let table: &[(Error, &str)] = &[
        (
            Error::DutyTooHigh { duty: 0.99999999 },
            "duty cycle 0.99999999 must be below 1",
        ),
        (
            Error::FeedRateAboveReach {
                target_mps: 0.2,
                max_mps: 0.1 * 2f64.sqrt(),
            },
            "feed rate 0.2 m/s cannot be reached within the limits while the part slides; the \
             most is 0.14142135623731 m/s",
        ),
        (
            Error::TicksOverflow {
                segment: feeder_shared::SegmentKind::Idle,
                exact_ticks: 1.25e16,
                max_ticks: u32::MAX,
            },
            "the idle segment needs 1.25e16 timer ticks but the timer counts at most 4294967295",
        ),
        (
            Error::NotPositive {
                quantity: Quantity::StrokeM,
                value: -1e-7,
            },
            "stroke x_max (m) must be greater than zero, got -1e-7",
        ),
    ];
    for (error, expected) in table {
        let text = error.to_string();
        assert!(text.starts_with(expected), "{text}");
    }
}

/// A decimal `[-]digits[.digits][e±exponent]` built from its parts.
fn decimal_text(negative: bool, digits: &str, point: usize, exponent: Option<i32>) -> String {
    let (integer, fraction) = digits.split_at(point.min(digits.len()));
    let mut text = String::from(if negative { "-" } else { "" });
    text.push_str(integer);
    if !fraction.is_empty() {
        write!(text, ".{fraction}").unwrap();
    }
    if let Some(exponent) = exponent {
        write!(text, "e{exponent}").unwrap();
    }
    text
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    /// What an operator types (up to 15 significant digits, decimal exponent within ±22) reads
    /// as exactly the `f64` core reads.
    #[test]
    fn operator_numbers_read_exactly(
        negative in prop::bool::ANY,
        digits in "[0-9]{1,15}",
        point in 0usize..16,
        exponent in prop::option::of(-7i32..=7),
    ) {
        let text = decimal_text(negative, &digits, point, exponent);
        let expected: f64 = text.parse().unwrap();
        prop_assert_eq!(split_decimal(&text), Some((expected, "")), "{}", text);
    }

    /// Up to 25 digits and any exponent keep to the documented bound; up to 19 digits with a
    /// decimal exponent within ±22 to two roundings, 2^-52 relative (plus core's rounding).
    #[test]
    fn any_decimal_reads_within_the_bound(
        negative in prop::bool::ANY,
        digits in "[0-9]{1,25}",
        point in 0usize..26,
        exponent in -330i32..=330,
    ) {
        let text = decimal_text(negative, &digits, point, Some(exponent));
        let expected: f64 = text.parse().unwrap();
        let Some((read, "")) = split_decimal(&text) else {
            return Err(TestCaseError::fail(format!("{text} not read")));
        };
        if expected.is_infinite() {
            prop_assert_eq!(read, expected, "{}", text);
        } else if read.is_infinite() {
            prop_assert!(expected.abs() > f64::MAX * (1.0 - WORST_RELATIVE_ERROR), "{}", text);
        } else {
            prop_assert!(close_to_parser_bound(read, expected), "{} read as {:e}", text, read);
            let fraction_digits = digits.len().saturating_sub(point) as i32;
            if digits.len() <= 19 && (exponent - fraction_digits).abs() <= 22 {
                let two_roundings = expected.abs() * 1.5 * f64::EPSILON;
                prop_assert!((read - expected).abs() <= two_roundings, "{}", text);
            }
        }
    }

    /// The prefix taken is the longest one core reads, and its value agrees with core's.
    #[test]
    fn prefixes_are_the_longest_core_reads(text in "[-+0-9.eEinfatyINFAThz ²]{0,12}") {
        match (split_decimal(&text), longest_parsed_prefix(&text)) {
            (None, None) => {}
            (Some((read, rest)), Some((expected, expected_rest))) => {
                prop_assert_eq!(rest, expected_rest, "{:?}", text);
                prop_assert!(
                    read.to_bits() == expected.to_bits()
                        || (read.is_nan() && expected.is_nan())
                        || close_to_parser_bound(read, expected),
                    "{:?} read as {}, core reads {}", text, read, expected
                );
            }
            (got, expected) => prop_assert!(false, "{:?}: {:?}, core {:?}", text, got, expected),
        }
    }

    /// Fixed places round like core's `{:.*}` (trailing zeros and the sign of zero dropped),
    /// including values right at a tie.
    #[test]
    fn fixed_matches_core_rounding(
        value in prop_oneof![
            -1e6f64..1e6,
            (-1_000_000i64..1_000_000, 1u32..=5)
                .prop_map(|(n, places)| (n as f64 + 0.5) / 10f64.powi(places as i32)),
        ],
        decimals in 0u32..=4,
    ) {
        let core = format!("{value:.*}", decimals as usize);
        let trimmed = if core.contains('.') {
            core.trim_end_matches('0').trim_end_matches('.')
        } else {
            &core
        };
        let expected = if trimmed == "-0" { "0" } else { trimmed };
        prop_assert_eq!(Fixed { value, decimals }.to_string(), expected);
    }

    /// Fifteen significant digits: any normal value reads back within half a unit of the last
    /// digit (5·10^-15 relative) and the scaling error, and a decimal with at most 15 digits
    /// prints as core prints it.
    #[test]
    fn significant_digits_read_back(
        value in any::<f64>().prop_filter("finite", |x| x.is_normal()),
        digits in "[1-9][0-9]{0,14}",
        exponent in -19i32..=0,
    ) {
        let text = Significant(value).to_string();
        let read: f64 = text.parse().unwrap();
        prop_assert!((read - value).abs() <= value.abs() * (5e-15 + WORST_RELATIVE_ERROR), "{:e} printed {}", value, text);
        let decimal: f64 = format!("{digits}e{exponent}").parse().unwrap();
        if (1e-5..1e15).contains(&decimal) {
            prop_assert_eq!(Significant(decimal).to_string(), decimal.to_string());
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// Any number core prints is read back within the parser's bound, and non-finite ones are
    /// refused; only values next to `f64::MAX` may overflow on the way.
    #[test]
    fn any_number_is_read_closely_or_refused(x in any::<f64>(), unit in prop::bool::ANY) {
        let line = if unit { format!("set freq {x} Hz") } else { format!("SET Freq {x}") };
        let parsed = protocol::parse(&line);
        if !x.is_finite() {
            prop_assert_eq!(parsed, Err(ReplyError::NotFinite));
        } else if let Ok(Command::Set(Setting::FrequencyHz(y))) = parsed {
            prop_assert!(close_to_parser_bound(y, x), "{} read as {}", x, y);
        } else {
            prop_assert_eq!(parsed, Err(ReplyError::NotFinite));
            prop_assert!(x.abs() > f64::MAX * (1.0 - WORST_RELATIVE_ERROR), "{}", x);
        }
    }
}

#[test]
fn lengths_are_read_in_the_unit_asked_for() {
    use feeder_shared::number::{parse_length, LengthError, LengthUnit};
    let (m, mm) = (LengthUnit::Metre, LengthUnit::Millimetre);
    for text in [
        "2.5mm", "2.5 mm", "2.5MM", "0.0025m", "0.0025 m", "2500um", "2500µm", "2500μm", "2.5e-3m",
        "0.0025",
    ] {
        assert_eq!(parse_length(text, m, m), Ok(0.0025), "{text}");
    }
    // The units' ratio is applied before the one rounding: exact where the decimal is.
    assert_eq!(parse_length("2500um", m, mm), Ok(2.5));
    assert_eq!(parse_length("0.0025m", m, mm), Ok(2.5));
    assert_eq!(parse_length("2.5", mm, mm), Ok(2.5));
    assert_eq!(parse_length("2.5", mm, m), Ok(0.0025));
    assert_eq!(parse_length("-1mm", m, m), Ok(-0.001));
    for (text, error) in [
        ("", LengthError::NotANumber),
        ("mm", LengthError::NotANumber),
        ("2.5in", LengthError::UnknownUnit),
        ("2.5 m m", LengthError::UnknownUnit),
        ("2.5e", LengthError::UnknownUnit),
        ("inf mm", LengthError::NotFinite),
        ("NaN", LengthError::NotFinite),
        ("1e400m", LengthError::NotFinite),
    ] {
        assert_eq!(parse_length(text, m, m), Err(error), "{text}");
    }
}

proptest! {
    /// A length typed in millimetres or micrometres reads as the same number typed in metres
    /// with its exponent moved, to the last bit.
    #[test]
    fn a_unit_moves_the_decimal_exponent(digits in 1u64..1_000_000_000, exponent in -12i32..12) {
        use feeder_shared::number::{parse_length, LengthUnit};
        let m = LengthUnit::Metre;
        let metres: f64 = format!("{digits}e{}", exponent).parse().unwrap();
        prop_assert_eq!(parse_length(&format!("{digits}e{}mm", exponent + 3), m, m), Ok(metres));
        prop_assert_eq!(parse_length(&format!("{digits}e{}um", exponent + 6), m, m), Ok(metres));
    }
}

//! The recipe record: layout, CRC-32, versioning, and the reason for every unusable record.

use feeder_shared::recipe::{self, crc32, FORMAT_VERSION, MAGIC, RECIPE_SLOTS, RECORD_LEN};
use feeder_shared::{Drive, Error, RecipeSlot, RecordError, Settings};
use proptest::prelude::*;

mod common;
use common::slot;
use feeder_shared::testing::machine;

fn sample() -> Settings {
    Settings {
        frequency_hz: 62.5,
        duty: 0.6,
        drive: Drive::Accel { accel_mps2: 150.0 },
        ramp_cycles: 7,
    }
}

/// CRC-32 by the byte-wise table method, independent of the bit-wise implementation.
fn crc32_table(bytes: &[u8]) -> u32 {
    let table: Vec<u32> = (0..256u32)
        .map(|n| {
            (0..8).fold(n, |c, _| {
                if c & 1 == 1 {
                    0xedb8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                }
            })
        })
        .collect();
    !bytes.iter().fold(!0u32, |crc, &b| {
        table[((crc ^ u32::from(b)) & 0xff) as usize] ^ (crc >> 8)
    })
}

#[test]
fn crc32_matches_the_standard_check_values() {
    assert_eq!(crc32(b""), 0);
    assert_eq!(crc32(b"123456789"), 0xcbf4_3926);
    assert_eq!(crc32(b"a"), 0xe8b7_be43);
    assert_eq!(
        crc32(b"The quick brown fox jumps over the lazy dog"),
        0x414f_a339
    );
    // zlib's values for a record's CRC span erased, zeroed, and every byte value once.
    assert_eq!(crc32(&[0xff; 36]), 0x1999_0159);
    assert_eq!(crc32(&[0; 36]), 0x6ab6_b2d5);
    assert_eq!(
        crc32(&core::array::from_fn::<u8, 256, _>(|n| n as u8)),
        0x2905_8c73
    );
}

#[test]
fn slots_are_numbered_from_zero() {
    const { assert!(RECIPE_SLOTS >= 8) };
    let all: Vec<u8> = RecipeSlot::all().map(RecipeSlot::number).collect();
    assert_eq!(all, (0..RECIPE_SLOTS as u8).collect::<Vec<_>>());
    assert_eq!(RecipeSlot::new(RECIPE_SLOTS as u8), None);
    assert_eq!(RecipeSlot::new(255), None);
    assert_eq!(slot(5).index(), 5);
    assert_eq!(slot(5).to_string(), "5");
}

#[test]
fn record_layout_is_as_documented() {
    assert_eq!(RECORD_LEN % 8, 0, "whole flash double words");
    let record = recipe::encode(slot(3), &sample());
    assert_eq!(&record[0..4], &MAGIC);
    assert_eq!(&record[0..4], b"FDRC");
    assert_eq!(record[4..6], FORMAT_VERSION.to_le_bytes());
    assert_eq!(record[6], 3);
    assert_eq!(record[7], 1, "acceleration drive");
    assert_eq!(record[8..16], 62.5f64.to_le_bytes());
    assert_eq!(record[16..24], 0.6f64.to_le_bytes());
    assert_eq!(record[24..32], 150.0f64.to_le_bytes());
    assert_eq!(record[32..34], 7u16.to_le_bytes());
    assert_eq!(record[34..36], [0, 0]);
    assert_eq!(record[36..40], crc32_table(&record[..36]).to_le_bytes());
    let stroke = recipe::encode(slot(0), &Settings::DEFAULT);
    assert_eq!(stroke[7], 0, "stroke drive");
    assert_eq!(stroke[24..32], 0.0025f64.to_le_bytes());
}

/// Rewrites the CRC so that only the field under test is wrong.
fn reseal(mut record: [u8; RECORD_LEN]) -> [u8; RECORD_LEN] {
    let crc = crc32_table(&record[..36]);
    record[36..40].copy_from_slice(&crc.to_le_bytes());
    record
}

#[test]
fn every_unusable_record_is_named() {
    let good = recipe::encode(slot(2), &sample());
    let mut old = good;
    old[4..6].copy_from_slice(&0u16.to_le_bytes());
    let mut newer = good;
    newer[4..6].copy_from_slice(&2u16.to_le_bytes());
    let mut flipped = good;
    flipped[20] ^= 0x04;
    let mut bad_drive = good;
    bad_drive[7] = 2;
    let mut reserved = good;
    reserved[35] = 1;
    let mut magic = good;
    magic[0] = b'X';
    let stored = u32::from_le_bytes(good[36..40].try_into().unwrap());

    let table: Vec<([u8; RECORD_LEN], RecordError, &str, &str)> = vec![
        (
            [0xff; RECORD_LEN],
            RecordError::Empty,
            "empty",
            "no recipe saved in this slot",
        ),
        (
            [0x00; RECORD_LEN],
            RecordError::BadMagic,
            "corrupt",
            "no recipe header",
        ),
        (magic, RecordError::BadMagic, "corrupt", "no recipe header"),
        (
            old,
            RecordError::UnsupportedVersion { found: 0 },
            "old-version",
            "record format version 0 is older than the supported version 1",
        ),
        (
            newer,
            RecordError::UnsupportedVersion { found: 2 },
            "new-version",
            "record format version 2 is newer than the supported version 1",
        ),
        (
            flipped,
            RecordError::CrcMismatch {
                stored,
                computed: crc32_table(&flipped[..36]),
            },
            "corrupt",
            "corrupt record: CRC 0x",
        ),
        (
            recipe::encode(slot(4), &sample()),
            RecordError::WrongSlot {
                found: 4,
                expected: slot(2),
            },
            "wrong-slot",
            "record belongs to slot 4, not slot 2",
        ),
        (
            reseal(bad_drive),
            RecordError::Malformed,
            "corrupt",
            "invalid field",
        ),
        (
            reseal(reserved),
            RecordError::Malformed,
            "corrupt",
            "invalid field",
        ),
    ];
    for (record, error, short, text) in table {
        assert_eq!(recipe::decode(&record, slot(2)), Err(error));
        assert_eq!(error.short_name(), short);
        assert!(error.to_string().contains(text), "{error}");
        assert_eq!(recipe::load(&record, slot(2), &machine()), Err(error));
    }
}

#[test]
fn an_intact_record_loads_its_settings() {
    let record = recipe::encode(slot(6), &sample());
    assert_eq!(recipe::decode(&record, slot(6)), Ok(sample()));
    let applied = recipe::load(&record, slot(6), &machine()).unwrap();
    assert_eq!(applied.settings, sample());
    assert_eq!(applied.plan.waveform.accel_mps2, 150.0);
}

#[test]
fn a_record_refused_on_this_machine_is_not_loaded() {
    let too_fast = Settings {
        frequency_hz: 400.0,
        ..sample()
    };
    let record = recipe::encode(slot(1), &too_fast);
    assert_eq!(recipe::decode(&record, slot(1)), Ok(too_fast));
    let issue = recipe::load(&record, slot(1), &machine()).unwrap_err();
    let RecordError::Rejected(Error::FrequencyOutOfBand { frequency_hz, .. }) = issue else {
        panic!("{issue:?}");
    };
    assert_eq!(frequency_hz, 400.0);
    assert_eq!(issue.short_name(), "rejected");
    assert!(issue
        .to_string()
        .starts_with("stored parameters refused: frequency 400 Hz"));
}

#[test]
fn an_erased_slot_is_empty() {
    assert_eq!(
        recipe::load(&[0xff; RECORD_LEN], slot(0), &machine()),
        Err(RecordError::Empty)
    );
}

fn settings() -> impl Strategy<Value = Settings> {
    (
        any::<f64>(),
        any::<f64>(),
        any::<bool>(),
        any::<f64>(),
        any::<u16>(),
    )
        .prop_map(
            |(frequency_hz, duty, stroke, value, ramp_cycles)| Settings {
                frequency_hz,
                duty,
                drive: if stroke {
                    Drive::Stroke { stroke_m: value }
                } else {
                    Drive::Accel { accel_mps2: value }
                },
                ramp_cycles,
            },
        )
}

fn plausible_settings() -> impl Strategy<Value = Settings> {
    (10.0f64..250.0, 0.45f64..1.05, 0.1f64..8.0, any::<u16>()).prop_map(
        |(frequency_hz, duty, stroke_mm, ramp_cycles)| Settings {
            frequency_hz,
            duty,
            drive: Drive::Stroke {
                stroke_m: stroke_mm / 1000.0,
            },
            ramp_cycles,
        },
    )
}

/// Bit patterns, so that NaNs compare equal to themselves.
fn bits(settings: &Settings) -> (u64, u64, bool, u64, u16) {
    let (stroke, value) = match settings.drive {
        Drive::Stroke { stroke_m } => (true, stroke_m),
        Drive::Accel { accel_mps2 } => (false, accel_mps2),
    };
    (
        settings.frequency_hz.to_bits(),
        settings.duty.to_bits(),
        stroke,
        value.to_bits(),
        settings.ramp_cycles,
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(5000))]

    #[test]
    fn records_round_trip(settings in settings(), number in 0u8..RECIPE_SLOTS as u8) {
        let record = recipe::encode(slot(number), &settings);
        let decoded = recipe::decode(&record, slot(number));
        prop_assert!(decoded.is_ok(), "{:?}", decoded);
        prop_assert_eq!(bits(&decoded.unwrap()), bits(&settings));
        let stored = u32::from_le_bytes(record[36..40].try_into().unwrap());
        prop_assert_eq!(stored, crc32_table(&record[..36]));
    }

    #[test]
    fn any_single_bit_flip_is_detected(
        settings in settings(),
        number in 0u8..RECIPE_SLOTS as u8,
        bit in 0usize..RECORD_LEN * 8,
    ) {
        let mut record = recipe::encode(slot(number), &settings);
        record[bit / 8] ^= 1 << (bit % 8);
        prop_assert!(recipe::decode(&record, slot(number)).is_err());
        prop_assert!(recipe::load(&record, slot(number), &machine()).is_err());
    }

    /// Random bytes or intact records of plausible settings, read from any slot: decoding never
    /// panics, and the record is used exactly when it decodes and validates.
    #[test]
    fn load_uses_a_record_exactly_when_it_is_valid(
        bytes in prop_oneof![
            prop::collection::vec(any::<u8>(), RECORD_LEN),
            (plausible_settings(), 0u8..RECIPE_SLOTS as u8)
                .prop_map(|(settings, number)| recipe::encode(slot(number), &settings).to_vec()),
        ],
        number in 0u8..RECIPE_SLOTS as u8,
    ) {
        let record: [u8; RECORD_LEN] = bytes.try_into().unwrap();
        let decoded = recipe::decode(&record, slot(number));
        if decoded.is_ok() {
            prop_assert_eq!(&record[0..4], &MAGIC);
            prop_assert_eq!(record[6], number);
            let stored = u32::from_le_bytes(record[36..40].try_into().unwrap());
            prop_assert_eq!(stored, crc32_table(&record[..36]));
        }
        let loaded = recipe::load(&record, slot(number), &machine());
        let usable = decoded.ok().filter(|settings| settings.validate(&machine()).is_ok());
        match usable {
            Some(settings) => prop_assert_eq!(loaded.map(|applied| applied.settings), Ok(settings)),
            None => prop_assert!(loaded.is_err()),
        }
    }

    #[test]
    fn crc32_matches_the_table_method(bytes in prop::collection::vec(any::<u8>(), 0..200)) {
        prop_assert_eq!(crc32(&bytes), crc32_table(&bytes));
    }
}

use proptest::prelude::*;

use super::record::{self, LoadError, FORMAT_VERSION, RECORD_LEN};
use super::*;
use crate::error::Error;
use crate::recipe::RecordError;
use crate::waveform::Drive;

const DAC_LOOP: BoardFacts = BoardFacts {
    clock: TickClock::new(1_000_000),
    output: OutputKind::Dac,
    encoder: true,
};

const PWM_OPEN: BoardFacts = BoardFacts {
    clock: TickClock::new(20_000),
    output: OutputKind::Pwm,
    encoder: false,
};

#[test]
fn the_defaults_hold_on_a_dac_board_with_an_encoder() {
    assert_eq!(Configuration::DEFAULT.check(&DAC_LOOP), Ok(()));
    let machine = Configuration::DEFAULT.machine(&DAC_LOOP);
    assert_eq!(machine.limits, MACHINE_LIMITS);
    assert_eq!(machine.loop_linear_mps2, Some(224.75));
}

#[test]
fn a_board_without_an_encoder_needs_the_closed_loop_off() {
    let refused = Configuration::DEFAULT.check(&PWM_OPEN);
    assert_eq!(
        refused,
        Err(ConfigError::new(Key::ClosedLoop, Problem::NoEncoder))
    );
    let open = Key::ClosedLoop
        .set(&Configuration::DEFAULT, KeyValue::Switch(false))
        .unwrap();
    assert_eq!(open.check(&PWM_OPEN), Ok(()));
    assert_eq!(open.machine(&PWM_OPEN).loop_linear_mps2, None);
}

#[test]
fn a_drive_limit_beyond_the_dac_linear_range_names_the_limit() {
    // 8 counts per m/s² and 1798 counts of headroom reach 224.75 m/s².
    let c = Key::MaxAccel
        .set(&Configuration::DEFAULT, KeyValue::Number(230.0))
        .unwrap();
    assert_eq!(
        c.check(&DAC_LOOP),
        Err(ConfigError::new(
            Key::MaxAccel,
            Problem::BeyondOutput {
                linear_mps2: 224.75
            }
        ))
    );
}

#[test]
fn a_zero_code_outside_the_linear_range_is_refused_as_the_drive_refuses_it() {
    let c = Key::DacZero
        .set(&Configuration::DEFAULT, KeyValue::Number(100.0))
        .unwrap();
    let Err(ConfigError {
        key: Key::DacZero,
        problem: Problem::Drive(DriveError::ZeroOutOfRange { zero_code: 100, .. }),
    }) = c.check(&DAC_LOOP)
    else {
        panic!("{:?}", c.check(&DAC_LOOP));
    };
}

#[test]
fn start_up_settings_the_machine_refuses_name_the_start_up_key() {
    let c = Key::StartDuty
        .set(&Configuration::DEFAULT, KeyValue::Number(0.5))
        .unwrap();
    assert_eq!(
        c.check(&DAC_LOOP),
        Err(ConfigError::new(
            Key::StartStroke,
            Problem::Startup(Error::DutyTooLow { duty: 0.5 })
        ))
    );
}

#[test]
fn the_frequency_band_must_not_be_empty() {
    let c = Key::MinFrequency
        .set(&Configuration::DEFAULT, KeyValue::Number(100.0))
        .unwrap();
    assert_eq!(
        c.check(&DAC_LOOP).map_err(|e| (e.key, e.problem)),
        Err((
            Key::MaxFrequency,
            Problem::NotAbove {
                other: Key::MinFrequency
            }
        ))
    );
}

#[test]
fn every_key_reads_back_what_was_set_in_its_console_unit() {
    for key in Key::ALL {
        let value = match key.kind() {
            ValueKind::Switch { .. } => {
                KeyValue::Switch(key.get(&Configuration::DEFAULT) != Some(KeyValue::Switch(true)))
            }
            ValueKind::Whole { min, max } => KeyValue::Number(f64::from(min.max(7).min(max))),
            ValueKind::Number { .. } => {
                let (min, max) = range(key);
                KeyValue::Number(min + 0.375 * (max - min))
            }
        };
        let set = key.set(&Configuration::DEFAULT, value).unwrap();
        assert_eq!(key.get(&set), Some(value), "{}", key.keyword());
        for other in Key::ALL.into_iter().filter(|&other| other != key) {
            if !matches!(
                (key, other),
                (Key::StartStroke, Key::StartAccel) | (Key::StartAccel, Key::StartStroke)
            ) {
                assert_eq!(
                    other.get(&set),
                    other.get(&Configuration::DEFAULT),
                    "{} changed {}",
                    key.keyword(),
                    other.keyword()
                );
            }
        }
    }
}

#[test]
fn the_start_up_drive_is_the_key_set_last() {
    let c = Key::StartAccel
        .set(&Configuration::DEFAULT, KeyValue::Number(120.0))
        .unwrap();
    assert_eq!(c.startup.drive, Drive::Accel { accel_mps2: 120.0 });
    assert_eq!(Key::StartStroke.get(&c), None);
    assert_eq!(Key::startup(&c.startup), Key::StartAccel);
}

#[test]
fn a_reversed_encoder_reads_forward_positions_from_falling_counts() {
    let forward = EncoderSetup::DEFAULT;
    let reversed = EncoderSetup {
        reversed: true,
        ..forward
    };
    assert_eq!(forward.position_m(10), 10.5e-6);
    assert_eq!(reversed.position_m(-10), 10.5e-6);
}

#[test]
fn the_record_puts_each_field_at_its_documented_offset() {
    let bytes = record::encode(&Configuration::DEFAULT);
    assert_eq!(&bytes[0..4], b"FDCF");
    assert_eq!(bytes[4..6], FORMAT_VERSION.to_le_bytes());
    assert_eq!(bytes[6..8], 136u16.to_le_bytes());
    assert_eq!(bytes[8..10], 2048u16.to_le_bytes());
    assert_eq!(bytes[10..12], 249u16.to_le_bytes());
    assert_eq!(bytes[12..14], 25u16.to_le_bytes());
    assert_eq!(bytes[14], 0b10, "closed loop on, encoder forward");
    assert_eq!(bytes[15], 0, "start-up drive: stroke");
    assert_eq!(bytes[16..24], 8.0f64.to_le_bytes());
    assert_eq!(bytes[48..56], 200.0f64.to_le_bytes());
    assert_eq!(bytes[112..120], 2.5e-3f64.to_le_bytes());
    assert_eq!(bytes[120], 1, "Modbus address");
    assert_eq!(bytes[121], 0, "8E1, console watchdog off");
    assert_eq!(bytes[122..124], 2000u16.to_le_bytes());
    assert_eq!(bytes[124..128], 19_200u32.to_le_bytes());
    assert_eq!(bytes[128..132], [0; 4]);
    assert_eq!(
        bytes[132..136],
        crate::recipe::crc32(&bytes[..132]).to_le_bytes()
    );
}

/// A record of the first layout as it was written: 128 bytes, zeros at 120..124, its CRC at
/// 124, then the rest of the page erased.
fn first_layout(configuration: &Configuration) -> [u8; RECORD_LEN] {
    let mut bytes = record::encode(configuration);
    bytes[4..6].copy_from_slice(&1u16.to_le_bytes());
    bytes[6..8].copy_from_slice(&128u16.to_le_bytes());
    bytes[120..124].fill(0);
    let crc = crate::recipe::crc32(&bytes[..124]);
    bytes[124..128].copy_from_slice(&crc.to_le_bytes());
    bytes[128..].fill(0xff);
    bytes
}

#[test]
fn a_first_layout_record_keeps_its_calibration_and_takes_the_line_defaults() {
    let calibrated = Key::DacZero
        .set(&Configuration::DEFAULT, KeyValue::Number(2040.0))
        .and_then(|c| Key::ModbusAddress.set(&c, KeyValue::Number(17.0)))
        .unwrap();
    let read = record::load(&first_layout(&calibrated), &DAC_LOOP).unwrap();
    assert_eq!(read.dac.zero_code, 2040);
    assert_eq!(read.line, LineSetup::DEFAULT);
    let mut corrupt = first_layout(&calibrated);
    corrupt[20] ^= 1;
    assert!(matches!(
        record::decode(&corrupt),
        Err(RecordError::CrcMismatch { .. })
    ));
}

#[test]
fn the_line_settings_survive_the_record() {
    let mut c = Configuration::DEFAULT;
    for (key, value) in [
        (Key::ModbusAddress, KeyValue::Number(247.0)),
        (Key::ModbusBaud, KeyValue::Number(115_200.0)),
        (Key::ModbusParity, KeyValue::Switch(false)),
        (Key::LinkTimeout, KeyValue::Number(0.0)),
        (Key::ConsoleWatchdog, KeyValue::Switch(true)),
    ] {
        c = key.set(&c, value).unwrap();
    }
    assert_eq!(record::load(&record::encode(&c), &DAC_LOOP), Ok(c));
    assert_eq!(
        Key::ModbusAddress.set(&c, KeyValue::Number(0.0)),
        Err(ConfigError::new(
            Key::ModbusAddress,
            Problem::OutOfRange {
                value: 0.0,
                min: 1.0,
                max: 247.0
            }
        ))
    );
}

#[test]
fn erased_flash_other_layouts_and_refused_records_are_named() {
    let erased = [0xff; RECORD_LEN];
    assert_eq!(
        record::load(&erased, &DAC_LOOP),
        Err(LoadError::Record(RecordError::Empty))
    );
    let mut newer = record::encode(&Configuration::DEFAULT);
    newer[4..6].copy_from_slice(&3u16.to_le_bytes());
    assert_eq!(
        record::decode(&newer),
        Err(RecordError::UnsupportedVersion { found: 3 })
    );
    let stored = record::encode(&Configuration::DEFAULT);
    assert_eq!(
        record::load(&stored, &PWM_OPEN),
        Err(LoadError::Refused(ConfigError::new(
            Key::ClosedLoop,
            Problem::NoEncoder
        )))
    );
}

/// Configurations whose every value lies in its key's range, valid as a whole or not.
fn configurations() -> impl Strategy<Value = Configuration> {
    let values = Key::ALL.map(|key| match key.kind() {
        ValueKind::Switch { .. } => any::<bool>().prop_map(KeyValue::Switch).boxed(),
        ValueKind::Whole { min, max } => (min..=max)
            .prop_map(|n| KeyValue::Number(f64::from(n)))
            .boxed(),
        ValueKind::Number { .. } => (0.0f64..=1.0).prop_map(KeyValue::Number).boxed(),
    });
    (values.to_vec(), any::<bool>()).prop_map(|(fractions, accel_last)| {
        let mut c = Configuration::DEFAULT;
        for (key, value) in Key::ALL.into_iter().zip(fractions) {
            if matches!(key, Key::StartStroke | Key::StartAccel)
                && (key == Key::StartAccel) != accel_last
            {
                continue;
            }
            let value = match (key.kind(), value) {
                (ValueKind::Number { .. }, KeyValue::Number(fraction)) => {
                    let (min, max) = range(key);
                    KeyValue::Number(min + fraction * (max - min))
                }
                (_, value) => value,
            };
            c = key.set(&c, value).unwrap();
        }
        c
    })
}

/// A key's range, found from its refusal of a value far outside it.
fn range(key: Key) -> (f64, f64) {
    match key.check(KeyValue::Number(-1e300)) {
        Err(ConfigError {
            problem: Problem::OutOfRange { min, max, .. },
            ..
        }) => (min, max),
        other => panic!("{other:?}"),
    }
}

proptest! {
    /// A configuration comes back from its record bit for bit, and is used exactly when it is
    /// valid as a whole.
    #[test]
    fn a_record_brings_back_what_it_stored(c in configurations()) {
        let bytes = record::encode(&c);
        prop_assert_eq!(record::decode(&bytes), Ok(c));
        prop_assert_eq!(record::load(&bytes, &DAC_LOOP).is_ok(), c.check(&DAC_LOOP).is_ok());
    }

    /// One flipped bit anywhere in a record is caught: it is never read as another configuration.
    #[test]
    fn a_flipped_bit_is_never_misread(c in configurations(), bit in 0..RECORD_LEN * 8) {
        let mut bytes = record::encode(&c);
        bytes[bit / 8] ^= 1 << (bit % 8);
        prop_assert!(record::decode(&bytes).is_err());
    }

    /// A value outside its key's range is refused and changes nothing.
    #[test]
    fn a_value_out_of_range_is_refused(index in 0..Key::ALL.len(), beyond in 1e-6f64..1e6, below in any::<bool>()) {
        let key = Key::ALL[index];
        prop_assume!(!matches!(key.kind(), ValueKind::Switch { .. }));
        let (min, max) = range(key);
        let value = if below { min - beyond } else { max + beyond };
        let refused = key.set(&Configuration::DEFAULT, KeyValue::Number(value));
        prop_assert_eq!(refused, Err(ConfigError::new(key, Problem::OutOfRange { value, min, max })));
    }
}

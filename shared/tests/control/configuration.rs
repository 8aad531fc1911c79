//! The configuration on the board: `config` edits a copy, checked per value; `save` checks the
//! whole and stores it while stopped; output keys and `restart` wait for the plate to stop.

use feeder_shared::configuration::record as config_record;
use feeder_shared::configuration::{BoardFacts, Configuration, OutputKind};
use feeder_shared::{Action, Controller, TickClock};

use crate::{controller, run, running, stopped, Memory};

const BOARD: BoardFacts = BoardFacts {
    clock: TickClock::new(1_000_000),
    output: OutputKind::Dac,
    encoder: true,
};

fn configured() -> Controller {
    Controller::configured(BOARD, Configuration::DEFAULT, Configuration::DEFAULT).unwrap()
}

fn reply(controller: &mut Controller, line: &str, store: &mut Memory) -> String {
    run(controller, line, &stopped(0), store)
        .reply
        .as_str()
        .to_string()
}

#[test]
fn the_list_shows_every_key_in_its_console_unit() {
    let mut store = Memory::erased();
    assert_eq!(
        reply(&mut configured(), "config list", &mut store),
        "OK config dac_zero=2048 dac_counts_per_mps2=8 dac_margin=249 pwm_full_mps2=250 \
         min_freq_hz=50 max_freq_hz=100 max_accel_mps2=200 max_stroke_mm=5 encoder_um=1 \
         encoder_dir=forward closed_loop=on part_mu=0.3 track_full_s=0.5 track_empty_s=1 \
         start_freq_hz=50 start_duty=0.586 start_stroke_mm=2.5 start_ramp=25 modbus_address=1 \
         modbus_baud=19200 modbus_parity=even link_timeout_ms=2000 console_watchdog=off"
    );
}

#[test]
fn a_value_is_set_read_back_saved_and_runs_from_the_next_start() {
    let mut controller = configured();
    let mut store = Memory::erased();
    assert_eq!(
        reply(&mut controller, "config set dac_zero 2050", &mut store),
        "OK dac_zero=2050 (not saved)"
    );
    assert_eq!(
        reply(&mut controller, "config get DAC_ZERO", &mut store),
        "OK dac_zero=2050"
    );
    assert_eq!(
        reply(
            &mut controller,
            "config set encoder_dir reversed",
            &mut store
        ),
        "OK encoder_dir=reversed (not saved)"
    );
    assert_eq!(store, Memory::erased(), "nothing is stored before save");
    assert_eq!(
        reply(&mut controller, "config save", &mut store),
        "OK config saved; restart to run it"
    );
    let saved = config_record::decode(&store.configuration).unwrap();
    assert_eq!(saved.dac.zero_code, 2050);
    assert!(saved.encoder.reversed);
    assert_eq!(controller.configuration(), Some(&Configuration::DEFAULT));
    let next = Controller::configured(BOARD, Configuration::DEFAULT, saved).unwrap();
    assert_eq!(next.configuration(), Some(&saved));
}

#[test]
fn output_keys_save_and_restart_wait_for_the_plate_to_stop() {
    let mut controller = configured();
    let mut store = Memory::erased();
    for line in [
        "config set dac_zero 2050",
        "config set closed_loop off",
        "config save",
        "restart",
    ] {
        let outcome = run(&mut controller, line, &running(5), &mut store);
        assert!(outcome.reply.as_str().starts_with("ERR 60 "), "{line}");
        assert_eq!(outcome.action, Action::None);
    }
    let start_up = run(
        &mut controller,
        "config set start_duty 0.6",
        &running(5),
        &mut store,
    );
    assert_eq!(start_up.reply.as_str(), "OK start_duty=0.6 (not saved)");
    let restart = run(&mut controller, "restart", &stopped(9), &mut store);
    assert_eq!(restart.action, Action::Restart);
}

#[test]
fn a_configuration_refused_as_a_whole_is_not_stored_and_names_its_key() {
    let mut controller = configured();
    let mut store = Memory::erased();
    reply(&mut controller, "config set max_accel_mps2 240", &mut store);
    assert_eq!(
        reply(&mut controller, "config save", &mut store),
        "ERR 65 max_accel_mps2: the output's linear range reaches only 224.75 m/s2: lower it \
         or change the output's calibration; nothing changed"
    );
    assert_eq!(store, Memory::erased());
    reply(
        &mut controller,
        "config set dac_counts_per_mps2 7",
        &mut store,
    );
    assert_eq!(
        reply(&mut controller, "config save", &mut store),
        "OK config saved; restart to run it"
    );
}

#[test]
fn values_outside_a_key_range_or_of_the_wrong_kind_are_refused() {
    let mut controller = configured();
    let mut store = Memory::erased();
    for (line, expected) in [
        (
            "config set part_mu 3",
            "ERR 65 part_mu: 3 lies outside 0.01 to 2; nothing changed",
        ),
        (
            "config set dac_zero 20.5",
            "ERR 27 not a whole number: expected the DAC code of zero acceleration",
        ),
        ("config set closed_loop maybe", "ERR 29 expected on or off"),
        (
            "config set max_stroke_mm 4 m",
            "ERR 26 wrong unit: expected the plate's travel in mm",
        ),
        (
            "config get gain",
            "ERR 23 unknown configuration key; config list shows them",
        ),
    ] {
        assert_eq!(reply(&mut controller, line, &mut store), expected);
    }
    assert_eq!(
        reply(&mut controller, "config list", &mut store),
        reply(&mut configured(), "config list", &mut store)
    );
}

#[test]
fn defaults_come_back_and_a_failed_write_stores_nothing() {
    let mut controller = configured();
    let mut store = Memory::erased();
    reply(
        &mut controller,
        "config set start_accel_mps2 120",
        &mut store,
    );
    assert_eq!(
        reply(&mut controller, "config get start_stroke_mm", &mut store),
        "OK start_stroke_mm=none"
    );
    assert_eq!(
        reply(&mut controller, "config defaults", &mut store),
        "OK config defaults (not saved)"
    );
    assert_eq!(
        reply(&mut controller, "config get start_stroke_mm", &mut store),
        "OK start_stroke_mm=2.5"
    );
    store.fail = true;
    assert!(reply(&mut controller, "config save", &mut store).starts_with("ERR 62 "));
    assert_eq!(
        store.configuration,
        [0xff; config_record::RECORD_LEN],
        "a failed write stores nothing"
    );
}

#[test]
fn a_board_that_keeps_no_configuration_says_so() {
    let mut store = Memory::erased();
    assert_eq!(
        reply(&mut controller(), "config list", &mut store),
        "ERR 66 this board keeps no configuration"
    );
}

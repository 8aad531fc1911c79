//! A run as an operator with only the user button B1 makes it, on an image without a console:
//! a press starts the feeder, a press once the asked cycles have begun stops it softly, and the
//! run goes on until the soft stop is over; then the `end` event closes the stream, as the
//! emulated board's scripted operator closes its own. The decoded log goes to `out` line by
//! line, for `host-sim hil`.

use std::io::{self, Write};

use feeder_shared::event::{parse_line, Event, SegmentEvent};

use crate::log::LogDecoder;
use crate::machine::{Machine, Stop};
use crate::outputs::{self, Levels, OutputCheck, OutputRecord};
use crate::peripherals::Output;
use crate::{Cycles, TwinError, CORE_HZ};

/// How long a press is held, s: longer than the firmware's debounce.
const PRESS_S: f64 = 0.1;
/// When the first press comes, s after power-up.
const FIRST_PRESS_S: f64 = 0.01;
/// Periods left for the soft stop beyond its ramp.
const STOP_MARGIN_PERIODS: u64 = 3;
/// The firmware's log line as a fault drill begins (`firmware/src/board/g474/drill.rs`).
const DRILL_LINE: &str = "fault drill now";

/// The longest a run may take in the core's time, s: a firmware that never starts or stops
/// ends there.
const LIMIT_S: f64 = 600.0;

/// What the run found.
#[derive(Debug, Clone, PartialEq)]
pub struct ButtonOutcome {
    /// The run went through both presses and the soft stop.
    pub completed: bool,
    /// A watchdog reset on the way, at this core time.
    pub watchdog_reset: Option<Cycles>,
    /// The DAC's output against the segments the firmware reported.
    pub outputs: OutputCheck,
}

fn seconds(s: f64) -> Cycles {
    (s * CORE_HZ as f64) as Cycles
}

/// The plan's period and ramp from the power-up plan's event: the period in core cycles, the
/// output's ticks in core cycles, and the ramp in cycles.
#[derive(Debug, Clone, Copy)]
struct Timing {
    period: Cycles,
    cycles_per_tick: Cycles,
    ramp_cycles: u64,
}

/// The log written so far, and what the twin reads from it.
struct Log<'d, 'o> {
    decoder: LogDecoder<'d>,
    out: &'o mut dyn Write,
    timing: Option<Timing>,
    /// The output tick of the start request.
    start_tick: Option<u64>,
    /// The segments the firmware reported as played.
    segments: Vec<SegmentEvent>,
    /// When the firmware announced a fault drill, by its log's timestamp.
    drill_at: Option<Cycles>,
    /// The watchdog's last feed before its last reset.
    feed_before_reset: Option<Cycles>,
}

impl<'d, 'o> Log<'d, 'o> {
    fn new(decoder: LogDecoder<'d>, out: &'o mut dyn Write) -> Self {
        Log {
            decoder,
            out,
            timing: None,
            start_tick: None,
            segments: Vec::new(),
            drill_at: None,
            feed_before_reset: None,
        }
    }

    fn take(&mut self, machine: &mut Machine) -> io::Result<()> {
        let clock_origin = machine.board().clock_origin().unwrap_or(0);
        for line in self.decoder.lines(&machine.take_log()) {
            writeln!(self.out, "{line}")?;
            if line.contains(DRILL_LINE) && self.drill_at.is_none() {
                self.drill_at = line
                    .split_whitespace()
                    .next()
                    .and_then(|stamp| stamp.parse::<f64>().ok())
                    .map(|stamp| clock_origin + seconds(stamp));
            }
            match parse_line(&line) {
                Ok(Some(Event::Plan {
                    tick: 0,
                    spec,
                    clock_hz,
                    ramp_cycles,
                })) => {
                    self.timing = Some(Timing {
                        period: (spec.period_s * CORE_HZ as f64) as Cycles,
                        cycles_per_tick: CORE_HZ / u64::from(clock_hz.max(1)),
                        ramp_cycles: u64::from(ramp_cycles),
                    })
                }
                Ok(Some(Event::Start { tick })) => self.start_tick = Some(tick),
                Ok(Some(Event::Segment(segment))) => self.segments.push(segment),
                _ => {}
            }
        }
        Ok(())
    }
}

/// Runs `machine` until `until`, the log taken; a watchdog reset ends the run early, and its
/// time is returned (its last feed kept in `log`).
fn run(machine: &mut Machine, log: &mut Log, until: Cycles) -> Result<Option<Cycles>, TwinError> {
    let stop = machine.run_until(until)?;
    log.take(machine).map_err(|error| TwinError::Engine {
        what: "write the log".into(),
        problem: error.to_string(),
    })?;
    Ok(match stop {
        Stop::WatchdogReset { at, last_feed } => {
            log.feed_before_reset = last_feed;
            Some(at)
        }
        Stop::Ended => None,
    })
}

/// Presses B1 for [`PRESS_S`] from `at`.
fn press(machine: &mut Machine, log: &mut Log, at: Cycles) -> Result<Option<Cycles>, TwinError> {
    if let Some(reset) = run(machine, log, at)? {
        return Ok(Some(reset));
    }
    machine.button(true);
    let reset = run(machine, log, at + seconds(PRESS_S))?;
    machine.button(false);
    Ok(reset)
}

/// Runs the button scenario for `cycles` motion cycles, the decoded log to `out`; `record` is
/// what the board's outputs did (the plate `machine` was loaded with, or kept beside it), and
/// `levels` what a segment's level may be on them.
pub fn button_run(
    machine: &mut Machine,
    decoder: LogDecoder,
    out: &mut dyn Write,
    cycles: u64,
    record: &OutputRecord,
    levels: Levels,
) -> Result<ButtonOutcome, TwinError> {
    let mut log = Log::new(decoder, out);
    let judge = |machine: &Machine, log: &Log| {
        let changes = record.changes();
        let zero_code = changes.iter().find_map(|change| match change {
            Output::Dac { code, .. } => Some(*code),
            _ => None,
        });
        outputs::check(
            &changes,
            &log.segments,
            machine.board().output_origin().unwrap_or(0),
            log.timing.map_or(1, |timing| timing.cycles_per_tick),
            zero_code.unwrap_or(0),
            levels,
        )
    };
    let failed = |machine: &Machine, log: &Log, reset| ButtonOutcome {
        completed: false,
        watchdog_reset: reset,
        outputs: judge(machine, log),
    };
    if let Some(reset) = press(machine, &mut log, seconds(FIRST_PRESS_S))? {
        return Ok(failed(machine, &log, Some(reset)));
    }
    // The start takes effect at the next period's boundary: wait for its request.
    let limit = seconds(LIMIT_S);
    while log.start_tick.is_none() && machine.now() < limit {
        let step = machine.now() + seconds(0.01);
        if let Some(reset) = run(machine, &mut log, step)? {
            return Ok(failed(machine, &log, Some(reset)));
        }
    }
    let (Some(timing), Some(start_tick)) = (log.timing, log.start_tick) else {
        return Ok(failed(machine, &log, None));
    };
    let origin = machine.board().output_origin().unwrap_or(0);
    let stop_at = origin + start_tick * timing.cycles_per_tick + cycles * timing.period;
    if let Some(reset) = press(machine, &mut log, stop_at)? {
        return Ok(failed(machine, &log, Some(reset)));
    }
    let end = machine.now() + (timing.ramp_cycles + STOP_MARGIN_PERIODS) * timing.period;
    if let Some(reset) = run(machine, &mut log, end)? {
        return Ok(failed(machine, &log, Some(reset)));
    }
    let tick = (machine.now() - origin) / timing.cycles_per_tick;
    writeln!(log.out, "{}", Event::End { tick }).map_err(|error| TwinError::Engine {
        what: "write the log".into(),
        problem: error.to_string(),
    })?;
    Ok(ButtonOutcome {
        completed: true,
        watchdog_reset: None,
        outputs: judge(machine, &log),
    })
}

/// What a fault drill did to the outputs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DrillOutcome {
    /// When the firmware announced the drill (its log's timestamp), core cycles.
    pub fault_at: Cycles,
    /// From when on the driver stayed disabled (a store, or the reset's pull-down).
    pub enable_off_at: Option<Cycles>,
    /// From when on the command stayed at zero (the zero code, or the DAC off by a reset).
    pub command_safe_at: Option<Cycles>,
    /// The watchdog's reset, if one came.
    pub watchdog_reset: Option<Cycles>,
    /// The watchdog's last feed before the reset (or the end).
    pub last_feed: Option<Cycles>,
}

/// How long after the drill the outputs are watched, s.
const DRILL_WATCH_S: f64 = 0.02;

/// Where a drill's fault comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Drill {
    /// The image's own (`FEEDER_FAULT_DRILL`), 2 s into the run, announced in its log.
    Firmware,
    /// A non-maskable interrupt from outside (a clock failure, a pin), 1 s into the run.
    Nmi,
}

/// When the twin raises an NMI, s into the run.
const NMI_AT_S: f64 = 1.0;

/// Runs a fault drill: a press starts the feeder, the fault comes, and the outputs are watched
/// for `DRILL_WATCH_S` after it; the decoded log goes to `out`. `None` when the fault never
/// came.
pub fn drill_run(
    machine: &mut Machine,
    decoder: LogDecoder,
    out: &mut dyn Write,
    record: &OutputRecord,
    drill: Drill,
) -> Result<Option<DrillOutcome>, TwinError> {
    let mut log = Log::new(decoder, out);
    let mut watchdog_reset = press(machine, &mut log, seconds(FIRST_PRESS_S))?;
    if drill == Drill::Nmi && watchdog_reset.is_none() {
        watchdog_reset = run(machine, &mut log, seconds(NMI_AT_S))?;
        log.drill_at = Some(machine.now());
        machine.nmi();
    }
    let limit = seconds(LIMIT_S);
    while log.drill_at.is_none() && machine.now() < limit && watchdog_reset.is_none() {
        let step = machine.now() + seconds(0.01);
        watchdog_reset = run(machine, &mut log, step)?;
    }
    let Some(fault_at) = log.drill_at else {
        return Ok(None);
    };
    let end = fault_at + seconds(DRILL_WATCH_S);
    while machine.now() < end {
        let reset = run(machine, &mut log, end)?;
        watchdog_reset = watchdog_reset.or(reset);
    }
    // The feed before the first reset (a later reset's would overwrite it only after another
    // watchdog expiry, which the watch is too short for).
    let last_feed = watchdog_reset.and(log.feed_before_reset);
    let changes = record.changes();
    let zero_code = changes.iter().find_map(|change| match change {
        Output::Dac { code, .. } => Some(*code),
        _ => None,
    });
    let after: Vec<&Output> = changes
        .iter()
        .filter(|change| change_at(change) >= fault_at)
        .collect();
    let safe_from = |unsafe_change: &dyn Fn(&Output) -> bool,
                     safe_change: &dyn Fn(&Output) -> bool| {
        let last_unsafe = after.iter().rposition(|change| unsafe_change(change));
        let from = last_unsafe.map_or(0, |index| index + 1);
        after[from..]
            .iter()
            .find(|change| safe_change(change))
            .map(|change| change_at(change))
            .or_else(|| last_unsafe.is_none().then_some(fault_at))
    };
    let enable_off_at = safe_from(
        &|change| matches!(change, Output::Enable { on: true, .. }),
        &|change| {
            matches!(
                change,
                Output::Enable { on: false, .. } | Output::Reset { .. }
            )
        },
    );
    let command_safe_at = safe_from(
        &|change| matches!(change, Output::Dac { code, .. } if Some(*code) != zero_code),
        &|change| {
            matches!(change, Output::Reset { .. })
                || matches!(change, Output::Dac { code, .. } if Some(*code) == zero_code)
        },
    );
    Ok(Some(DrillOutcome {
        fault_at,
        enable_off_at,
        command_safe_at,
        watchdog_reset,
        last_feed,
    }))
}

fn change_at(change: &Output) -> Cycles {
    match *change {
        Output::Dac { at, .. }
        | Output::Enable { at, .. }
        | Output::Reset { at }
        | Output::Pwm { at, .. } => at,
    }
}

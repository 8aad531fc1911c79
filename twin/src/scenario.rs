//! A run as an operator with only the user button B1 makes it, on an image without a console:
//! a press starts the feeder, a press once the asked cycles have begun stops it softly, and the
//! run goes on until the soft stop is over; then the `end` event closes the stream, as the
//! emulated board's scripted operator closes its own. The decoded log goes to `out` line by
//! line, for `host-sim hil`.

use std::io::{self, Write};

use feeder_shared::event::{parse_line, Event, SegmentEvent};

use crate::log::LogDecoder;
use crate::machine::{Machine, Stop};
use crate::outputs::{self, OutputCheck, OutputRecord};
use crate::{Cycles, TwinError, CORE_HZ};

/// How long a press is held, s: longer than the firmware's debounce.
const PRESS_S: f64 = 0.1;
/// When the first press comes, s after power-up.
const FIRST_PRESS_S: f64 = 0.01;
/// Periods left for the soft stop beyond its ramp.
const STOP_MARGIN_PERIODS: u64 = 3;
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

/// The plan's period and ramp, in core cycles and cycles, from the power-up plan's event.
#[derive(Debug, Clone, Copy)]
struct Timing {
    period: Cycles,
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
}

impl Log<'_, '_> {
    fn take(&mut self, machine: &mut Machine) -> io::Result<()> {
        for line in self.decoder.lines(&machine.take_log()) {
            writeln!(self.out, "{line}")?;
            match parse_line(&line) {
                Ok(Some(Event::Plan {
                    tick: 0,
                    spec,
                    clock_hz,
                    ramp_cycles,
                })) => {
                    self.timing = Some(Timing {
                        period: (spec.period_s * f64::from(clock_hz)) as Cycles,
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

/// Runs `machine` until `until`, the log taken; a watchdog reset ends the run.
fn run(machine: &mut Machine, log: &mut Log, until: Cycles) -> Result<Option<Cycles>, TwinError> {
    let stop = machine.run_until(until)?;
    log.take(machine).map_err(|error| TwinError::Engine {
        what: "write the log".into(),
        problem: error.to_string(),
    })?;
    Ok(match stop {
        Stop::WatchdogReset { at } => Some(at),
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
/// what the board's outputs did (the plate `machine` was loaded with).
pub fn button_run(
    machine: &mut Machine,
    decoder: LogDecoder,
    out: &mut dyn Write,
    cycles: u64,
    record: &OutputRecord,
) -> Result<ButtonOutcome, TwinError> {
    let mut log = Log {
        decoder,
        out,
        timing: None,
        start_tick: None,
        segments: Vec::new(),
    };
    let judge = |machine: &Machine, log: &Log| {
        let changes = record.changes();
        let zero_code = changes.iter().find_map(|change| match change {
            crate::peripherals::Output::Dac { code, .. } => Some(*code),
            crate::peripherals::Output::Enable { .. } => None,
        });
        outputs::check(
            &changes,
            &log.segments,
            machine.board().output_origin().unwrap_or(0),
            zero_code.unwrap_or(0),
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
    let stop_at = origin + start_tick + cycles * timing.period;
    if let Some(reset) = press(machine, &mut log, stop_at)? {
        return Ok(failed(machine, &log, Some(reset)));
    }
    let end = machine.now() + (timing.ramp_cycles + STOP_MARGIN_PERIODS) * timing.period;
    if let Some(reset) = run(machine, &mut log, end)? {
        return Ok(failed(machine, &log, Some(reset)));
    }
    let tick = machine.now() - origin;
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

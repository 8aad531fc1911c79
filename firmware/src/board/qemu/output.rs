//! The emulated output stage: TIM2's semantics on the emulated clock, every level change
//! reported as an `EVT` line.

use embassy_time::{Instant, Timer};
use feeder_shared::configuration::Configuration;
use feeder_shared::scenario::{qemu_clock, QEMU_TICK_HZ};
use feeder_shared::{DriveError, Segment, TickClock};

use super::edge_work::{overrun_if_provoked, record_edge_work};
use super::time_driver::{self, CYCLES_PER_TICK};
use super::{exit, register_read, register_write, OUTPUT_CODE, OUTPUT_RUN, SAFE_STATE_WRITES};
use crate::config;
use crate::output::{DacCodes, EdgeMissed, SegmentOutput, SegmentStart, TrimmedCycle};
use crate::trace;

// The output's clock (`feeder_shared::scenario::qemu_clock`) counts embassy's ticks.
const _: () = assert!(embassy_time::TICK_HZ == QEMU_TICK_HZ as u64);

/// The output stage: TIM2's semantics on the emulated clock. Each segment takes effect on its
/// planned tick whatever the software does, which only preloads the next segment while the
/// current one plays. At each edge the model writes the segment's DAC code to [`OUTPUT_CODE`],
/// unless [`OUTPUT_RUN`] says the timer was stopped: then it plays no edge at all. A preload
/// after its deadline (the start of the segment it preloads) is too late: at the deadline the
/// update event found nothing new and the timer played the playing segment again, level and
/// length. The stage returns [`EdgeMissed`] and reports the replay (`EVT replay`) at the halt
/// that follows, with the output's zero (`EVT zero`), so that the report does not delay the
/// halt.
///
/// `actual` ticks count from the first restart on one timeline: the planned ticks until a halt,
/// after which the restart shifts the plan against it.
pub struct ReportingOutput {
    /// Clock tick of scheduler tick 0, set by each restart (wrapping).
    origin_ticks: u64,
    /// Clock tick of actual tick 0: the first restart.
    timeline_ticks: u64,
    /// The segment playing and its preload slack (`None`: restarted), until a halt.
    playing: Option<(Segment, Option<u32>)>,
    /// The preloaded segment, its slack and its DAC code.
    queued: Option<(Segment, u32, u32)>,
    /// The codes of the plan's levels and of the trimmed cycle, as the board's DAC stage has them.
    codes: DacCodes,
    /// Timer cycle of the edge that began the playing segment, until the next preload.
    edge_cycles: Option<u64>,
    /// The missed edge's replay, until the halt reports it.
    replay: Option<Replay>,
}

/// At a missed edge the timer played `segment` again from `actual_tick`; `slack_ticks` is the
/// late preload's slack, `None` if software had not tried yet.
#[derive(Clone, Copy)]
struct Replay {
    segment: Segment,
    actual_tick: u64,
    slack_ticks: Option<i64>,
}

impl ReportingOutput {
    pub fn new() -> Self {
        Self {
            origin_ticks: 0,
            timeline_ticks: u64::MAX,
            playing: None,
            queued: None,
            codes: DacCodes::new(config::CONFIGURATION.dac),
            edge_cycles: None,
            replay: None,
        }
    }

    /// Sends the level the output applies at `actual_tick` to the plant and, if `segment`
    /// begins a cycle, takes the plant's capture at that tick and logs it. A failed link ends the
    /// run with the output at zero and the driver disabled.
    #[cfg(feature = "cosim")]
    fn exchange(&mut self, segment: &Segment, actual_tick: u64, code: u32) {
        let captured = super::plant_link::with(|plant| {
            plant.send_level(actual_tick, code)?;
            match segment.starts_cycle() {
                true => plant.sample(actual_tick).map(Some),
                false => Ok(None),
            }
        });
        if let Some(count) = captured {
            defmt::info!(
                "plant: cycle {=u64} tick={=u64} count={=i32}",
                segment.cycle,
                actual_tick,
                count
            );
        }
    }

    /// The DAC code of `segment` as the output register holds it.
    fn code(&self, segment: &Segment) -> u32 {
        u32::from(self.codes.code(segment))
    }

    /// The clock tick of scheduler tick `tick`.
    fn clock_tick(&self, tick: u64) -> u64 {
        self.origin_ticks.wrapping_add(tick)
    }

    /// The actual tick of clock tick `clock_tick`.
    fn actual(&self, clock_tick: u64) -> u64 {
        clock_tick.saturating_sub(self.timeline_ticks)
    }
}

impl SegmentOutput for ReportingOutput {
    fn clock(&self) -> TickClock {
        qemu_clock()
    }

    fn level_step_mps2(&self) -> f64 {
        self.codes.level_step_mps2()
    }

    fn calibrate(&mut self, configuration: &Configuration) {
        self.codes.calibrate(configuration.dac);
        let zero_code = u32::from(self.codes.zero_code());
        SAFE_STATE_WRITES[super::ZERO_CODE_WRITE].set(zero_code);
        register_write(OUTPUT_CODE as usize, zero_code);
    }

    fn set_peak_accel(&mut self, peak_accel_mps2: f64) -> Result<(), DriveError> {
        self.codes.set_peak_accel(peak_accel_mps2)
    }

    fn trim(&mut self, trimmed: &TrimmedCycle) -> Result<(), DriveError> {
        self.codes.trim(trimmed)
    }

    fn restart(&mut self, segment: &Segment) {
        let now_ticks = Instant::now().as_ticks();
        self.origin_ticks = now_ticks.wrapping_sub(segment.start_tick);
        if now_ticks < self.timeline_ticks {
            self.timeline_ticks = now_ticks;
            exit::set_timeline(now_ticks);
        }
        let code = self.code(segment);
        register_write(OUTPUT_CODE as usize, code);
        register_write(OUTPUT_RUN as usize, 1);
        self.playing = Some((*segment, None));
        self.queued = None;
        self.edge_cycles = None;
        #[cfg(feature = "cosim")]
        self.exchange(segment, self.actual(now_ticks), code);
    }

    fn preload(&mut self, segment: &Segment) -> Result<(), EdgeMissed> {
        let deadline_cycles = self.clock_tick(segment.start_tick) * CYCLES_PER_TICK;
        overrun_if_provoked(segment, deadline_cycles);
        let now_cycles = time_driver::now_cycles();
        if now_cycles >= deadline_cycles {
            self.replay = self.playing.map(|(playing, _)| Replay {
                segment: playing,
                actual_tick: self.actual(self.clock_tick(segment.start_tick)),
                slack_ticks: Some(
                    (deadline_cycles as i64 - now_cycles as i64).div_euclid(CYCLES_PER_TICK as i64),
                ),
            });
            return Err(EdgeMissed);
        }
        if let Some(edge_cycles) = self.edge_cycles.take() {
            record_edge_work(now_cycles - edge_cycles);
        }
        let slack_ticks = (deadline_cycles - now_cycles) / CYCLES_PER_TICK;
        self.queued = Some((*segment, slack_ticks as u32, self.code(segment)));
        Ok(())
    }

    async fn wait_edge(&mut self) -> Result<(), EdgeMissed> {
        let (segment, slack_ticks, code) = self.queued.take().ok_or(EdgeMissed)?;
        let edge_ticks = self.clock_tick(segment.start_tick);
        Timer::at(Instant::from_ticks(edge_ticks)).await;
        if register_read(OUTPUT_RUN as usize) == 0 {
            // A stopped timer has no further edge.
            core::future::pending::<()>().await;
        }
        register_write(OUTPUT_CODE as usize, code);
        #[cfg(feature = "cosim")]
        self.exchange(&segment, self.actual(edge_ticks), code);
        self.playing = Some((segment, Some(slack_ticks)));
        let end_ticks = self.clock_tick(segment.end_tick());
        if Instant::now().as_ticks() >= end_ticks {
            // More than one edge has passed: the segment played, then the timer played it again.
            trace::segment(&segment, self.started(&segment));
            self.replay = Some(Replay {
                segment,
                actual_tick: self.actual(end_ticks),
                slack_ticks: None,
            });
            return Err(EdgeMissed);
        }
        self.edge_cycles = Some(edge_ticks * CYCLES_PER_TICK);
        Ok(())
    }

    fn halt(&mut self) {
        register_write(OUTPUT_CODE as usize, u32::from(self.codes.zero_code()));
        register_write(OUTPUT_RUN as usize, 0);
        let now_ticks = Instant::now().as_ticks();
        self.queued = None;
        self.edge_cycles = None;
        if let Some(replay) = self.replay.take() {
            trace::replay(&replay.segment, replay.actual_tick, replay.slack_ticks);
        }
        if self.playing.take().is_some() {
            trace::zero(self.actual(now_ticks));
        }
    }

    fn started(&self, segment: &Segment) -> SegmentStart {
        SegmentStart {
            tick: self.actual(self.clock_tick(segment.start_tick)),
            slack_ticks: self.playing.and_then(|(_, slack_ticks)| slack_ticks),
        }
    }
}

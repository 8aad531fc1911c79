//! The closed loop, below the edge path (on a board with a position sensor): at every cycle
//! boundary the shared course (`feeder_shared::closed_loop::Course`) takes the plate's positions
//! and decides the next cycle's trims; the control loop takes the decision at its next edge and
//! the output stage swaps the trimmed levels in at the cycle boundary. The drive's
//! identification runs on the background executor, below this task, while the course holds the
//! plate on the nominal drive; so does the search for the amplitude that gives the ideal plate's
//! feed behind the drive's lag, once per plan and drive.

use core::cell::Cell;

use defmt::{error, info, Display2Format};
use embassy_futures::select::{select, Either};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::mutex::Mutex as AsyncMutex;
use embassy_sync::signal::Signal;
use feeder_shared::closed_loop::{
    Course, CourseConfig, CourseError, Decision, FeedCompensation, FeedRequest, Identification,
    Identified, IdentifyError, PositionSample, Probe, Stage, Trims,
};
use feeder_shared::{Scheduler, Segment};

use crate::ports::PositionSensor;
use crate::{config, configured, status};

/// The positions one boundary takes at most: a cycle at the lowest frequency sampled every
/// 0.25 ms, with room to spare; older ones are dropped.
const SAMPLES_MAX: usize = 128;

/// A cycle (or idle period) the output has begun, as the control loop hands it over.
pub struct Boundary {
    /// Its first segment.
    pub begun: Segment,
    /// The scheduler right after it, for the plans of the cycles ahead.
    pub ahead: Scheduler,
    /// The output's actual tick at which it began: the sensor's capture.
    pub start_tick: u64,
}

/// What the control loop takes from the closed loop.
#[derive(Clone, Copy)]
pub enum Ruling {
    /// The trims of cycle `decision.cycle`, whether the hold ends, and the feedforward for a
    /// cycle whose trims were not decided (the one after an idle period).
    Trim {
        decision: Decision,
        feedforward: Trims,
    },
    /// The course stopped: the feeder must stop.
    Stop,
}

/// The newest boundary; the task takes each one (a boundary it misses stops the course).
pub static BOUNDARY: Signal<CriticalSectionRawMutex, Boundary> = Signal::new();

/// The newest ruling, taken by the control loop at its next edge.
pub static RULING: Mutex<CriticalSectionRawMutex, Cell<Option<Ruling>>> =
    Mutex::new(Cell::new(None));

/// The probe to identify, handed to the background task (copied in place: a probe is several
/// kilobytes, too many for an interrupt's stack), and its result back.
static PROBE: AsyncMutex<CriticalSectionRawMutex, Probe> = AsyncMutex::new(Probe::new());
static PROBE_READY: Signal<CriticalSectionRawMutex, ()> = Signal::new();
static IDENTIFIED: Signal<CriticalSectionRawMutex, Identification> = Signal::new();

/// The feed compensation the course asks for, handed to the background task, and its answer.
static FEED_ASKED: Signal<CriticalSectionRawMutex, FeedRequest> = Signal::new();
static FEED_FOUND: Signal<CriticalSectionRawMutex, (FeedRequest, FeedCompensation)> = Signal::new();

/// The course's probe step for the scheduler's hold on a soft start of `ramp_cycles`: the
/// control loop holds its scheduler there before the first start and with every new ramp length.
pub fn probe_step(ramp_cycles: u16) -> u16 {
    course_config(0.0).probe_step(ramp_cycles.max(1))
}

/// The settle segments before each start from rest, for the scheduler.
pub fn settle_segments() -> u16 {
    course_config(0.0).settle_segments
}

/// The course for an output whose levels move in steps of `level_step_mps2`, with the feed
/// compensated for the configured part within the output's linear range.
fn course_config(level_step_mps2: f64) -> CourseConfig {
    let configuration = configured::get();
    let config = CourseConfig::new(configuration.encoder.resolution_m, level_step_mps2);
    config.with_feed(
        configuration.friction().accel_mps2(),
        configuration.linear_limit_mps2(config::OUTPUT),
    )
}

type Sensor = <crate::board::Hardware as crate::ports::Parts>::Sensor;

/// Runs the course at every boundary until it stops; the output's levels move in steps of
/// `level_step_mps2`.
#[embassy_executor::task]
pub async fn regulate_task(mut sensor: Sensor, level_step_mps2: f64) {
    let ramp_cycles = configured::get().startup.ramp_cycles;
    let mut course = Course::new(course_config(level_step_mps2), ramp_cycles.max(1));
    let mut samples = [PositionSample {
        tick: 0,
        position_m: 0.0,
    }; SAMPLES_MAX];
    let mut last_cycle: Option<u64> = None;
    let mut feed_asked: Option<FeedRequest> = None;
    // The capture that began the cycle measured last, for its telemetry.
    #[cfg(feature = "console")]
    let mut previous_start: Option<PositionSample> = None;
    loop {
        let boundary = BOUNDARY.wait().await;
        let stage = course.stage();
        if let Some(identification) = IDENTIFIED.try_take() {
            report(&identification.result);
            course.set_identified(identification);
        }
        if let Some((request, found)) = FEED_FOUND.try_take() {
            course.set_feed(request, found);
        }
        if let Some(last) = last_cycle.filter(|last| boundary.begun.cycle != last + 1) {
            stop(CourseError::MissedBoundary { cycle: last + 1 });
            return;
        }
        last_cycle = Some(boundary.begun.cycle);
        let count = sensor.take_until(boundary.start_tick, &mut samples);
        let Some((start, during)) = samples[..count]
            .split_last()
            .filter(|(start, _)| start.tick == boundary.start_tick)
        else {
            stop(CourseError::NoCapture {
                tick: boundary.start_tick,
            });
            return;
        };
        let outcome = course.boundary(&boundary.begun, &boundary.ahead, *start, during);
        #[cfg(feature = "console")]
        let last_start = core::mem::replace(&mut previous_start, Some(*start));
        match outcome {
            Ok(decision) => {
                if course.stage() != stage {
                    info!(
                        "closed loop: {} at cycle {=u64}",
                        course.stage(),
                        boundary.begun.cycle
                    );
                    status::publish_loop(course.report());
                }
                if decision.identify {
                    if let Some(probe) = course.probe() {
                        PROBE.lock().await.copy_from(probe);
                        PROBE_READY.signal(());
                    }
                }
                if let Some(request) = course.feed_request().filter(|r| feed_asked != Some(*r)) {
                    feed_asked = Some(request);
                    FEED_ASKED.signal(request);
                }
                #[cfg(feature = "console")]
                crate::telemetry::publish_loop(
                    course.stage(),
                    last_start
                        .map(|last| feeder_shared::telemetry::cycle_positions(last, during, *start)),
                    Some(decision.trims),
                );
                let feedforward = course.feedforward();
                RULING.lock(|ruling| {
                    ruling.set(Some(Ruling::Trim {
                        decision,
                        feedforward,
                    }))
                });
            }
            Err(error) => {
                status::publish_loop(course.report());
                stop(error);
                return;
            }
        }
        if course.stage() == Stage::Failed {
            return;
        }
    }
}

/// Identifies the drive from each probe handed over, and finds each feed compensation asked
/// for.
#[embassy_executor::task]
pub async fn identify_task() {
    loop {
        match select(PROBE_READY.wait(), FEED_ASKED.wait()).await {
            Either::First(()) => {
                info!("identifying the drive");
                let result = PROBE.lock().await.identify();
                IDENTIFIED.signal(result);
            }
            Either::Second(request) => {
                let found = request.solve();
                report_feed(&found);
                FEED_FOUND.signal((request, found));
            }
        }
    }
}

fn report_feed(found: &FeedCompensation) {
    if found.limited {
        info!(
            "feed compensated: levels x{=f64}, the most the drive's linear range allows: \
             {=f64} mm/s instead of the ideal plate's {=f64} mm/s",
            found.amplitude,
            found.feed_mps * 1e3,
            found.ideal_mps * 1e3
        );
    } else {
        info!(
            "feed compensated: levels x{=f64} for the ideal plate's {=f64} mm/s behind the \
             drive's lag",
            found.amplitude,
            found.ideal_mps * 1e3
        );
    }
}

fn report(result: &Result<Identified, IdentifyError>) {
    match result {
        Ok(drive) => info!(
            "drive identified: gain + {=f64}, gain − {=f64}, offset {=f64} m/s², lag {=f64} s, \
             Coulomb {=f64} m/s², viscous {=f64} 1/s, spring {=f64} 1/s², residual {=f64} m",
            drive.gain_positive,
            drive.gain_negative,
            drive.offset_mps2,
            drive.lag_s,
            drive.coulomb_mps2,
            drive.viscous_per_s,
            drive.spring_per_s2,
            drive.residual_m
        ),
        Err(error) => error!("drive identification refused: {}", Display2Format(error)),
    }
}

fn stop(error: CourseError) {
    error!("closed loop stopped: {}", Display2Format(&error));
    RULING.lock(|ruling| ruling.set(Some(Ruling::Stop)));
}

//! The seam between the application and a board: what the application needs from one.
//!
//! A board names the types of its parts in one [`Parts`] implementation and hands the parts over
//! as a [`Board`]; the fault handlers make its safe state from its table of [`RegisterWrite`]s.

use core::sync::atomic::{AtomicU32, Ordering};

use embassy_executor::SendSpawner;
use embedded_hal::digital::{InputPin, OutputPin};
use embedded_hal_async::digital::Wait;
use feeder_shared::closed_loop::PositionSample;
use feeder_shared::configuration::Configuration;
use feeder_shared::{Fault, TickClock};

use crate::output::SegmentOutput;

/// The types of a board's parts.
pub trait Parts {
    /// The output stage, which times every edge in hardware.
    type Output: SegmentOutput;
    /// The driver enable: high enables the driver.
    type DriverEnable: OutputPin;
    /// The status LED: high lights it.
    type Led: OutputPin;
    /// The start/stop button: high while pressed.
    type Button: InputPin + Wait;
    type Watchdog: Watchdog;
    /// Who operates the feeder besides the button.
    type Operator: Operator;
    /// The plate's position sensor; a board without one ([`NoSensor`]) runs open loop.
    type Sensor: PositionSensor;
    /// The track's part sensor; a board without one ([`NoPartSensor`]) has no track control.
    type PartSensor: PartSensor;
}

/// Everything the application needs from the board.
pub struct Board<P: Parts> {
    pub output: P::Output,
    pub driver_enable: P::DriverEnable,
    pub led: P::Led,
    pub button: P::Button,
    pub watchdog: P::Watchdog,
    pub operator: P::Operator,
    pub sensor: P::Sensor,
    pub part_sensor: P::PartSensor,
    /// What power-up found wrong, latched before anything runs: the watchdog's reset, or a
    /// failed self-test.
    pub latched_at_power_up: Option<Fault>,
    /// Spawner of the executor that runs the control loop above the other tasks.
    pub control_spawner: SendSpawner,
    /// Spawner of the executor that runs the closed loop's course, below the control loop and
    /// above the other tasks: an operator's command never holds a decision past the segment
    /// it is due in (a settle segment is 2.5 ms). A board without a position sensor runs no
    /// course and passes the tasks' spawner.
    pub loop_spawner: SendSpawner,
    /// Spawner of the executor below every other: long computations (the drive's
    /// identification) that must not hold the closed loop up.
    pub background_spawner: SendSpawner,
}

/// A watchdog that the monitor feeds while the application makes progress.
pub trait Watchdog {
    /// How often the monitor checks progress and feeds the watchdog.
    const MONITOR_PERIOD_US: u64;
    /// The monitor runs on the control executor, above the tasks' executor, which beats for it:
    /// the watchdog's timeout is shorter than the longest work of a task (a recipe write).
    const WATCHES_TASKS: bool;

    /// Feeds the watchdog unless the board holds the feed back; true if it fed.
    fn feed(&mut self) -> bool;
}

/// An operator besides the button: a serial console or a script.
pub trait Operator {
    /// The configuration the board runs, for an output timed by `clock`: the one saved in the
    /// operator's store ([`crate::configured::at_power_up`]), or the compiled defaults where it
    /// keeps none. Called once at power-up, before anything plays.
    fn load_configuration(&mut self, clock: TickClock) -> Configuration;

    /// Spawns the operator's task on `spawner`; it plans every waveform on the output's `clock`.
    fn spawn(self, spawner: SendSpawner, clock: TickClock);
}

/// The plate's position, sampled by hardware on the output's clock: at a fixed interval and at
/// every cycle's start tick (a capture at the tick the output begins the cycle).
pub trait PositionSensor: Send {
    /// False for a board without a sensor: the closed loop is not run at all.
    const PRESENT: bool;
    /// Moves the positions sampled up to and including `tick` (the output's actual tick, a
    /// cycle start the output has begun) into `out`, oldest first, the one at `tick` last, and
    /// returns how many; those that do not fit are dropped, the oldest first.
    fn take_until(&mut self, tick: u64, out: &mut [PositionSample]) -> usize;
}

/// A board without a position sensor.
#[allow(
    dead_code,
    reason = "every board but the co-simulated one with an encoder names it"
)]
pub struct NoSensor;

impl PositionSensor for NoSensor {
    const PRESENT: bool = false;

    fn take_until(&mut self, _tick: u64, _out: &mut [PositionSample]) -> usize {
        0
    }
}

/// A light barrier near the end of the track: blocked while a part stands in it.
pub trait PartSensor: Send {
    /// False for a board without one: track control is not run at all.
    const PRESENT: bool;
    /// Waits until the barrier changes and says whether it is blocked now.
    async fn changed(&mut self) -> bool;
}

/// A board without a part sensor.
#[allow(dead_code, reason = "boards with a part sensor do not name it")]
pub struct NoPartSensor;

impl PartSensor for NoPartSensor {
    const PRESENT: bool = false;

    async fn changed(&mut self) -> bool {
        core::future::pending().await
    }
}

/// One 32-bit store of a board's safe state, made by the HardFault entry before it touches the
/// stack (see `crate::fault`). The value of the store that zeroes the command is the configured
/// zero code, set once at power-up ([`RegisterWrite::set`]) before any task runs.
#[repr(C)]
pub struct RegisterWrite {
    pub address: u32,
    value: AtomicU32,
}

impl RegisterWrite {
    pub const fn new(address: u32, value: u32) -> Self {
        Self {
            address,
            value: AtomicU32::new(value),
        }
    }

    /// Stores `value` from now on.
    #[cfg_attr(
        all(feature = "board-g474", feature = "output-pwm"),
        expect(dead_code, reason = "the PWM stage's zero is no duty: nothing to set")
    )]
    pub fn set(&self, value: u32) {
        self.value.store(value, Ordering::Relaxed)
    }

    pub fn value(&self) -> u32 {
        self.value.load(Ordering::Relaxed)
    }
}

/// Makes `writes` in their order and waits until they are done.
pub fn write_all(writes: &[RegisterWrite]) {
    for write in writes {
        // SAFETY: a board's safe-state table holds its output registers and the values that
        // stop them.
        unsafe { core::ptr::write_volatile(write.address as *mut u32, write.value()) }
    }
    cortex_m::asm::dsb();
}

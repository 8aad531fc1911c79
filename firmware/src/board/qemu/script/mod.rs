//! The scripted operator of an emulated run (without the `console` feature), configured on
//! QEMU's command line, the first argument being the program's name
//! (`-semihosting-config enable=on,target=native,arg=feeder-firmware,arg=cycles=1000`):
//!
//! Keys and values are read by `feeder_shared::scenario`, which refuses unknown keys and malformed
//! values and runs whose waveforms this board cannot play (`Scenario::check`, which
//! `cargo xtask run` applies before it starts QEMU); the run then ends with a failure code:
//!
//! | argument            | meaning                                         | default              |
//! |---------------------|-------------------------------------------------|----------------------|
//! | `cycles=N`          | request the soft stop once N cycles have begun  | 300                  |
//! |                     | (with the closed loop: N cycles after its course released the soft start) | |
//! | `freq_hz=F`         | waveform frequency                              | the firmware default |
//! | `duty=D`            | duty at start                                   | the firmware default |
//! | `stroke_m=X`        | stroke (peak-to-peak plate travel), in m or with its unit (`2.5mm`) | the firmware default |
//! | `new_duty=D`        | duty of the live change at N/2 cycles           | `duty` + 0.02        |
//! | `ramp=R`            | soft start/stop cycles                          | the firmware default |
//! | `panic_at=C`        | panic in thread mode once C cycles have begun   | never                |
//! | `overflow_at=C`     | overflow the stack in thread mode from cycle C  | never                |
//! | `mask_at=C`         | mask interrupts for two periods at cycle C      | never                |
//! | `late_preload_at=C` | preload cycle C's first segment too late        | never                |
//! | `changes=K`         | K random changes instead of the one at N/2      | none                 |
//! | `seed=S`            | seed of the random changes (`changes`)          | 1                    |
//!
//! The run starts (soft), changes the duty at N/2, stops (soft) at N, and exits with code 0 once
//! the output is idle again; an image with the closed loop counts N from the cycle at which its
//! course (probe, identification, centring) released the soft start, so that the change and
//! the stop fall in the feeding it is judged on, with the work per edge (`EVT work`) and `EVT end`. The missed edge
//! of `late_preload_at` halts the output with the driver disabled; the operator then resets and
//! starts again, once. Any other fault ends the run with a failure code.
//!
//! `panic_at`, `overflow_at` and `mask_at` are carried out by thread mode ([`idle`]), below the
//! interrupt executors, which keep running the output: a panic, a recursion without bound
//! (a HardFault once the stack crosses the bottom of RAM) and a critical section that holds the
//! control loop off past its edges (a missed edge when interrupts come back).

mod changes;

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m_semihosting::debug::{self, EXIT_SUCCESS};
use cortex_m_semihosting::nr::GET_CMDLINE;
use defmt::{info, unwrap, Display2Format};
use embassy_executor::SendSpawner;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;
use embassy_time::{Instant, Timer};
#[cfg(feature = "encoder")]
use feeder_shared::closed_loop::Stage;
use feeder_shared::configuration::Configuration;
use feeder_shared::scenario::Scenario;
use feeder_shared::{RunState, SupervisorEvent, TickClock, WaveformSpec};

use super::edge_work::{edge_work, provoke_late_preload};
use super::exit::{self, after_fault, sleep_forever};
use super::time_driver::{self, CYCLES_PER_TICK};
use crate::mailbox::{ReadyPlan, NEXT_PLAN, REQUESTS};
use crate::status;
use crate::{config, configured, ports, stack_overflow, trace};
use changes::RandomChanges;

/// How often the operator looks at the cycle count.
const POLL_MS: u64 = 5;
/// Cycles past the stop request by which the output must be idle again.
const STOP_GRACE_CYCLES: u32 = 100;

/// The cycles from which thread mode panics, recurses without bound or masks interrupts
/// (`u32::MAX`: never), set before the start.
static PANIC_AT: AtomicU32 = AtomicU32::new(u32::MAX);
static OVERFLOW_AT: AtomicU32 = AtomicU32::new(u32::MAX);
static MASK_AT: AtomicU32 = AtomicU32::new(u32::MAX);
/// How long thread mode masks interrupts, in timer cycles.
static MASK_CYCLES: AtomicU32 = AtomicU32::new(0);

/// Thread mode under a script: spins below the interrupt executors (see `sleep_forever`), or,
/// once its cycle has begun, makes the fault the scenario asks for while they run the output.
pub fn idle() -> ! {
    loop {
        let begun = cycle();
        let panic_at = PANIC_AT.load(Ordering::Relaxed);
        if begun >= panic_at {
            panic!("scenario: panic requested at cycle {}", panic_at);
        }
        if begun >= OVERFLOW_AT.load(Ordering::Relaxed) {
            info!("scenario: thread mode recurses without bound");
            stack_overflow::recurse(0);
        }
        if begun >= MASK_AT.load(Ordering::Relaxed) {
            MASK_AT.store(u32::MAX, Ordering::Relaxed);
            mask_interrupts(MASK_CYCLES.load(Ordering::Relaxed).into());
        }
    }
}

/// Masks interrupts for `cycles` timer cycles, busy-waiting on the clock timer: a critical
/// section that holds the control loop off past its edges.
fn mask_interrupts(cycles: u64) {
    info!(
        "scenario: interrupts masked for {=u64} us",
        cycles / CYCLES_PER_TICK
    );
    cortex_m::interrupt::free(|_| {
        let until = time_driver::now_cycles() + cycles;
        while time_driver::now_cycles() < until {}
    });
}

/// Reads the semihosting command line into `buffer`.
fn command_line(buffer: &mut [u8]) -> &str {
    let mut block = [buffer.as_mut_ptr() as usize, buffer.len()];
    // SAFETY: SYS_GET_CMDLINE writes at most `block[1]` bytes into `buffer` and the length into
    // `block[1]`; both outlive the call.
    let status =
        unsafe { cortex_m_semihosting::syscall1(GET_CMDLINE, block.as_mut_ptr() as usize) };
    // SAFETY: `block` is a live local written by the host during the call.
    let length = unsafe { core::ptr::read_volatile(&block[1]) };
    if status != 0 || length > buffer.len() {
        return "";
    }
    core::str::from_utf8(&buffer[..length]).unwrap_or("")
}

/// The track's light barrier as the script sets it (`track_full_at`, `track_room_at`).
static BARRIER: Signal<CriticalSectionRawMutex, bool> = Signal::new();

/// The script's light barrier: the readings the script hands over.
pub struct ScriptedBarrier;

/// The scripted image's part sensor.
pub type PartSensor = ScriptedBarrier;

/// The part sensor the scripted image has.
pub fn part_sensor() -> PartSensor {
    ScriptedBarrier
}

impl ports::PartSensor for ScriptedBarrier {
    const PRESENT: bool = true;

    async fn changed(&mut self) -> bool {
        BARRIER.wait().await
    }
}

/// Blocks the barrier from cycle `full`, clears it from cycle `room` (either may be never).
#[embassy_executor::task]
async fn barrier_task(full: Option<u32>, room: Option<u32>) {
    let mut steps = [(full, true), (room, false)];
    steps.sort_unstable_by_key(|(cycle, _)| cycle.unwrap_or(u32::MAX));
    for (cycle, blocked) in steps {
        let Some(cycle) = cycle else { return };
        while self::cycle() < cycle {
            Timer::after_millis(POLL_MS).await;
        }
        info!(
            "scenario: the track's barrier {=str} at cycle {=u32}",
            if blocked { "blocked" } else { "clear" },
            cycle
        );
        BARRIER.signal(blocked);
    }
}

/// The script, read when its task starts.
pub struct Operator;

impl Operator {
    pub fn new() -> Self {
        Self
    }
}

impl ports::Operator for Operator {
    /// The scripted image keeps no flash: its runs are the compiled defaults'.
    fn load_configuration(&mut self, _: TickClock) -> Configuration {
        config::CONFIGURATION
    }

    fn spawn(self, spawner: SendSpawner, clock: TickClock) {
        spawner.spawn(unwrap!(operator_task(clock, spawner)));
    }
}

/// The cycle (or idle period) begun last, as the control loop last published it (wrapping at
/// 32 bits, as the script's cycles are counted).
fn cycle() -> u32 {
    status::get().cycle as u32
}

/// Whether a fault is latched, as the control loop last published it.
fn faulted() -> bool {
    matches!(status::get().state, RunState::Faulted(_))
}

/// Queues `event` for the control loop; a full queue drops it.
fn request(event: SupervisorEvent) {
    let _ = REQUESTS.try_send(event);
}

/// Hands `ready` to the control loop, replacing any plan it has not taken yet.
fn offer(ready: ReadyPlan) {
    NEXT_PLAN.lock(|next| next.set(Some(ready)));
}

/// Cycles a fault's stop may take to bring the plate to rest and disable the driver: a
/// controlled stop ends the cycle in progress, idles, then disables it.
const AT_REST_CYCLES: u32 = 4;

/// Waits until the fault's stop has disabled the driver (at once for an immediate stop), or
/// [`AT_REST_CYCLES`] have begun, so that the run ends with the stop carried out.
async fn until_at_rest() {
    let deadline = cycle() + AT_REST_CYCLES;
    while exit::driver_enabled() && cycle() <= deadline {
        Timer::after_millis(POLL_MS).await;
    }
}

/// The scripted operator during the run.
struct Run {
    scenario: Scenario,
    /// The provoked missed edge was acknowledged and the feeder started again.
    restarted: bool,
}

impl Run {
    /// Ends the run with a failure code if the firmware faulted, unless it is the missed edge
    /// the scenario provoked: that one is acknowledged and the feeder started again, once.
    async fn watch_faults(&mut self) {
        if !faulted() {
            return;
        }
        let provoked = self
            .scenario
            .late_preload_cycle
            .is_some_and(|late_cycle| cycle() >= late_cycle);
        if !provoked || self.restarted {
            defmt::error!("scenario: the firmware faulted");
            until_at_rest().await;
            after_fault();
        }
        info!("scenario: the provoked missed edge halted the output; reset and start");
        request(SupervisorEvent::ResetRequested);
        request(SupervisorEvent::StartRequested);
        self.restarted = true;
        while faulted() {
            Timer::after_millis(POLL_MS).await;
        }
    }

    /// The cycle from which the scenario counts: where the closed loop's course released the
    /// soft start (or gave up, or the feeder stopped), 0 on an image without one.
    async fn feeding_cycle(&mut self) -> u32 {
        #[cfg(feature = "encoder")]
        loop {
            self.watch_faults().await;
            let stage = status::closed_loop().map(|report| report.stage);
            let stopped = cycle() > 0 && status::get().state == RunState::Stopped;
            if stopped || matches!(stage, Some(Stage::Feeding | Stage::Failed)) {
                let origin = cycle();
                info!(
                    "scenario: counting cycles from {=u32}, after the course",
                    origin
                );
                return origin;
            }
            Timer::after_millis(POLL_MS).await;
        }
        #[cfg(not(feature = "encoder"))]
        0
    }

    async fn until_cycle(&mut self, until: u32) {
        loop {
            self.watch_faults().await;
            if cycle() >= until {
                return;
            }
            Timer::after_millis(POLL_MS).await;
        }
    }
}

#[embassy_executor::task]
async fn operator_task(clock: TickClock, spawner: SendSpawner) {
    let mut buffer = [0u8; 256];
    // The first word is the program's name (the kernel's path when QEMU got no `arg=`).
    let words = command_line(&mut buffer).split_whitespace().skip(1);
    let scenario = match Scenario::parse(words) {
        Ok(scenario) => scenario,
        Err(error) => {
            defmt::error!("scenario: {}", Display2Format(&error));
            after_fault();
        }
    };
    if let Err(refusal) = scenario.check(clock, configured::machine(clock).loop_linear_mps2) {
        defmt::error!("scenario: {}", Display2Format(&refusal));
        after_fault();
    }
    let plan = |duty| match ReadyPlan::new(
        clock,
        &WaveformSpec {
            duty,
            ..scenario.spec
        },
        scenario.ramp_cycles,
    ) {
        Ok(ready) => ready,
        Err(error) => {
            defmt::error!("scenario: waveform refused: {}", Display2Format(&error));
            after_fault();
        }
    };
    let (first, second) = (plan(scenario.spec.duty), plan(scenario.new_duty));
    let half = scenario.stop_after_cycles / 2;
    info!(
        "scenario: {=u32} cycles, duty {=f64} then {=f64} at cycle {=u32}, ramp {=u16}",
        scenario.stop_after_cycles,
        scenario.spec.duty,
        scenario.new_duty,
        half,
        scenario.ramp_cycles
    );
    if let Some(cycle) = scenario.late_preload_cycle {
        provoke_late_preload(cycle);
    }
    if scenario.track_full_cycle.is_some() || scenario.track_room_cycle.is_some() {
        spawner.spawn(unwrap!(barrier_task(
            scenario.track_full_cycle,
            scenario.track_room_cycle
        )));
    }
    // Two periods: longer than the segment playing when the mask begins and the one preloaded
    // after it together, so at least one edge passes with nothing preloaded.
    let mask_cycles = u64::from(first.plan.period_ticks) * 2 * CYCLES_PER_TICK;
    MASK_CYCLES.store(
        u32::try_from(mask_cycles).unwrap_or(u32::MAX),
        Ordering::Relaxed,
    );
    let never = |cycle: Option<u32>| cycle.unwrap_or(u32::MAX);
    PANIC_AT.store(never(scenario.panic_at_cycle), Ordering::Relaxed);
    OVERFLOW_AT.store(never(scenario.overflow_cycle), Ordering::Relaxed);
    MASK_AT.store(never(scenario.mask_cycle), Ordering::Relaxed);
    let (stop_after, ramp_cycles) = (scenario.stop_after_cycles, scenario.ramp_cycles);
    let (count, start_spec) = (scenario.random_changes, first.spec);
    let mut random = RandomChanges::new(scenario.seed, clock, start_spec, ramp_cycles);
    let mut operator = Run {
        scenario,
        restarted: false,
    };
    offer(first);
    request(SupervisorEvent::StartRequested);
    let origin = operator.feeding_cycle().await;
    let (half, stop_after) = (origin + half, origin + stop_after);
    if count == 0 {
        operator.until_cycle(half).await;
        offer(second);
    }
    let first_cycle = cycle();
    for index in 0..count {
        operator
            .until_cycle(RandomChanges::cycle_of(
                index,
                count,
                first_cycle,
                stop_after,
            ))
            .await;
        random.change().await;
    }
    operator.until_cycle(stop_after).await;
    request(SupervisorEvent::StopRequested);
    let deadline = stop_after + u32::from(ramp_cycles) + STOP_GRACE_CYCLES;
    while status::get().state != RunState::Stopped || cycle() <= stop_after {
        operator.watch_faults().await;
        if cycle() > deadline {
            defmt::error!(
                "scenario: the output did not stop by cycle {=u32}",
                deadline
            );
            after_fault();
        }
        Timer::after_millis(POLL_MS).await;
    }
    let work = edge_work();
    trace::work(
        work.edges,
        work.max_cycles,
        work.total_cycles,
        time_driver::TIMER_HZ as u32,
    );
    trace::end(Instant::now().as_ticks());
    info!("scenario: done");
    debug::exit(EXIT_SUCCESS);
    sleep_forever()
}

//! The scripted operator of an emulated run (without the `qemu-console` feature), configured on
//! QEMU's command line, the first argument being the program's name
//! (`-semihosting-config enable=on,target=native,arg=feeder-firmware,arg=cycles=1000`):
//!
//! Keys and values are read by `feeder_shared::scenario`, which refuses unknown keys and malformed
//! values (the run then ends with a failure code):
//!
//! | argument            | meaning                                         | default              |
//! |---------------------|-------------------------------------------------|----------------------|
//! | `cycles=N`          | request the soft stop once N cycles have begun  | 300                  |
//! | `freq_hz=F`         | waveform frequency                              | the firmware default |
//! | `duty=D`            | duty at start                                   | the firmware default |
//! | `stroke_m=X`        | stroke (peak-to-peak plate travel)              | the firmware default |
//! | `new_duty=D`        | duty of the live change at N/2 cycles           | `duty` + 0.02        |
//! | `ramp=R`            | soft start/stop cycles                          | the firmware default |
//! | `panic_at=C`        | panic once C cycles have begun (tests failures) | never                |
//! | `late_preload_at=C` | preload cycle C's first segment too late        | never                |
//! | `changes=K`         | K random changes instead of the one at N/2      | none                 |
//! | `seed=S`            | seed of the random changes (`changes`)          | 1                    |
//!
//! The run starts (soft), changes the duty at N/2, stops (soft) at N, and exits with code 0 once
//! the output is idle again, with the work per edge (`EVT work`) and `EVT end`. The missed edge
//! of `late_preload_at` halts the output with the driver disabled; the operator then resets and
//! starts again, once. Any other fault ends the run with a failure code.

use cortex_m_semihosting::debug::{self, EXIT_SUCCESS};
use cortex_m_semihosting::nr::GET_CMDLINE;
use defmt::{info, unwrap};
use embassy_executor::SendSpawner;
use embassy_time::{Instant, Timer};
use feeder_shared::scenario::parse_setting;
use feeder_shared::{Drive, ScenarioError, ScenarioSetting, TickClock, WaveformSpec};

use super::changes::RandomChanges;
use super::{after_fault, edge_work, provoke_late_preload, sleep_forever, time_driver};
use crate::app::{self, OperatorRequest, OperatorView};
use crate::{config, trace};

/// How often the operator looks at the cycle count.
const POLL_MS: u64 = 5;
/// Cycles past the stop request by which the output must be idle again.
const STOP_GRACE_CYCLES: u32 = 100;

struct Scenario {
    stop_after_cycles: u32,
    spec: WaveformSpec,
    new_duty: f64,
    ramp_cycles: u16,
    panic_at_cycle: Option<u32>,
    late_preload_cycle: Option<u32>,
    random_changes: u32,
    seed: u32,
}

impl Scenario {
    /// Reads the `key=value` words of the command line with the shared parser; the first word it
    /// refuses ends the run.
    fn parse(command_line: &str) -> Result<Self, ScenarioError<'_>> {
        let mut scenario = Scenario {
            stop_after_cycles: 300,
            spec: config::WAVEFORM,
            new_duty: f64::NAN,
            ramp_cycles: config::RAMP_CYCLES,
            panic_at_cycle: None,
            late_preload_cycle: None,
            random_changes: 0,
            seed: 1,
        };
        // The first word is the program's name (the kernel's path when QEMU got no `arg=`).
        for word in command_line.split_whitespace().skip(1) {
            match parse_setting(word)? {
                ScenarioSetting::Cycles(n) => scenario.stop_after_cycles = n,
                ScenarioSetting::FreqHz(f) => scenario.spec.period_s = 1.0 / f,
                ScenarioSetting::Duty(d) => scenario.spec.duty = d,
                ScenarioSetting::StrokeM(stroke_m) => {
                    scenario.spec.drive = Drive::Stroke { stroke_m }
                }
                ScenarioSetting::NewDuty(d) => scenario.new_duty = d,
                ScenarioSetting::Ramp(r) => scenario.ramp_cycles = r,
                ScenarioSetting::PanicAt(c) => scenario.panic_at_cycle = Some(c),
                ScenarioSetting::LatePreloadAt(c) => scenario.late_preload_cycle = Some(c),
                ScenarioSetting::Changes(k) => scenario.random_changes = k,
                ScenarioSetting::Seed(seed) => scenario.seed = seed,
            }
        }
        if scenario.new_duty.is_nan() {
            scenario.new_duty = scenario.spec.duty + 0.02;
        }
        Ok(scenario)
    }
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

/// Spawns the scripted operator, which plans on the output's `clock`.
pub fn spawn_operator(spawner: SendSpawner, clock: TickClock) {
    spawner.spawn(unwrap!(operator_task(clock)));
}

/// The scripted operator during the run.
struct Operator {
    scenario: Scenario,
    /// The provoked missed edge was acknowledged and the feeder started again.
    restarted: bool,
}

impl Operator {
    /// Ends the run with a failure code if the firmware faulted, unless it is the missed edge
    /// the scenario provoked: that one is acknowledged and the feeder started again, once.
    async fn watch_faults(&mut self) {
        if app::state() != OperatorView::Faulted {
            return;
        }
        let provoked = self
            .scenario
            .late_preload_cycle
            .is_some_and(|cycle| app::cycles_begun() >= cycle);
        if !provoked || self.restarted {
            defmt::error!("scenario: the firmware faulted");
            after_fault();
        }
        info!("scenario: the provoked missed edge halted the output; reset and start");
        app::request(OperatorRequest::Reset);
        app::request(OperatorRequest::Start);
        self.restarted = true;
        while app::state() == OperatorView::Faulted {
            Timer::after_millis(POLL_MS).await;
        }
    }

    async fn until_cycle(&mut self, cycle: u32) {
        loop {
            self.watch_faults().await;
            let begun = app::cycles_begun();
            if let Some(panic_at) = self.scenario.panic_at_cycle {
                if begun >= panic_at {
                    panic!("scenario: panic requested at cycle {}", panic_at);
                }
            }
            if begun >= cycle {
                return;
            }
            Timer::after_millis(POLL_MS).await;
        }
    }
}

#[embassy_executor::task]
async fn operator_task(clock: TickClock) {
    let mut buffer = [0u8; 256];
    let scenario = match Scenario::parse(command_line(&mut buffer)) {
        Ok(scenario) => scenario,
        Err(error) => {
            defmt::error!("scenario: {}", error);
            after_fault();
        }
    };
    let plan = |duty| match app::plan(
        clock,
        &WaveformSpec {
            duty,
            ..scenario.spec
        },
        scenario.ramp_cycles,
    ) {
        Ok(ready) => ready,
        Err(error) => {
            defmt::error!("scenario: waveform refused: {}", error);
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
    let (stop_after, ramp_cycles) = (scenario.stop_after_cycles, scenario.ramp_cycles);
    let (count, start_spec) = (scenario.random_changes, first.spec);
    let mut random = RandomChanges::new(scenario.seed, clock, start_spec, ramp_cycles);
    let mut operator = Operator {
        scenario,
        restarted: false,
    };
    app::offer(first);
    app::request(OperatorRequest::Start);
    if count == 0 {
        operator.until_cycle(half).await;
        app::offer(second);
    }
    let first_cycle = app::cycles_begun();
    for index in 0..count {
        operator
            .until_cycle(RandomChanges::cycle_of(index, count, first_cycle, stop_after))
            .await;
        random.change().await;
    }
    operator.until_cycle(stop_after).await;
    app::request(OperatorRequest::Stop);
    let deadline = stop_after + u32::from(ramp_cycles) + STOP_GRACE_CYCLES;
    while app::state() != OperatorView::Stopped || app::cycles_begun() <= stop_after {
        operator.watch_faults().await;
        if app::cycles_begun() > deadline {
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

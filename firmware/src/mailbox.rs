//! The control loop's mailbox: what operators (the button, a script, the console) hand it, taken
//! at its next edge. Planning is done by the sender, in its own task, so that the control loop
//! only swaps a plan in.

use core::cell::Cell;

use defmt::info;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::Channel;
use feeder_shared::settings::plan_waveform;
use feeder_shared::{Error, SupervisorEvent, TickClock, TickPlan, WaveformSpec};

use crate::app::regulate::probe_step;
use crate::configured;

/// Operator requests, taken in order at the control loop's next edge: the supervisor's operator
/// events (`ButtonPressed`, `StartRequested`, `StopRequested`, `ResetRequested`).
pub static REQUESTS: Channel<CriticalSectionRawMutex, SupervisorEvent, 4> = Channel::new();

/// The newest plan the control loop has not taken yet. A newer one replaces it, so changes that
/// arrive faster than edges coalesce: the last accepted one runs from the next cycle boundary.
pub static NEXT_PLAN: Mutex<CriticalSectionRawMutex, Cell<Option<ReadyPlan>>> =
    Mutex::new(Cell::new(None));

/// A validated waveform planned on the output's clock, with its ramp length: all the arithmetic
/// of a change, done by the task that made it.
#[derive(Clone, Copy)]
pub struct ReadyPlan {
    pub spec: WaveformSpec,
    pub plan: TickPlan,
    pub ramp_cycles: u16,
    /// The closed loop's probe step on this ramp length, held in place of the scaled one while
    /// its course holds the scheduler.
    pub hold_step: u16,
}

impl ReadyPlan {
    /// Validates `spec` against the configured machine's limits and, where the closed loop
    /// runs, against the room the loop keeps in the output's linear range; plans it on the
    /// output's `clock`.
    pub fn new(clock: TickClock, spec: &WaveformSpec, ramp_cycles: u16) -> Result<Self, Error> {
        let machine = configured::machine(clock);
        let (waveform, plan) =
            plan_waveform(*spec, &machine.limits, machine.loop_linear_mps2, clock)?;
        info!(
            "plan: {=f64} Hz ({=u32} ticks of {=u32} Hz), d = {=f64}, a_max = {=f64} m/s², \
             x_max = {=f64} m, drift bound {=f64} m",
            plan.realized_frequency_hz(),
            plan.period_ticks,
            plan.clock_hz,
            waveform.duty,
            waveform.accel_mps2,
            waveform.stroke_m,
            plan.drift_bound_m
        );
        Ok(Self {
            spec: *spec,
            plan,
            ramp_cycles,
            hold_step: probe_step(ramp_cycles),
        })
    }
}

/// Hands an operator's `action` to the control loop: a motion request to [`REQUESTS`], a
/// planned waveform to [`NEXT_PLAN`] (the newest replaces one not yet taken).
#[cfg(feature = "console")]
pub async fn dispatch(action: feeder_shared::Action) {
    if let Some(request) = action.request() {
        REQUESTS.send(request).await;
    }
    if let feeder_shared::Action::Configure {
        spec,
        plan,
        ramp_cycles,
    } = action
    {
        NEXT_PLAN.lock(|next| {
            next.set(Some(ReadyPlan {
                spec,
                plan,
                ramp_cycles,
                hold_step: probe_step(ramp_cycles),
            }))
        })
    }
}

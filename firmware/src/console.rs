//! The operator's serial console: bytes in, one reply line out per command line.
//!
//! Received bytes go through the shared [`LineAssembler`] and [`Controller`]; the reply is written
//! back followed by `\r\n`. The controller validates and plans every change here, below the
//! control loop; the control loop only takes the newest ready plan at its next edge and runs it
//! from the next cycle boundary, and start, stop and reset are queued for it. The console runs
//! below the control loop: waiting for bytes, for room in the request queue or for the
//! transmitter only ever delays the console.

use defmt::{error, info, warn};
use embassy_futures::select::{select, Either};
use embassy_time::{Instant, Timer};
use embedded_io_async::{Read, Write};
use feeder_shared::telemetry::{Pacer, MAX_LINE_BYTES};
use feeder_shared::{
    Action, ConfigurationStore, Controller, LineAssembler, RecipeStore, Snapshot, SupervisorEvent,
    TickClock,
};

use crate::app::regulate::probe_step;
use crate::mailbox::{ReadyPlan, NEXT_PLAN, REQUESTS};
use crate::{config, configured, status};

/// Bytes taken from the port per read.
const READ_CHUNK_BYTES: usize = 32;

/// The console link's rate: LPUART1's on the board, the same budget under QEMU.
const LINK_BAUD: u32 = 115_200;

/// How often the console looks for a new cycle to report while telemetry is on.
const TELEMETRY_POLL_MS: u64 = 5;

/// Serves the console on `port` for good, with the configuration and the recipes in `store`;
/// `clock` is the output's tick clock, on which every new waveform must be representable.
/// Returns only if the configuration the board runs is refused.
pub async fn serve<P: Read + Write, S: RecipeStore + ConfigurationStore>(
    mut port: P,
    mut store: S,
    clock: TickClock,
) {
    let mut controller = match Controller::configured(
        configured::facts(clock),
        config::CONFIGURATION,
        configured::get(),
    ) {
        Ok(controller) => controller,
        Err(err) => {
            error!(
                "console disabled: the configuration is refused: {}",
                defmt::Display2Format(&err)
            );
            return;
        }
    };
    info!("console ready");
    let mut assembler = LineAssembler::new();
    let mut chunk = [0u8; READ_CHUNK_BYTES];
    let mut telemetry = Telemetry::off();
    loop {
        let read = match telemetry.on {
            true => match select(
                port.read(&mut chunk),
                Timer::after_millis(TELEMETRY_POLL_MS),
            )
            .await
            {
                Either::First(read) => read,
                Either::Second(()) => {
                    telemetry.send(&mut port).await;
                    continue;
                }
            },
            false => port.read(&mut chunk).await,
        };
        let received = match read {
            Ok(received) => received,
            Err(_) => {
                warn!("console: receive error, partial line dropped");
                assembler.clear();
                continue;
            }
        };
        for &byte in chunk.iter().take(received) {
            let Some(line) = assembler.push(byte) else {
                continue;
            };
            let outcome = controller.handle(line, &snapshot(), &mut store);
            match outcome.action {
                Action::None => {}
                Action::Start => REQUESTS.send(SupervisorEvent::StartRequested).await,
                Action::Stop => REQUESTS.send(SupervisorEvent::StopRequested).await,
                Action::Reset => REQUESTS.send(SupervisorEvent::ResetRequested).await,
                Action::Restart => {}
                Action::Telemetry(on) => telemetry = Telemetry { on, ..telemetry },
                Action::Configure {
                    spec,
                    plan,
                    ramp_cycles,
                } => NEXT_PLAN.lock(|next| {
                    next.set(Some(ReadyPlan {
                        spec,
                        plan,
                        ramp_cycles,
                        hold_step: probe_step(ramp_cycles),
                    }))
                }),
            }
            let sent = port.write_all(outcome.reply.as_str().as_bytes()).await;
            if sent.is_err() || port.write_all(b"\r\n").await.is_err() {
                warn!("console: transmit error, reply lost");
            }
            if outcome.action == Action::Restart {
                // The reply is out first: the operator sees it before the board goes. The log
                // line marks the restart for `cargo xtask console`'s check.
                let _ = port.flush().await;
                info!("restart: the board restarts with its saved configuration");
                cortex_m::peripheral::SCB::sys_reset();
            }
        }
    }
}

/// Telemetry on the link: on or off, the pacing of its lines and the cycle reported last.
#[derive(Clone, Copy)]
struct Telemetry {
    on: bool,
    pacer: Pacer,
    last_cycle: Option<u64>,
}

impl Telemetry {
    fn off() -> Self {
        Self {
            on: false,
            pacer: Pacer::new(LINK_BAUD),
            last_cycle: None,
        }
    }

    /// Writes the record of the cycle begun last, if it is new and the link has room.
    async fn send<P: Write>(&mut self, port: &mut P) {
        let now = Instant::now();
        let status = status::get();
        if self.last_cycle == Some(status.cycle) || !self.pacer.ready(now.as_micros()) {
            return;
        }
        let record = crate::telemetry::record(now.as_millis());
        let mut line = heapless::String::<{ MAX_LINE_BYTES + 2 }>::new();
        if record.write_line(&mut line).is_err() || line.push_str("\r\n").is_err() {
            return;
        }
        self.last_cycle = Some(record.cycle);
        self.pacer.sent(now.as_micros(), line.len());
        if port.write_all(line.as_bytes()).await.is_err() {
            warn!("console: transmit error, telemetry line lost");
        }
    }
}

/// The feeder as the control loop last published it.
fn snapshot() -> Snapshot {
    let status = status::get();
    Snapshot {
        state: status.state,
        phase: status.phase,
        uptime_ms: embassy_time::Instant::now().as_millis(),
        cycles: status.cycle,
        closed_loop: status::closed_loop(),
        track: status::track(),
    }
}

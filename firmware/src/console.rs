//! The operator's serial console: bytes in, one reply line out per command line.
//!
//! Received bytes go through the shared [`LineAssembler`] and [`Controller`]; the reply is written
//! back followed by `\r\n`. The controller validates and plans every change here, below the
//! control loop; the control loop only takes the newest ready plan at its next edge and runs it
//! from the next cycle boundary, and start, stop and reset are queued for it. The console runs
//! below the control loop: waiting for bytes, for room in the request queue or for the
//! transmitter only ever delays the console.

use defmt::{error, info, warn};
use embedded_io_async::{Read, Write};
use feeder_shared::{
    Action, ConfigurationStore, Controller, LineAssembler, RecipeStore, Snapshot, SupervisorEvent,
    TickClock,
};

use crate::app::regulate::probe_step;
use crate::mailbox::{ReadyPlan, NEXT_PLAN, REQUESTS};
use crate::{config, configured, status};

/// Bytes taken from the port per read.
const READ_CHUNK_BYTES: usize = 32;

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
    loop {
        let received = match port.read(&mut chunk).await {
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
                // The reply is out first: the operator sees it before the board goes.
                let _ = port.flush().await;
                info!("restart: the board restarts with its saved configuration");
                cortex_m::peripheral::SCB::sys_reset();
            }
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

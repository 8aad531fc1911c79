//! The operator's serial console: bytes in, one reply line out per command line; beside it, on
//! boards that have them, the line's Modbus port and discrete lines (`crate::line`), served by
//! the same task through the same controller.
//!
//! Received bytes go through the shared [`LineAssembler`] and [`Controller`]; the reply is written
//! back followed by `\r\n`. The controller validates and plans every change here, below the
//! control loop; the control loop only takes the newest ready plan at its next edge and runs it
//! from the next cycle boundary, and start, stop and reset are queued for it. The console runs
//! below the control loop: waiting for bytes, for room in the request queue or for the
//! transmitter only ever delays the console.

use defmt::{error, info, warn};
use embassy_futures::select::{select3, Either3};
use embassy_time::{Instant, Timer};
use embedded_hal::digital::{InputPin, OutputPin};
use embedded_io_async::{Read, Write};
use feeder_shared::line::LinkWatchdog;
use feeder_shared::telemetry::{Pacer, MAX_LINE_BYTES};
use feeder_shared::{
    Action, ConfigurationStore, Controller, LineAssembler, RecipeStore, TickClock,
};

use crate::line::{expire, DiscreteLines, Lines, ModbusLink, ModbusPort};
use crate::mailbox::dispatch;
use crate::status::snapshot;
use crate::{config, configured, status};

/// Bytes taken from a port per read.
const READ_CHUNK_BYTES: usize = 32;

/// The console link's rate: LPUART1's on the board, the same budget under QEMU.
const LINK_BAUD: u32 = 115_200;

/// How often the console looks for a new cycle to report while telemetry is on.
const TELEMETRY_POLL_MS: u64 = 5;

/// How often the discrete lines are sampled and set.
const LINES_POLL_MS: u64 = 5;

/// Serves the operator's links for good: the console on `port`, and where the board has them
/// the Modbus port and the discrete lines, all through one controller, with the configuration
/// and the recipes in `store`; `clock` is the output's tick clock, on which every new waveform
/// must be representable. Returns only if the configuration the board runs is refused.
pub async fn serve<P, S, M, I, O>(
    mut port: P,
    mut store: S,
    clock: TickClock,
    modbus: Option<ModbusPort<M>>,
    lines: Option<DiscreteLines<I, O>>,
) where
    P: Read + Write,
    S: RecipeStore + ConfigurationStore,
    M: Read + Write,
    I: InputPin,
    O: OutputPin,
{
    let configuration = configured::get();
    let mut controller =
        match Controller::configured(configured::facts(clock), config::CONFIGURATION, configuration)
        {
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
    let line = configuration.line;
    let mut modbus = modbus.map(|port| ModbusLink::new(port, &line));
    let mut lines = lines.map(Lines::new);
    let mut watchdog = LinkWatchdog::new(match line.console_watchdog {
        true => line.link_timeout_ms,
        false => 0,
    });
    let mut assembler = LineAssembler::new();
    let mut chunk = [0u8; READ_CHUNK_BYTES];
    let mut frames = [0u8; READ_CHUNK_BYTES];
    let mut telemetry = Telemetry::off();
    loop {
        let wake_ms = wake_after_ms(
            telemetry.on,
            lines.is_some(),
            [watchdog.deadline_ms(), modbus.as_ref().and_then(ModbusLink::deadline_ms)],
        );
        let event = select3(
            port.read(&mut chunk),
            async {
                match modbus.as_mut() {
                    Some(link) => link.receive(&mut frames).await,
                    None => core::future::pending().await,
                }
            },
            async {
                match wake_ms {
                    Some(ms) => Timer::after_millis(ms).await,
                    None => core::future::pending().await,
                }
            },
        )
        .await;
        match event {
            Either3::First(Ok(received)) => {
                watchdog.heard(Instant::now().as_millis());
                for &byte in chunk.iter().take(received) {
                    let Some(line) = assembler.push(byte) else {
                        continue;
                    };
                    let outcome = controller.handle(line, &snapshot(), &mut store);
                    if outcome.action == Action::Start {
                        watchdog.started(Instant::now().as_millis());
                    }
                    if let Action::Telemetry(on) = outcome.action {
                        telemetry = Telemetry { on, ..telemetry };
                    }
                    dispatch(outcome.action).await;
                    let sent = port.write_all(outcome.reply.as_str().as_bytes()).await;
                    if sent.is_err() || port.write_all(b"\r\n").await.is_err() {
                        warn!("console: transmit error, reply lost");
                    }
                    if outcome.action == Action::Restart {
                        // The reply is out first: the operator sees it before the board goes.
                        // The log line marks the restart for `cargo xtask console`'s check.
                        let _ = port.flush().await;
                        info!("restart: the board restarts with its saved configuration");
                        cortex_m::peripheral::SCB::sys_reset();
                    }
                }
            }
            Either3::First(Err(_)) => {
                warn!("console: receive error, partial line dropped");
                assembler.clear();
            }
            Either3::Second(received) => {
                if let Some(link) = modbus.as_mut() {
                    link.serve(received, &frames, &mut controller, &mut store)
                        .await;
                }
            }
            Either3::Third(()) => {
                if telemetry.on {
                    telemetry.send(&mut port).await;
                }
                if let Some(lines) = lines.as_mut() {
                    lines.poll(&mut controller, &mut store).await;
                }
                expire(&mut watchdog, "the console").await;
                if let Some(link) = modbus.as_mut() {
                    link.watch().await;
                }
            }
        }
    }
}

/// How long the operator's task may sleep before it has periodic work: telemetry, the
/// discrete lines, or a link watchdog's deadline; `None`: until a byte arrives.
fn wake_after_ms(telemetry: bool, lines: bool, deadlines_ms: [Option<u64>; 2]) -> Option<u64> {
    let now_ms = Instant::now().as_millis();
    let periodic = [
        telemetry.then_some(TELEMETRY_POLL_MS),
        lines.then_some(LINES_POLL_MS),
    ];
    let deadlines = deadlines_ms
        .into_iter()
        .map(|deadline| deadline.map(|deadline_ms| deadline_ms.saturating_sub(now_ms) + 1));
    periodic.into_iter().chain(deadlines).flatten().min()
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

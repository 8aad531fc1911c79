//! The production line's links beside the console: the Modbus RTU port and the discrete lines
//! (release and recipe-select inputs, ready and fault outputs), each with the shared rules
//! (`feeder_shared::modbus`, `feeder_shared::line`). The operator's task
//! (`crate::console::serve`) owns the one controller they all act through.

use defmt::{info, warn};
use embassy_futures::select::{select, Either};
use embassy_time::{Duration, Instant, Timer};
use embedded_hal::digital::{InputPin, OutputPin};
use embedded_io_async::{Read, Write};
use feeder_shared::configuration::LineSetup;
use feeder_shared::line::{LineInputs, LineOutputs, LinkWatchdog, RecipeSelect};
use feeder_shared::modbus::{FrameAssembler, Response, Server, MAX_FRAME_BYTES};
use feeder_shared::{ConfigurationStore, Controller, RecipeStore, RunState, SupervisorEvent};

use crate::mailbox::dispatch;
use crate::status::{self, snapshot};

/// The Modbus RTU port of a board: its byte stream and the silence that ends a frame on it.
pub struct ModbusPort<M> {
    pub port: M,
    /// The frame gap, µs: 3.5 characters on a serial line ([`feeder_shared::modbus::frame_gap_us`]).
    pub gap_us: u64,
    /// The silence before an answer, µs: a frame gap on a serial line, so that the answer is a
    /// frame of its own on the bus and a master's transceiver has turned around.
    pub turnaround_us: u64,
}

/// What a wait on the Modbus port ended with.
pub enum Received {
    /// This many bytes.
    Bytes(usize),
    /// A frame gap of silence while part of a frame was held.
    Silence,
}

/// A request, copied out of the frame assembler.
type Frame = heapless::Vec<u8, MAX_FRAME_BYTES>;

fn frame(bytes: &[u8]) -> Frame {
    // Never longer than the assembler's buffer, which is as long.
    Frame::from_slice(bytes).unwrap_or_default()
}

/// The Modbus link: frames in, answers out, its link watchdog.
///
/// A byte's time is not when the task reads it: bytes wait in the port's buffer while the task
/// does other work, and a frame read in two parts would look cut by a silence that never was.
/// So the frame assembler runs on a line clock that advances only across a silence the task
/// has seen itself: a frame gap from the last read that took bytes with none arriving since,
/// however often the task's other work (telemetry, the discrete lines) ends its wait.
pub struct ModbusLink<M> {
    port: M,
    gap_us: u64,
    turnaround_us: u64,
    /// The line clock, µs: the silences seen so far, each one frame gap long.
    line_us: u64,
    /// When a read last took bytes.
    last_read: Instant,
    assembler: FrameAssembler,
    server: Server,
    watchdog: LinkWatchdog,
    response: Response,
}

impl<M: Read + Write> ModbusLink<M> {
    /// The link on `port`, at the address and with the watchdog of `setup`.
    pub fn new(port: ModbusPort<M>, setup: &LineSetup) -> Self {
        info!(
            "modbus: slave {=u8} at {=u32} baud, {}, link watchdog {=u16} ms",
            setup.modbus_address,
            setup.baud,
            if setup.parity_even { "8E1" } else { "8N2" },
            setup.link_timeout_ms
        );
        Self {
            port: port.port,
            gap_us: port.gap_us,
            turnaround_us: port.turnaround_us,
            line_us: 0,
            last_read: Instant::now(),
            assembler: FrameAssembler::new(port.gap_us),
            server: Server::new(setup.modbus_address),
            watchdog: LinkWatchdog::new(setup.link_timeout_ms),
            response: Response::new(),
        }
    }

    /// Waits for bytes from the master, or, while part of a frame is held, for a frame gap of
    /// silence, which ends it.
    pub async fn receive(&mut self, chunk: &mut [u8]) -> Received {
        let read = match self.assembler.pending() {
            true => {
                let quiet_from = self.last_read + Duration::from_micros(self.gap_us);
                // The port first: bytes already waiting are no silence, however late it is.
                match select(self.port.read(chunk), Timer::at(quiet_from)).await {
                    Either::First(read) => read,
                    Either::Second(()) => return Received::Silence,
                }
            }
            false => self.port.read(chunk).await,
        };
        match read {
            Ok(received) => {
                self.last_read = Instant::now();
                Received::Bytes(received)
            }
            Err(_) => {
                warn!("modbus: receive error, partial frame dropped");
                self.assembler.discard();
                Received::Bytes(0)
            }
        }
    }

    /// Answers every request `received` completes (bytes from `chunk`, or a silence), through
    /// `controller`.
    pub async fn serve<S: RecipeStore + ConfigurationStore>(
        &mut self,
        received: Received,
        chunk: &[u8],
        controller: &mut Controller,
        store: &mut S,
    ) {
        match received {
            Received::Bytes(count) => {
                for &byte in chunk.iter().take(count) {
                    let request = self.assembler.push(byte, self.line_us).map(frame);
                    if let Some(request) = request {
                        self.answer(&request, controller, store).await;
                    }
                }
            }
            Received::Silence => {
                self.line_us += self.gap_us + 1;
                let request = self.assembler.silence(self.line_us).map(frame);
                if let Some(request) = request {
                    self.answer(&request, controller, store).await;
                }
            }
        }
    }

    /// Answers one request through `controller` and hands what it asks to the control loop.
    async fn answer<S: RecipeStore + ConfigurationStore>(
        &mut self,
        request: &[u8],
        controller: &mut Controller,
        store: &mut S,
    ) {
        let now = Instant::now();
        let exchange =
            self.server
                .handle(request, controller, &snapshot(), store, &mut self.response);
        if exchange.broken {
            self.assembler.discard();
        }
        if exchange.heard {
            self.watchdog.heard(now.as_millis());
        }
        if exchange.started() {
            self.watchdog.started(now.as_millis());
        }
        for &request in &exchange.requests {
            crate::mailbox::REQUESTS.send(request).await;
        }
        if let Some(action) = exchange.configure {
            dispatch(action).await;
        }
        if self.response.is_empty() {
            return;
        }
        Timer::at(now + Duration::from_micros(self.turnaround_us)).await;
        if self.port.write_all(&self.response).await.is_err() {
            warn!("modbus: transmit error, response lost");
        }
    }

    /// Checks the link watchdog: fires the soft stop once the master has been silent too long.
    pub async fn watch(&mut self) {
        expire(&mut self.watchdog, "the Modbus master").await
    }

    /// When the watchdog fires, if the master stays silent.
    pub fn deadline_ms(&self) -> Option<u64> {
        self.watchdog.deadline_ms()
    }
}

/// Latches a lost link if `watchdog` has run out while the feeder runs.
pub async fn expire(watchdog: &mut LinkWatchdog, who: &str) {
    let running = status::get().state == RunState::Running;
    if watchdog.expired(Instant::now().as_millis(), running) {
        warn!("link lost: {} fell silent; soft stop", who);
        crate::mailbox::REQUESTS
            .send(SupervisorEvent::Fault(feeder_shared::Fault::LinkLost))
            .await;
    }
}

/// The discrete lines of a board: the release and recipe-select inputs, the ready and fault
/// outputs.
pub struct DiscreteLines<I, O> {
    pub release: I,
    pub select: [I; 2],
    pub ready: O,
    pub fault: O,
}

/// How long the release input must hold a level before it counts.
const RELEASE_DEBOUNCE_MS: u64 = 20;

/// The discrete lines with their debounced state.
pub struct Lines<I, O> {
    pins: DiscreteLines<I, O>,
    inputs: LineInputs,
    outputs: Option<LineOutputs>,
}

impl<I: InputPin, O: OutputPin> Lines<I, O> {
    pub fn new(pins: DiscreteLines<I, O>) -> Self {
        Self {
            pins,
            inputs: LineInputs::new(RELEASE_DEBOUNCE_MS),
            outputs: None,
        }
    }

    /// Samples the inputs, runs what a change asks for through `controller`, and sets the
    /// outputs from the feeder's state.
    pub async fn poll<S: RecipeStore + ConfigurationStore>(
        &mut self,
        controller: &mut Controller,
        store: &mut S,
    ) {
        let high = |pin: &mut I| pin.is_high().unwrap_or(false);
        let release = high(&mut self.pins.release);
        let select = RecipeSelect {
            bit0: high(&mut self.pins.select[0]),
            bit1: high(&mut self.pins.select[1]),
        };
        let commands = self
            .inputs
            .sample(release, select, Instant::now().as_millis());
        for command in commands {
            let outcome = controller.execute(command, &snapshot(), store);
            if let Some(refusal) = outcome.refusal {
                warn!(
                    "release line: {} refused: {}",
                    command,
                    defmt::Display2Format(&refusal)
                );
                break;
            }
            dispatch(outcome.action).await;
        }
        let outputs = LineOutputs::of(status::get().state);
        if self.outputs != Some(outputs) {
            let _ = self.pins.ready.set_state(outputs.ready.into());
            let _ = self.pins.fault.set_state(outputs.fault.into());
            self.outputs = Some(outputs);
        }
    }
}

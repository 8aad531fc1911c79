//! One request frame into its response and the actions it makes: the Modbus slave.
//!
//! Reads take the registers' values from the controller and the feeder's snapshot. A write is
//! the console's command for each register written ([`Holding::command`]), executed by the
//! controller; a write of several registers is all or nothing: it is tried on a copy of the
//! controller and kept only if every register is accepted. A refused write answers with an
//! exception (02 for an address with no register, 03 for a value the rules refuse, 04 for a
//! command the feeder's state refuses) and leaves its `ERR` code and register in the input
//! registers `refusal` and `refused_register`. A frame that fails its CRC or its shape gets no
//! answer, as the serial line specification asks.

use rmodbus::consts::ModbusFunction;
use rmodbus::server::{ModbusFrame, Read, Write};
use rmodbus::{ErrorKind, ModbusProto};

use super::frames::{crc_holds, MAX_FRAME_BYTES};
use super::map::{Holding, Input, LinkState};
use crate::control::{Action, ConfigurationStore, Controller, RecipeStore, Snapshot};
use crate::protocol::ReplyError;
use crate::supervisor::{RunState, SupervisorEvent};

/// A response frame.
pub type Response = heapless::Vec<u8, MAX_FRAME_BYTES>;

/// The most holding registers one write may name (function code 16).
const MAX_WRITE_REGISTERS: usize = 123;

/// What one request did, besides its response.
#[derive(Debug, Clone, PartialEq)]
pub struct Exchange {
    /// The supervisor's requests the write made, in register order.
    pub requests: heapless::Vec<SupervisorEvent, { Holding::ALL.len() }>,
    /// The waveform the write leaves the controller with, where it changed one.
    pub configure: Option<Action>,
    /// The request was a frame for this slave (or a broadcast): the link is alive.
    pub heard: bool,
    /// The bytes were no frame (CRC, shape): what follows them until a silence belongs to them.
    pub broken: bool,
}

impl Exchange {
    const NONE: Exchange = Exchange {
        requests: heapless::Vec::new(),
        configure: None,
        heard: false,
        broken: false,
    };

    /// The write started the feeder.
    pub fn started(&self) -> bool {
        self.requests.contains(&SupervisorEvent::StartRequested)
    }
}

/// The Modbus slave at one address; see the module documentation.
#[derive(Debug, Clone)]
pub struct Server {
    address: u8,
    link: LinkState,
    /// Requests answered, exceptions included.
    answered: u32,
}

impl Server {
    /// A slave at `address` (1 to 247; 0 is the broadcast address).
    pub const fn new(address: u8) -> Self {
        Self {
            address,
            link: LinkState { refusal: None },
            answered: 0,
        }
    }

    /// This link's state, as the input registers report it.
    pub const fn link(&self) -> &LinkState {
        &self.link
    }

    /// Requests answered so far, exceptions included.
    pub const fn answered(&self) -> u32 {
        self.answered
    }

    /// Answers `request` into `response` (left empty when no answer is due) and says what it
    /// did.
    pub fn handle<S: RecipeStore + ConfigurationStore>(
        &mut self,
        request: &[u8],
        controller: &mut Controller,
        snapshot: &Snapshot,
        store: &mut S,
        response: &mut Response,
    ) -> Exchange {
        let mut exchange = Exchange::NONE;
        let unanswerable = self.unanswerable(request);
        let mut frame = ModbusFrame::new(self.address, request, ModbusProto::Rtu, response);
        if unanswerable || frame.parse().is_err() {
            response.clear();
            exchange.broken = true;
            return exchange;
        }
        exchange.heard = frame.response_required || frame.processing_required;
        let processed = match (frame.processing_required, frame.readonly) {
            (false, _) => Ok(()),
            (true, true) => {
                let func = frame.func;
                let read = match frame.get_external_read() {
                    Ok(Read::Words(words)) => read_words(
                        func,
                        words.address,
                        words.buf,
                        controller,
                        snapshot,
                        &self.link,
                    ),
                    Ok(Read::Bits(_)) => Err(ErrorKind::IllegalFunction),
                    Err(error) => Err(error),
                };
                frame.process_external_read(read)
            }
            (true, false) => {
                let mut values = [0u16; MAX_WRITE_REGISTERS];
                let written = match frame.get_external_write() {
                    Ok(Write::Words(words)) => words_of(words.count, words.data, &mut values)
                        .map(|count| (words.address, count)),
                    Ok(Write::Bits(_)) => Err(ErrorKind::IllegalFunction),
                    Err(error) => Err(error),
                };
                let write = written.and_then(|(address, count)| {
                    self.write(address, &values[..count], controller, snapshot, store)
                });
                let result = match write {
                    Ok(done) => {
                        exchange.requests = done.requests;
                        exchange.configure = done.configure;
                        Ok(())
                    }
                    Err(error) => Err(error),
                };
                frame.process_external_write(result)
            }
        };
        let respond = frame.response_required;
        let finalized = match (processed, respond) {
            (Ok(()), true) => frame.finalize_response(),
            (Ok(()), false) => Ok(()),
            (Err(error), _) => Err(error),
        };
        if finalized.is_err() || !respond {
            response.clear();
        }
        if !response.is_empty() {
            self.answered = self.answered.saturating_add(1);
        }
        exchange
    }

    /// A request for this slave with a function code `rmodbus` does not know that is no frame:
    /// `rmodbus` answers such a code with exception 01 without checking the CRC, and a code from
    /// 0x80 on (an exception response's, never a request's) has no exception code to answer
    /// with (`rmodbus` adds 0x80 to it, which overflows).
    fn unanswerable(&self, request: &[u8]) -> bool {
        match *request {
            [unit, function, ..]
                if unit == self.address && ModbusFunction::try_from(function).is_err() =>
            {
                function >= 0x80 || !crc_holds(request)
            }
            _ => false,
        }
    }

    /// Executes the console's command of every register from `address` on, on a copy of the
    /// controller, and keeps the copy only if all are accepted.
    fn write<S: RecipeStore + ConfigurationStore>(
        &mut self,
        first: u16,
        values: &[u16],
        controller: &mut Controller,
        snapshot: &Snapshot,
        store: &mut S,
    ) -> Result<Written, ErrorKind> {
        let mut trial = controller.clone();
        let mut written = Written {
            requests: heapless::Vec::new(),
            configure: None,
        };
        for (address, &value) in (first..).zip(values) {
            let outcome = Holding::at(address)
                .ok_or(ReplyError::UnknownParameter)
                .and_then(|register| register.command(value))
                .map(|command| trial.execute(command, snapshot, store))
                .and_then(|outcome| match outcome.refusal {
                    Some(error) => Err(error),
                    None => Ok(outcome),
                });
            let action = match outcome {
                Ok(outcome) => outcome.action,
                Err(error) => {
                    self.link.refusal = Some((error.code(), address));
                    return Err(exception(&error));
                }
            };
            match action {
                Action::Configure { .. } => written.configure = Some(action),
                action => {
                    if let Some(request) = action.request() {
                        // One register, one request at most: room by construction.
                        let _ = written.requests.push(request);
                    }
                }
            }
        }
        *controller = trial;
        self.link.refusal = None;
        Ok(written)
    }
}

/// What an accepted write asks of the control loop.
struct Written {
    requests: heapless::Vec<SupervisorEvent, { Holding::ALL.len() }>,
    configure: Option<Action>,
}

/// The registers of a write into `values`: how many, or why the data does not hold `count`
/// registers.
fn words_of(
    count: u16,
    data: &[u8],
    values: &mut [u16; MAX_WRITE_REGISTERS],
) -> Result<usize, ErrorKind> {
    let count = usize::from(count);
    if count == 0 || count > MAX_WRITE_REGISTERS || data.len() != 2 * count {
        return Err(ErrorKind::IllegalDataValue);
    }
    for (value, pair) in values.iter_mut().zip(data.chunks_exact(2)) {
        *value = u16::from_be_bytes([pair[0], pair[1]]);
    }
    Ok(count)
}

/// Fills `buffer` with the registers from `first` on: holding or input, as `func` reads.
fn read_words(
    func: ModbusFunction,
    first: u16,
    buffer: &mut [u8],
    controller: &Controller,
    snapshot: &Snapshot,
    link: &LinkState,
) -> Result<(), ErrorKind> {
    if buffer.is_empty() {
        return Err(ErrorKind::IllegalDataValue);
    }
    let status = controller.status(snapshot);
    let running = snapshot.state == RunState::Running;
    for (address, pair) in (first..).zip(buffer.chunks_exact_mut(2)) {
        let value = match func {
            ModbusFunction::GetHoldings => Holding::at(address)
                .map(|register| register.read(&status, controller.recipe(), running)),
            _ => Input::at(address).map(|register| register.read(snapshot, &status, link)),
        };
        let value = value.ok_or(ErrorKind::IllegalDataAddress)?;
        pair.copy_from_slice(&value.to_be_bytes());
    }
    Ok(())
}

/// The exception a refused write answers with.
fn exception(error: &ReplyError) -> ErrorKind {
    match error {
        ReplyError::UnknownParameter | ReplyError::UnknownKey => ErrorKind::IllegalDataAddress,
        ReplyError::NotStopped
        | ReplyError::FaultLatched
        | ReplyError::StorageFailed
        | ReplyError::RecipeUnusable { .. }
        | ReplyError::NoConfiguration => ErrorKind::SlaveDeviceFailure,
        _ => ErrorKind::IllegalDataValue,
    }
}

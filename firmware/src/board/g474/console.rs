//! The operator's serial console on LPUART1 (ST-LINK virtual COM port, 115200 8N1), with the
//! configuration and the recipes in flash (`--features console`); beside it, served by the same
//! task, the line's Modbus RTU port on USART1 (RS-485, the UART's own driver enable) and the
//! discrete lines (`crate::line`).

use defmt::{error, unwrap};
use embassy_executor::SendSpawner;
use embassy_stm32::flash::Flash;
use embassy_stm32::gpio::{self, Level, Pull, Speed};
use embassy_stm32::interrupt::{self, InterruptExt, Priority};
use embassy_stm32::peripherals::{FLASH, LPUART1, PA12, PA2, PA3, PC4, PC5, USART1};
use embassy_stm32::usart::{self, BufferedUart, DataBits, Parity, StopBits};
use embassy_stm32::{bind_interrupts, Peri};
use feeder_shared::configuration::{Configuration, LineSetup};
use feeder_shared::modbus::frame_gap_us;
use feeder_shared::TickClock;

use super::flash_store::FlashStore;
use super::pins::LinePins;
use crate::line::{DiscreteLines, ModbusPort};
use crate::{configured, ports};

bind_interrupts!(struct Irqs {
    LPUART1 => usart::BufferedInterruptHandler<LPUART1>;
    USART1 => usart::BufferedInterruptHandler<USART1>;
});

/// Bytes the console's transmitter buffers: a whole reply line.
const TX_BUFFER_BYTES: usize = 336;
/// Bytes the console's receiver buffers while a reply is being composed.
const RX_BUFFER_BYTES: usize = 128;
/// Bytes the Modbus port's transmitter buffers: every response the register map gives.
const MODBUS_TX_BUFFER_BYTES: usize = 128;
/// Bytes the Modbus port's receiver buffers until the task takes them (its reader is woken at
/// every byte: [`modbus_config`]).
const MODBUS_RX_BUFFER_BYTES: usize = 128;

/// The discrete lines' pins: plain inputs and outputs, which the task samples and sets.
type Lines = DiscreteLines<gpio::Input<'static>, gpio::Output<'static>>;

/// The console's and the Modbus port's peripherals, the discrete lines and the flash, handed to
/// [`console_task`].
pub struct Operator {
    lpuart: Peri<'static, LPUART1>,
    tx: Peri<'static, PA2>,
    rx: Peri<'static, PA3>,
    modbus: ModbusPins,
    lines: Lines,
    store: FlashStore,
}

/// USART1 and its pins, for the Modbus port.
struct ModbusPins {
    usart: Peri<'static, USART1>,
    tx: Peri<'static, PC4>,
    rx: Peri<'static, PC5>,
    de: Peri<'static, PA12>,
}

impl Operator {
    /// Takes the peripherals; the discrete lines' outputs are driven low (not ready, no fault)
    /// at once, their inputs pulled down, until the task serves them.
    pub fn new(
        lpuart: Peri<'static, LPUART1>,
        tx: Peri<'static, PA2>,
        rx: Peri<'static, PA3>,
        flash: Peri<'static, FLASH>,
        line: LinePins,
    ) -> Self {
        let lines = DiscreteLines {
            release: gpio::Input::new(line.release, Pull::Down),
            select: [
                gpio::Input::new(line.select.0, Pull::Down),
                gpio::Input::new(line.select.1, Pull::Down),
            ],
            ready: gpio::Output::new(line.ready, Level::Low, Speed::Low),
            fault: gpio::Output::new(line.fault, Level::Low, Speed::Low),
        };
        Self {
            lpuart,
            tx,
            rx,
            modbus: ModbusPins {
                usart: line.usart,
                tx: line.tx,
                rx: line.rx,
                de: line.de,
            },
            lines,
            store: FlashStore::new(Flash::new_blocking(flash)),
        }
    }
}

impl ports::Operator for Operator {
    fn load_configuration(&mut self, clock: TickClock) -> Configuration {
        configured::at_power_up(&mut self.store, clock)
    }

    fn spawn(self, spawner: SendSpawner, clock: TickClock) {
        spawner.spawn(unwrap!(console_task(self, clock)));
    }
}

/// The Modbus port's character format from the configuration: 8E1, or 8N2 without parity, 11
/// bits a character either way. Embassy counts the parity bit apart from the data bits (8 data
/// bits with parity are the UART's 9-bit word, M0, with PCE).
fn modbus_config(line: &LineSetup) -> usart::Config {
    let mut config = usart::Config::default();
    config.baudrate = line.baud;
    config.data_bits = DataBits::DataBits8;
    (config.parity, config.stop_bits) = match line.parity_even {
        true => (Parity::ParityEven, StopBits::STOP1),
        false => (Parity::ParityNone, StopBits::STOP2),
    };
    // The transceiver's receiver is off while it drives the bus (/RE tied to DE): RO then
    // floats, and the pull-up holds RX idle.
    config.rx_pull = Pull::Up;
    // Every byte wakes the reader: without it a read in the middle of a request takes the
    // bytes so far and the rest only come when the line goes idle, and the task, waiting on the
    // port meanwhile, would see a silence as long as the frame gap inside a request.
    config.eager_reads = Some(1);
    config
}

/// Serves the console, the Modbus port and the discrete lines in thread mode, below every
/// interrupt.
#[embassy_executor::task]
async fn console_task(operator: Operator, clock: TickClock) {
    let mut tx_buffer = [0u8; TX_BUFFER_BYTES];
    let mut rx_buffer = [0u8; RX_BUFFER_BYTES];
    let mut modbus_tx_buffer = [0u8; MODBUS_TX_BUFFER_BYTES];
    let mut modbus_rx_buffer = [0u8; MODBUS_RX_BUFFER_BYTES];
    // Below the edges and the control executor.
    interrupt::LPUART1.set_priority(Priority::P3);
    interrupt::USART1.set_priority(Priority::P3);
    let port = match BufferedUart::new(
        operator.lpuart,
        operator.rx,
        operator.tx,
        &mut tx_buffer,
        &mut rx_buffer,
        Irqs,
        usart::Config::default(),
    ) {
        Ok(port) => port,
        Err(err) => {
            error!(
                "console disabled: LPUART1 refused its configuration: {}",
                err
            );
            return;
        }
    };
    let line = configured::get().line;
    let pins = operator.modbus;
    let modbus = match BufferedUart::new_with_de(
        pins.usart,
        pins.rx,
        pins.tx,
        pins.de,
        Irqs,
        &mut modbus_tx_buffer,
        &mut modbus_rx_buffer,
        modbus_config(&line),
    ) {
        Ok(port) => Some(ModbusPort {
            port,
            gap_us: frame_gap_us(line.baud),
            turnaround_us: frame_gap_us(line.baud),
        }),
        Err(err) => {
            error!(
                "modbus disabled: USART1 refused {=u32} baud: {}",
                line.baud, err
            );
            None
        }
    };
    crate::console::serve(
        port,
        operator.store,
        clock,
        modbus,
        Some(operator.lines),
    )
    .await
}

//! The CMSDK APB UARTs of mps2-an386 as byte streams: UART0 (0x4000_4000, RX interrupt 0, TX 1)
//! for the console, UART1 (0x4000_5000, RX interrupt 2, TX 3) for the Modbus port. QEMU
//! connects each to a `-serial` backend, in order.
//!
//! A UART holds one received byte; QEMU keeps the rest in the backend until the firmware has
//! read it, so nothing is lost while the task is busy. The interrupts only wake the task, which
//! moves the bytes itself.

use core::convert::Infallible;
use core::future::poll_fn;
use core::task::Poll;

use cortex_m::peripheral::NVIC;
use embassy_sync::waitqueue::AtomicWaker;

use super::setup::TASK_PRIORITY;
use super::{register_read, register_write, set_priority, Irq};

const DATA: usize = 0x00;
const STATE: usize = 0x04;
const CTRL: usize = 0x08;
/// INTSTATUS on reads, INTCLEAR (write one to clear) on writes.
const INTSTATUS: usize = 0x0c;
const BAUDDIV: usize = 0x10;

const STATE_TX_FULL: u32 = 1 << 0;
const STATE_RX_FULL: u32 = 1 << 1;
const CTRL_TX_ENABLE: u32 = 1 << 0;
const CTRL_RX_ENABLE: u32 = 1 << 1;
const CTRL_TX_INTERRUPT: u32 = 1 << 2;
const CTRL_RX_INTERRUPT: u32 = 1 << 3;
const INT_TX: u32 = 1 << 0;
const INT_RX: u32 = 1 << 1;

/// 115200 baud from the 25 MHz peripheral clock (QEMU does not pace the bytes).
const BAUD_DIVISOR: u32 = 25_000_000 / 115_200;

/// One of the machine's UARTs: its registers and interrupts.
#[derive(Clone, Copy)]
pub enum Port {
    /// UART0: the console.
    Console = 0,
    /// UART1: the Modbus port.
    Modbus = 1,
}

impl Port {
    const fn base(self) -> usize {
        match self {
            Port::Console => 0x4000_4000,
            Port::Modbus => 0x4000_5000,
        }
    }

    const fn interrupts(self) -> [Irq; 2] {
        match self {
            Port::Console => [Irq::Uart0Rx, Irq::Uart0Tx],
            Port::Modbus => [Irq::Uart1Rx, Irq::Uart1Tx],
        }
    }

    fn read(self, offset: usize) -> u32 {
        register_read(self.base() + offset)
    }

    fn write(self, offset: usize, value: u32) {
        register_write(self.base() + offset, value)
    }
}

static RX_WAKERS: [AtomicWaker; 2] = [AtomicWaker::new(), AtomicWaker::new()];
static TX_WAKERS: [AtomicWaker; 2] = [AtomicWaker::new(), AtomicWaker::new()];

/// RX interrupt of `port`: a byte has arrived.
pub fn on_receive(port: Port) {
    port.write(INTSTATUS, INT_RX);
    RX_WAKERS[port as usize].wake();
}

/// TX interrupt of `port`: the transmitter has room again.
pub fn on_transmit(port: Port) {
    port.write(INTSTATUS, INT_TX);
    TX_WAKERS[port as usize].wake();
}

/// The task's end of one UART.
pub struct Uart(Port);

impl Uart {
    /// Enables `port` with both interrupts at the priority of the task executor, so that the
    /// handlers and the task never preempt each other.
    pub fn new(port: Port) -> Self {
        port.write(BAUDDIV, BAUD_DIVISOR);
        port.write(
            CTRL,
            CTRL_TX_ENABLE | CTRL_RX_ENABLE | CTRL_TX_INTERRUPT | CTRL_RX_INTERRUPT,
        );
        for irq in port.interrupts() {
            set_priority(irq, TASK_PRIORITY);
            // SAFETY: both handlers only clear their flag and wake a waker.
            unsafe { NVIC::unmask(irq) };
        }
        Uart(port)
    }
}

impl embedded_io_async::ErrorType for Uart {
    type Error = Infallible;
}

impl embedded_io_async::Read for Uart {
    async fn read(&mut self, buffer: &mut [u8]) -> Result<usize, Infallible> {
        let port = self.0;
        poll_fn(|cx| {
            RX_WAKERS[port as usize].register(cx.waker());
            let mut received = 0;
            for slot in buffer.iter_mut() {
                if port.read(STATE) & STATE_RX_FULL == 0 {
                    break;
                }
                *slot = port.read(DATA) as u8;
                received += 1;
            }
            if received > 0 || buffer.is_empty() {
                Poll::Ready(Ok(received))
            } else {
                Poll::Pending
            }
        })
        .await
    }
}

impl embedded_io_async::Write for Uart {
    async fn write(&mut self, bytes: &[u8]) -> Result<usize, Infallible> {
        let port = self.0;
        poll_fn(|cx| {
            TX_WAKERS[port as usize].register(cx.waker());
            let mut sent = 0;
            for &byte in bytes {
                if port.read(STATE) & STATE_TX_FULL != 0 {
                    break;
                }
                port.write(DATA, u32::from(byte));
                sent += 1;
            }
            if sent > 0 || bytes.is_empty() {
                Poll::Ready(Ok(sent))
            } else {
                Poll::Pending
            }
        })
        .await
    }

    async fn flush(&mut self) -> Result<(), Infallible> {
        let port = self.0;
        poll_fn(|cx| {
            TX_WAKERS[port as usize].register(cx.waker());
            if port.read(STATE) & STATE_TX_FULL == 0 {
                Poll::Ready(Ok(()))
            } else {
                Poll::Pending
            }
        })
        .await
    }
}

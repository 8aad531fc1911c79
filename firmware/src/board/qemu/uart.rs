//! UART0 of mps2-an386 (CMSDK APB UART at 0x4000_4000, RX interrupt 0, TX interrupt 1) as the
//! console's byte stream. QEMU connects it to its `-serial` backend.
//!
//! The UART holds one received byte; QEMU keeps the rest in the backend until the firmware has
//! read it, so nothing is lost while the console is busy. The interrupts only wake the console
//! task, which moves the bytes itself.

use core::convert::Infallible;
use core::future::poll_fn;
use core::task::Poll;

use cortex_m::peripheral::NVIC;
use embassy_sync::waitqueue::AtomicWaker;

use super::setup::TASK_PRIORITY;
use super::{register_read, register_write, set_priority, Irq};

const BASE: usize = 0x4000_4000;
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

static RX_WAKER: AtomicWaker = AtomicWaker::new();
static TX_WAKER: AtomicWaker = AtomicWaker::new();

fn read(offset: usize) -> u32 {
    register_read(BASE + offset)
}

fn write(offset: usize, value: u32) {
    register_write(BASE + offset, value)
}

/// RX interrupt: a byte has arrived.
pub fn on_receive() {
    write(INTSTATUS, INT_RX);
    RX_WAKER.wake();
}

/// TX interrupt: the transmitter has room again.
pub fn on_transmit() {
    write(INTSTATUS, INT_TX);
    TX_WAKER.wake();
}

/// The console's end of UART0.
pub struct Uart(());

impl Uart {
    /// Enables UART0 with both interrupts at the priority of the task executor, so that the
    /// handlers and the console task never preempt each other.
    pub fn new() -> Self {
        write(BAUDDIV, BAUD_DIVISOR);
        write(
            CTRL,
            CTRL_TX_ENABLE | CTRL_RX_ENABLE | CTRL_TX_INTERRUPT | CTRL_RX_INTERRUPT,
        );
        for irq in [Irq::Uart0Rx, Irq::Uart0Tx] {
            set_priority(irq, TASK_PRIORITY);
            // SAFETY: both handlers only clear their flag and wake a waker.
            unsafe { NVIC::unmask(irq) };
        }
        Uart(())
    }
}

impl embedded_io_async::ErrorType for Uart {
    type Error = Infallible;
}

impl embedded_io_async::Read for Uart {
    async fn read(&mut self, buffer: &mut [u8]) -> Result<usize, Infallible> {
        poll_fn(|cx| {
            RX_WAKER.register(cx.waker());
            let mut received = 0;
            for slot in buffer.iter_mut() {
                if read(STATE) & STATE_RX_FULL == 0 {
                    break;
                }
                *slot = read(DATA) as u8;
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
        poll_fn(|cx| {
            TX_WAKER.register(cx.waker());
            let mut sent = 0;
            for &byte in bytes {
                if read(STATE) & STATE_TX_FULL != 0 {
                    break;
                }
                write(DATA, u32::from(byte));
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
        poll_fn(|cx| {
            TX_WAKER.register(cx.waker());
            if read(STATE) & STATE_TX_FULL == 0 {
                Poll::Ready(Ok(()))
            } else {
                Poll::Pending
            }
        })
        .await
    }
}

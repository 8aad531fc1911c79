//! embassy-time driver for mps2-an386 on the two CMSDK APB timers (25 MHz, 32-bit down counters).
//!
//! TIMER1 runs free from `u32::MAX` and extends its count to 64 bits in its wrap interrupt;
//! TIMER0 is the one-shot alarm for the timer queue. Ticks are 1 µs (25 timer cycles).

use core::cell::{Cell, RefCell};
use core::task::Waker;

use critical_section::{CriticalSection, Mutex};
use embassy_time_driver::Driver;
use embassy_time_queue_utils::Queue;

use super::{register_read, register_write, Irq};

/// Base addresses of the CMSDK APB timers.
const ALARM_TIMER: usize = 0x4000_0000;
const CLOCK_TIMER: usize = 0x4000_1000;
/// Register offsets and control bits.
const CTRL: usize = 0x00;
const VALUE: usize = 0x04;
const RELOAD: usize = 0x08;
const INT_STATUS_CLEAR: usize = 0x0C;
const CTRL_ENABLE: u32 = 1 << 0;
const CTRL_IRQ_ENABLE: u32 = 1 << 3;

pub const TIMER_HZ: u64 = 25_000_000;
pub const CYCLES_PER_TICK: u64 = TIMER_HZ / embassy_time_driver::TICK_HZ;
/// Longest alarm programmed at once; later deadlines are reached in steps.
const MAX_ALARM_CYCLES: u64 = 1 << 31;

fn write(base: usize, offset: usize, value: u32) {
    register_write(base + offset, value)
}

fn read(base: usize, offset: usize) -> u32 {
    register_read(base + offset)
}

struct CmsdkTimeDriver {
    /// Completed wraps of the clock timer.
    wraps: Mutex<Cell<u32>>,
    queue: Mutex<RefCell<Queue>>,
}

embassy_time_driver::time_driver_impl!(static DRIVER: CmsdkTimeDriver = CmsdkTimeDriver {
    wraps: Mutex::new(Cell::new(0)),
    queue: Mutex::new(RefCell::new(Queue::new())),
});

/// Starts the clock timer; interrupts are enabled by the board.
pub fn init() {
    write(CLOCK_TIMER, CTRL, 0);
    write(CLOCK_TIMER, RELOAD, u32::MAX);
    write(CLOCK_TIMER, VALUE, u32::MAX);
    write(CLOCK_TIMER, INT_STATUS_CLEAR, 1);
    write(CLOCK_TIMER, CTRL, CTRL_ENABLE | CTRL_IRQ_ENABLE);
}

/// Timer cycles since start: the finest time this machine reads (40 ns).
pub fn now_cycles() -> u64 {
    critical_section::with(|cs| DRIVER.cycles(cs))
}

/// Interrupts served here: the alarm and the clock wrap.
pub const IRQS: [Irq; 2] = [Irq::Timer0, Irq::Timer1];

/// Clock timer wrap: count it.
pub fn on_clock_wrap() {
    critical_section::with(|cs| {
        if read(CLOCK_TIMER, INT_STATUS_CLEAR) & 1 != 0 {
            write(CLOCK_TIMER, INT_STATUS_CLEAR, 1);
            let wraps = DRIVER.wraps.borrow(cs);
            wraps.set(wraps.get().wrapping_add(1));
        }
    })
}

/// Alarm: wake what is due and program the next alarm.
pub fn on_alarm() {
    write(ALARM_TIMER, CTRL, 0);
    write(ALARM_TIMER, INT_STATUS_CLEAR, 1);
    critical_section::with(|cs| DRIVER.dispatch(cs));
}

impl CmsdkTimeDriver {
    /// Timer cycles since start. A wrap not yet counted shows as a pending interrupt; the count
    /// is then re-read after the wrap.
    fn cycles(&self, cs: CriticalSection) -> u64 {
        let wraps = u64::from(self.wraps.borrow(cs).get());
        let value = read(CLOCK_TIMER, VALUE);
        if read(CLOCK_TIMER, INT_STATUS_CLEAR) & 1 != 0 {
            let value = read(CLOCK_TIMER, VALUE);
            ((wraps + 1) << 32) + u64::from(u32::MAX - value)
        } else {
            (wraps << 32) + u64::from(u32::MAX - value)
        }
    }

    fn ticks(&self, cs: CriticalSection) -> u64 {
        self.cycles(cs) / CYCLES_PER_TICK
    }

    /// Programs the alarm for tick `at`; `false` if it has already passed.
    fn set_alarm(&self, cs: CriticalSection, at: u64) -> bool {
        write(ALARM_TIMER, CTRL, 0);
        write(ALARM_TIMER, INT_STATUS_CLEAR, 1);
        if at == u64::MAX {
            return true;
        }
        let now = self.cycles(cs);
        let at_cycles = at.saturating_mul(CYCLES_PER_TICK);
        if at_cycles <= now {
            return false;
        }
        let delay = (at_cycles - now).min(MAX_ALARM_CYCLES) as u32;
        write(ALARM_TIMER, RELOAD, delay);
        write(ALARM_TIMER, VALUE, delay);
        write(ALARM_TIMER, CTRL, CTRL_ENABLE | CTRL_IRQ_ENABLE);
        true
    }

    fn dispatch(&self, cs: CriticalSection) {
        let mut queue = self.queue.borrow(cs).borrow_mut();
        let mut next = queue.next_expiration(self.ticks(cs));
        while !self.set_alarm(cs, next) {
            next = queue.next_expiration(self.ticks(cs));
        }
    }
}

impl Driver for CmsdkTimeDriver {
    fn now(&self) -> u64 {
        critical_section::with(|cs| self.ticks(cs))
    }

    fn schedule_wake(&self, at: u64, waker: &Waker) {
        critical_section::with(|cs| {
            let earlier = self.queue.borrow(cs).borrow_mut().schedule_wake(at, waker);
            if earlier {
                self.dispatch(cs);
            }
        })
    }
}

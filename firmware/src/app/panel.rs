//! The front panel: the start/stop button and the status LED.

use embassy_time::Timer;
use embedded_hal::digital::{InputPin, OutputPin};
use embedded_hal_async::digital::Wait;
use feeder_shared::{Led, SupervisorEvent};

use crate::board;
use crate::config;
use crate::mailbox::REQUESTS;
use crate::ports::Parts;
use crate::status;

type Button = <board::Hardware as Parts>::Button;
type LedPin = <board::Hardware as Parts>::Led;

/// Turns debounced presses of the start/stop button into requests for the control loop.
#[embassy_executor::task]
pub async fn button_task(mut button: Button) {
    loop {
        if Wait::wait_for_rising_edge(&mut button).await.is_err() {
            continue;
        }
        Timer::after_millis(config::DEBOUNCE_MS).await;
        if InputPin::is_high(&mut button) == Ok(true) {
            // A press while the queue is full is dropped.
            let _ = REQUESTS.try_send(SupervisorEvent::ButtonPressed);
            while Wait::wait_for_low(&mut button).await.is_err() {}
            Timer::after_millis(config::DEBOUNCE_MS).await;
        }
    }
}

/// Off when stopped, on while moving, blinking on a fault.
#[embassy_executor::task]
pub async fn led_task(mut led: LedPin) {
    let mut lit = false;
    loop {
        lit = match status::get().led {
            Led::On => true,
            Led::Blink => !lit,
            Led::Off => false,
        };
        // Board pins are infallible; a failed write only leaves the LED as it was.
        let _ = if lit {
            OutputPin::set_high(&mut led)
        } else {
            OutputPin::set_low(&mut led)
        };
        Timer::after_millis(config::BLINK_HALF_PERIOD_MS).await;
    }
}

//! Motor-command firmware of the vibrating-plate parts feeder.
#![no_std]
#![no_main]

use defmt_rtt as _;

#[embassy_executor::main]
async fn main(_spawner: embassy_executor::Spawner) {
    let _peripherals = embassy_stm32::init(Default::default());
    defmt::info!("feeder firmware up");
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    defmt::error!("panic: {}", defmt::Display2Format(info));
    loop {
        cortex_m::asm::wfi();
    }
}

//! The pin and clock facts the other modules share: the core clock, the driver enable's pin and
//! the store that disables the driver, and the production line's pins, which either operator
//! takes.

use embassy_stm32::peripherals::{PA12, PC0, PC2, PC3, PC4, PC5, PC6, PC8, USART1};
use embassy_stm32::{pac, rcc, Config, Peri};

use crate::ports::RegisterWrite;

/// Core clock ([`clocks`]).
pub const CORE_HZ: f64 = 170e6;

/// Pin number of the driver enable on GPIOA (PA10).
pub const DRIVER_ENABLE_PIN: usize = 10;

/// GPIOA_BSRR: a 1 in bit 16 + n drives PAn low (RM0440, GPIO, "GPIO port bit set/reset register").
const GPIOA_BSRR: u32 = 0x4800_0018;

/// The first store of the safe state: the driver enable (PA10) low.
#[allow(
    clippy::declare_interior_mutable_const,
    reason = "copied once into the stage's safe-state table"
)]
pub const DRIVER_DISABLE: RegisterWrite =
    RegisterWrite::new(GPIOA_BSRR, 1 << (16 + DRIVER_ENABLE_PIN));

// The raw value above means what its comment says, as the PAC decodes it.
const _: () = assert!(pac::gpio::regs::Bsrr(1 << (16 + DRIVER_ENABLE_PIN)).br(DRIVER_ENABLE_PIN));

/// 170 MHz from HSI16: /4 × 85 /2, range 1 boost; the DMA channels' interrupts (which nothing
/// here enables a flag for) below the edges and the control executor.
pub fn clocks() -> Config {
    let mut config = Config::default();
    config.bdma_interrupt_priority = embassy_stm32::interrupt::Priority::P2;
    config.rcc.pll = Some(rcc::Pll {
        source: rcc::PllSource::HSI,
        prediv: rcc::PllPreDiv::DIV4,
        mul: rcc::PllMul::MUL85,
        divp: None,
        divq: None,
        divr: Some(rcc::PllRDiv::DIV2),
    });
    config.rcc.sys = rcc::Sysclk::PLL1_R;
    config.rcc.boost = true;
    config
}

/// The production line's peripherals: the Modbus port (USART1 to an RS-485 transceiver, its
/// driver enable the UART's own) and the discrete lines. The console image serves them
/// (`console.rs`); the button-only image leaves them as reset left them.
#[cfg_attr(
    not(feature = "console"),
    expect(dead_code, reason = "the button-only image takes the pins and leaves them")
)]
pub struct LinePins {
    pub usart: Peri<'static, USART1>,
    /// USART1 TX (AF7), to the transceiver's DI.
    pub tx: Peri<'static, PC4>,
    /// USART1 RX (AF7), from the transceiver's RO.
    pub rx: Peri<'static, PC5>,
    /// USART1 DE (AF7), to the transceiver's DE and /RE.
    pub de: Peri<'static, PA12>,
    /// The release input, high runs the feeder.
    pub release: Peri<'static, PC0>,
    /// The recipe-select inputs, bit 0 and bit 1.
    pub select: (Peri<'static, PC2>, Peri<'static, PC3>),
    /// The ready output.
    pub ready: Peri<'static, PC6>,
    /// The fault output.
    pub fault: Peri<'static, PC8>,
}

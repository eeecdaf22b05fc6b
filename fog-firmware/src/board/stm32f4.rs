//! STM32F407 (e.g. STM32F4-Discovery, 8 MHz crystal) at 168 MHz: the gyro on USART2
//! (PA2 TX, PA3 RX, 115 200 bps 8N1 here: set the gyro's rate), DWT CYCCNT as the counter
//! (core cycles), defmt over RTT, an optional TMP117 temperature sensor on I2C1 (PB8 SCL,
//! PB9 SDA, 100 kHz, address 0x48; external pull-ups). Builds in CI; it has not run on a board.
//!
//! At the end marker the final record is written and the core sleeps (no semihosting on a
//! board without a debugger).

use cortex_m::peripheral::DWT;
use cortex_m_rt::{entry, exception, ExceptionFrame};
use defmt_rtt as _;
use fog_core::tmp117::Address;
use stm32f4xx_hal::{i2c::Mode, pac, prelude::*, rcc, serial::config::Config};

use crate::temperature::TemperatureSource;

use crate::app::TickCounter;

/// HSE crystal of the board, Hz.
const HSE_MHZ: u32 = 8;
/// Core clock, Hz.
const SYSCLK_MHZ: u32 = 168;
/// Gyro link baud rate.
const BAUD: u32 = 115_200;
/// I2C1 clock (standard mode), kHz.
const I2C_KHZ: u32 = 100;
/// TMP117 address (ADD0 to ground).
const TMP117_ADDRESS: Address = Address::Gnd;

/// DWT cycle counter, 32 bits, counting up at the core clock.
pub struct CycleCounter;

impl TickCounter for CycleCounter {
    const UNIT: &'static str = "cycles";
    const TICKS_PER_UNIT_X10: u32 = 10;

    fn stamp(&self) -> u32 {
        DWT::cycle_count()
    }

    fn ticks_since(&self, start: u32) -> u32 {
        DWT::cycle_count().wrapping_sub(start)
    }
}

fn halt() -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}

#[entry]
fn main() -> ! {
    let (Some(dp), Some(mut cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
        halt()
    };
    let mut rcc = dp
        .RCC
        .freeze(rcc::Config::hse(HSE_MHZ.MHz()).sysclk(SYSCLK_MHZ.MHz()));
    cp.DCB.enable_trace();
    cp.DWT.enable_cycle_counter();

    let gpioa = dp.GPIOA.split(&mut rcc);
    let serial = match dp.USART2.serial(
        (gpioa.pa2, gpioa.pa3),
        Config::default().baudrate(BAUD.bps()),
        &mut rcc,
    ) {
        Ok(s) => s,
        Err(_) => {
            defmt::error!("USART2 configuration refused");
            halt()
        }
    };
    let (mut tx, rx) = serial.split();

    #[cfg(not(feature = "budget"))]
    {
        let gpiob = dp.GPIOB.split(&mut rcc);
        let i2c = dp.I2C1.i2c(
            (gpiob.pb8, gpiob.pb9),
            Mode::standard(I2C_KHZ.kHz()),
            &mut rcc,
        );
        let temperature = TemperatureSource::probe(Some(i2c), TMP117_ADDRESS);
        let stop = crate::app::run(
            rx,
            &mut tx,
            &CycleCounter,
            super::stack_used_bytes,
            temperature,
        );
        defmt::info!("stopped: {}", stop);
    }
    #[cfg(feature = "budget")]
    {
        let _ = rx;
        let ok = crate::budget::run(&mut tx, &CycleCounter, super::spin, super::stack_used_bytes);
        defmt::info!("budget done: {=bool}", ok);
    }
    halt()
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    match info.location() {
        Some(l) => defmt::error!("panic at {=str}:{=u32}", l.file(), l.line()),
        None => defmt::error!("panic"),
    }
    halt()
}

#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    defmt::error!("hard fault at pc {=u32:#x}", frame.pc());
    halt()
}

//! STM32F407 (e.g. STM32F4-Discovery, 8 MHz crystal) at 168 MHz: the gyro on USART2
//! (PA2 TX, PA3 RX, 115 200 bps 8N1 here: set the gyro's rate), DWT CYCCNT as the counter
//! (core cycles), defmt over RTT. Builds in CI; it has not run on a board.
//!
//! At the end marker the final record is written and the core sleeps (no semihosting on a
//! board without a debugger).

use cortex_m::peripheral::DWT;
use cortex_m_rt::{entry, exception, ExceptionFrame};
use defmt_rtt as _;
use stm32f4xx_hal::{pac, prelude::*, rcc, serial::config::Config};

use crate::app::TickCounter;

/// HSE crystal of the board, Hz.
const HSE_MHZ: u32 = 8;
/// Core clock, Hz.
const SYSCLK_MHZ: u32 = 168;
/// Gyro link baud rate.
const BAUD: u32 = 115_200;

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
        let stop = crate::app::run(rx, &mut tx, &CycleCounter, super::stack_used_bytes);
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

//! STM32F407 (e.g. STM32F4-Discovery, 8 MHz crystal) at 168 MHz: the gyro on USART2
//! (PA2 TX, PA3 RX, 115 200 bps 8N1 here: set the gyro's rate), DWT CYCCNT as the counter
//! (core cycles), defmt over RTT, an optional TMP117 temperature sensor on I2C1 (PB8 SCL,
//! PB9 SDA, 100 kHz, address 0x48; external pull-ups). Builds in CI; it has not run on a board.
//!
//! Receive: the USART2 interrupt (RXNE, through the HAL's `RxListen`) moves each byte into
//! the queue of `board::rx`; an overrun (ORE) or another receive error becomes a marker at
//! its place in the stream.
//!
//! External still flag (feature `still-pa0`): PA0 as an input with pull-down, active high =
//! still (a vehicle's "parked" or zero-velocity signal, 3.3 V logic). Without the feature the
//! board has no still input (`None`: the detector decides). The in-band still-flag commands
//! of the input stream (`pipeline::STILL_MARKER`, ...) override it.
//!
//! At the end marker the final record is written and the core sleeps (no semihosting on a
//! board without a debugger).
//!
//! **Feature `qemu-netduinoplus2`**: this build, made to run under QEMU 7.2's
//! `-machine netduinoplus2` (STM32F405: same core, same USART block at the same addresses
//! and interrupt numbers as the F407). QEMU 7.2 models the USARTs (receive interrupt on
//! RXNE with RXNEIE), SysTick, TIM2-5, EXTI and SYSCFG; RCC, the flash interface, GPIO and
//! I2C1-3 are "unimplemented devices" (writes ignored, reads 0; `-d unimp` logs them). The
//! build differs from the board build in exactly these places, each marked
//! `QEMU-DIFFERENCE` below:
//!
//! 1. **Clock tree**: `RCC.freeze(hse 8 MHz, sysclk 168 MHz)` waits for HSERDY in RCC_CR,
//!    which reads 0 under QEMU: the unmodified ELF spins there for ever (measured: 629,345
//!    reads of RCC offset 0x000 in 5 s, `-d unimp`). The variant takes the HAL's reset clocks
//!    (`constrain`: 16 MHz HSI, nothing written); QEMU runs the core at a fixed 168 MHz
//!    whatever RCC says, and its USART ignores BRR.
//! 2. **I2C1**: not modelled, so the HAL's blocking start waits for SB in I2C1_SR1 for ever
//!    (measured with the probe left in: 1,284,595 reads of I2C1 offset 0x14 in 5 s); the
//!    variant passes no bus (`temp_c` is `None`, as on a board without the sensor).
//! 3. **PA0** (`still-pa0`): GPIO is not modelled (IDR reads 0: "moving" for ever); the
//!    variant refuses that feature at compile time.
//!
//! The USART2 set-up (HAL `serial`, `listen`), the receive interrupt, the queue, the main
//! loop, the DWT set-up and the RTT logger are the board build's code unchanged.

use cortex_m::peripheral::{DWT, NVIC};
use cortex_m_rt::{entry, exception, ExceptionFrame};
use embedded_hal_nb::serial::{Error as _, ErrorKind, Read};
#[cfg(not(feature = "qemu-netduinoplus2"))]
use fog_core::{tmp105, tmp117};
#[cfg(feature = "qemu-netduinoplus2")]
use stm32f4xx_hal::i2c::I2c;
use stm32f4xx_hal::pac::{interrupt, Interrupt};
use stm32f4xx_hal::serial::{Rx, RxListen};
#[cfg(not(feature = "qemu-netduinoplus2"))]
use stm32f4xx_hal::{i2c::Mode, rcc};
use stm32f4xx_hal::{pac, prelude::*, serial::config::Config};

use crate::temperature::TemperatureSource;

// QEMU-DIFFERENCE 3: GPIO is not modelled, so PA0 cannot be the still input there.
#[cfg(all(feature = "qemu-netduinoplus2", feature = "still-pa0"))]
compile_error!(
    "still-pa0 cannot run under QEMU netduinoplus2: GPIO is not modelled (PA0 would read 0)"
);

use super::rx::RxIsr;

use crate::app::TickCounter;

/// HSE crystal of the board, Hz.
#[cfg(not(feature = "qemu-netduinoplus2"))]
const HSE_MHZ: u32 = 8;
/// Core clock, Hz.
#[cfg(not(feature = "qemu-netduinoplus2"))]
const SYSCLK_MHZ: u32 = 168;
/// Gyro link baud rate.
const BAUD: u32 = 115_200;
/// I2C1 clock (standard mode), kHz.
#[cfg(not(feature = "qemu-netduinoplus2"))]
const I2C_KHZ: u32 = 100;
/// TMP117 address (ADD0 to ground).
#[cfg(not(feature = "qemu-netduinoplus2"))]
const TMP117_ADDRESS: tmp117::Address = tmp117::Address::Gnd;
/// TMP105 address (A0 low), probed when no TMP117 answers.
#[cfg(not(feature = "qemu-netduinoplus2"))]
const TMP105_ADDRESS: tmp105::Address = tmp105::Address::A0Low;

/// GPIOA input data register (RM0090: GPIOA at 0x4002_0000, IDR at offset 0x10).
#[cfg(feature = "still-pa0")]
const GPIOA_IDR: usize = 0x4002_0010;

/// The external still flag: PA0 high = still (feature `still-pa0`), else `None`.
fn still_input() -> Option<bool> {
    #[cfg(feature = "still-pa0")]
    {
        // SAFETY: a volatile read of GPIOA's input data register, a read-only register of
        // this chip with no read side effects; PA0 was made an input by `main` (through the
        // HAL) before the loop that calls this runs.
        let idr = unsafe { core::ptr::read_volatile(GPIOA_IDR as *const u32) };
        Some(idr & 1 != 0)
    }
    #[cfg(not(feature = "still-pa0"))]
    None
}

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

/// What the USART2 interrupt owns: the receive half and the queue's producer. Written once
/// by `main` before the interrupt is unmasked; afterwards only the interrupt touches it.
static mut USART2_RX: Option<(Rx<pac::USART2>, RxIsr)> = None;

/// NVIC priority of the receive interrupt.
const PRIO_RX: u8 = 0x80;

/// Unmasks and pends the receive interrupt after a pause (the queue was full).
fn rx_resume() {
    // SAFETY: `USART2_RX` was set before the first unmask.
    unsafe { NVIC::unmask(Interrupt::USART2) };
    NVIC::pend(Interrupt::USART2);
}

#[interrupt]
fn USART2() {
    // SAFETY: only this interrupt (one priority, never re-entered) uses `USART2_RX` once
    // `main` has unmasked it, after writing it.
    let Some((rx, isr)) = (unsafe { (*core::ptr::addr_of_mut!(USART2_RX)).as_mut() }) else {
        return;
    };
    loop {
        if !isr.has_room() {
            // Back-pressure: the byte stays in the USART (see `board::rx`).
            NVIC::mask(Interrupt::USART2);
            isr.pause();
            return;
        }
        match rx.read() {
            Ok(byte) => isr.deliver(byte, false),
            Err(nb::Error::WouldBlock) => return,
            Err(nb::Error::Other(e)) => {
                if e.kind() == ErrorKind::Overrun {
                    super::rx::count_overrun(1);
                }
                isr.error(e.kind());
            }
        }
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
    #[cfg(not(feature = "qemu-netduinoplus2"))]
    let mut rcc = dp
        .RCC
        .freeze(rcc::Config::hse(HSE_MHZ.MHz()).sysclk(SYSCLK_MHZ.MHz()));
    // QEMU-DIFFERENCE 1: RCC is not modelled (HSERDY never reads 1): the reset clocks,
    // nothing written. QEMU's core runs at 168 MHz regardless.
    #[cfg(feature = "qemu-netduinoplus2")]
    let mut rcc = dp.RCC.constrain();
    cp.DCB.enable_trace();
    cp.DWT.enable_cycle_counter();

    let gpioa = dp.GPIOA.split(&mut rcc);
    // The pin's mode stays configured when its handle is dropped; `still_input` reads it.
    #[cfg(feature = "still-pa0")]
    let _ = gpioa.pa0.into_pull_down_input();
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
    let (mut tx, mut rx) = serial.split();
    let Some((isr, queue_rx)) = super::rx::split(rx_resume) else {
        halt()
    };
    rx.listen();
    // SAFETY: the interrupt is still masked: nothing else refers to `USART2_RX`; priority
    // set before the unmask.
    unsafe {
        *core::ptr::addr_of_mut!(USART2_RX) = Some((rx, isr));
        cp.NVIC.set_priority(Interrupt::USART2, PRIO_RX);
        NVIC::unmask(Interrupt::USART2);
    }

    #[cfg(not(feature = "budget"))]
    {
        #[cfg(not(feature = "qemu-netduinoplus2"))]
        let temperature = {
            let gpiob = dp.GPIOB.split(&mut rcc);
            let i2c = dp.I2C1.i2c(
                (gpiob.pb8, gpiob.pb9),
                Mode::standard(I2C_KHZ.kHz()),
                &mut rcc,
            );
            TemperatureSource::probe(Some(i2c), TMP117_ADDRESS, TMP105_ADDRESS)
        };
        // QEMU-DIFFERENCE 2: I2C1 is not modelled (the HAL waits for SB for ever): no bus.
        #[cfg(feature = "qemu-netduinoplus2")]
        let temperature = TemperatureSource::<I2c<pac::I2C1>>::probe(
            None,
            fog_core::tmp117::Address::Gnd,
            fog_core::tmp105::Address::A0Low,
        );
        let stop = crate::app::run(
            queue_rx,
            &mut tx,
            &CycleCounter,
            super::stack_used_bytes,
            super::rx::loss,
            temperature,
            still_input,
        );
        defmt::info!("stopped: {}", stop);
    }
    #[cfg(feature = "budget")]
    {
        let _ = queue_rx;
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

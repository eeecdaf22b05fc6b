//! QEMU `-machine mps2-an386` (Cortex-M4 with FPU): CMSDK APB UART0, SysTick as the
//! instruction counter, exit through semihosting, a TMP117 probed at 0x48 on the Shield1
//! SBCon I2C port (bit-banged, `sbcon_i2c.rs`; QEMU attaches nothing there by default: the
//! firmware then reports "no sensor").
//!
//! Under `-icount shift=6,align=off,sleep=off` each instruction takes 64 ns of virtual time
//! and SysTick runs on the 25 MHz core clock, so it advances 1.6 ticks per instruction,
//! deterministically. Without `-icount` SysTick follows host time and its counts mean
//! nothing.

use cortex_m::peripheral::{syst::SystClkSource, SYST};
use cortex_m_rt::{entry, exception, ExceptionFrame};
use cortex_m_semihosting::debug;
use embedded_hal_nb::serial::{ErrorKind, ErrorType, Read, Write};

use fog_core::tmp117::Address;

use super::sbcon_i2c::{self, SbconI2c};
use crate::app::TickCounter;
use crate::temperature::TemperatureSource;

/// CMSDK APB UART0 base address.
const UART0_BASE: usize = 0x4000_4000;
/// Data register (read: received byte, write: byte to send).
const DATA: usize = 0x0;
/// State: bit 0 TX full, bit 1 RX full, bit 2 TX overrun, bit 3 RX overrun (write 1 clears).
const STATE: usize = 0x4;
/// Control: bit 0 TX enable, bit 1 RX enable.
const CTRL: usize = 0x8;
/// Baud divider (core clock / baud rate, >= 16).
const BAUDDIV: usize = 0x10;

const STATE_TX_FULL: u32 = 1 << 0;
const STATE_RX_FULL: u32 = 1 << 1;
const STATE_RX_OVERRUN: u32 = 1 << 3;
const CTRL_TX_EN: u32 = 1 << 0;
const CTRL_RX_EN: u32 = 1 << 1;

/// Core clock of the AN386 image, Hz.
const SYSCLK_HZ: u32 = 25_000_000;
/// Baud rate set (QEMU ignores it; a real MPS2 board would not).
const BAUD: u32 = 115_200;

fn uart_read(offset: usize) -> u32 {
    // SAFETY: UART0's registers are at fixed, word-aligned MMIO addresses of this machine;
    // reads have no side effect besides the documented one (DATA pops the received byte).
    unsafe { core::ptr::read_volatile((UART0_BASE + offset) as *const u32) }
}

fn uart_write(offset: usize, value: u32) {
    // SAFETY: as `uart_read`; the UART is only driven from the single thread of `main`.
    unsafe { core::ptr::write_volatile((UART0_BASE + offset) as *mut u32, value) }
}

/// Receive half of UART0.
pub struct UartRx(());
/// Transmit half of UART0.
pub struct UartTx(());

impl ErrorType for UartRx {
    type Error = ErrorKind;
}

impl ErrorType for UartTx {
    type Error = ErrorKind;
}

impl Read<u8> for UartRx {
    fn read(&mut self) -> nb::Result<u8, ErrorKind> {
        let state = uart_read(STATE);
        if state & STATE_RX_OVERRUN != 0 {
            uart_write(STATE, STATE_RX_OVERRUN);
            return Err(nb::Error::Other(ErrorKind::Overrun));
        }
        if state & STATE_RX_FULL == 0 {
            return Err(nb::Error::WouldBlock);
        }
        Ok((uart_read(DATA) & 0xFF) as u8)
    }
}

impl Write<u8> for UartTx {
    fn write(&mut self, byte: u8) -> nb::Result<(), ErrorKind> {
        if uart_read(STATE) & STATE_TX_FULL != 0 {
            return Err(nb::Error::WouldBlock);
        }
        uart_write(DATA, u32::from(byte));
        Ok(())
    }

    fn flush(&mut self) -> nb::Result<(), ErrorKind> {
        if uart_read(STATE) & STATE_TX_FULL != 0 {
            return Err(nb::Error::WouldBlock);
        }
        Ok(())
    }
}

/// SysTick, 24 bits, counting down on the core clock.
pub struct SysTickCounter;

impl TickCounter for SysTickCounter {
    const UNIT: &'static str = "instructions (valid under -icount shift=6)";
    const TICKS_PER_UNIT_X10: u32 = 16;

    fn stamp(&self) -> u32 {
        SYST::get_current()
    }

    fn ticks_since(&self, start: u32) -> u32 {
        start.wrapping_sub(SYST::get_current()) & 0x00FF_FFFF
    }
}

/// Ends the QEMU run with the program's status (semihosting `SYS_EXIT`).
fn exit(ok: bool) -> ! {
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    loop {
        cortex_m::asm::nop();
    }
}

#[entry]
fn main() -> ! {
    let Some(cp) = cortex_m::Peripherals::take() else {
        exit(false)
    };
    let mut syst = cp.SYST;
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(0x00FF_FFFF);
    syst.clear_current();
    syst.enable_counter();

    uart_write(BAUDDIV, SYSCLK_HZ / BAUD);
    uart_write(CTRL, CTRL_TX_EN | CTRL_RX_EN);
    let rx = UartRx(());
    let mut tx = UartTx(());

    #[cfg(not(feature = "budget"))]
    let ok = {
        // SAFETY: SHIELD1_BASE is an SBCon port of this machine, and only this driver uses it.
        let i2c = unsafe { SbconI2c::new(sbcon_i2c::SHIELD1_BASE) };
        let temperature = TemperatureSource::probe(Some(i2c), Address::Gnd);
        crate::app::run(
            rx,
            &mut tx,
            &SysTickCounter,
            super::stack_used_bytes,
            temperature,
        ) == crate::app::Stop::EndOfInput
    };
    #[cfg(feature = "budget")]
    let ok = {
        let _ = rx;
        crate::budget::run(
            &mut tx,
            &SysTickCounter,
            super::spin,
            super::stack_used_bytes,
        )
    };
    exit(ok)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    match info.location() {
        Some(l) => defmt::error!("panic at {=str}:{=u32}", l.file(), l.line()),
        None => defmt::error!("panic"),
    }
    exit(false)
}

#[exception]
unsafe fn HardFault(frame: &ExceptionFrame) -> ! {
    defmt::error!("hard fault at pc {=u32:#x}", frame.pc());
    exit(false)
}

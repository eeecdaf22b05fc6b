//! QEMU `-machine mps2-an386` (Cortex-M4 with FPU): CMSDK APB UART0, SysTick as the
//! instruction counter, exit through semihosting, a TMP117, else a TMP105, probed at 0x48 on
//! the Shield1 SBCon I2C port (bit-banged, `sbcon_i2c.rs`; QEMU attaches nothing there by
//! default: the firmware then reports "no sensor"; `-device tmp105,address=0x48` puts QEMU's
//! TMP105 there, which the firmware then reads).
//!
//! Under `-icount shift=6,align=off,sleep=off` each instruction takes 64 ns of virtual time
//! and SysTick runs on the 25 MHz core clock, so it advances 1.6 ticks per instruction,
//! deterministically. Without `-icount` SysTick follows host time and its counts mean
//! nothing.
// The test feed (`rt-feed`) replaces UART0's receive side: its registers go unused there.
#![cfg_attr(feature = "rt-feed", allow(dead_code))]

use cortex_m::peripheral::{syst::SystClkSource, SYST};
use cortex_m_rt::{entry, exception, ExceptionFrame};
use cortex_m_semihosting::debug;
use embedded_hal_nb::serial::{ErrorKind, ErrorType, Write};

#[cfg(not(feature = "budget"))]
use fog_core::{tmp105, tmp117};

#[cfg(not(feature = "budget"))]
use super::sbcon_i2c::{self, SbconI2c};
use crate::app::TickCounter;
#[cfg(not(feature = "budget"))]
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

/// Interrupt status (read) / clear (write 1): bit 0 TX, bit 1 RX, bit 2 TX overrun, bit 3
/// RX overrun.
const INTCLEAR: usize = 0xC;

const STATE_TX_FULL: u32 = 1 << 0;
const STATE_RX_FULL: u32 = 1 << 1;
const STATE_RX_OVERRUN: u32 = 1 << 3;
const CTRL_TX_EN: u32 = 1 << 0;
const CTRL_RX_EN: u32 = 1 << 1;
const CTRL_RX_INT_EN: u32 = 1 << 3;
const INT_RX: u32 = 1 << 1;
const INT_RX_OVERRUN: u32 = 1 << 3;

/// External interrupt numbers of the AN385/AN386 image (QEMU `hw/arm/mps2.c`).
#[derive(Debug, Clone, Copy)]
pub struct Irq(u16);

/// UART0 receive interrupt.
pub const IRQ_UART0_RX: Irq = Irq(0);

// SAFETY: the numbers are external interrupts of this machine (below its 32 lines).
unsafe impl cortex_m::interrupt::InterruptNumber for Irq {
    fn number(self) -> u16 {
        self.0
    }
}

/// NVIC priority of the receive interrupt (lower than the test feed's timer, which models
/// the line and must preempt it).
const PRIO_RX: u8 = 0x80;

#[cfg(feature = "rt-feed")]
#[path = "rt_feed.rs"]
mod rt_feed;

/// The receive interrupt's half of the queue. Written once by `main` before the receive
/// interrupt is unmasked; afterwards only that interrupt touches it.
static mut RX_ISR: Option<super::rx::RxIsr> = None;

/// Runs `f` on the receive interrupt's state.
fn with_rx_isr(f: impl FnOnce(&mut super::rx::RxIsr)) {
    // SAFETY: called only from the receive interrupt (one priority, so never re-entered),
    // and `main` wrote `RX_ISR` before unmasking it: no other reference exists meanwhile.
    if let Some(isr) = unsafe { (*core::ptr::addr_of_mut!(RX_ISR)).as_mut() } {
        f(isr);
    }
}

/// Unmasks the receive interrupt after a pause (the queue was full) and pends it, so that a
/// byte waiting meanwhile is read at once.
fn rx_resume() {
    // SAFETY: the handler's state (`RX_ISR`) was set before the first unmask.
    unsafe { cortex_m::peripheral::NVIC::unmask(IRQ_UART0_RX) };
    cortex_m::peripheral::NVIC::pend(IRQ_UART0_RX);
}

/// Masks the receive interrupt: the queue is full (see `rx`, back-pressure).
fn rx_pause(isr: &mut super::rx::RxIsr) {
    cortex_m::peripheral::NVIC::mask(IRQ_UART0_RX);
    isr.pause();
}

/// UART0 receive interrupt: drains the receive register into the queue.
#[cfg(not(feature = "rt-feed"))]
fn uart0_rx_isr() {
    uart_write(INTCLEAR, INT_RX | INT_RX_OVERRUN);
    with_rx_isr(|isr| loop {
        if !isr.has_room() {
            rx_pause(isr);
            break;
        }
        let state = uart_read(STATE);
        let overrun = state & STATE_RX_OVERRUN != 0;
        if overrun {
            uart_write(STATE, STATE_RX_OVERRUN);
            super::rx::count_overrun(1);
        }
        if state & STATE_RX_FULL == 0 {
            if overrun {
                isr.error(ErrorKind::Overrun);
            }
            break;
        }
        isr.deliver((uart_read(DATA) & 0xFF) as u8, overrun);
    });
}

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

/// Transmit half of UART0.
pub struct UartTx(());

impl ErrorType for UartTx {
    type Error = ErrorKind;
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
    let Some(mut cp) = cortex_m::Peripherals::take() else {
        exit(false)
    };
    let mut syst = cp.SYST;
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(0x00FF_FFFF);
    syst.clear_current();
    syst.enable_counter();

    let Some((isr, queue_rx)) = super::rx::split(rx_resume) else {
        exit(false)
    };
    // SAFETY: the receive interrupt is still masked: nothing else refers to `RX_ISR`.
    unsafe { *core::ptr::addr_of_mut!(RX_ISR) = Some(isr) };
    uart_write(BAUDDIV, SYSCLK_HZ / BAUD);
    // With the test feed the input comes from its timer, not from UART0's RX line.
    let ctrl = if cfg!(feature = "rt-feed") {
        CTRL_TX_EN
    } else {
        CTRL_TX_EN | CTRL_RX_EN | CTRL_RX_INT_EN
    };
    uart_write(CTRL, ctrl);
    // SAFETY: priorities are set before the interrupt is unmasked; `RX_ISR` is in place,
    // which is all the handler needs (it runs at one priority, never re-entered).
    unsafe {
        cp.NVIC.set_priority(IRQ_UART0_RX, PRIO_RX);
        if !cfg!(feature = "rt-feed-poll") {
            cortex_m::peripheral::NVIC::unmask(IRQ_UART0_RX);
        }
    }
    #[cfg(feature = "rt-feed")]
    rt_feed::start(&mut cp.NVIC);
    #[cfg(feature = "rt-feed-poll")]
    let rx = {
        let _ = queue_rx;
        rt_feed::PolledRx
    };
    #[cfg(not(feature = "rt-feed-poll"))]
    let rx = queue_rx;
    let mut tx = UartTx(());

    #[cfg(not(feature = "budget"))]
    let ok = {
        // SAFETY: SHIELD1_BASE is an SBCon port of this machine, and only this driver uses it.
        let i2c = unsafe { SbconI2c::new(sbcon_i2c::SHIELD1_BASE) };
        let temperature =
            TemperatureSource::probe(Some(i2c), tmp117::Address::Gnd, tmp105::Address::A0Low);
        crate::app::run(
            rx,
            &mut tx,
            &SysTickCounter,
            super::stack_used_bytes,
            super::rx::loss,
            temperature,
            // No still input pin on this board: the external flag comes from the in-band
            // commands of the input stream (`pipeline::STILL_MARKER`, ...).
            || None,
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

/// External interrupts (cortex-m-rt without a device crate sends them all here): UART0 RX,
/// and the test feed's timer.
#[exception]
unsafe fn DefaultHandler(irqn: i16) {
    match irqn {
        0 => {
            #[cfg(not(feature = "rt-feed"))]
            uart0_rx_isr();
            #[cfg(feature = "rt-feed")]
            rt_feed::rx_isr();
        }
        #[cfg(feature = "rt-feed")]
        8 => rt_feed::timer_isr(),
        _ => {}
    }
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

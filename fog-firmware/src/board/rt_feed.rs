//! Test build only (feature `rt-feed`): bytes that arrive in real time, whether or not the
//! firmware is ready for them.
//!
//! # What it models
//! A UART line at `FOG_RT_BAUD` (build-time, default 115,200) feeding a receiver with a
//! **one-byte receive register** and no FIFO (the STM32 USART's RDR): CMSDK timer 0
//! (0x4000_0000, interrupt 8, highest priority) fires once per byte period and writes the
//! next byte of a capture built into the image (`FOG_RT_CAPTURE`, copied by `build.rs`)
//! into a software receive register. If the register still holds an unread byte, that byte
//! is **overwritten** and counted as lost (an overrun). The receive interrupt (UART0 RX's
//! vector, interrupt 0, lower priority), pended by the timer, must drain the register into
//! the queue before the next tick; the main loop sees only the queue. With
//! `rt-feed-poll` the receive interrupt is never enabled and the main loop polls the
//! register between samples, as the firmware did before the queue: bytes are then lost
//! while a long sample runs.
//!
//! # Time
//! Under `qemu-system-arm -icount shift=6,align=off,sleep=off` one instruction is 64 ns of
//! virtual time and the timer, clocked at 25 MHz, advances 1.6 ticks per instruction,
//! deterministically. The byte period is set in instructions as **cycles of a 168 MHz
//! core at one instruction per cycle**: 10 bits (8N1) = 168e6 * 10 / baud instructions (14,583
//! at 115,200, 23,333 timer ticks). A real M4F needs
//! more cycles than instructions (divisions, loads, flash wait states), so on a board a
//! long sample spans more bytes than here.
//!
//! # What it does not model
//! Not the real USART: no start/stop bits, no framing, parity or noise errors, no baud-rate
//! error; the interrupt entry latency is QEMU's, not the core's (12 cycles); the transmit
//! side (records) takes no time; the register is written exactly once per period with no
//! jitter.

use core::sync::atomic::{AtomicBool, AtomicU8, AtomicUsize, Ordering};

use cortex_m::peripheral::NVIC;
use embedded_hal_nb::serial::{ErrorKind, ErrorType, Read};

use super::Irq;

// `BYTE_PERIOD_TICKS` and `BAUD`, from build.rs.
include!(concat!(env!("OUT_DIR"), "/rt_feed_config.rs"));

/// The capture, delivered byte by byte. An array, so that the ELF's symbol table names it
/// (the real-time test reads it back from the ELF it runs).
static CAPTURE: [u8; CAPTURE_LEN] = *include_bytes!(concat!(env!("OUT_DIR"), "/rt_capture.bin"));

/// Length of [`CAPTURE`], bytes.
const CAPTURE_LEN: usize = include_bytes!(concat!(env!("OUT_DIR"), "/rt_capture.bin")).len();

/// CMSDK APB timer 0.
const TIMER0_BASE: usize = 0x4000_0000;
const CTRL: usize = 0x0;
const RELOAD: usize = 0x8;
const VALUE: usize = 0x4;
const INTCLEAR: usize = 0xC;
const CTRL_EN: u32 = 1 << 0;
const CTRL_INT_EN: u32 = 1 << 3;
/// Timer 0's interrupt.
const IRQ_TIMER0: Irq = Irq(8);

fn timer_write(offset: usize, value: u32) {
    // SAFETY: timer 0's registers are fixed, word-aligned MMIO addresses of this machine,
    // written only by `start` (before its interrupt is unmasked) and by its interrupt.
    unsafe { core::ptr::write_volatile((TIMER0_BASE + offset) as *mut u32, value) }
}

/// The software receive register.
static RX_DATA: AtomicU8 = AtomicU8::new(0);
static RX_FULL: AtomicBool = AtomicBool::new(false);
static RX_OVERRUN: AtomicBool = AtomicBool::new(false);
/// Next byte of the capture.
static NEXT: AtomicUsize = AtomicUsize::new(0);

/// Starts the line: one byte per `BYTE_PERIOD_TICKS`.
pub fn start(nvic: &mut NVIC) {
    timer_write(RELOAD, BYTE_PERIOD_TICKS - 1);
    timer_write(VALUE, BYTE_PERIOD_TICKS - 1);
    // SAFETY: the handler only touches the statics above, which are atomics.
    unsafe {
        nvic.set_priority(IRQ_TIMER0, 0);
        NVIC::unmask(IRQ_TIMER0);
    }
    timer_write(CTRL, CTRL_EN | CTRL_INT_EN);
    defmt::info!(
        "rt-feed: {=usize} bytes at {=u32} baud, one every {=u32} timer ticks",
        CAPTURE.len(),
        BAUD,
        BYTE_PERIOD_TICKS
    );
}

/// Timer 0: the next byte lands in the receive register, overwriting an unread one.
pub fn timer_isr() {
    timer_write(INTCLEAR, 1);
    let i = NEXT.load(Ordering::Relaxed);
    let Some(&byte) = CAPTURE.get(i) else {
        timer_write(CTRL, 0);
        return;
    };
    NEXT.store(i + 1, Ordering::Relaxed);
    if RX_FULL.load(Ordering::Relaxed) {
        RX_OVERRUN.store(true, Ordering::Relaxed);
        super::super::rx::count_overrun(1);
    }
    RX_DATA.store(byte, Ordering::Relaxed);
    RX_FULL.store(true, Ordering::Relaxed);
    if !cfg!(feature = "rt-feed-poll") {
        NVIC::pend(super::IRQ_UART0_RX);
    }
}

/// Takes the register's byte (and its overrun flag) with the timer masked, as a UART read
/// of status then data would.
fn take() -> Option<(u8, bool)> {
    cortex_m::interrupt::free(|_| {
        if !RX_FULL.load(Ordering::Relaxed) {
            return None;
        }
        RX_FULL.store(false, Ordering::Relaxed);
        let overrun = RX_OVERRUN.swap(false, Ordering::Relaxed);
        Some((RX_DATA.load(Ordering::Relaxed), overrun))
    })
}

/// The receive interrupt of the test build: drains the software register into the queue.
pub fn rx_isr() {
    super::with_rx_isr(|isr| {
        if !isr.has_room() {
            super::rx_pause(isr);
        } else if let Some((byte, overrun)) = take() {
            isr.deliver(byte, overrun);
        }
    });
}

/// `rt-feed-poll`: the main loop reads the register itself (no receive interrupt).
pub struct PolledRx;

impl ErrorType for PolledRx {
    type Error = ErrorKind;
}

impl Read<u8> for PolledRx {
    fn read(&mut self) -> nb::Result<u8, ErrorKind> {
        if RX_OVERRUN.swap(false, Ordering::Relaxed) {
            return Err(nb::Error::Other(ErrorKind::Overrun));
        }
        match take() {
            Some((byte, _)) => Ok(byte),
            None => Err(nb::Error::WouldBlock),
        }
    }
}

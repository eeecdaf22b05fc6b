//! Interrupt-driven receive: the board's receive interrupt moves each byte from the UART into
//! a `heapless::spsc::Queue`; the main loop decodes from the queue ([`QueueRx`], an
//! `embedded-hal-nb` `Read<u8>`). Shared by both boards.
//!
//! A loss (a byte overwritten in the UART's receive register, or a full queue) is put into
//! the queue as a **marker** at the place in the stream where it happened. The main loop
//! reads it as a receive error (`ErrorKind::Overrun` / `ErrorKind::Other`): the decoder
//! drops the frame it cut, counts it, and resynchronises on the next whole frame. The lost
//! bytes themselves are counted here ([`loss`]) and reported in the statistics record.
//!
//! **Back-pressure**: when the queue has no room for a byte (and a marker), the receive
//! interrupt leaves the byte in the UART, masks itself ([`RxIsr::pause`]) and the main loop
//! unmasks it once the queue is half empty. On a real line the byte is then overwritten by
//! the next one, an overrun that is counted like any other; QEMU's UART, which waits for the
//! guest to read (flow control), simply waits, so the hardware-in-the-loop test loses nothing.
//!
//! Queue size: [`QUEUE_LEN`] - 1 = 63 entries of 2 bytes (128 B of RAM). At 115,200 baud
//! (8N1) a byte arrives every 14,583 cycles of a 168 MHz core, so the queue covers 0.9 M
//! cycles of main-loop stall, 148 times the worst sample's estimated 6,174 cycles (figures:
//! `fog-firmware/README.md`); at 1,000,000 baud, 17 times. ASSUMED enough: the 16-KiB RAM
//! budget keeps 1 KiB spare with it (128 entries did not).

use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use embedded_hal_nb::serial::{ErrorKind, ErrorType, Read};
use heapless::spsc::{Consumer, Producer, Queue};

use crate::app::RxLoss;

/// Entries of the queue (heapless 0.8 keeps one free: 63 usable).
pub const QUEUE_LEN: usize = 64;

/// Queue entry of a byte overwritten in the receive register (overrun) before this point.
const MARK_OVERRUN: u16 = 0x100;
/// Queue entry of bytes dropped because the queue was full before this point.
const MARK_QUEUE_FULL: u16 = 0x101;
/// Queue entries of other receive errors reported by the UART (framing, parity, noise).
const MARK_FRAMING: u16 = 0x102;
const MARK_PARITY: u16 = 0x103;
const MARK_NOISE: u16 = 0x104;
const MARK_OTHER: u16 = 0x105;

/// The receive interrupt masked itself: the queue was full.
static PAUSED: AtomicBool = AtomicBool::new(false);

static OVERRUN_BYTES: AtomicU32 = AtomicU32::new(0);
static QUEUE_FULL_BYTES: AtomicU32 = AtomicU32::new(0);

/// Counts `n` bytes lost in the receive register (called by the interrupt that sees it).
pub fn count_overrun(n: u32) {
    OVERRUN_BYTES.fetch_add(n, Ordering::Relaxed);
}

/// The bytes lost so far.
#[cfg_attr(feature = "budget", allow(dead_code))]
pub fn loss() -> RxLoss {
    RxLoss {
        overrun: OVERRUN_BYTES.load(Ordering::Relaxed),
        queue_full: QUEUE_FULL_BYTES.load(Ordering::Relaxed),
    }
}

/// The producer half, owned by the receive interrupt.
pub struct RxIsr {
    producer: Producer<'static, u16, QUEUE_LEN>,
    /// A loss marker not yet in the queue (the queue was full): every byte is dropped until
    /// it is in, so that the marker stays at the place of the loss.
    pending: Option<u16>,
}

impl RxIsr {
    /// Room for one more byte and a loss marker.
    pub fn has_room(&self) -> bool {
        self.producer.len() + 2 <= self.producer.capacity()
    }

    /// Notes that the interrupt masked itself; [`QueueRx`] calls `resume` when the queue is
    /// half empty again.
    pub fn pause(&mut self) {
        PAUSED.store(true, Ordering::Release);
    }

    /// Queues `byte`; `overrun` says that one or more bytes before it were lost in the
    /// receive register (the caller counts them with [`count_overrun`]).
    pub fn deliver(&mut self, byte: u8, overrun: bool) {
        if overrun && self.pending.is_none() {
            self.pending = Some(MARK_OVERRUN);
        }
        if let Some(mark) = self.pending {
            if self.producer.enqueue(mark).is_ok() {
                self.pending = None;
            }
        }
        if self.pending.is_some() || self.producer.enqueue(u16::from(byte)).is_err() {
            QUEUE_FULL_BYTES.fetch_add(1, Ordering::Relaxed);
            self.pending.get_or_insert(MARK_QUEUE_FULL);
        }
    }

    /// A receive error without a byte to go with it (an overrun flagged on an empty
    /// register, or a byte the UART refused: framing, parity, noise). An overrun's lost
    /// bytes are counted by the caller ([`count_overrun`]).
    #[cfg_attr(feature = "rt-feed", allow(dead_code))]
    pub fn error(&mut self, kind: ErrorKind) {
        if self.pending.is_none() {
            self.pending = Some(match kind {
                ErrorKind::Overrun => MARK_OVERRUN,
                ErrorKind::FrameFormat => MARK_FRAMING,
                ErrorKind::Parity => MARK_PARITY,
                ErrorKind::Noise => MARK_NOISE,
                _ => MARK_OTHER,
            });
        }
        if let Some(mark) = self.pending {
            if self.producer.enqueue(mark).is_ok() {
                self.pending = None;
            }
        }
    }
}

/// The consumer half, read by the main loop.
pub struct QueueRx {
    consumer: Consumer<'static, u16, QUEUE_LEN>,
    /// Unmasks (and pends) the receive interrupt after a pause.
    resume: fn(),
}

impl ErrorType for QueueRx {
    type Error = ErrorKind;
}

impl Read<u8> for QueueRx {
    fn read(&mut self) -> nb::Result<u8, ErrorKind> {
        if self.consumer.len() <= QUEUE_LEN / 2 && PAUSED.swap(false, Ordering::AcqRel) {
            (self.resume)();
        }
        match self.consumer.dequeue() {
            None => Err(nb::Error::WouldBlock),
            Some(MARK_OVERRUN) => Err(nb::Error::Other(ErrorKind::Overrun)),
            Some(MARK_FRAMING) => Err(nb::Error::Other(ErrorKind::FrameFormat)),
            Some(MARK_PARITY) => Err(nb::Error::Other(ErrorKind::Parity)),
            Some(MARK_NOISE) => Err(nb::Error::Other(ErrorKind::Noise)),
            Some(v) if v > 0xFF => Err(nb::Error::Other(ErrorKind::Other)),
            Some(v) => Ok(v as u8),
        }
    }
}

/// The queue, split once at start-up.
static mut QUEUE: Queue<u16, QUEUE_LEN> = Queue::new();

/// Splits the queue; `resume` unmasks and pends the board's receive interrupt. Returns
/// `None` on a second call.
pub fn split(resume: fn()) -> Option<(RxIsr, QueueRx)> {
    static TAKEN: AtomicBool = AtomicBool::new(false);
    if TAKEN.swap(true, Ordering::AcqRel) {
        return None;
    }
    // SAFETY: `TAKEN` lets exactly one call get here, so this is the only reference ever made
    // to `QUEUE`; it lives for the rest of the program.
    let queue: &'static mut Queue<u16, QUEUE_LEN> = unsafe { &mut *core::ptr::addr_of_mut!(QUEUE) };
    let (producer, consumer) = queue.split();
    Some((
        RxIsr {
            producer,
            pending: None,
        },
        QueueRx { consumer, resume },
    ))
}

//! defmt global logger on a SEGGER RTT up-channel (channel 0, "defmt"), for the STM32F407
//! board: read with `probe-rs` or any RTT host.
//!
//! Written here instead of using the `defmt-rtt` crate because that one panics when the
//! logger is re-entered (`panic!("defmt logger taken reentrantly")`), which links the panic
//! machinery into the release ELF; here a re-entered frame is dropped (`defmt_frames`). Non-blocking: bytes
//! that do not fit in the buffer (host not reading) are dropped, like `defmt-rtt`'s default
//! mode.

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicU32, Ordering};

use super::defmt_frames::{Frames, Sink};

/// Bytes of the up-channel's ring buffer. ASSUMED enough: the host (probe-rs) reads the
/// channel while the firmware runs, and the firmware logs a few frames at start and a
/// statistics frame per period; what does not fit is dropped (non-blocking). 256 B, not
/// the 1 KiB of `defmt-rtt`, so that the STM32 build keeps 1 KiB of its 16-KiB RAM budget.
const BUF_SIZE: usize = 256;

/// RTT channel descriptor (layout fixed by the RTT protocol).
#[repr(C)]
struct Channel {
    name: *const u8,
    buffer: *mut u8,
    size: u32,
    write: AtomicU32,
    read: AtomicU32,
    flags: AtomicU32,
}

/// RTT control block with one up-channel and no down-channel.
#[repr(C)]
struct Header {
    id: [u8; 16],
    max_up_channels: u32,
    max_down_channels: u32,
    up: Channel,
}

// SAFETY: the raw pointers point at statics that live for the whole program; the buffer is
// written only inside the logger's critical section (one writer) and read by the debugger.
unsafe impl Sync for Header {}

struct Buffer(UnsafeCell<[u8; BUF_SIZE]>);

// SAFETY: as for `Header`: one writer, inside the critical section.
unsafe impl Sync for Buffer {}

static BUFFER: Buffer = Buffer(UnsafeCell::new([0; BUF_SIZE]));
static NAME: [u8; 6] = *b"defmt\0";

#[no_mangle]
static _SEGGER_RTT: Header = Header {
    id: *b"SEGGER RTT\0\0\0\0\0\0",
    max_up_channels: 1,
    max_down_channels: 0,
    up: Channel {
        name: NAME.as_ptr(),
        buffer: BUFFER.0.get() as *mut u8,
        size: BUF_SIZE as u32,
        write: AtomicU32::new(0),
        read: AtomicU32::new(0),
        // 0: non-blocking, skip what does not fit.
        flags: AtomicU32::new(0),
    },
};

/// Appends `bytes` to the ring as far as they fit (the debugger advances `read`).
fn emit(bytes: &[u8]) {
    let ch = &_SEGGER_RTT.up;
    let read = ch.read.load(Ordering::Acquire) as usize % BUF_SIZE;
    let mut write = ch.write.load(Ordering::Relaxed) as usize % BUF_SIZE;
    for &b in bytes {
        let next = (write + 1) % BUF_SIZE;
        if next == read {
            break;
        }
        // SAFETY: `write < BUF_SIZE`, inside `BUFFER`; the host reads only between `read`
        // and `write`, so this byte is not being read.
        unsafe { ch.buffer.add(write).write_volatile(b) };
        write = next;
    }
    ch.write.store(write as u32, Ordering::Release);
}

/// The RTT up-channel as a defmt sink.
struct Rtt;

impl Sink for Rtt {
    fn emit(&mut self, bytes: &[u8]) {
        emit(bytes);
    }
}

static FRAMES: Frames<Rtt> = Frames::new(Rtt);

#[defmt::global_logger]
struct Logger;

// SAFETY: the contract of `defmt::Logger` is kept by `Frames` (one frame at a time, inside a
// critical section; a re-entered frame dropped).
unsafe impl defmt::Logger for Logger {
    fn acquire() {
        FRAMES.acquire();
    }

    unsafe fn flush() {}

    unsafe fn release() {
        // SAFETY: defmt calls it after `acquire`.
        unsafe { FRAMES.release() };
    }

    unsafe fn write(bytes: &[u8]) {
        // SAFETY: defmt calls it between `acquire` and `release`.
        unsafe { FRAMES.write(bytes) };
    }
}

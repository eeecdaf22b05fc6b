//! defmt global logger on a SEGGER RTT up-channel (channel 0, "defmt"), for the STM32F407
//! board: read with `probe-rs` or any RTT host.
//!
//! Written here instead of using the `defmt-rtt` crate because that one panics when the
//! logger is re-entered (`panic!("defmt logger taken reentrantly")`), which links the panic
//! machinery into the release ELF; here a re-entered frame is dropped. Non-blocking: bytes
//! that do not fit in the buffer (host not reading) are dropped, like `defmt-rtt`'s default
//! mode.

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

/// Bytes of the up-channel's ring buffer.
const BUF_SIZE: usize = 1024;

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

#[defmt::global_logger]
struct Logger;

struct State {
    encoder: defmt::Encoder,
    restore: critical_section::RestoreState,
}

struct Shared {
    taken: AtomicBool,
    /// A frame started inside another (a log inside a log) is being dropped.
    nested: AtomicBool,
    state: UnsafeCell<State>,
}

// SAFETY: `state` is only touched between `acquire` and `release`, inside a critical section
// on a single core, and `taken` refuses re-entry.
unsafe impl Sync for Shared {}

static SHARED: Shared = Shared {
    taken: AtomicBool::new(false),
    nested: AtomicBool::new(false),
    state: UnsafeCell::new(State {
        encoder: defmt::Encoder::new(),
        restore: critical_section::RestoreState::invalid(),
    }),
};

// SAFETY: the contract of `defmt::Logger`, kept as in `defmt_stderr`: `acquire` takes a
// critical section and marks the logger taken; `write`/`flush`/`release` are only called
// between `acquire` and `release`.
unsafe impl defmt::Logger for Logger {
    fn acquire() {
        // SAFETY: paired with exactly one `critical_section::release`.
        let restore = unsafe { critical_section::acquire() };
        if SHARED.taken.swap(true, Ordering::Relaxed) {
            // Re-entered: this frame is dropped (no state touched).
            SHARED.nested.store(true, Ordering::Relaxed);
            // SAFETY: releases the section just taken.
            unsafe { critical_section::release(restore) };
            return;
        }
        // SAFETY: inside the critical section with `taken` set: exclusive access.
        let state = unsafe { &mut *SHARED.state.get() };
        state.restore = restore;
        state.encoder.start_frame(emit);
    }

    unsafe fn flush() {}

    unsafe fn release() {
        if SHARED.nested.swap(false, Ordering::Relaxed) {
            return;
        }
        // SAFETY: called after `acquire` (defmt's contract): exclusive access.
        let state = unsafe { &mut *SHARED.state.get() };
        state.encoder.end_frame(emit);
        let restore = state.restore;
        SHARED.taken.store(false, Ordering::Relaxed);
        // SAFETY: paired with the `acquire` of this frame.
        unsafe { critical_section::release(restore) };
    }

    unsafe fn write(bytes: &[u8]) {
        if SHARED.nested.load(Ordering::Relaxed) {
            return;
        }
        // SAFETY: called between `acquire` and `release` (defmt's contract).
        let state = unsafe { &mut *SHARED.state.get() };
        state.encoder.write(bytes, emit);
    }
}

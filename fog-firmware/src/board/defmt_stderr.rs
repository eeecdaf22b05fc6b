//! defmt global logger writing its frames to the host's **stderr** through semihosting
//! (`:tt` opened for append), so that QEMU's stdout stays free for UART0.
//!
//! (`defmt-semihosting` writes to stdout, where `-serial stdio` puts the UART.) Decode with
//! `defmt-print -e ELF < defmt.bin`.

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicBool, Ordering};

use cortex_m_semihosting::hio::{self, HostStream};

#[defmt::global_logger]
struct Logger;

struct State {
    encoder: defmt::Encoder,
    stream: Option<HostStream>,
    restore: critical_section::RestoreState,
}

struct Shared {
    taken: AtomicBool,
    state: UnsafeCell<State>,
}

// SAFETY: `state` is only touched between `acquire` and `release`, inside a critical section
// on a single core, and `taken` refuses re-entry; so never from two contexts at once.
unsafe impl Sync for Shared {}

static SHARED: Shared = Shared {
    taken: AtomicBool::new(false),
    state: UnsafeCell::new(State {
        encoder: defmt::Encoder::new(),
        stream: None,
        restore: critical_section::RestoreState::invalid(),
    }),
};

fn emit(stream: &mut Option<HostStream>, bytes: &[u8]) {
    if let Some(s) = stream {
        // A lost log frame is not worth stopping for.
        let _ = s.write_all(bytes);
    }
}

// SAFETY: the contract of `defmt::Logger`: `acquire` takes a critical section and marks the
// logger taken, `write`/`flush`/`release` are only called by defmt between `acquire` and
// `release`, so they have exclusive access to `SHARED.state`.
unsafe impl defmt::Logger for Logger {
    fn acquire() {
        // SAFETY: paired with exactly one `critical_section::release` in `release`.
        let restore = unsafe { critical_section::acquire() };
        if SHARED.taken.swap(true, Ordering::Relaxed) {
            // Re-entered (a log inside a log): drop this frame's bytes by not touching state;
            // defmt never does this on one core without interrupts that log.
            // SAFETY: releases the section just taken.
            unsafe { critical_section::release(restore) };
            return;
        }
        // SAFETY: inside the critical section with `taken` set: exclusive access.
        let state = unsafe { &mut *SHARED.state.get() };
        state.restore = restore;
        if state.stream.is_none() {
            state.stream = hio::hstderr().ok();
        }
        let State {
            encoder, stream, ..
        } = state;
        encoder.start_frame(|b| emit(stream, b));
    }

    unsafe fn flush() {
        // Semihosting writes are synchronous: nothing is buffered here.
    }

    unsafe fn release() {
        // SAFETY: called after `acquire` (defmt's contract): exclusive access.
        let state = unsafe { &mut *SHARED.state.get() };
        let State {
            encoder, stream, ..
        } = state;
        encoder.end_frame(|b| emit(stream, b));
        let restore = state.restore;
        SHARED.taken.store(false, Ordering::Relaxed);
        // SAFETY: paired with the `acquire` of this frame.
        unsafe { critical_section::release(restore) };
    }

    unsafe fn write(bytes: &[u8]) {
        // SAFETY: called between `acquire` and `release` (defmt's contract).
        let state = unsafe { &mut *SHARED.state.get() };
        let State {
            encoder, stream, ..
        } = state;
        encoder.write(bytes, |b| emit(stream, b));
    }
}

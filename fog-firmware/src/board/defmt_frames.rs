//! The framing half of a defmt global logger, shared by the boards' loggers
//! (`defmt_stderr`, `defmt_rtt`): one frame at a time inside a critical section, a frame
//! started inside another (a log inside a log) dropped instead of panicking, the bytes handed
//! to a [`Sink`].

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicBool, Ordering};

/// Where a logger's encoded bytes go.
pub trait Sink {
    /// Called once per frame, before its first byte (e.g. to open a stream).
    fn open(&mut self) {}
    /// Writes encoded bytes; what cannot be written is dropped.
    fn emit(&mut self, bytes: &[u8]);
}

struct State<S> {
    encoder: defmt::Encoder,
    sink: S,
    restore: critical_section::RestoreState,
}

/// A logger's state: use it from `defmt::Logger`'s four functions.
pub struct Frames<S> {
    taken: AtomicBool,
    /// A frame started inside another is being dropped: its `write`s and its `release` must
    /// not touch the outer frame's state.
    nested: AtomicBool,
    state: UnsafeCell<State<S>>,
}

// SAFETY: `state` is only touched between `acquire` and `release`, inside a critical section
// on a single core, and `taken` refuses re-entry; so never from two contexts at once.
unsafe impl<S: Send> Sync for Frames<S> {}

impl<S: Sink> Frames<S> {
    /// Idle state around `sink`.
    pub const fn new(sink: S) -> Self {
        Self {
            taken: AtomicBool::new(false),
            nested: AtomicBool::new(false),
            state: UnsafeCell::new(State {
                encoder: defmt::Encoder::new(),
                sink,
                restore: critical_section::RestoreState::invalid(),
            }),
        }
    }

    /// `defmt::Logger::acquire`.
    pub fn acquire(&self) {
        // SAFETY: paired with exactly one `critical_section::release` (here on re-entry, in
        // `release` otherwise).
        let restore = unsafe { critical_section::acquire() };
        if self.taken.swap(true, Ordering::Relaxed) {
            // Re-entered: this frame is dropped, the outer one's state left alone.
            self.nested.store(true, Ordering::Relaxed);
            // SAFETY: releases the section just taken.
            unsafe { critical_section::release(restore) };
            return;
        }
        // SAFETY: inside the critical section with `taken` set: exclusive access.
        let state = unsafe { &mut *self.state.get() };
        state.restore = restore;
        state.sink.open();
        let State { encoder, sink, .. } = state;
        encoder.start_frame(|b| sink.emit(b));
    }

    /// `defmt::Logger::write`.
    ///
    /// # Safety
    /// Only between `acquire` and `release` (defmt's contract).
    pub unsafe fn write(&self, bytes: &[u8]) {
        if self.nested.load(Ordering::Relaxed) {
            return;
        }
        // SAFETY: between `acquire` and `release`: exclusive access.
        let State { encoder, sink, .. } = unsafe { &mut *self.state.get() };
        encoder.write(bytes, |b| sink.emit(b));
    }

    /// `defmt::Logger::release`.
    ///
    /// # Safety
    /// Only after `acquire` (defmt's contract).
    pub unsafe fn release(&self) {
        if self.nested.swap(false, Ordering::Relaxed) {
            return;
        }
        // SAFETY: after `acquire`: exclusive access.
        let state = unsafe { &mut *self.state.get() };
        let State { encoder, sink, .. } = state;
        encoder.end_frame(|b| sink.emit(b));
        let restore = state.restore;
        self.taken.store(false, Ordering::Relaxed);
        // SAFETY: paired with the `acquire` of this frame.
        unsafe { critical_section::release(restore) };
    }
}

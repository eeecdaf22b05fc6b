//! defmt global logger writing its frames to the host's **stderr** through semihosting
//! (`:tt` opened for append), so that QEMU's stdout stays free for UART0.
//!
//! (`defmt-semihosting` writes to stdout, where `-serial stdio` puts the UART.) Decode with
//! `defmt-print -e ELF < defmt.bin`.

use cortex_m_semihosting::hio::{self, HostStream};

use super::defmt_frames::{Frames, Sink};

/// Semihosting stderr, opened at the first frame.
struct Stderr(Option<HostStream>);

impl Sink for Stderr {
    fn open(&mut self) {
        if self.0.is_none() {
            self.0 = hio::hstderr().ok();
        }
    }

    fn emit(&mut self, bytes: &[u8]) {
        if let Some(s) = &mut self.0 {
            // A lost log frame is not worth stopping for.
            let _ = s.write_all(bytes);
        }
    }
}

static FRAMES: Frames<Stderr> = Frames::new(Stderr(None));

#[defmt::global_logger]
struct Logger;

// SAFETY: the contract of `defmt::Logger` is kept by `Frames` (one frame at a time, inside a
// critical section; a re-entered frame dropped).
unsafe impl defmt::Logger for Logger {
    fn acquire() {
        FRAMES.acquire();
    }

    unsafe fn flush() {
        // Semihosting writes are synchronous: nothing is buffered here.
    }

    unsafe fn release() {
        // SAFETY: defmt calls it after `acquire`.
        unsafe { FRAMES.release() };
    }

    unsafe fn write(bytes: &[u8]) {
        // SAFETY: defmt calls it between `acquire` and `release`.
        unsafe { FRAMES.write(bytes) };
    }
}

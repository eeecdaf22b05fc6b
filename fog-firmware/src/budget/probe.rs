//! Timing windows the cycle tool can find in an instruction trace (`fw-cycles`,
//! `tests/src/cycles.rs`).
//!
//! Each window kind has its own pair of functions, never inlined, that read the counter:
//! `<probe::Pipeline as probe::Window>::open` and `...::close`. The cycle tool finds their
//! entry addresses in the ELF's symbols and, in the trace of the same run, cuts the
//! instruction stream into the windows the firmware times, by name. The names are the
//! contract with the tool: `Empty` is the counter overhead the firmware subtracts, and the
//! tool subtracts the same window's instruction count.
//!
//! Each function also passes its kind's number through `black_box`, so that no two are
//! identical and LLVM's function merging cannot fold them into one address.

use crate::app::TickCounter;

/// One kind of timing window.
pub trait Window {
    /// Reads the counter at the start of the window.
    fn open<C: TickCounter>(c: &C) -> u32;
    /// Ticks since `t0`, read at the end of the window.
    fn close<C: TickCounter>(c: &C, t0: u32) -> u32;
}

macro_rules! windows {
    ($($(#[$doc:meta])* $name:ident = $id:literal,)*) => {$(
        $(#[$doc])*
        pub struct $name;

        impl Window for $name {
            #[inline(never)]
            fn open<C: TickCounter>(c: &C) -> u32 {
                core::hint::black_box($id as u32);
                c.stamp()
            }

            #[inline(never)]
            fn close<C: TickCounter>(c: &C, t0: u32) -> u32 {
                core::hint::black_box($id as u32);
                c.ticks_since(t0)
            }
        }
    )*};
}

windows! {
    /// Nothing inside: the counter overhead (removed from every other window).
    Empty = 1,
    /// The calibration loop (`subs`/`bne`).
    Spin = 2,
    /// Decode of one frame's 8 bytes + the stage + the record.
    Pipeline = 3,
    /// `pipeline::process`: drift filter + denoiser + status.
    Stage = 4,
    /// Frame decode alone (8 bytes).
    Decode = 5,
    /// `DriftFilter::push` alone (its stillness test included).
    Estimate = 7,
    /// `ResumableDenoiser::push` alone.
    Denoise = 8,
    /// The resumable-denoiser table (`budget/resumable.rs`).
    Resumable = 10,
}

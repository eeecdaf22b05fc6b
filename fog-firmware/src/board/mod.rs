//! Hardware layer: the only module of the firmware with `unsafe` (each block says why it is
//! sound). One board is selected by cargo feature; everything else is in `app`, `pipeline`
//! and `budget`.

#[cfg(all(feature = "board-mps2-an386", feature = "board-stm32f407"))]
compile_error!("select one board feature: board-mps2-an386 (default) or board-stm32f407");
#[cfg(not(any(feature = "board-mps2-an386", feature = "board-stm32f407")))]
compile_error!("select a board feature: board-mps2-an386 (default) or board-stm32f407");

mod defmt_frames;
#[cfg(feature = "board-stm32f407")]
mod defmt_rtt;
#[cfg(feature = "board-mps2-an386")]
mod defmt_stderr;
#[cfg(feature = "board-mps2-an386")]
mod mps2_an386;
mod rx;
// The budget image does not probe the temperature sensor.
#[cfg(all(feature = "board-mps2-an386", not(feature = "budget")))]
mod sbcon_i2c;
#[cfg(feature = "board-stm32f407")]
mod stm32f4;

use cortex_m_rt::STACK_PAINT_VALUE;

extern "C" {
    /// Lowest address of the stack region (cortex-m-rt linker script, `link.x`).
    static _stack_end: u32;
    /// Highest address (exclusive) of the stack region.
    static _stack_start: u32;
}

/// Stack high-water mark, bytes: cortex-m-rt (`paint-stack`) fills the stack region with
/// [`STACK_PAINT_VALUE`] at reset; the deepest word that no longer holds it marks the most
/// stack ever used. Scans from the bottom up, so it costs one read per unused word.
pub fn stack_used_bytes() -> u32 {
    // Taking the address of an extern static is safe; nothing is read through it here.
    let bottom = core::ptr::addr_of!(_stack_end) as usize;
    let top = core::ptr::addr_of!(_stack_start) as usize;
    let mut p = bottom;
    while p < top {
        // SAFETY: `p` is 4-aligned (cortex-m-rt asserts both bounds are) and inside the
        // stack region, which is RAM owned by this program; a volatile read of a word that the
        // stack may be using races with nothing (single core, no interrupt writes to it
        // while this runs below the current stack pointer).
        let word = unsafe { core::ptr::read_volatile(p as *const u32) };
        if word != STACK_PAINT_VALUE {
            break;
        }
        p += 4;
    }
    (top - p) as u32
}

/// Executes exactly `2 * iterations` instructions (`subs`, `bne`) for calibrating the
/// instruction counter; `iterations` 0 is taken as 1.
#[cfg_attr(not(feature = "budget"), allow(dead_code))]
#[inline(never)]
pub fn spin(iterations: u32) {
    let n = iterations.max(1);
    // SAFETY: a register-only loop: it touches no memory and no stack, and clobbers only the
    // register it is given (declared) and the flags (not preserved by default).
    unsafe {
        core::arch::asm!(
            "2:",
            "subs {0}, {0}, #1",
            "bne 2b",
            inout(reg) n => _,
            options(nomem, nostack),
        );
    }
}

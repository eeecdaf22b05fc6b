//! Budget rows of the resumable denoiser: `ResumableDenoiser::push` against
//! `BlockDenoiser::push`, side by side on the same samples, with an on-target check that
//! both give the same bits.
#![forbid(unsafe_code)]

use fog_core::denoise::{BlockDenoiser, DenoiseConfig, Push, ResumableDenoiser};

use super::{row, time, Acc, Calibration, Source};
use crate::app::TickCounter;
use crate::pipeline::{self, BLOCK};

/// Blocks pushed through both denoisers (the first two give no resumable output yet).
const BLOCKS: usize = 24;

/// Pushes `BLOCKS` blocks of the budget's gyro model into a `BlockDenoiser` and a
/// `ResumableDenoiser` (paper configuration, `B = BLOCK`), timing every push of each, and
/// prints their mean and max and the number of resumable outputs that differ in any bit
/// from the block denoiser's (0 expected).
pub(super) fn table<C: TickCounter, W: core::fmt::Write>(
    c: &C,
    cal: &Calibration,
    out: &mut W,
) -> core::fmt::Result {
    let (Ok(mut block), Ok(mut res)) = (
        BlockDenoiser::<BLOCK>::new(DenoiseConfig::PAPER),
        ResumableDenoiser::<BLOCK>::new(DenoiseConfig::PAPER),
    ) else {
        return writeln!(out, "resumable denoiser: could not be built");
    };
    let mut source = Source {
        state: 0xD0_15E,
        k: 0,
    };
    // The block denoiser's last two blocks: the resumable one hands out the older.
    let (mut prev, mut last) = ([0.0f32; BLOCK], [0.0f32; BLOCK]);
    let (mut a_block, mut a_res, mut a_res_end) = (Acc::default(), Acc::default(), Acc::default());
    let (mut compared, mut differ) = (0u32, 0u32);
    let mut worst_at = 0usize;
    for k in 0..BLOCKS * BLOCK {
        let rate_dps = f32::from(source.next_counts()) * (pipeline::FULL_SCALE_DPS / 32768.0);
        let (got, t) = time::<super::probe::Resumable, _, _>(c, || res.push(rate_dps));
        if t > a_res.max {
            worst_at = k % BLOCK;
        }
        a_res.add(t);
        if k % BLOCK == BLOCK - 1 {
            a_res_end.add(t);
        }
        if let Ok(Some(v)) = got {
            compared += 1;
            if prev.get(k % BLOCK).map(|w| w.to_bits()) != Some(v.to_bits()) {
                differ += 1;
            }
        }
        let (done, t) = time::<super::probe::Resumable, _, _>(c, || match block.push(rate_dps) {
            Ok(Push::Block(b, _)) => Some(*b),
            _ => None,
        });
        a_block.add(t);
        if let Some(b) = done {
            prev = last;
            last = b;
        }
    }
    writeln!(
        out,
        "resumable denoiser ({BLOCKS} blocks of {BLOCK}, paper config, {} units per push):",
        res.units_per_push()
    )?;
    row(
        out,
        cal,
        "BlockDenoiser::push (same samples)",
        "sample",
        &a_block,
    )?;
    row(out, cal, "ResumableDenoiser::push", "sample", &a_res)?;
    row(
        out,
        cal,
        "  of which block-completing pushes",
        "block",
        &a_res_end,
    )?;
    writeln!(
        out,
        "resumable outputs compared with the block denoiser's: {compared}, differing in any bit: {differ}; late finishes: {}; worst push: sample {worst_at} of its block",
        res.late_finishes()
    )
}

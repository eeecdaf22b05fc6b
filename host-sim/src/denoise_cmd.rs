//! `host-sim denoise`: the fog-core block denoiser over a recorded CSV.
//!
//! # Blocks and the tail rule
//! - Without `--block`, a record whose length is a power of two is denoised as one block.
//! - Otherwise the record is cut into blocks of `--block` samples (default
//!   [`DEFAULT_BLOCK`], the firmware's block), or of the largest power of two that fits
//!   when the record is shorter than that.
//! - **Tail rule**: when the length is not a multiple of the block, the last block is the
//!   last `B` samples of the record (it overlaps the block before it). Samples already
//!   written keep the values of their own block; only the `r` tail samples take the values
//!   of the overlapping block. Every input row gets exactly one output row: nothing is
//!   dropped, nothing is padded with invented data.
//! - A record shorter than the smallest block the levels allow (`8 * 2^levels` samples, 64
//!   for 3 levels) is refused with an error that says so.

use crate::record::{self, ReadOptions, Record};
use crate::record_args::RecordArgs;
use anyhow::{bail, Context, Result};
use fog_core::denoise::{denoise_in_place, DenoiseConfig};
use fog_core::{Sigma, ThresholdRule};
use std::io::Write;
use std::path::PathBuf;

/// Default block length, samples: the firmware's block (5.12 s at 100 Hz).
pub const DEFAULT_BLOCK: usize = 512;

/// Arguments of `host-sim denoise`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Interchange CSV to read (`t_s`, `rate_dps`, optional other columns).
    #[arg(long)]
    pub input: PathBuf,
    /// CSV to write: the input rows with a `denoised_dps` column added.
    #[arg(long)]
    pub output: PathBuf,
    /// The rate column and scale (the denoised rate is in deg/s), the sample rate of a
    /// record without `t_s`.
    #[command(flatten)]
    pub record: RecordArgs,
    /// Decomposition levels (the paper uses 3).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=16))]
    pub levels: u32,
    /// Block length in samples, a power of two; see the tail rule in the docs.
    #[arg(long)]
    pub block: Option<usize>,
    /// Shrinkage rule.
    #[arg(long, value_enum, default_value_t = Rule::Soft)]
    pub rule: Rule,
    /// Noise estimate: `finest` (MAD of the finest details, the default), `per-level`, or a
    /// fixed sigma in deg/s.
    #[arg(long, default_value = "finest", value_parser = parse_sigma)]
    pub sigma: SigmaArg,
}

/// Shrinkage rule on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Rule {
    /// Soft threshold (paper eq. 1).
    Soft,
    /// Hard threshold.
    Hard,
}

/// Sigma choice on the command line.
#[derive(Clone, Copy, Debug)]
pub struct SigmaArg(pub Sigma);

fn parse_sigma(s: &str) -> Result<SigmaArg, String> {
    match s {
        "finest" => Ok(SigmaArg(Sigma::FinestMad)),
        "per-level" => Ok(SigmaArg(Sigma::PerLevelMad)),
        v => match v.parse::<f32>() {
            Ok(x) if x.is_finite() && x >= 0.0 => Ok(SigmaArg(Sigma::Fixed(x))),
            _ => Err(format!(
                "expected `finest`, `per-level` or a sigma >= 0 in deg/s, got {v:?}"
            )),
        },
    }
}

/// One block: denoise `input[start..start + len]`, write its values from `keep_from` on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Block {
    /// First sample of the block.
    pub start: usize,
    /// Block length (a power of two).
    pub len: usize,
    /// Offset inside the block of the first value that goes to the output.
    pub keep_from: usize,
}

/// The block plan for a record of `n` samples (see the module docs).
pub fn plan(n: usize, block: Option<usize>, levels: u32) -> Result<Vec<Block>> {
    let min = 8usize << levels;
    let b = match block {
        None if n.is_power_of_two() => n,
        Some(b) if !b.is_power_of_two() => bail!("--block {b} is not a power of two"),
        Some(b) if b < min => {
            bail!("--block {b} is too short for {levels} levels (need at least {min})")
        }
        Some(b) => b,
        None => DEFAULT_BLOCK,
    };
    let b = if n < b {
        1usize << (usize::BITS - 1 - n.leading_zeros())
    } else {
        b
    };
    if n < min || b < min {
        bail!("record has {n} samples; {levels} levels need at least {min}");
    }
    let mut out: Vec<Block> = (0..n / b)
        .map(|k| Block {
            start: k * b,
            len: b,
            keep_from: 0,
        })
        .collect();
    let tail = n % b;
    if tail > 0 {
        out.push(Block {
            start: n - b,
            len: b,
            keep_from: b - tail,
        });
    }
    Ok(out)
}

/// Denoises `rate_dps` block by block following `blocks` (from [`plan`]); returns the
/// denoised samples and the sum of the finest-level sigmas of the blocks. On error, the
/// failing block's first sample index and the error.
pub fn denoise_blocks(
    rate_dps: &[f32],
    blocks: &[Block],
    cfg: &DenoiseConfig,
) -> Result<(Vec<f32>, f64), (usize, fog_core::DenoiseError)> {
    let mut denoised = vec![0.0f32; rate_dps.len()];
    let mut buf = Vec::new();
    let mut scratch = Vec::new();
    let mut sigma_sum = 0.0f64;
    for b in blocks {
        buf.clear();
        buf.extend_from_slice(&rate_dps[b.start..b.start + b.len]);
        scratch.resize(b.len, 0.0);
        let t = denoise_in_place(&mut buf, &mut scratch, cfg).map_err(|e| (b.start, e))?;
        sigma_sum += f64::from(t.sigma[0]);
        denoised[b.start + b.keep_from..b.start + b.len].copy_from_slice(&buf[b.keep_from..]);
    }
    Ok((denoised, sigma_sum))
}

/// Runs the command.
pub fn run(args: &Args) -> Result<()> {
    record::refuse_overwrite(&args.input, &args.output)?;
    let opts = ReadOptions {
        optional_columns: false,
        keep_rows: true,
        ..args.record.options()
    };
    let rec = Record::read(&args.input, &opts)?;
    let rate: Vec<f32> = rec.rate_dps.iter().map(|&x| x as f32).collect();
    let n = rate.len();
    let blocks =
        plan(n, args.block, args.levels).with_context(|| args.input.display().to_string())?;
    let cfg = DenoiseConfig {
        levels: args.levels,
        rule: match args.rule {
            Rule::Soft => ThresholdRule::Soft,
            Rule::Hard => ThresholdRule::Hard,
        },
        sigma: args.sigma.0,
    };
    let (denoised, sigma_sum) = denoise_blocks(&rate, &blocks, &cfg).map_err(|(start, e)| {
        anyhow::anyhow!("{}: block at line {}: {e}", args.input.display(), start + 2)
    })?;
    let out_path = &args.output;
    record::write_atomic(out_path, |w| {
        let mut wtr = csv::Writer::from_writer(w);
        let mut header = rec.header.clone();
        header.push_field("denoised_dps");
        wtr.write_record(&header)?;
        for (row, d) in rec.rows.iter().zip(&denoised) {
            let mut r = row.clone();
            r.push_field(&d.to_string());
            wtr.write_record(&r)?;
        }
        wtr.flush()?;
        Ok(())
    })?;
    let holes = rec.holes();
    let mut err = std::io::stderr().lock();
    writeln!(
        err,
        "{}: {n} samples denoised in {} block(s) of {} ({} levels, mean finest sigma {:.6} deg/s) -> {}",
        args.input.display(),
        blocks.len(),
        blocks[0].len,
        args.levels,
        sigma_sum / blocks.len() as f64,
        out_path.display()
    )?;
    if let Some(w) = holes.warning(
        &args.input.display().to_string(),
        "samples are denoised as if evenly spaced, none dropped or interpolated",
    ) {
        writeln!(err, "{w}")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plan_covers_every_sample_once() {
        for n in [64usize, 100, 511, 512, 513, 1000, 1024, 5000] {
            let p = plan(n, None, 3).expect("valid");
            let mut covered = vec![0u32; n];
            for b in &p {
                assert!(b.len.is_power_of_two());
                for c in &mut covered[b.start + b.keep_from..b.start + b.len] {
                    *c += 1;
                }
            }
            assert!(covered.iter().all(|&c| c == 1), "n = {n}: {p:?}");
        }
        assert_eq!(plan(1024, None, 3).expect("valid").len(), 1);
        assert!(plan(63, None, 3).is_err());
        assert!(plan(1000, Some(100), 3).is_err());
        assert!(plan(1000, Some(32), 3).is_err());
    }
}

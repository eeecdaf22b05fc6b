//! The record the motion replay reads: an interchange CSV (any rate column, scaled; `t_s`
//! optional), or a binary / ASCII capture decoded whole, with the truth columns when the
//! record carries them.

use super::stream::{self, Decoded, InputFormat, Options};
use crate::identify::series::Series;
use crate::nav::NavRecord;
use crate::record::{ReadOptions, Record};
use crate::report::BytesSummary;
use anyhow::{anyhow, bail, Result};
use std::path::Path;

/// A record read for the motion replay.
#[derive(Debug, Clone)]
pub struct Input {
    /// What the estimator runs on.
    pub record: Series,
    /// The truth, when the record has both `true_rate_dps` and `drift_dps` (`moving`
    /// optional: without it every sample counts as still).
    pub truth: Option<NavRecord>,
    /// The truth has a `moving` column (else every sample counts as still).
    pub has_moving: bool,
    /// Format read.
    pub format: InputFormat,
    /// Where `t_s` came from.
    pub t_s_source: &'static str,
    /// `t_s` is `row index / rate_hz` (no time stamps in the input): the rate is the
    /// caller's, not the record's.
    pub t_s_from_rate: bool,
    /// Byte counts of a capture.
    pub bytes: Option<BytesSummary>,
    /// DSP-3000 fault lines (no sample, no output row).
    pub fault_lines: u64,
}

/// Reads `path`: CSV (see [`read_csv`], with `csv`'s rate column, scale and still column)
/// or a capture decoded with `opts`.
pub fn read(path: &Path, opts: &Options, csv: &ReadOptions) -> Result<Input> {
    let is_csv = match opts.format {
        InputFormat::Csv => true,
        InputFormat::Auto => {
            let mut head = vec![0u8; 8192];
            let n = {
                use std::io::Read;
                let mut f = std::fs::File::open(path)
                    .map_err(|e| anyhow!("{}: cannot open: {e}", path.display()))?;
                f.read(&mut head)
                    .map_err(|e| anyhow!("{}: read failed at byte 0: {e}", path.display()))?
            };
            stream::sniff(&path.display().to_string(), &head[..n])? == InputFormat::Csv
        }
        _ => false,
    };
    if is_csv {
        return read_csv(
            path,
            &ReadOptions {
                rate_hz: Some(opts.rate_hz),
                ..csv.clone()
            },
        );
    }
    if csv.still_column.is_some() {
        bail!("--still-column needs CSV input");
    }
    let Decoded {
        format,
        t_s,
        rate_dps,
        fault_lines,
        bytes,
    } = stream::decode(path, opts)?;
    if rate_dps.is_empty() {
        bail!("{}: no sample decoded", path.display());
    }
    Ok(Input {
        record: Series {
            name: path.display().to_string(),
            t_s,
            rate_dps,
            ..Series::default()
        },
        truth: None,
        has_moving: false,
        format,
        t_s_source: "index / rate_hz (no time stamps in the capture)",
        t_s_from_rate: true,
        bytes,
        fault_lines,
    })
}

/// Reads an interchange CSV with [`Record::read`] (`opts.rate_hz` gives `t_s` when the file
/// has no `t_s` column); the truth when the record has `true_rate_dps` and `drift_dps`.
pub fn read_csv(path: &Path, opts: &ReadOptions) -> Result<Input> {
    let r = Record::read(path, opts)?;
    Ok(Input {
        record: (&r).into(),
        truth: NavRecord::try_from(&r).ok(),
        has_moving: r.moving.is_some(),
        format: InputFormat::Csv,
        t_s_source: if r.t_s_from_rate {
            "row index / rate_hz (the CSV has no t_s column)"
        } else {
            "the CSV's t_s column"
        },
        t_s_from_rate: r.t_s_from_rate,
        bytes: None,
        fault_lines: 0,
    })
}

//! The record options every subcommand that reads an interchange CSV takes, the same
//! everywhere: they fill [`ReadOptions`] for [`crate::record::Record::read`]; and the JSON
//! form of the gaps the reader finds in `t_s` ([`HolesSummary`]; `record.rs` itself is
//! compiled into a fuzz target without serde).

use crate::record::{self, Holes, ReadOptions};
use serde::Serialize;

/// How a record's CSV is read: the rate column and its unit, and the sample rate of a
/// record without `t_s`.
#[derive(clap::Args, Debug, Clone, PartialEq)]
pub struct RecordArgs {
    /// The rate column (e.g. `gz_dps` of a multi-axis recording, `dtheta_x_deg` of the KVH
    /// log).
    #[arg(long, default_value = "rate_dps")]
    pub rate_column: String,
    /// Factor from the rate column's unit to deg/s (e.g. 57.29578 for rad/s, 1000 for angle
    /// increments in deg per 1-ms sample, -1 for an axis mounted the other way round).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub rate_scale: f64,
    /// Sample rate, Hz, of a CSV without a `t_s` column (`t_s = row index / rate_hz`;
    /// without it such a CSV is refused).
    // A command that reads more than CSV says so in its own help (`REPLAY_RATE_HZ_HELP`).
    #[arg(long)]
    pub rate_hz: Option<f64>,
}

/// `replay`'s help of `--rate-hz` (`replay` also reads captures, which have no time stamps).
pub const REPLAY_RATE_HZ_HELP: &str = "Sample rate, Hz, of a record without time stamps: a CSV without a `t_s` column (`t_s = row index / rate_hz`; without it such a CSV is refused unless --sensor gives the rate) and binary and ASCII captures (default: the sensor's)";

impl Default for RecordArgs {
    fn default() -> Self {
        Self {
            rate_column: "rate_dps".into(),
            rate_scale: 1.0,
            rate_hz: None,
        }
    }
}

impl RecordArgs {
    /// The reader's options (every other option at its default).
    pub fn options(&self) -> ReadOptions {
        ReadOptions {
            rate_hz: self.rate_hz,
            ..ReadOptions::rate(&self.rate_column, self.rate_scale)
        }
    }
}

/// The gaps in a record's `t_s` ([`Holes`]: the rule, the nominal period and the rate) as
/// `identify` and `replay` write them in their JSON.
#[derive(Debug, Clone, Serialize)]
pub struct HolesSummary {
    /// The record.
    pub record: String,
    /// The rule, in words.
    pub rule: String,
    /// The nominal period: the median step of `t_s`, s.
    pub median_step_s: f64,
    /// Gaps.
    pub count: u64,
    /// So many gaps that the stamps are irregular, not a stream with holes.
    pub irregular: bool,
    /// `t_s` of the last sample before the largest gap, s.
    pub largest_start_t_s: Option<f64>,
    /// Its line (header = 1).
    pub largest_start_line: Option<u64>,
    /// Line of the first sample after it.
    pub largest_end_line: Option<u64>,
    /// Its length (the step), s.
    pub largest_s: Option<f64>,
    /// Samples missing in all the gaps.
    pub samples_missing: u64,
    /// The sample rate from `t_s` ([`Holes::period_s`]), Hz.
    pub rate_hz: f64,
}

impl HolesSummary {
    /// `h`, found in `record`.
    pub fn new(record: &str, h: &Holes) -> Self {
        let g = h.largest;
        Self {
            record: record.to_string(),
            rule: format!(
                "a gap is a step over {}x the median step; the rate is the mean of the other steps (of every step when over {} % of them are gaps)",
                record::GAP_FACTOR,
                100.0 * record::RARE_GAPS
            ),
            median_step_s: h.nominal_step_s,
            count: h.count,
            irregular: h.irregular(),
            largest_start_t_s: g.map(|g| g.t_s),
            largest_start_line: g.map(|g| g.start_line),
            largest_end_line: g.map(|g| g.line),
            largest_s: g.map(|g| g.dt_s),
            samples_missing: h.samples_missing,
            rate_hz: 1.0 / h.period_s(),
        }
    }
}

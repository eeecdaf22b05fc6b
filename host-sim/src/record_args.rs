//! The record options every subcommand that reads an interchange CSV takes, the same
//! everywhere: they fill [`ReadOptions`] for [`crate::record::Record::read`].

use crate::record::ReadOptions;

/// How a record's CSV is read: the rate column and its unit, and the sample rate of a
/// record without `t_s`.
#[derive(clap::Args, Debug, Clone, PartialEq)]
pub struct RecordArgs {
    /// The rate column (e.g. `gz_dps` of a multi-axis recording, `dtheta_x_deg` of the KVH
    /// log).
    #[arg(long, default_value = "rate_dps")]
    pub rate_column: String,
    /// Factor from the rate column's unit to deg/s (e.g. 57.29578 for rad/s, 1000 for angle
    /// increments in deg per 1-ms sample).
    #[arg(long, default_value_t = 1.0)]
    pub rate_scale: f64,
    /// Sample rate, Hz, of a record without time stamps: a CSV without `t_s` (`t_s = row
    /// index / rate_hz`; without it such a CSV is refused) and, for `replay`, binary and
    /// ASCII captures (default there: the sensor's).
    #[arg(long)]
    pub rate_hz: Option<f64>,
}

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

//! A record with its ground truth, for scoring: from the simulator's samples or from a
//! [`Record`] read from a CSV.

use crate::record::Record;
use anyhow::Result;

/// Columns of a scored record (one entry per sample).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct NavRecord {
    /// Time since power-on, s.
    pub t_s: Vec<f64>,
    /// Measured rate, deg/s.
    pub rate_dps: Vec<f64>,
    /// Sensor temperature, deg C (None when the record has no `temp_c` column).
    pub temp_c: Option<Vec<f64>>,
    /// True platform + Earth rate, deg/s.
    pub true_rate_dps: Vec<f64>,
    /// True drift, deg/s.
    pub drift_dps: Vec<f64>,
    /// Ground truth: the platform moves (all false when the record has no `moving` column,
    /// e.g. a static calibration record).
    pub moving: Vec<bool>,
}

impl NavRecord {
    /// Samples.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// True when there is no sample.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }

    /// The truth still flags (`!moving`).
    pub fn still_truth(&self) -> Vec<bool> {
        self.moving.iter().map(|m| !m).collect()
    }

    /// From simulator samples.
    pub fn from_samples(samples: &[crate::sim::Sample]) -> Self {
        Self {
            t_s: samples.iter().map(|s| s.t_s).collect(),
            rate_dps: samples.iter().map(|s| s.rate_dps).collect(),
            temp_c: Some(samples.iter().map(|s| s.temp_c).collect()),
            true_rate_dps: samples.iter().map(|s| s.true_rate_dps).collect(),
            drift_dps: samples.iter().map(|s| s.drift_dps).collect(),
            moving: samples.iter().map(|s| s.moving).collect(),
        }
    }
}

impl TryFrom<&Record> for NavRecord {
    type Error = anyhow::Error;

    /// The scored shape of a record read with [`crate::record::Record::read`]: refused,
    /// naming the file and its header, without `true_rate_dps` or `drift_dps`; without
    /// `moving` every sample counts as still.
    fn try_from(r: &Record) -> Result<Self> {
        let need = |v: &Option<Vec<f64>>, c: &str| v.clone().ok_or_else(|| r.missing(c));
        Ok(Self {
            t_s: r.t_s.clone(),
            rate_dps: r.rate_dps.clone(),
            temp_c: r.temp_c.clone(),
            true_rate_dps: need(&r.true_rate_dps, "true_rate_dps")?,
            drift_dps: need(&r.drift_dps, "drift_dps")?,
            moving: r.moving.clone().unwrap_or_else(|| vec![false; r.len()]),
        })
    }
}

//! One record as columns, and where records come from (files or the simulator).

use crate::record::{ReadOptions, Record};
use anyhow::{bail, Context, Result};
use std::path::PathBuf;

/// A record's columns in single precision, as the estimator and the trainers read them
/// (from a [`Record`], or from the simulator). `drift_dps` and `true_rate_dps` are the
/// ground truth, present in simulated records.
#[derive(Debug, Clone, Default)]
pub struct Series {
    /// Where it came from (file path or simulator seed), for messages.
    pub name: String,
    /// Seconds since the start.
    pub t_s: Vec<f64>,
    /// Measured rate, deg/s.
    pub rate_dps: Vec<f32>,
    /// True drift, deg/s, when the record carries it.
    pub drift_dps: Option<Vec<f32>>,
    /// Sensor temperature, deg C, when the record carries it (column `temp_c`, optional).
    pub temp_c: Option<Vec<f32>>,
    /// External still flag per row (`--still-column`): `None` where the cell is empty.
    pub still: Option<Vec<Option<bool>>>,
    /// True rate, deg/s (`true_rate_dps`, simulator records).
    pub true_rate_dps: Option<Vec<f32>>,
}

impl Series {
    /// Sample period ([`crate::record::Holes::period_s`]): the mean step of `t_s` with its
    /// gaps (steps over 1.5x the median) left out, so a hole does not move it; the mean of
    /// every step when the stamps are irregular (host arrival times in bursts, the MPU6050
    /// set: median step 2 ms, mean 10 ms, where only the mean gives the sensor's rate). 1 s
    /// for a one-sample record.
    pub fn sample_period_s(&self) -> f64 {
        crate::record::period_s(&self.t_s)
    }
}

impl From<&Record> for Series {
    /// The columns the estimator and the trainers read, in single precision.
    fn from(r: &Record) -> Self {
        let single = |v: &Vec<f64>| v.iter().map(|&x| x as f32).collect();
        Self {
            name: r.name.clone(),
            t_s: r.t_s.clone(),
            rate_dps: single(&r.rate_dps),
            drift_dps: r.drift_dps.as_ref().map(single),
            temp_c: r.temp_c.as_ref().map(single),
            still: r.still.clone(),
            true_rate_dps: r.true_rate_dps.as_ref().map(single),
        }
    }
}

/// A list of records read one at a time (so that memory holds one record, not the set).
pub trait Records {
    /// Number of records.
    fn len(&self) -> usize;
    /// Record `i`.
    fn get(&self, i: usize) -> Result<Series>;
    /// True when there is no record.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// CSV files given on the command line: files, or folders whose `*.csv` (and `*.csv.gz`)
/// files are taken in name order, each read with the options given.
pub struct CsvFiles(pub Vec<PathBuf>, pub ReadOptions);

impl CsvFiles {
    /// Expands folders; refuses a path that does not exist or a set with no file.
    pub fn from_args(paths: &[PathBuf], opts: &ReadOptions) -> Result<Self> {
        let mut out = Vec::new();
        for p in paths {
            if p.is_dir() {
                let mut v: Vec<PathBuf> = std::fs::read_dir(p)
                    .with_context(|| format!("{}: cannot list", p.display()))?
                    .filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|q| {
                        let n = q.to_string_lossy();
                        n.ends_with(".csv") || n.ends_with(".csv.gz")
                    })
                    .collect();
                v.sort();
                if v.is_empty() {
                    bail!("{}: no .csv file in this folder", p.display());
                }
                out.extend(v);
            } else if p.is_file() {
                out.push(p.clone());
            } else {
                bail!("{}: no such file or folder", p.display());
            }
        }
        if out.is_empty() {
            bail!("no record given");
        }
        Ok(Self(out, opts.clone()))
    }
}

impl Records for CsvFiles {
    fn len(&self) -> usize {
        self.0.len()
    }
    fn get(&self, i: usize) -> Result<Series> {
        Ok((&Record::read(&self.0[i], &self.1)?).into())
    }
}

//! One record as columns, and where records come from (files or the simulator).

use crate::record::parse_field;
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};

/// A record's columns. `drift_dps` is the ground truth, present in simulated records.
#[derive(Debug, Clone)]
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
}

impl Series {
    /// Sample period: the mean step of `t_s`, `(t_last - t_first) / (n - 1)` (1 s for a
    /// one-sample record). The mean, not the median: some real recordings carry host arrival
    /// times in bursts (the MPU6050 set: median step 2 ms, mean 10 ms), where only the mean
    /// gives the sensor's rate; a gap lengthens it by the gap's share of the record.
    pub fn sample_period_s(&self) -> f64 {
        match (self.t_s.first(), self.t_s.last()) {
            (Some(a), Some(b)) if self.t_s.len() > 1 && b > a => {
                (b - a) / (self.t_s.len() - 1) as f64
            }
            _ => 1.0,
        }
    }

    /// Reads an interchange CSV (`t_s`, `rate_dps`, optional `drift_dps` and `temp_c`), with the same
    /// checks and messages as every host-sim reader.
    pub fn read_csv(path: &Path) -> Result<Self> {
        Self::read_csv_column(path, "rate_dps")
    }

    /// [`Series::read_csv`] taking the rate from column `rate_column` (e.g. `gz_dps` of a
    /// multi-axis recording); a `.gz` file is decompressed on the fly.
    pub fn read_csv_column(path: &Path, rate_column: &str) -> Result<Self> {
        Self::from_reader(path, crate::record::open_maybe_gz(path)?, rate_column)
    }

    /// [`Series::read_csv_column`] from any (already decompressed) reader; `path` only names
    /// the input in messages (the fuzz target `fuzz/fuzz_targets/csv_record.rs` feeds it
    /// arbitrary bytes).
    pub fn from_reader<R: std::io::Read>(path: &Path, input: R, rate_column: &str) -> Result<Self> {
        let name = path.display().to_string();
        let (mut rdr, header) = crate::record::csv_with_header(&name, input)?;
        let col = |want: &str| header.iter().position(|h| h.trim() == want);
        let (Some(tc), Some(rc)) = (col("t_s"), col(rate_column)) else {
            bail!(
                "{name}:1: needs columns `t_s` and `{rate_column}` (the header has: {})",
                header.iter().collect::<Vec<_>>().join(", ")
            );
        };
        let dc = col("drift_dps");
        let tc_c = col("temp_c");
        let mut s = Series {
            name: name.clone(),
            t_s: Vec::new(),
            rate_dps: Vec::new(),
            drift_dps: dc.map(|_| Vec::new()),
            temp_c: tc_c.map(|_| Vec::new()),
        };
        for rec in rdr.records() {
            let rec = rec.map_err(|e| {
                anyhow::anyhow!("{name}:{}: {e}", e.position().map_or(0, |p| p.line()))
            })?;
            let line = rec.position().map_or(0, |p| p.line());
            let t: f64 = parse_field(&rec, tc, "t_s", path, line)?;
            if s.t_s.last().is_some_and(|&p| t <= p) {
                bail!("{name}:{line}: t_s = {t} does not increase");
            }
            s.t_s.push(t);
            s.rate_dps
                .push(parse_field(&rec, rc, "rate_dps", path, line)?);
            if let (Some(c), Some(v)) = (dc, s.drift_dps.as_mut()) {
                v.push(parse_field(&rec, c, "drift_dps", path, line)?);
            }
            if let (Some(c), Some(v)) = (tc_c, s.temp_c.as_mut()) {
                v.push(parse_field(&rec, c, "temp_c", path, line)?);
            }
        }
        if s.t_s.is_empty() {
            bail!("{name}: no data rows");
        }
        Ok(s)
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
/// files are taken in name order; the rate is read from `rate_column`.
pub struct CsvFiles(pub Vec<PathBuf>, pub String);

impl CsvFiles {
    /// Expands folders; refuses a path that does not exist or a set with no file.
    pub fn from_args(paths: &[PathBuf], rate_column: &str) -> Result<Self> {
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
        Ok(Self(out, rate_column.to_string()))
    }
}

impl Records for CsvFiles {
    fn len(&self) -> usize {
        self.0.len()
    }
    fn get(&self, i: usize) -> Result<Series> {
        Series::read_csv_column(&self.0[i], &self.1)
    }
}

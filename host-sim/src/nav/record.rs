//! A record with its ground truth, read from the simulators' CSV.

use anyhow::{anyhow, bail, Context, Result};
use std::path::Path;

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

    /// Reads a CSV with the columns `t_s`, `rate_dps`, `true_rate_dps`, `drift_dps`, and
    /// optionally `temp_c` and `moving` (0/1), in any order (both simulators' output).
    /// Errors name the file and the line.
    pub fn read(path: &Path) -> Result<Self> {
        let name = path.display().to_string();
        let file = std::fs::File::open(path).with_context(|| format!("{name}: cannot open"))?;
        let mut rdr = csv::Reader::from_reader(std::io::BufReader::new(file));
        let header = rdr.headers().map_err(|e| anyhow!("{name}:1: {e}"))?.clone();
        let col = |w: &str| header.iter().position(|h| h.trim() == w);
        let need = |w: &str| col(w).ok_or_else(|| anyhow!("{name}:1: missing column `{w}`"));
        let (tc, rc, vc, dc) = (
            need("t_s")?,
            need("rate_dps")?,
            need("true_rate_dps")?,
            need("drift_dps")?,
        );
        let (cc, mc) = (col("temp_c"), col("moving"));
        let mut rec = Self {
            temp_c: cc.map(|_| Vec::new()),
            ..Self::default()
        };
        for (i, row) in rdr.records().enumerate() {
            let line = i + 2;
            let row = row.map_err(|e| anyhow!("{name}:{line}: {e}"))?;
            let num = |c: usize| -> Result<f64> {
                let f = row.get(c).unwrap_or("").trim();
                match f.parse::<f64>() {
                    Ok(v) if v.is_finite() => Ok(v),
                    _ => bail!(
                        "{name}:{line}: `{}` = `{f}`: not a finite number",
                        &header[c]
                    ),
                }
            };
            rec.t_s.push(num(tc)?);
            rec.rate_dps.push(num(rc)?);
            rec.true_rate_dps.push(num(vc)?);
            rec.drift_dps.push(num(dc)?);
            if let (Some(c), Some(v)) = (cc, rec.temp_c.as_mut()) {
                v.push(num(c)?);
            }
            rec.moving
                .push(match mc.map(|c| row.get(c).unwrap_or("").trim()) {
                    None | Some("0") => false,
                    Some("1") => true,
                    Some(f) => bail!("{name}:{line}: `moving` = `{f}`: must be 0 or 1"),
                });
        }
        Ok(rec)
    }
}

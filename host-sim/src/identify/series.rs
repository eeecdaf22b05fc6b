//! One record as columns, and where records come from (files or the simulator).

use crate::record::{Holes, ReadOptions, Record};
use crate::record_args::HolesSummary;
use anyhow::{bail, Context, Result};
use std::cell::RefCell;
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
    /// The gaps in `t_s` found by the read that loaded it ([`Record::holes`]: file lines
    /// named); `None` for a series not read from a file (the simulator's).
    pub holes: Option<Holes>,
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
            holes: Some(r.holes()),
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

/// A record's name (its path) and the gaps in its `t_s`.
pub type RecordHoles = (String, Holes);

/// CSV files given on the command line: files, or folders whose `*.csv` (and `*.csv.gz`)
/// files are taken in name order, each read with the options given. Each read keeps the
/// record's gaps in `t_s` ([`Series::holes`]), so that [`CsvFiles::holes`] reports them
/// without reading the files again.
pub struct CsvFiles(
    pub Vec<PathBuf>,
    pub ReadOptions,
    RefCell<Vec<Option<Holes>>>,
);

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
        let seen = RefCell::new(vec![None; out.len()]);
        Ok(Self(out, opts.clone(), seen))
    }

    /// Every record's name and gaps in `t_s`, as found by the first read of it through
    /// [`Records::get`] (a record not read yet is read now).
    pub fn holes(&self) -> Result<Vec<RecordHoles>> {
        (0..self.0.len())
            .map(|i| {
                let seen = self.2.borrow().get(i).copied().flatten();
                let h = match seen {
                    Some(h) => h,
                    None => Record::read(&self.0[i], &self.1)?.holes(),
                };
                Ok((self.0[i].display().to_string(), h))
            })
            .collect()
    }
}

impl Records for CsvFiles {
    fn len(&self) -> usize {
        self.0.len()
    }
    fn get(&self, i: usize) -> Result<Series> {
        let s: Series = (&Record::read(&self.0[i], &self.1)?).into();
        if let Some(slot) = self.2.borrow_mut().get_mut(i) {
            if slot.is_none() {
                *slot = s.holes;
            }
        }
        Ok(s)
    }
}

/// Prints one line on stderr for each record with gaps in its `t_s` ([`Holes::warning`]:
/// count, the largest one's start (time, line) and length, the samples missing, the rate
/// from the steps that are not gaps) and what identify does with them; returns every
/// record's for the JSON. A record with gaps is used as it is, none of its samples dropped
/// or interpolated: the identifier and the bench fits take the samples as evenly spaced at
/// that rate, so after a gap their time since power-on is behind `t_s` by the gap's length
/// (said in the line).
pub fn report_holes(records: &[RecordHoles]) -> Vec<HolesSummary> {
    records
        .iter()
        .map(|(name, h)| {
            let how = if h.irregular() {
                "identify takes the samples as evenly spaced at that rate (the identifier and the bench fits assume uniform sampling), none dropped or interpolated".to_string()
            } else {
                format!(
                    "the identifier and the bench fits assume uniform sampling: identify takes the samples as evenly spaced at that rate, none dropped or interpolated, so after the gaps their time since power-on runs {:.3} s behind t_s and the window across the largest joins samples {} s apart (split the record at the gap if that matters)",
                    h.behind_s(),
                    h.largest.map_or(0.0, |g| (g.dt_s * 1e6).round() / 1e6)
                )
            };
            if let Some(w) = h.warning(name, &how) {
                eprintln!("{w}");
            }
            HolesSummary::new(name, h)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The holes come from the read that loaded the record: once read through
    /// [`Records::get`], the file is not read again (here it is gone).
    #[test]
    fn holes_come_from_the_read_that_loaded_the_record() {
        let dir = tempfile::tempdir().expect("tmp");
        let p = dir.path().join("hole.csv");
        let mut text = String::from("t_s,rate_dps\n");
        for k in (0..100).filter(|k| !(40..50).contains(k)) {
            text += &format!("{:.2},0.001\n", f64::from(k) * 0.01);
        }
        std::fs::write(&p, text).expect("write");
        let files =
            CsvFiles::from_args(std::slice::from_ref(&p), &ReadOptions::default()).expect("files");
        let s = files.get(0).expect("read");
        let h = s.holes.expect("read from a file");
        assert_eq!((h.count, h.samples_missing), (1, 10));
        assert_eq!(h.largest.map(|g| (g.start_line, g.line)), Some((41, 42)));
        std::fs::remove_file(&p).expect("remove");
        let got = files.holes().expect("no second read");
        assert_eq!(got, vec![(p.display().to_string(), h)]);
        // A record not read yet is read for its holes.
        let q = dir.path().join("unread.csv");
        std::fs::write(&q, "t_s,rate_dps\n0,0\n0.01,0\n").expect("write");
        let unread =
            CsvFiles::from_args(std::slice::from_ref(&q), &ReadOptions::default()).expect("f");
        assert_eq!(unread.holes().expect("read")[0].1.count, 0);
    }
}

//! The record the motion replay reads, sample by sample in bounded memory: an interchange
//! CSV ([`record::Rows`]: any rate column, scaled; `t_s` optional; the truth and the
//! external still flag when the file has them) or a binary / ASCII capture
//! ([`stream::Capture`]).
//!
//! The sample rate must be known before the estimator starts (the built-in sensor is picked
//! by it and the image's rate is checked against it), so the first [`LOOKAHEAD`] samples
//! are read ahead. Their median step is the nominal period against which every step of the
//! record is checked for gaps ([`record::HoleFinder`], the rule of [`record::Holes`]: steps
//! over 1.5x the median), and the rate is the look-ahead's mean step with the gaps left
//! out, so a hole does not move it; on a record no longer than that it is the whole
//! record's. At the end the whole record's is known ([`Input::sample_period_s`]) and the
//! caller checks it again; [`Input::holes`] gives the gaps for the report.

use super::stream::{self, Capture, CaptureEvent, InputFormat, Options};
use crate::record::{self, Present, ReadOptions};
use crate::report::BytesSummary;
use anyhow::{bail, Result};
use std::collections::VecDeque;
use std::path::Path;

/// Samples read ahead for the rate: 2^16 (11 min at 100 Hz, 65 s at 1 kHz; about 5 MB).
pub const LOOKAHEAD: usize = 1 << 16;

/// One sample of a record, as in the file (rate times the scale).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Line in the CSV (header = 1); for a capture, the sample's number from 1.
    pub line: u64,
    /// Seconds since the start.
    pub t_s: f64,
    /// Rate, deg/s.
    pub rate_dps: f64,
    /// `temp_c`, deg C.
    pub temp_c: Option<f64>,
    /// `drift_dps` (true drift), deg/s.
    pub drift_dps: Option<f64>,
    /// The reference (true) rate, deg/s.
    pub true_rate_dps: Option<f64>,
    /// `moving` (ground truth).
    pub moving: Option<bool>,
    /// The external still flag (`None`: no column or an empty cell).
    pub still: Option<bool>,
}

enum Source {
    Csv(Box<record::Rows<Box<dyn std::io::Read>>>),
    Capture(Box<Capture>),
}

/// A record opened for the motion replay.
pub struct Input {
    name: String,
    source: Source,
    ahead: VecDeque<Sample>,
    ended: bool,
    /// Format read.
    pub format: InputFormat,
    /// Columns present (none for a capture).
    pub columns: Present,
    /// Where `t_s` comes from.
    pub t_s_source: &'static str,
    /// `t_s` is `row index / rate_hz` (no time stamps in the input): the rate is the
    /// caller's, not the record's.
    pub t_s_from_rate: bool,
    fault_lines: u64,
    read: u64,
    first_t: Option<f64>,
    last_t: Option<f64>,
    /// The gaps in `t_s`, from the end of the look-ahead on (it fixes the nominal period).
    holes: Option<record::HoleFinder>,
}

impl Input {
    /// Opens `path`: CSV (with `csv`'s rate column, scale, still column and, without a
    /// `t_s` column, `opts.rate_hz`) or a capture decoded with `opts`.
    pub fn open(path: &Path, opts: &Options, csv: &ReadOptions) -> Result<Self> {
        let is_csv = stream::detect_format(path, opts.format)? == InputFormat::Csv;
        if is_csv {
            let o = ReadOptions {
                rate_hz: Some(opts.rate_hz),
                ..csv.clone()
            };
            let rows = record::Rows::new(
                &path.display().to_string(),
                record::open_maybe_gz(path)?,
                &o,
            )?;
            let columns = rows.columns();
            return Ok(Self::new(
                path,
                Source::Csv(Box::new(rows)),
                InputFormat::Csv,
                columns,
            ));
        }
        if csv.still_column.is_some() {
            bail!("--still-column needs CSV input");
        }
        let cap = Capture::open(path, opts)?;
        let format = cap.format();
        Ok(Self::new(
            path,
            Source::Capture(Box::new(cap)),
            format,
            Present::default(),
        ))
    }

    fn new(path: &Path, source: Source, format: InputFormat, columns: Present) -> Self {
        let (csv, from_rate) = (format == InputFormat::Csv, !columns.t_s);
        Self {
            name: path.display().to_string(),
            source,
            ahead: VecDeque::new(),
            ended: false,
            format,
            columns,
            t_s_source: match (csv, from_rate) {
                (true, true) => "row index / rate_hz (the CSV has no t_s column)",
                (true, false) => "the CSV's t_s column",
                _ => "index / rate_hz (no time stamps in the capture)",
            },
            t_s_from_rate: from_rate,
            fault_lines: 0,
            read: 0,
            first_t: None,
            last_t: None,
            holes: None,
        }
    }

    /// Reads the next sample from the file (skipping fault lines, counted).
    fn read_one(&mut self) -> Result<Option<Sample>> {
        if self.ended {
            return Ok(None);
        }
        let s = loop {
            let next = match &mut self.source {
                Source::Csv(rows) => rows.next_row()?.map(|r| Sample {
                    line: r.line,
                    t_s: r.t_s,
                    rate_dps: r.rate_dps,
                    temp_c: r.temp_c,
                    drift_dps: r.drift_dps,
                    true_rate_dps: r.true_rate_dps,
                    moving: r.moving,
                    still: r.still.flatten(),
                }),
                Source::Capture(c) => match c.next_event()? {
                    None => None,
                    Some(CaptureEvent::Fault) => {
                        self.fault_lines += 1;
                        continue;
                    }
                    Some(CaptureEvent::Sample { t_s, rate_dps }) => Some(Sample {
                        line: self.read + 1,
                        t_s,
                        rate_dps: f64::from(rate_dps),
                        temp_c: None,
                        drift_dps: None,
                        true_rate_dps: None,
                        moving: None,
                        still: None,
                    }),
                },
            };
            break next;
        };
        match s {
            Some(s) => {
                self.read += 1;
                self.first_t.get_or_insert(s.t_s);
                self.last_t = Some(s.t_s);
                if let Some(h) = self.holes.as_mut() {
                    h.push(s.t_s, s.line);
                }
            }
            None => self.ended = true,
        }
        Ok(s)
    }

    /// Reads up to [`LOOKAHEAD`] samples ahead, takes their median step as the nominal
    /// period of the gap finder and returns their sample period ([`record::Holes::period_s`]:
    /// the mean step with the gaps left out), s (the whole record's when it is no longer).
    /// Refuses a record without a sample.
    pub fn lookahead_period_s(&mut self) -> Result<f64> {
        while self.ahead.len() < LOOKAHEAD {
            match self.read_one()? {
                Some(s) => self.ahead.push_back(s),
                None => break,
            }
        }
        let t: Vec<f64> = self.ahead.iter().map(|s| s.t_s).collect();
        let mut finder = record::HoleFinder::new(record::median_step_s(&t).unwrap_or(0.0));
        for s in &self.ahead {
            finder.push(s.t_s, s.line);
        }
        self.holes = Some(finder);
        if self.ahead.is_empty() {
            bail!(
                "{}: {}",
                self.name,
                match self.format {
                    InputFormat::Csv => "no data rows after the header",
                    _ => "no sample decoded",
                }
            );
        }
        Ok(self.sample_period_s())
    }

    /// The next sample; `None` at the end.
    pub fn next_sample(&mut self) -> Result<Option<Sample>> {
        match self.ahead.pop_front() {
            Some(s) => Ok(Some(s)),
            None => self.read_one(),
        }
    }

    /// Sample period of the samples read so far ([`record::Holes::period_s`]: the mean step
    /// with the gaps left out; before the look-ahead, the mean step; 1 s below two samples):
    /// after the end, the whole record's.
    pub fn sample_period_s(&self) -> f64 {
        if let Some(h) = &self.holes {
            return h.holes().period_s();
        }
        match (self.first_t, self.last_t) {
            (Some(a), Some(b)) if self.read > 1 && b > a => (b - a) / (self.read - 1) as f64,
            _ => 1.0,
        }
    }

    /// The gaps in `t_s` of the samples read so far (none before the look-ahead): after the
    /// end, the whole record's.
    pub fn holes(&self) -> record::Holes {
        self.holes
            .as_ref()
            .map_or_else(record::Holes::default, record::HoleFinder::holes)
    }

    /// DSP-3000 fault lines so far (no sample, no output row).
    pub fn fault_lines(&self) -> u64 {
        self.fault_lines
    }

    /// Byte counts of a capture (complete after the end).
    pub fn bytes(&self) -> Option<BytesSummary> {
        match &self.source {
            Source::Capture(c) => c.bytes(),
            Source::Csv(_) => None,
        }
    }
}

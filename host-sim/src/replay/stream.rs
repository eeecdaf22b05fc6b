//! `host-sim replay`: a recording through the firmware's fog-core pipeline, streamed.
//!
//! # Input
//! - `csv`: interchange CSV (`t_s`, `rate_dps`, optional others). Rows are validated as by
//!   `host-sim denoise` (a bad row stops the command with one line naming the file and
//!   line, and no output is left); `t_s` is taken from the file. A `drift_dps` column (the
//!   simulator's true drift) is used, when present, to compare the estimates with it.
//! - `ecore-bin`: E-Core 2000 8-byte frames, decoded byte by byte by
//!   [`fog_core::frame::EcoreDecoder`] (`--full-scale-dps`).
//! - `dsp3000`: KVH DSP-3000 21-byte ASCII lines ([`fog_core::frame::Dsp3000Decoder`]),
//!   value in deg/s (rate mode). Fault lines (status `0`) are counted and not identified.
//! - `auto` (default): bytes with bit 7 set in the first 8 KiB mean `ecore-bin`; otherwise a
//!   first line containing `,` means `csv`, a CR LF means `dsp3000`.
//!
//! For binary and ASCII input there is no time stamp: **`t_s = index / rate_hz`**, where
//! `index` counts the frames and lines the decoder delivered (fault lines included: they
//! hold a sample slot). A frame lost to corruption takes no index, so later `t_s` are early
//! by one period per lost frame; the lost frames are counted.
//!
//! # Pipeline
//! Every good sample goes into the identifier the firmware runs,
//! `presets::level_trend::<512>` (default) or `presets::paper::<512>` (`--preset paper`:
//! Mexican-hat neurons, [`DrlsConfig::PAPER`]), with sample period `1 / rate_hz` rounded to
//! f32. A sample the identifier refuses (|rate| above its range) is counted and gets no
//! output row.
//!
//! # Output
//! One row per identified sample: `index,t_s,rate_dps,denoised_dps,drift_dps,compensated_dps`
//! (`index`: 0-based sample number in the input, so refused samples and fault lines show
//! as missing indices). f32 values use Rust's shortest round-trip formatting: they parse
//! back to the same bits. `denoised_dps` is known only when the sample's block of 512
//! completes: at most 512 rows wait in memory for it, then are written. **The rows of the
//! final partial block have an empty `denoised_dps`** (the firmware never denoises a
//! partial block either).
//!
//! # Memory
//! Constant: the input is streamed, at most one block of rows is held, and the report
//! (`--report`) keeps bounded decimations and at most
//! [`report::ALLAN_MAX_SAMPLES`] samples for the Allan deviation ([`report`]).
//!
//! Peak-memory check (release build; records from `host-sim simulate --preset ecore2000
//! --seed 1 --duration-s 1000` (10^5 samples) and `--duration-s 100000` (10^7 samples, a
//! 576 MB CSV)):
//! ```text
//! /usr/bin/time -v target/release/host-sim replay --input a.csv --output out.csv
//!     # "Maximum resident set size": 4272 kB (10^5), 4508 kB (10^7, 40 s)
//! ... --report DIR
//!     # 6792 kB (10^5), 21456 kB (10^7: the 2^20-sample Allan buffer and its phase, f64)
//! ```

use crate::record;
use crate::report::{
    self, BytesSummary, Collector, CsvSummary, Summary, Tail, TruthAcc, TruthSummary,
};
use anyhow::{anyhow, bail, Context, Result};
use fog_core::baseline::RandomWalkKalman;
use fog_core::frame::{Decoder, Dsp3000Decoder, Dsp3000Line, EcoreDecoder};
use fog_core::identify::{presets, Estimate, IdentifyError};
use fog_core::train::DrlsConfig;
use fog_core::wnn::Activation;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::collections::VecDeque;
use std::fs::File;
use std::io::{BufRead, BufReader, IsTerminal, Write};
use std::path::Path;

/// Denoising block of the pipeline, samples (the firmware's).
pub const BLOCK: usize = 512;

/// Header of the per-sample output.
pub const OUTPUT_HEADER: &str = "index,t_s,rate_dps,denoised_dps,drift_dps,compensated_dps";

/// Window of the moving-average baseline, s.
pub const MOVING_AVERAGE_S: f64 = 10.0;

/// Input formats.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputFormat {
    /// Guess from the first bytes (see the module docs).
    Auto,
    /// Interchange CSV.
    Csv,
    /// E-Core 2000 binary frames.
    EcoreBin,
    /// KVH DSP-3000 ASCII lines.
    Dsp3000,
}

impl InputFormat {
    /// The format's name as the command line spells it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Csv => "csv",
            Self::EcoreBin => "ecore-bin",
            Self::Dsp3000 => "dsp3000",
        }
    }
}

/// Identifier configurations (fog-core `identify::presets`).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum IdPreset {
    /// `presets::level_trend` with `LEVEL_TREND_SCALING` (the firmware's default).
    LevelTrend,
    /// `presets::paper`: Mexican-hat neurons, `PAPER_SCALING`, `DrlsConfig::PAPER`.
    Paper,
}

impl IdPreset {
    /// The preset's name as the command line spells it.
    pub fn name(self) -> &'static str {
        match self {
            Self::LevelTrend => "level-trend",
            Self::Paper => "paper",
        }
    }
}

/// The identifier of either preset.
pub enum Pipeline {
    /// `presets::level_trend::<512>`.
    LevelTrend(Box<presets::LevelTrend<BLOCK>>),
    /// `presets::paper::<512>`.
    Paper(Box<presets::Paper<BLOCK>>),
}

impl Pipeline {
    /// The identifier of `preset` for sample period `sample_period_s`.
    pub fn new(preset: IdPreset, sample_period_s: f32) -> Result<Self, IdentifyError> {
        Ok(match preset {
            IdPreset::LevelTrend => Self::LevelTrend(Box::new(presets::level_trend::<BLOCK>(
                presets::LEVEL_TREND_SCALING,
                sample_period_s,
            )?)),
            IdPreset::Paper => Self::Paper(Box::new(presets::paper::<BLOCK>(
                Activation::MexicanHat,
                presets::PAPER_SCALING,
                DrlsConfig::PAPER,
                sample_period_s,
            )?)),
        })
    }

    /// One sample ([`fog_core::identify::Identifier::push`]).
    pub fn push(&mut self, rate_dps: f32) -> Result<Estimate, IdentifyError> {
        match self {
            Self::LevelTrend(i) => i.push(rate_dps),
            Self::Paper(i) => i.push(rate_dps),
        }
    }

    /// Denoised values of the block that completed last.
    pub fn last_denoised_block(&self) -> &[f32; BLOCK] {
        match self {
            Self::LevelTrend(i) => i.last_denoised_block(),
            Self::Paper(i) => i.last_denoised_block(),
        }
    }
}

/// The identifier's sample period for `rate_hz`: `1 / rate_hz` in f64, rounded to f32.
pub fn sample_period_s(rate_hz: f64) -> f32 {
    (1.0 / rate_hz) as f32
}

/// What a replay is asked to do.
#[derive(Debug, Clone)]
pub struct Options {
    /// Input format.
    pub format: InputFormat,
    /// E-Core full scale, deg/s.
    pub full_scale_dps: f32,
    /// Nominal sample rate, Hz.
    pub rate_hz: f64,
    /// Identifier.
    pub preset: IdPreset,
    /// Collect what the report needs.
    pub collect: bool,
}

/// What [`replay`] returns.
pub struct Outcome {
    /// Counts and figures.
    pub summary: Summary,
    /// The report's data (with [`Options::collect`]).
    pub collector: Option<Collector>,
}

/// One input event.
enum Event {
    /// A sample: time (CSV only), rate, true drift (CSV `drift_dps` column).
    Sample {
        t_s: Option<f64>,
        rate_dps: f32,
        truth: Option<f64>,
    },
    /// A DSP-3000 fault line: holds a slot, is not identified.
    Fault,
}

/// Interchange CSV, row by row ([`record::Rows`]: the columns and checks of every reader).
struct CsvSource {
    name: String,
    rows: record::Rows<Box<dyn std::io::Read>>,
    rows_read: u64,
    first_t: Option<f64>,
    prev_t: Option<f64>,
    /// Gaps against the identifier's period, `1 / rate_hz`.
    holes: record::HoleFinder,
}

impl CsvSource {
    /// `path` opened again by the record reader (`.csv.gz` decompressed).
    fn new(path: &Path, rate_hz: f64) -> Result<Self> {
        let name = path.display().to_string();
        let input = record::open_maybe_gz(path)?;
        Ok(Self {
            rows: record::Rows::new(&name, input, &record::ReadOptions::default())?,
            name,
            rows_read: 0,
            first_t: None,
            prev_t: None,
            holes: record::HoleFinder::new(1.0 / rate_hz),
        })
    }

    fn next(&mut self) -> Result<Option<Event>> {
        let Some(row) = self.rows.next_row()? else {
            if self.rows_read == 0 {
                bail!("{}: no data rows after the header", self.name);
            }
            return Ok(None);
        };
        let t = row.t_s;
        self.holes.push(t, row.line);
        self.first_t.get_or_insert(t);
        self.prev_t = Some(t);
        self.rows_read += 1;
        Ok(Some(Event::Sample {
            t_s: Some(t),
            rate_dps: row.rate_dps as f32,
            truth: row.drift_dps,
        }))
    }

    fn position(&self) -> u64 {
        self.rows.byte_position()
    }

    fn summary(&self) -> CsvSummary {
        let mean = match (self.first_t, self.prev_t) {
            (Some(a), Some(b)) if self.rows_read > 1 => Some((b - a) / (self.rows_read - 1) as f64),
            _ => None,
        };
        let h = self.holes.holes();
        CsvSummary {
            rows: self.rows_read,
            gaps: h.count,
            largest_gap_s: h.largest.map(|g| g.dt_s),
            largest_gap_line: h.largest.map(|g| g.line),
            mean_step_s: mean,
            holes: h,
        }
    }
}

/// A byte-at-a-time decoder over a file, with the offsets the report needs.
struct ByteSource<D: Decoder> {
    name: String,
    reader: BufReader<File>,
    decoder: D,
    /// Bytes consumed so far.
    offset: u64,
    first_drop: Option<u64>,
    tail: Option<Tail>,
    done: bool,
    /// Decoded output -> rate (None: fault line).
    map: fn(D::Output) -> Option<f32>,
}

impl<D: Decoder> ByteSource<D> {
    fn next(&mut self) -> Result<Option<Event>> {
        if self.done {
            return Ok(None);
        }
        loop {
            let buf = self
                .reader
                .fill_buf()
                .with_context(|| format!("{}: read failed at byte {}", self.name, self.offset))?;
            if buf.is_empty() {
                let st = *self.decoder.stats();
                if st.bytes_pending > 0 {
                    self.tail = Some(Tail {
                        bytes: st.bytes_pending,
                        offset: st.bytes_total - st.bytes_pending,
                    });
                }
                self.decoder.flush();
                self.done = true;
                return Ok(None);
            }
            let mut used = 0usize;
            let mut out = None;
            for &b in buf {
                let dropped = self.decoder.stats().skipped.total();
                let o = self.decoder.push(b);
                if self.first_drop.is_none() && self.decoder.stats().skipped.total() != dropped {
                    self.first_drop = Some(self.offset + used as u64);
                }
                used += 1;
                if o.is_some() {
                    out = o;
                    break;
                }
            }
            self.reader.consume(used);
            self.offset += used as u64;
            if let Some(o) = out {
                return Ok(Some(match (self.map)(o) {
                    Some(rate_dps) => Event::Sample {
                        t_s: None,
                        rate_dps,
                        truth: None,
                    },
                    None => Event::Fault,
                }));
            }
        }
    }

    fn summary(&self) -> BytesSummary {
        let s = self.decoder.stats();
        BytesSummary {
            bytes_total: s.bytes_total,
            bytes_good: s.bytes_good,
            bytes_dropped: s.skipped.total(),
            skipped: (&s.skipped).into(),
            frames_good: s.frames_good,
            frames_fault: s.frames_fault,
            frames_bad: s.frames_bad,
            first_drop_at_byte: self.first_drop,
            tail: self.tail,
        }
    }
}

enum Source {
    Csv(Box<CsvSource>),
    Ecore(ByteSource<EcoreDecoder>),
    Dsp(ByteSource<Dsp3000Decoder>),
}

impl Source {
    fn next(&mut self) -> Result<Option<Event>> {
        match self {
            Self::Csv(s) => s.next(),
            Self::Ecore(s) => s.next(),
            Self::Dsp(s) => s.next(),
        }
    }

    fn position(&self) -> u64 {
        match self {
            Self::Csv(s) => s.position(),
            Self::Ecore(s) => s.offset,
            Self::Dsp(s) => s.offset,
        }
    }
}

/// One event of a capture read by [`Capture`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CaptureEvent {
    /// A delivered sample: `t_s = index / rate_hz` (the index counts fault lines: they hold
    /// a slot), rate in deg/s.
    Sample {
        /// Seconds.
        t_s: f64,
        /// deg/s.
        rate_dps: f32,
    },
    /// A DSP-3000 fault line: a slot without a sample.
    Fault,
}

/// A binary or ASCII capture (E-Core frames or DSP-3000 lines) read sample by sample in
/// constant memory. CSV input is refused here: it has its own reader with the truth columns
/// ([`record::Rows`]).
pub struct Capture {
    src: Source,
    format: InputFormat,
    rate_hz: f64,
    index: u64,
}

impl Capture {
    /// Opens `input` (format from `opts.format` or sniffed; E-Core full scale and the rate
    /// that gives `t_s` from `opts`).
    pub fn open(input: &Path, opts: &Options) -> Result<Self> {
        let (src, format, _) = open_source(input, opts)?;
        if matches!(src, Source::Csv(_)) {
            bail!("{}: a CSV record, not a capture", input.display());
        }
        Ok(Self {
            src,
            format,
            rate_hz: opts.rate_hz,
            index: 0,
        })
    }

    /// The format read (never `Auto` or `Csv`).
    pub fn format(&self) -> InputFormat {
        self.format
    }

    /// The next event; `None` at the end of the file.
    pub fn next_event(&mut self) -> Result<Option<CaptureEvent>> {
        let Some(ev) = self.src.next()? else {
            return Ok(None);
        };
        let k = self.index;
        self.index += 1;
        Ok(Some(match ev {
            Event::Fault => CaptureEvent::Fault,
            Event::Sample { rate_dps, .. } => CaptureEvent::Sample {
                t_s: k as f64 / self.rate_hz,
                rate_dps,
            },
        }))
    }

    /// Byte and frame counts so far (complete at the end of the file).
    pub fn bytes(&self) -> Option<BytesSummary> {
        match &self.src {
            Source::Ecore(s) => Some(s.summary()),
            Source::Dsp(s) => Some(s.summary()),
            Source::Csv(_) => None,
        }
    }
}

/// Guesses the format from the first bytes (see the module docs); gzip data is a
/// compressed CSV when the name ends in `.gz` (the record reader decompresses it).
pub(crate) fn sniff(name: &str, head: &[u8]) -> Result<InputFormat> {
    if head.is_empty() {
        bail!("{name}: empty file");
    }
    if head.starts_with(&[0x1f, 0x8b]) {
        if name.ends_with(".gz") {
            return Ok(InputFormat::Csv);
        }
        bail!("{name}: gzip data: only a compressed CSV is read, named *.csv.gz");
    }
    if head.iter().any(|&b| b & 0x80 != 0) {
        return Ok(InputFormat::EcoreBin);
    }
    let first_line = head.split(|&b| b == b'\n').next().unwrap_or(head);
    if first_line.contains(&b',') {
        return Ok(InputFormat::Csv);
    }
    if head.windows(2).any(|w| w == b"\r\n") {
        return Ok(InputFormat::Dsp3000);
    }
    bail!(
        "{name}: cannot tell the format from the first bytes; give --format csv|ecore-bin|dsp3000"
    )
}

/// `format`, or for `Auto` the format [`sniff`] tells from the first 8 KiB of `path`.
pub(crate) fn detect_format(path: &Path, format: InputFormat) -> Result<InputFormat> {
    if format != InputFormat::Auto {
        return Ok(format);
    }
    let name = path.display().to_string();
    let file = File::open(path).with_context(|| format!("{name}: cannot open"))?;
    let mut reader = BufReader::with_capacity(8192, file);
    let head = reader
        .fill_buf()
        .with_context(|| format!("{name}: read failed at byte 0"))?;
    sniff(&name, head)
}

fn open_source(path: &Path, opts: &Options) -> Result<(Source, InputFormat, u64)> {
    let name = path.display().to_string();
    let file = File::open(path).with_context(|| format!("{name}: cannot open"))?;
    let len = file.metadata().map(|m| m.len()).unwrap_or(0);
    let reader = BufReader::with_capacity(1 << 16, file);
    let format = detect_format(path, opts.format)?;
    let src = match format {
        InputFormat::Csv | InputFormat::Auto => {
            Source::Csv(Box::new(CsvSource::new(path, opts.rate_hz)?))
        }
        InputFormat::EcoreBin => Source::Ecore(ByteSource {
            decoder: EcoreDecoder::new(opts.full_scale_dps)
                .map_err(|e| anyhow!("--full-scale-dps {}: {e}", opts.full_scale_dps))?,
            name,
            reader,
            offset: 0,
            first_drop: None,
            tail: None,
            done: false,
            map: |f| Some(f.rate_dps),
        }),
        InputFormat::Dsp3000 => Source::Dsp(ByteSource {
            decoder: Dsp3000Decoder::new(),
            name,
            reader,
            offset: 0,
            first_drop: None,
            tail: None,
            done: false,
            map: |l| match l {
                Dsp3000Line::Valid(v) => Some(v.to_f32()),
                Dsp3000Line::Fault(_) => None,
            },
        }),
    };
    Ok((src, format, len))
}

/// A row waiting for its block's denoised value.
struct Row {
    index: u64,
    t_s: f64,
    rate_dps: f32,
    drift_dps: f32,
    compensated_dps: f32,
}

fn write_row(w: &mut impl Write, r: &Row, denoised: Option<f32>) -> std::io::Result<()> {
    match denoised {
        Some(d) => writeln!(
            w,
            "{},{},{},{},{},{}",
            r.index, r.t_s, r.rate_dps, d, r.drift_dps, r.compensated_dps
        ),
        None => writeln!(
            w,
            "{},{},{},,{},{}",
            r.index, r.t_s, r.rate_dps, r.drift_dps, r.compensated_dps
        ),
    }
}

/// Causal moving average over a fixed number of samples (the current one included).
struct MovingAverage {
    window: VecDeque<f32>,
    len: usize,
    sum: f64,
}

impl MovingAverage {
    fn new(len: usize) -> Self {
        Self {
            window: VecDeque::with_capacity(len.max(1)),
            len: len.max(1),
            sum: 0.0,
        }
    }

    fn push(&mut self, x: f32) -> f64 {
        if self.window.len() == self.len {
            if let Some(old) = self.window.pop_front() {
                self.sum -= f64::from(old);
            }
        }
        self.window.push_back(x);
        self.sum += f64::from(x);
        self.sum / self.window.len() as f64
    }
}

/// Replays `input` into `output` (atomically). `truth`, when given, is called once per
/// sample read (fault lines included) and gives that sample's true drift, deg/s; otherwise
/// a CSV `drift_dps` column is used when present.
pub fn replay(
    input: &Path,
    output: &Path,
    opts: &Options,
    mut truth: Option<&mut dyn FnMut() -> f64>,
    truth_source: &str,
) -> Result<Outcome> {
    let name = input.display().to_string();
    record::refuse_overwrite(input, output)?;
    if !(opts.rate_hz.is_finite() && opts.rate_hz > 0.0) {
        bail!("--rate-hz {}: must be finite and > 0", opts.rate_hz);
    }
    let dt = sample_period_s(opts.rate_hz);
    let pipe = Pipeline::new(opts.preset, dt)
        .map_err(|e| anyhow!("identifier ({}): {e}", opts.preset.name()))?;
    let (mut src, format, len) = open_source(input, opts)?;
    let bar = progress_bar(len);
    let mut run = Run::new(pipe, opts);
    let out = output.display().to_string();
    record::write_atomic(output, |w| {
        writeln!(w, "{OUTPUT_HEADER}").map_err(write_failed(&out))?;
        while let Some(ev) = src.next()? {
            let k = run.counts.samples_read;
            run.counts.samples_read += 1;
            if k.is_multiple_of(4096) {
                bar.set_position(src.position());
            }
            let injected = truth.as_mut().map(|f| f());
            let (t_opt, rate_dps, csv_truth) = match ev {
                Event::Fault => {
                    run.counts.fault_lines += 1;
                    continue;
                }
                Event::Sample {
                    t_s,
                    rate_dps,
                    truth,
                } => (t_s, rate_dps, truth),
            };
            let t_s = t_opt.unwrap_or(k as f64 / opts.rate_hz);
            if run.sample(k, t_s, rate_dps, injected.or(csv_truth)) {
                run.write_block(w, &name, &out)?;
            }
        }
        run.write_partial_block(w, &out)
    })?;
    bar.finish_and_clear();
    let (bytes, csv) = match &src {
        Source::Csv(s) => (None, Some(s.summary())),
        Source::Ecore(s) => (Some(s.summary()), None),
        Source::Dsp(s) => (Some(s.summary()), None),
    };
    let n = &run.counts;
    let summary = Summary {
        input: name,
        format: format.name(),
        output: out,
        preset: opts.preset.name(),
        block_samples: BLOCK,
        rate_hz: opts.rate_hz,
        sample_period_s: dt,
        t_s_source: if format == InputFormat::Csv {
            "the CSV's t_s column"
        } else {
            "index / rate_hz (no time stamps in the capture)"
        },
        full_scale_dps: (format == InputFormat::EcoreBin).then_some(opts.full_scale_dps),
        samples_read: n.samples_read,
        samples_identified: n.samples_identified,
        samples_rejected: n.samples_rejected,
        fault_lines: n.fault_lines,
        drift_non_finite: n.drift_non_finite,
        blocks: n.blocks,
        rows_written: n.rows_written,
        rows_without_denoised: run.pending.len() as u64,
        t_first_s: n.t_first_s,
        t_last_s: n.t_last_s,
        rms_train_error_dps: (n.train_n > 0).then(|| (n.train_sq / n.train_n as f64).sqrt()),
        bytes,
        csv,
        truth: run.truth_summary(if truth.is_some() {
            truth_source
        } else {
            "the CSV's drift_dps column"
        }),
        allan: None,
    };
    Ok(Outcome {
        summary,
        collector: run.collector,
    })
}

/// A progress bar over `len` input bytes on stderr when that is a terminal; hidden
/// otherwise.
fn progress_bar(len: u64) -> ProgressBar {
    if std::io::stderr().is_terminal() {
        let b = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
        if let Ok(style) = ProgressStyle::with_template("{bar:40} {percent:>3}% {eta} left") {
            b.set_style(style);
        }
        b
    } else {
        ProgressBar::hidden()
    }
}

/// The error of a failed write to the output named `out`.
fn write_failed(out: &str) -> impl Fn(std::io::Error) -> anyhow::Error + '_ {
    move |e| anyhow!("{out}: write failed: {e}")
}

/// The counts of a replay.
#[derive(Default)]
struct Counts {
    /// Samples read, fault lines included (the next sample's index).
    samples_read: u64,
    samples_identified: u64,
    /// Samples the identifier refused.
    samples_rejected: u64,
    fault_lines: u64,
    /// Identified drift values that are not finite.
    drift_non_finite: u64,
    /// Denoising blocks completed.
    blocks: u64,
    rows_written: u64,
    /// `t_s` of the first sample (fault lines excluded), s.
    t_first_s: Option<f64>,
    /// `t_s` of the last sample (fault lines excluded), s.
    t_last_s: Option<f64>,
    /// Sum of the squared finite training errors, (deg/s)^2.
    train_sq: f64,
    /// Their number.
    train_n: u64,
}

/// A replay's running state: the identifier, the baselines, the rows waiting for their
/// block's denoised values, the report's data and the counts.
struct Run {
    pipe: Pipeline,
    /// Rows of the current block, waiting for its denoised values.
    pending: Vec<Row>,
    /// The causal moving-average baseline ([`MOVING_AVERAGE_S`]).
    ma: MovingAverage,
    /// The random-walk Kalman baseline.
    kf: RandomWalkKalman,
    /// The three estimates against the true drift.
    truth_acc: TruthAcc,
    /// Whether an identified sample had a true drift.
    truth_seen: bool,
    /// The report's data (with [`Options::collect`]).
    collector: Option<Collector>,
    counts: Counts,
}

impl Run {
    /// Nothing read yet; identifier `pipe`, baselines for `opts.rate_hz`.
    fn new(pipe: Pipeline, opts: &Options) -> Self {
        Self {
            pipe,
            pending: Vec::with_capacity(BLOCK),
            ma: MovingAverage::new((MOVING_AVERAGE_S * opts.rate_hz).round() as usize),
            kf: RandomWalkKalman::new(1e-6, 1.0),
            truth_acc: TruthAcc::default(),
            truth_seen: false,
            collector: opts.collect.then(Collector::default),
            counts: Counts::default(),
        }
    }

    /// Sample `index` at `t_s` (s), rate `rate_dps` (deg/s), true drift `truth_dps`
    /// (deg/s) when known: identified (or counted as refused), its row queued, the
    /// baselines, the truth comparison and the report fed. Returns whether it completed
    /// a denoising block.
    fn sample(&mut self, index: u64, t_s: f64, rate_dps: f32, truth_dps: Option<f64>) -> bool {
        let n = &mut self.counts;
        n.t_first_s.get_or_insert(t_s);
        n.t_last_s = Some(t_s);
        let Ok(est) = self.pipe.push(rate_dps) else {
            n.samples_rejected += 1;
            return false;
        };
        n.samples_identified += 1;
        if !est.drift_dps.is_finite() {
            n.drift_non_finite += 1;
        }
        if est.train_error_dps.is_finite() {
            n.train_sq += f64::from(est.train_error_dps).powi(2);
            n.train_n += 1;
        }
        self.pending.push(Row {
            index,
            t_s,
            rate_dps,
            drift_dps: est.drift_dps,
            compensated_dps: est.compensated_dps,
        });
        let ma_dps = self.ma.push(rate_dps);
        let kf_dps = f64::from(self.kf.push(rate_dps));
        let estimates_dps = [f64::from(est.drift_dps), ma_dps, kf_dps];
        if let Some(tr) = truth_dps {
            self.truth_seen = true;
            self.truth_acc.add(tr, estimates_dps);
        }
        if let Some(c) = self.collector.as_mut() {
            collect_sample(c, t_s, rate_dps, estimates_dps, truth_dps);
        }
        est.block_done
    }

    /// Writes the rows of the block that just completed with its denoised values (input
    /// `name` and output `out` for the errors).
    fn write_block(&mut self, w: &mut impl Write, name: &str, out: &str) -> Result<()> {
        self.counts.blocks += 1;
        let block = self.pipe.last_denoised_block();
        if self.pending.len() != BLOCK {
            bail!(
                "{name}: internal error: block completed with {} rows pending",
                self.pending.len()
            );
        }
        for (r, &d) in self.pending.iter().zip(block.iter()) {
            write_row(w, r, Some(d)).map_err(write_failed(out))?;
            if let Some(c) = self.collector.as_mut() {
                c.denoised.push(r.t_s, f64::from(d));
            }
        }
        self.counts.rows_written += self.pending.len() as u64;
        self.pending.clear();
        Ok(())
    }

    /// Writes the rows of the final partial block, without denoised values (they stay
    /// pending: the summary counts them).
    fn write_partial_block(&mut self, w: &mut impl Write, out: &str) -> Result<()> {
        for r in &self.pending {
            write_row(w, r, None).map_err(write_failed(out))?;
        }
        self.counts.rows_written += self.pending.len() as u64;
        Ok(())
    }

    /// The comparison with the true drift taken from `source`, when a sample had one.
    fn truth_summary(&self, source: &str) -> Option<TruthSummary> {
        if self.truth_seen {
            self.truth_acc.summary(source)
        } else {
            None
        }
    }
}

/// Feeds the report's series with one identified sample at `t_s` (s): rate `rate_dps`,
/// the identifier's, the moving average's and the Kalman filter's drift `estimates_dps`
/// (deg/s), and their errors (deg/h) against the true drift `truth_dps` when known.
fn collect_sample(
    c: &mut Collector,
    t_s: f64,
    rate_dps: f32,
    estimates_dps: [f64; 3],
    truth_dps: Option<f64>,
) {
    let [identifier_dps, ma_dps, kf_dps] = estimates_dps;
    c.measured.push(t_s, f64::from(rate_dps));
    c.drift.push(t_s, identifier_dps);
    c.push_allan(rate_dps);
    if let Some(tr) = truth_dps {
        let dph = report::DPH_PER_DPS;
        c.truth.push(t_s, tr);
        c.err_identifier.push(t_s, (identifier_dps - tr) * dph);
        c.err_moving_average.push(t_s, (ma_dps - tr) * dph);
        c.err_kalman.push(t_s, (kf_dps - tr) * dph);
    }
}

/// Prints the summary of a replay on stderr.
pub fn print_summary(s: &Summary) -> Result<()> {
    let mut err = std::io::stderr().lock();
    writeln!(
        err,
        "{}: {} samples ({}) through the {} identifier, {} blocks of {}; {} rows -> {} ({} rows of the final partial block without denoised_dps)",
        s.input,
        s.samples_read,
        s.format,
        s.preset,
        s.blocks,
        s.block_samples,
        s.rows_written,
        s.output,
        s.rows_without_denoised
    )?;
    if s.samples_rejected > 0 || s.fault_lines > 0 {
        writeln!(
            err,
            "{}: rejected: {} samples refused by the identifier, {} DSP-3000 fault lines (no output rows)",
            s.input, s.samples_rejected, s.fault_lines
        )?;
    }
    if s.drift_non_finite > 0 {
        writeln!(
            err,
            "{}: warning: {} identified drift values are not finite (the {} identifier's trainer diverged); they are written as NaN",
            s.input, s.drift_non_finite, s.preset
        )?;
    }
    if let Some(b) = &s.bytes {
        let k = &b.skipped;
        writeln!(
            err,
            "{}: bytes: {} read, {} in good frames, {} dropped (no sync {}, checksum {}, cut short {}, UART {}, malformed {}, too long {}, incomplete {}); {} frames dropped{}",
            s.input,
            b.bytes_total,
            b.bytes_good,
            b.bytes_dropped,
            k.no_sync,
            k.checksum,
            k.cut_short,
            k.uart,
            k.malformed,
            k.too_long,
            k.incomplete,
            b.frames_bad,
            b.first_drop_at_byte
                .map_or(String::new(), |o| format!(", first drop at byte {o}"))
        )?;
        if let Some(t) = b.tail {
            writeln!(
                err,
                "{}: warning: the capture ends inside a frame: {} bytes from byte offset {} dropped (incomplete)",
                s.input, t.bytes, t.offset
            )?;
        }
    }
    if let Some(c) = &s.csv {
        if let Some(w) = c.holes.warning(
            &s.input,
            "the nominal period is 1/--rate-hz; samples are identified as if evenly spaced, none dropped or interpolated",
        ) {
            writeln!(err, "{w}")?;
        }
        if let Some(m) = c.mean_step_s {
            let nominal = 1.0 / s.rate_hz;
            if (m - nominal).abs() > 0.01 * nominal {
                writeln!(
                    err,
                    "{}: warning: mean t_s step {m:.6} s differs from 1/--rate-hz = {nominal} s by more than 1 %",
                    s.input
                )?;
            }
        }
    }
    if let Some(t) = &s.truth {
        writeln!(
            err,
            "{}: against the true drift (RMS {:.4} deg/h): e_truth identifier {:.4}, 10-s moving average {:.4}, Kalman {:.4}; best: {}",
            s.input,
            t.rms_true_drift_dph,
            t.e_truth.identifier,
            t.e_truth.moving_average_10s,
            t.e_truth.kalman_random_walk,
            t.best
        )?;
    }
    Ok(())
}

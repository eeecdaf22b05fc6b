//! The interchange CSV (`shared/spec/serial-protocols.md`, section 3): one reader for every
//! subcommand, and writing output files atomically.
//!
//! A record is `t_s` (or `row index / rate_hz` when the file has none), a rate column
//! (`rate_dps`, or any column times a scale), and optional columns by name: `temp_c`, the
//! truth (`drift_dps`, `true_rate_dps` or another reference column, `moving` 0/1) and an
//! external still flag. A `.gz` file is decompressed on the fly. [`Rows`] reads it row by row
//! (constant memory: the streamed replay), [`Record`] holds it whole; both resolve the header
//! and parse the fields with the same code, so every subcommand refuses the same things with
//! the same one-line messages: file and line (1-based, header = line 1), and for a missing
//! column the header.

use anyhow::{anyhow, bail, Context, Result};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// A time step larger than this many nominal sample periods is a gap (a hole) in `t_s`: one
/// or more samples missing ([`Holes`], the rule every command applies).
pub const GAP_FACTOR: f64 = 1.5;

/// Gaps are missing samples when at most this share of the steps are gaps (ASSUMED: 1 %);
/// beyond it the stamps are irregular (bursty host arrival times, coarse jitter), not a
/// regular stream with holes ([`Holes::irregular`]).
pub const RARE_GAPS: f64 = 0.01;

/// How to read a record: the options every subcommand takes.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadOptions {
    /// The rate column (`--rate-column`, default `rate_dps`).
    pub rate_column: String,
    /// Factor from the rate column's unit to deg/s (`--rate-scale`, default 1).
    pub rate_scale: f64,
    /// Without a `t_s` column, `t_s = row index / rate_hz` (`--rate-hz`); `None`: `t_s` is
    /// required.
    pub rate_hz: Option<f64>,
    /// Column of an external still flag (1/0, true/false, still/moving; empty: unknown).
    pub still_column: Option<String>,
    /// The reference (true) rate column: required when given; otherwise `true_rate_dps`
    /// when the file has it.
    pub reference_column: Option<String>,
    /// Also read the optional columns (`temp_c`, `drift_dps`, the reference, `moving`);
    /// `false`: `t_s` and the rate only, the others are passed through unread.
    pub optional_columns: bool,
    /// Keep every data row as in the file ([`Record::rows`]: output that repeats them).
    pub keep_rows: bool,
}

impl Default for ReadOptions {
    fn default() -> Self {
        Self {
            rate_column: "rate_dps".into(),
            rate_scale: 1.0,
            rate_hz: None,
            still_column: None,
            reference_column: None,
            optional_columns: true,
            keep_rows: false,
        }
    }
}

impl ReadOptions {
    /// The defaults with the rate from `column` times `scale`.
    pub fn rate(column: &str, scale: f64) -> Self {
        Self {
            rate_column: column.into(),
            rate_scale: scale,
            ..Self::default()
        }
    }
}

/// The error for a column the header lacks: file, the header's line (1 unless blank lines
/// come before it), the column and the header.
pub fn missing_column(
    name: &str,
    header_line: u64,
    header: &csv::StringRecord,
    column: &str,
) -> anyhow::Error {
    anyhow!(
        "{name}:{header_line}: missing column `{column}` (the header has: {})",
        header.iter().collect::<Vec<_>>().join(", ")
    )
}

/// Where each column is in the header (`t_s`: None for `row index / rate_hz`; `true_rate_dps`:
/// the reference column).
#[derive(Debug, Clone, Copy)]
struct Columns {
    t_s: Option<usize>,
    rate: usize,
    temp_c: Option<usize>,
    drift_dps: Option<usize>,
    true_rate_dps: Option<usize>,
    moving: Option<usize>,
    still: Option<usize>,
}

impl Columns {
    /// Finds the columns `opts` asks for in `header`; refuses a missing required one.
    fn resolve(
        name: &str,
        header_line: u64,
        header: &csv::StringRecord,
        opts: &ReadOptions,
    ) -> Result<Self> {
        let col = |want: &str| header.iter().position(|h| h.trim() == want);
        let need =
            |want: &str| col(want).ok_or_else(|| missing_column(name, header_line, header, want));
        let t_s = match (col("t_s"), opts.rate_hz) {
            (Some(c), _) => Some(c),
            (None, Some(_)) => None,
            (None, None) => {
                let e = missing_column(name, header_line, header, "t_s");
                bail!("{e}; a record without time stamps needs its rate (--rate-hz)");
            }
        };
        let rate = col(&opts.rate_column).ok_or_else(|| {
            let e = missing_column(name, header_line, header, &opts.rate_column);
            anyhow!("{e}; the rate is read from --rate-column")
        })?;
        let still = opts.still_column.as_deref().map(need).transpose()?;
        let extra = |want: &str| {
            if opts.optional_columns {
                col(want)
            } else {
                None
            }
        };
        let true_rate_dps = match &opts.reference_column {
            Some(c) => Some(need(c)?),
            None => extra("true_rate_dps"),
        };
        Ok(Self {
            t_s,
            rate,
            temp_c: extra("temp_c"),
            drift_dps: extra("drift_dps"),
            true_rate_dps,
            moving: extra("moving"),
            still,
        })
    }
}

/// Which columns a record has beside the rate (optional ones only when asked for).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Present {
    /// `t_s` (else `row index / rate_hz`).
    pub t_s: bool,
    /// `temp_c`.
    pub temp_c: bool,
    /// `drift_dps`.
    pub drift_dps: bool,
    /// The reference rate (`true_rate_dps` or `--reference-column`).
    pub true_rate_dps: bool,
    /// `moving`.
    pub moving: bool,
    /// The external still flag.
    pub still: bool,
}

impl Present {
    /// Both `true_rate_dps` (or the reference) and `drift_dps`: the record can be scored.
    pub fn truth(&self) -> bool {
        self.true_rate_dps && self.drift_dps
    }
}

/// One data row, parsed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    /// Line in the file (header = 1).
    pub line: u64,
    /// Seconds.
    pub t_s: f64,
    /// The rate column times the scale, deg/s.
    pub rate_dps: f64,
    /// `temp_c`, deg C.
    pub temp_c: Option<f64>,
    /// `drift_dps`, deg/s.
    pub drift_dps: Option<f64>,
    /// The reference rate, deg/s.
    pub true_rate_dps: Option<f64>,
    /// `moving`.
    pub moving: Option<bool>,
    /// The still flag: `Some(None)` for an empty cell.
    pub still: Option<Option<bool>>,
}

/// Opens `path` for reading, decompressing a `.gz` file on the fly ([`GzFile`]: a
/// truncated or corrupt one is an error saying so, with the compressed byte offset).
pub fn open_maybe_gz(path: &Path) -> Result<Box<dyn std::io::Read>> {
    let file = File::open(path).with_context(|| format!("{}: cannot open", path.display()))?;
    Ok(if path.extension().is_some_and(|e| e == "gz") {
        let len = file.metadata().map(|m| m.len()).ok();
        Box::new(GzFile::new(file, len))
    } else {
        Box::new(std::io::BufReader::new(file))
    })
}

/// Counts the bytes read through it.
struct Counted<R> {
    inner: R,
    bytes: std::rc::Rc<std::cell::Cell<u64>>,
}

impl<R: std::io::Read> std::io::Read for Counted<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.bytes.set(self.bytes.get() + n as u64);
        Ok(n)
    }
}

/// A `.gz` file decompressed on the fly whose read errors say that the file is truncated
/// or corrupt and where: the compressed bytes read from the file so far (the decoder reads
/// ahead in blocks of at most 32 KiB, so the damage lies before that offset, at the end of
/// the file when it is truncated), of the file's length, and the decompressed bytes
/// delivered (the CSV reader adds the line).
pub struct GzFile {
    dec: flate2::read::GzDecoder<Counted<File>>,
    compressed: std::rc::Rc<std::cell::Cell<u64>>,
    file_len: Option<u64>,
    decompressed: u64,
}

impl GzFile {
    /// `file`, of `file_len` bytes when known.
    pub fn new(file: File, file_len: Option<u64>) -> Self {
        let compressed = std::rc::Rc::new(std::cell::Cell::new(0));
        Self {
            dec: flate2::read::GzDecoder::new(Counted {
                inner: file,
                bytes: compressed.clone(),
            }),
            compressed,
            file_len,
            decompressed: 0,
        }
    }
}

impl std::io::Read for GzFile {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        match self.dec.read(buf) {
            Ok(n) => {
                self.decompressed += n as u64;
                Ok(n)
            }
            Err(e) => Err(std::io::Error::new(
                e.kind(),
                format!(
                    "the gzip data is truncated or corrupt ({e}) after {} compressed bytes read{} ({} bytes decompressed)",
                    self.compressed.get(),
                    self.file_len
                        .map_or(String::new(), |n| format!(" of the file's {n}")),
                    self.decompressed
                ),
            )),
        }
    }
}

/// The input of [`Rows`], numbering the lines as the CSV reader pulls bytes through. The
/// `csv` crate ends a record at `\n`, `\r\n` and a lone `\r` alike, but its
/// `Position::line` advances on `\n` only (after a lone `\r` two records share a line), and
/// its position of a record is where the previous one's terminator began: blank lines
/// before the record are not counted. Here a line break is a `\r`, or a `\n` not right
/// after a `\r` (a `\r\n` counts once, also across two reads), and a record's line is the
/// line of its first byte: the first byte at or after the crate's position that is not a
/// line break. Kept: the offset and line of each line whose first byte follows a break,
/// dropped once a query passes them (queries come in increasing offset order; the reader
/// reads ahead one buffer, so at most one buffer's lines are held).
struct LineBreaks<R> {
    inner: R,
    /// Bytes pulled through so far.
    read: u64,
    /// Line breaks pulled through so far.
    breaks: u64,
    /// The last byte pulled through was `\r`.
    after_cr: bool,
    /// The last byte pulled through was a line break (or there was none).
    after_break: bool,
    /// `(offset, line)` of the first byte of each line not yet passed by a query.
    starts: std::collections::VecDeque<(u64, u64)>,
}

impl<R> LineBreaks<R> {
    fn new(inner: R) -> Self {
        Self {
            inner,
            read: 0,
            breaks: 0,
            after_cr: false,
            after_break: true,
            starts: std::collections::VecDeque::new(),
        }
    }

    /// The 1-based line of the first byte at or after offset `byte` that is not a line
    /// break (the line after the last break when there is none yet).
    fn line_of(&mut self, byte: u64) -> u64 {
        while self.starts.front().is_some_and(|&(at, _)| at < byte) {
            self.starts.pop_front();
        }
        self.starts
            .front()
            .map_or(self.breaks + 1, |&(_, line)| line)
    }
}

impl<R: std::io::Read> std::io::Read for LineBreaks<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        for (i, &b) in buf.iter().take(n).enumerate() {
            let is_break = b == b'\r' || b == b'\n';
            if b == b'\r' || (b == b'\n' && !self.after_cr) {
                self.breaks += 1;
            } else if !is_break && self.after_break {
                self.starts
                    .push_back((self.read + i as u64, self.breaks + 1));
            }
            self.after_cr = b == b'\r';
            self.after_break = is_break;
        }
        self.read += n as u64;
        Ok(n)
    }
}

/// `field K is not valid UTF-8 (its byte B)`: a record's invalid field, 1-based, and the
/// byte within it where the invalid UTF-8 starts.
fn utf8_words(err: &csv::Utf8Error) -> String {
    format!(
        "field {} is not valid UTF-8 (its byte {})",
        err.field() + 1,
        err.valid_up_to()
    )
}

/// A record read row by row: every row validated (finite numbers, `t_s` strictly
/// increasing) as it comes.
pub struct Rows<R: std::io::Read> {
    name: String,
    rdr: csv::Reader<LineBreaks<R>>,
    header: csv::StringRecord,
    /// The header's line: 1 unless blank lines come before it (the `csv` crate skips them).
    header_line: u64,
    cols: Columns,
    rate_column: String,
    rate_scale: f64,
    rate_hz: f64,
    rec: csv::StringRecord,
    index: u64,
    prev_t: Option<f64>,
}

impl<R: std::io::Read> Rows<R> {
    /// Reads the header of `input` and finds the columns; `name` names the input in messages.
    pub fn new(name: &str, input: R, opts: &ReadOptions) -> Result<Self> {
        if !(opts.rate_scale.is_finite() && opts.rate_scale != 0.0) {
            bail!("--rate-scale {}: must be finite and not 0", opts.rate_scale);
        }
        let mut rdr = csv::ReaderBuilder::new()
            .has_headers(true)
            .from_reader(LineBreaks::new(input));
        let header = rdr.headers().cloned();
        let header_line = rdr.get_mut().line_of(0);
        let header = header.map_err(|e| {
            // The crate's own text counts lines its way (see `LineBreaks`).
            match e.kind() {
                csv::ErrorKind::Utf8 { err, .. } => {
                    anyhow!(
                        "{name}:{header_line}: cannot read the header: {}",
                        utf8_words(err)
                    )
                }
                csv::ErrorKind::Io(io) => {
                    anyhow!("{name}:{header_line}: cannot read the header: read error: {io}")
                }
                _ => anyhow!("{name}:{header_line}: cannot read the header: {e}"),
            }
        })?;
        if header.is_empty() || (header.len() == 1 && header[0].is_empty()) {
            bail!("{name}: empty file (no header line)");
        }
        let cols = Columns::resolve(name, header_line, &header, opts)?;
        if let (None, Some(hz)) = (cols.t_s, opts.rate_hz) {
            if !(hz.is_finite() && hz > 0.0) {
                bail!("--rate-hz {hz}: must be finite and > 0");
            }
        }
        Ok(Self {
            name: name.to_string(),
            rdr,
            header,
            header_line,
            cols,
            rate_column: opts.rate_column.clone(),
            rate_scale: opts.rate_scale,
            rate_hz: opts.rate_hz.unwrap_or(f64::NAN),
            rec: csv::StringRecord::new(),
            index: 0,
            prev_t: None,
        })
    }

    /// The header, as in the file.
    pub fn header(&self) -> &csv::StringRecord {
        &self.header
    }

    /// The header's line: 1 unless blank lines come before it.
    pub fn header_line(&self) -> u64 {
        self.header_line
    }

    /// The fields of the row [`Rows::next_row`] returned last, as in the file.
    pub fn fields(&self) -> &csv::StringRecord {
        &self.rec
    }

    /// Which columns the record has.
    pub fn columns(&self) -> Present {
        let c = &self.cols;
        Present {
            t_s: c.t_s.is_some(),
            temp_c: c.temp_c.is_some(),
            drift_dps: c.drift_dps.is_some(),
            true_rate_dps: c.true_rate_dps.is_some(),
            moving: c.moving.is_some(),
            still: c.still.is_some(),
        }
    }

    /// Bytes read so far.
    pub fn byte_position(&self) -> u64 {
        self.rdr.position().byte()
    }

    /// The next row; `None` at the end of the file.
    pub fn next_row(&mut self) -> Result<Option<Row>> {
        let name = &self.name;
        let reached = self.rdr.position().byte();
        let more = match self.rdr.read_record(&mut self.rec) {
            Ok(more) => more,
            Err(e) => {
                let at = e.position().map_or(reached, |p| p.byte());
                let line = self.rdr.get_mut().line_of(at);
                // The csv error's own text would name its line as the crate counts them
                // (`\n` only): the kinds a data row can raise are worded here.
                return Err(match e.kind() {
                    // A read error has no position of its own: the line the reader had reached.
                    csv::ErrorKind::Io(io) => anyhow!(
                        "{name}:{line}: read error at line {line} (the lines before it were read): {io}"
                    ),
                    csv::ErrorKind::UnequalLengths {
                        expected_len, len, ..
                    } => anyhow!(
                        "{name}:{line}: the row has {len} fields, the header {expected_len}"
                    ),
                    csv::ErrorKind::Utf8 { err, .. } => {
                        anyhow!("{name}:{line}: {}", utf8_words(err))
                    }
                    _ => anyhow!("{name}:{line}: {e}"),
                });
            }
        };
        if !more {
            return Ok(None);
        }
        let rec = &self.rec;
        let line = match rec.position() {
            Some(p) => self.rdr.get_mut().line_of(p.byte()),
            None => self.index + 2,
        };
        let num = |c: usize, what: &str| field(name, rec, c, what, line, true);
        let c = &self.cols;
        let t = match c.t_s {
            Some(col) => field(name, rec, col, "t_s", line, false)?,
            None => self.index as f64 / self.rate_hz,
        };
        if let Some(prev) = self.prev_t {
            if t <= prev {
                bail!("{name}:{line}: t_s = {t} does not increase (previous row {prev})");
            }
        }
        let raw = num(c.rate, &self.rate_column)?;
        let rate_dps = raw * self.rate_scale;
        if self.rate_scale != 1.0 && !single(rate_dps) {
            bail!(
                "{name}:{line}: `{}` x {} = {rate_dps} is beyond the single-precision range",
                self.rate_column,
                self.rate_scale
            );
        }
        let opt = |col: Option<usize>, what: &str| col.map(|k| num(k, what)).transpose();
        let row = Row {
            line,
            t_s: t,
            rate_dps,
            temp_c: opt(c.temp_c, "temp_c")?,
            drift_dps: opt(c.drift_dps, "drift_dps")?,
            true_rate_dps: match c.true_rate_dps {
                Some(k) => Some(num(k, &self.header[k])?),
                None => None,
            },
            moving: match c.moving.map(|k| rec.get(k).unwrap_or("").trim()) {
                None => None,
                Some("0") => Some(false),
                Some("1") => Some(true),
                Some(f) => bail!("{name}:{line}: `moving` = `{f}`: must be 0 or 1"),
            },
            still: match c.still {
                None => None,
                Some(k) => {
                    let raw = rec.get(k).unwrap_or("");
                    Some(match raw.trim() {
                        "" => None,
                        "1" | "true" | "still" => Some(true),
                        "0" | "false" | "moving" => Some(false),
                        _ => bail!("{name}:{line}: still flag {raw:?} is not 1/0/true/false/empty"),
                    })
                }
            },
        };
        self.prev_t = Some(t);
        self.index += 1;
        Ok(Some(row))
    }
}

/// Whether `x` is finite in single precision.
fn single(x: f64) -> bool {
    x.is_finite() && x.abs() <= f64::from(f32::MAX)
}

/// Field `col` of `rec` (line `line`) as a finite number, within the single-precision range
/// if `single_range`; `what` names it in messages.
fn field(
    name: &str,
    rec: &csv::StringRecord,
    col: usize,
    what: &str,
    line: u64,
    single_range: bool,
) -> Result<f64> {
    let Some(raw) = rec.get(col) else {
        bail!(
            "{name}:{line}: missing field `{what}` (row has {} fields)",
            rec.len()
        );
    };
    let v: f64 = raw
        .trim()
        .parse()
        .map_err(|_| anyhow!("{name}:{line}: `{what}` is not a number: {raw:?}"))?;
    if !v.is_finite() {
        bail!("{name}:{line}: `{what}` is not finite: {raw:?}");
    }
    if single_range && !single(v) {
        bail!("{name}:{line}: `{what}` = {raw:?} is beyond the single-precision range (|x| <= 3.4e38)");
    }
    Ok(v)
}

/// A whole record, validated row by row ([`Rows`]): columns of equal length, one entry per
/// data row; an optional column is `Some` when the file has it (and it was asked for).
#[derive(Debug, Clone, Default)]
pub struct Record {
    /// The file, for messages.
    pub name: String,
    /// Header fields, as in the file.
    pub header: csv::StringRecord,
    /// Every data row as in the file (with [`ReadOptions::keep_rows`]; else empty).
    pub rows: Vec<csv::StringRecord>,
    /// Seconds: the `t_s` column, or `row index / rate_hz`.
    pub t_s: Vec<f64>,
    /// `t_s` is `row index / rate_hz`: the file has no `t_s` column.
    pub t_s_from_rate: bool,
    /// The rate column times the scale, deg/s.
    pub rate_dps: Vec<f64>,
    /// `temp_c`, deg C.
    pub temp_c: Option<Vec<f64>>,
    /// `drift_dps`, deg/s (the simulator's true drift).
    pub drift_dps: Option<Vec<f64>>,
    /// The reference rate (`true_rate_dps` or `--reference-column`), deg/s.
    pub true_rate_dps: Option<Vec<f64>>,
    /// `moving` (the simulator's ground truth).
    pub moving: Option<Vec<bool>>,
    /// The external still flag per row (`None` where the cell is empty).
    pub still: Option<Vec<Option<bool>>>,
    /// `(row, line)` wherever a row's line is not the previous row's plus one (blank or
    /// multi-line rows before it): [`Record::line`].
    line_jumps: Vec<(usize, u64)>,
    /// The header's line ([`Rows::header_line`]; 0 in a `Record::default()`).
    header_line: u64,
}

/// A gap in time: no samples between line `start_line` and line `line`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gap {
    /// Line of the last sample before the gap (header = 1).
    pub start_line: u64,
    /// Line of the first sample after the gap.
    pub line: u64,
    /// `t_s` of the last sample before the gap: where it starts, seconds.
    pub t_s: f64,
    /// Length of the step, seconds.
    pub dt_s: f64,
}

/// The gaps (holes) in a record's `t_s`, found by one rule for every command that reads a
/// record (`denoise`, `allan`, `identify`, `replay`):
///
/// - the **nominal period** is the median step of `t_s` (a hole is one step, so it does not
///   move the median; the streamed replay takes the median of its look-ahead's steps);
/// - a step longer than [`GAP_FACTOR`] (1.5) nominal periods is a **gap**: at least one
///   sample is missing (a step of 1.5 periods or less is jitter: no whole sample fits in
///   it); it misses `round(step / nominal) - 1` samples;
/// - the **sample period** ([`Holes::period_s`]) is the mean of the steps that are not gaps
///   (the median's value on evenly spaced stamps, to within their jitter and rounding; a
///   gap does not move it), unless gaps are more than [`RARE_GAPS`] of the steps: then the
///   stamps are irregular, not a stream with holes (e.g. host arrival times in bursts,
///   where the median is not the rate), and the period is the mean of every step.
///
/// Nothing is interpolated or dropped: each command says on stderr how it treats the gaps
/// ([`Holes::warning`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Holes {
    /// The nominal period: the median step, s (0 below two samples; [`HoleFinder`]: the
    /// period it was given).
    pub nominal_step_s: f64,
    /// Steps (samples - 1).
    pub steps: u64,
    /// `t_last - t_first`, s.
    pub span_s: f64,
    /// Gaps.
    pub count: u64,
    /// The longest gap (the first of equal ones).
    pub largest: Option<Gap>,
    /// Samples missing in all the gaps (each `round(step / nominal) - 1`).
    pub samples_missing: u64,
    /// The gaps' steps summed, s.
    pub gaps_s: f64,
}

impl Holes {
    /// The gaps of `t` (increasing); `line(i)` is the file line of sample `i`.
    pub fn of(t: &[f64], line: impl Fn(usize) -> u64) -> Self {
        let mut f = HoleFinder::new(median_step_s(t).unwrap_or(0.0));
        for (i, &x) in t.iter().enumerate() {
            f.push(x, line(i));
        }
        f.holes()
    }

    /// More than [`RARE_GAPS`] of the steps are gaps: irregular stamps, not holes.
    pub fn irregular(&self) -> bool {
        self.count as f64 > RARE_GAPS * self.steps as f64
    }

    /// The sample period, s: the mean step with the gaps left out, or the mean of every step
    /// when the stamps are [`irregular`](Holes::irregular); 1 s below two samples (as
    /// [`mean_step_s`]).
    pub fn period_s(&self) -> f64 {
        let kept = self.steps - self.count;
        if self.steps == 0 || self.span_s <= 0.0 {
            1.0
        } else if self.irregular() || kept == 0 {
            self.span_s / self.steps as f64
        } else {
            (self.span_s - self.gaps_s) / kept as f64
        }
    }

    /// How far a reader that takes the samples as evenly spaced at [`Holes::period_s`] is
    /// behind `t_s` after the gaps: their length beyond one period each, s.
    pub fn behind_s(&self) -> f64 {
        (self.gaps_s - self.count as f64 * self.period_s()).max(0.0)
    }

    /// The one line a command prints on stderr for a record with gaps (`None` without):
    /// `NAME: warning: ...` with their count, the largest one's start (time and line) and
    /// length, the samples missing and the rate, then `how`: what the command does with them.
    pub fn warning(&self, name: &str, how: &str) -> Option<String> {
        let g = self.largest?;
        let hz = 1.0 / self.period_s();
        let (nominal, largest) = (round6(self.nominal_step_s), round6(g.dt_s));
        Some(if self.irregular() {
            format!(
                "{name}: warning: irregular t_s: {} of {} steps over {GAP_FACTOR}x the nominal period {nominal} s (too many for missing samples: bursty or jittery stamps), the largest {largest} s from t_s = {} s (line {}); rate {hz:.4} Hz from the mean of every step; {how}",
                self.count,
                self.steps,
                round6(g.t_s),
                g.start_line,
            )
        } else {
            format!(
                "{name}: warning: {} gap(s) in t_s (steps over {GAP_FACTOR}x the nominal period {nominal} s): the largest {largest} s from t_s = {} s (line {}) to line {}, {} samples missing in all; rate {hz:.4} Hz from the other steps; {how}",
                self.count,
                round6(g.t_s),
                g.start_line,
                g.line,
                self.samples_missing,
            )
        })
    }
}

/// `x` rounded to 6 decimals for messages (a step of 10.009999999999998 s prints 10.01).
fn round6(x: f64) -> f64 {
    (x * 1e6).round() / 1e6
}

/// [`Holes`] found sample by sample against a nominal period known beforehand (the
/// streamed readers': the median step of the motion replay's look-ahead; `1 / --rate-hz`
/// for the streamed level-trend and paper replays, whose identifier runs at that rate).
#[derive(Debug, Clone, Default)]
pub struct HoleFinder {
    holes: Holes,
    first_t: Option<f64>,
    prev: Option<(f64, u64)>,
}

impl HoleFinder {
    /// A finder for gaps against `nominal_step_s` (the median step).
    pub fn new(nominal_step_s: f64) -> Self {
        Self {
            holes: Holes {
                nominal_step_s,
                ..Holes::default()
            },
            ..Self::default()
        }
    }

    /// The next sample: its time, s, and its line in the file.
    pub fn push(&mut self, t_s: f64, line: u64) {
        let h = &mut self.holes;
        if let Some((prev, prev_line)) = self.prev {
            let dt = t_s - prev;
            h.steps += 1;
            if h.nominal_step_s > 0.0 && dt > GAP_FACTOR * h.nominal_step_s {
                h.count += 1;
                h.gaps_s += dt;
                h.samples_missing += ((dt / h.nominal_step_s).round() as u64).saturating_sub(1);
                if h.largest.is_none_or(|g| dt > g.dt_s) {
                    h.largest = Some(Gap {
                        start_line: prev_line,
                        line,
                        t_s: prev,
                        dt_s: dt,
                    });
                }
            }
        }
        let first = *self.first_t.get_or_insert(t_s);
        h.span_s = t_s - first;
        self.prev = Some((t_s, line));
    }

    /// What was found so far.
    pub fn holes(&self) -> Holes {
        self.holes
    }
}

/// The median step of `t` (the value at sorted index `(n - 1) / 2` of the `n - 1` steps),
/// s; `None` below two samples.
pub fn median_step_s(t: &[f64]) -> Option<f64> {
    let mut dt: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if dt.is_empty() {
        return None;
    }
    let mid = dt.len() / 2;
    Some(*dt.select_nth_unstable_by(mid, f64::total_cmp).1)
}

/// The sample period of `t` by the rule of [`Holes`] ([`Holes::period_s`]), s.
pub fn period_s(t: &[f64]) -> f64 {
    Holes::of(t, |i| i as u64 + 2).period_s()
}

impl Record {
    /// Reads and validates an interchange CSV (or `.csv.gz`) file.
    pub fn read(path: &Path, opts: &ReadOptions) -> Result<Self> {
        Self::from_reader(&path.display().to_string(), open_maybe_gz(path)?, opts)
    }

    /// [`Record::read`] from any (already decompressed) reader; `name` names the input in
    /// messages (the fuzz target `fuzz/fuzz_targets/csv_record.rs` feeds it arbitrary bytes).
    pub fn from_reader<R: std::io::Read>(name: &str, input: R, opts: &ReadOptions) -> Result<Self> {
        let mut rows = Rows::new(name, input, opts)?;
        let c = rows.cols;
        let mut r = Self {
            name: name.to_string(),
            header: rows.header().clone(),
            header_line: rows.header_line(),
            t_s_from_rate: c.t_s.is_none(),
            temp_c: c.temp_c.map(|_| Vec::new()),
            drift_dps: c.drift_dps.map(|_| Vec::new()),
            true_rate_dps: c.true_rate_dps.map(|_| Vec::new()),
            moving: c.moving.map(|_| Vec::new()),
            still: c.still.map(|_| Vec::new()),
            ..Self::default()
        };
        while let Some(row) = rows.next_row()? {
            if row.line != r.line(r.t_s.len()) {
                r.line_jumps.push((r.t_s.len(), row.line));
            }
            r.t_s.push(row.t_s);
            r.rate_dps.push(row.rate_dps);
            push(&mut r.temp_c, row.temp_c);
            push(&mut r.drift_dps, row.drift_dps);
            push(&mut r.true_rate_dps, row.true_rate_dps);
            push(&mut r.moving, row.moving);
            push(&mut r.still, row.still);
            if opts.keep_rows {
                r.rows.push(rows.fields().clone());
            }
        }
        if r.t_s.is_empty() {
            bail!("{name}: no data rows after the header");
        }
        Ok(r)
    }

    /// Samples.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// True when there is no sample (never, for a record read from a file).
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }

    /// The error for a column this record lacks ([`missing_column`]).
    pub fn missing(&self, column: &str) -> anyhow::Error {
        missing_column(&self.name, self.header_line.max(1), &self.header, column)
    }

    /// Sample period ([`Holes::period_s`]): the mean step with the gaps in `t_s` left out,
    /// so a hole does not move it; the mean of every step when the stamps are irregular
    /// (some real recordings carry host arrival times in bursts, the MPU6050 set: median
    /// step 2 ms, mean 10 ms, where only the mean gives the sensor's rate). 1 s for a
    /// one-sample record.
    pub fn sample_period_s(&self) -> f64 {
        self.holes().period_s()
    }

    /// Line of data row `i` (header = 1), as [`Rows`] counts them (a lone `\r` ends a line).
    pub fn line(&self, i: usize) -> u64 {
        let k = self.line_jumps.partition_point(|&(row, _)| row <= i);
        match k.checked_sub(1).map(|k| self.line_jumps[k]) {
            Some((row, line)) => line + (i - row) as u64,
            None => i as u64 + 2,
        }
    }

    /// The gaps in `t_s` ([`Holes`]: count, the largest, samples missing, the period).
    pub fn holes(&self) -> Holes {
        Holes::of(&self.t_s, |i| self.line(i))
    }
}

fn push<T>(v: &mut Option<Vec<T>>, x: Option<T>) {
    if let (Some(v), Some(x)) = (v.as_mut(), x) {
        v.push(x);
    }
}

/// The mean step of `t`, `(t_last - t_first) / (n - 1)`; 1 s for fewer than 2 samples.
pub fn mean_step_s(t: &[f64]) -> f64 {
    match (t.first(), t.last()) {
        (Some(a), Some(b)) if t.len() > 1 && b > a => (b - a) / (t.len() - 1) as f64,
        _ => 1.0,
    }
}

/// Refuses to write `output` when it is the same file as `input`: the same path once
/// symbolic links and `..` are resolved, or (Unix) another name of the same file, a hard
/// link, found by device and inode. An `output` that does not exist yet is never the input.
/// Every subcommand calls this for each (input, output) pair before it writes.
pub fn refuse_overwrite(input: &Path, output: &Path) -> Result<()> {
    if same_file(input, output) {
        bail!(
            "{}: refusing to overwrite the input file (it is {})",
            output.display(),
            input.display()
        );
    }
    Ok(())
}

/// [`refuse_overwrite`] for every pair of `inputs` and `outputs`.
pub fn refuse_overwrite_all(inputs: &[&Path], outputs: &[&Path]) -> Result<()> {
    for i in inputs {
        for o in outputs {
            refuse_overwrite(i, o)?;
        }
    }
    Ok(())
}

/// Whether `a` and `b` name the same existing file.
pub(crate) fn same_file(a: &Path, b: &Path) -> bool {
    if let (Ok(x), Ok(y)) = (a.canonicalize(), b.canonicalize()) {
        if x == y {
            return true;
        }
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(x), Ok(y)) = (std::fs::metadata(a), std::fs::metadata(b)) {
            return x.dev() == y.dev() && x.ino() == y.ino();
        }
    }
    false
}

/// The temporary files [`write_atomic`] is writing now: what the interrupt handler
/// ([`remove_live_temp_files`]) removes.
static LIVE_TEMP_FILES: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn live_temp_files() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    LIVE_TEMP_FILES
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Removes every temporary file [`write_atomic`] is writing now and returns how many: what
/// `host-sim`'s Ctrl-C / SIGTERM / SIGHUP handler calls before it exits. The lock it takes
/// is held by a rename into place too, so an output is either complete or absent.
pub fn remove_live_temp_files() -> usize {
    let live = live_temp_files();
    for p in live.iter() {
        let _ = std::fs::remove_file(p);
    }
    live.len()
}

/// Unregisters a temporary file from [`LIVE_TEMP_FILES`] when dropped.
struct LiveTemp(PathBuf);

impl Drop for LiveTemp {
    fn drop(&mut self) {
        live_temp_files().retain(|p| p != &self.0);
    }
}

/// Writes a file atomically: into a temporary file beside `path`, renamed over `path` only
/// when `fill` succeeds. On error nothing is left behind, nor on Ctrl-C or SIGTERM once a
/// handler calls [`remove_live_temp_files`] (as `host-sim`'s does).
pub fn write_atomic(
    path: &Path,
    fill: impl FnOnce(&mut BufWriter<&mut File>) -> Result<()>,
) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut tmp = tempfile::Builder::new()
        .prefix(".host-sim-")
        .suffix(".tmp")
        .tempfile_in(&dir)
        .with_context(|| {
            format!(
                "{}: cannot create a temporary file in {}",
                path.display(),
                dir.display()
            )
        })?;
    live_temp_files().push(tmp.path().to_path_buf());
    let _live = LiveTemp(tmp.path().to_path_buf());
    // tempfile creates the file 0600; output is an ordinary file (0644, less the umask
    // that `File::create` would apply: we cannot read the umask portably, 0644 is the usual
    // result of 0666 & !022).
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(tmp.path(), std::fs::Permissions::from_mode(0o644))
            .with_context(|| format!("{}: cannot set permissions", path.display()))?;
    }
    {
        let mut w = BufWriter::new(tmp.as_file_mut());
        fill(&mut w)?;
        w.flush()
            .with_context(|| format!("{}: write failed", path.display()))?;
    }
    let live = live_temp_files();
    tmp.persist(path).map_err(|e| {
        anyhow::anyhow!("{}: cannot rename into place: {}", path.display(), e.error)
    })?;
    drop(live);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str, opts: &ReadOptions) -> Result<Record> {
        Record::from_reader("r.csv", text.as_bytes(), opts)
    }

    fn err(text: &str, opts: &ReadOptions) -> String {
        format!("{:#}", read(text, opts).expect_err("refused"))
    }

    #[test]
    fn every_column_by_name_and_the_rows_reader_agrees() {
        let text = "moving,t_s,temp_c,rate_dps,drift_dps,true_rate_dps,zupt\n\
                    0,0,25,0.5,0.01,0.4,1\n1,0.5,25.5,1.5,0.02,1.4,\n";
        let opts = ReadOptions {
            still_column: Some("zupt".into()),
            ..ReadOptions::default()
        };
        let r = read(text, &opts).expect("reads");
        assert_eq!(r.t_s, [0.0, 0.5]);
        assert_eq!(r.rate_dps, [0.5, 1.5]);
        assert_eq!(r.temp_c.as_deref(), Some(&[25.0, 25.5][..]));
        assert_eq!(r.drift_dps.as_deref(), Some(&[0.01, 0.02][..]));
        assert_eq!(r.true_rate_dps.as_deref(), Some(&[0.4, 1.4][..]));
        assert_eq!(r.moving.as_deref(), Some(&[false, true][..]));
        assert_eq!(r.still.as_deref(), Some(&[Some(true), None][..]));
        assert!(!r.t_s_from_rate && r.rows.is_empty());
        assert_eq!(r.sample_period_s(), 0.5);
        let mut rows = Rows::new("r.csv", text.as_bytes(), &opts).expect("header");
        let first = rows.next_row().expect("row").expect("some");
        assert_eq!((first.line, first.t_s, first.moving), (2, 0.0, Some(false)));
        assert_eq!(rows.next_row().expect("row").map(|r| r.line), Some(3));
        assert!(rows.next_row().expect("end").is_none());
        // Only `t_s` and the rate: the others are not read (a bad cell passes).
        let plain = ReadOptions {
            optional_columns: false,
            keep_rows: true,
            ..ReadOptions::default()
        };
        let r = read("t_s,rate_dps,temp_c\n0,1,hot\n", &plain).expect("reads");
        assert!(r.temp_c.is_none() && r.rows.len() == 1);
        assert!(
            err("t_s,rate_dps,temp_c\n0,1,hot\n", &ReadOptions::default())
                .contains("r.csv:2: `temp_c` is not a number: \"hot\"")
        );
    }

    #[test]
    fn rate_column_scale_and_time_from_the_rate() {
        let opts = ReadOptions {
            rate_hz: Some(4.0),
            ..ReadOptions::rate("gz_rads", 2.0)
        };
        let r = read("gz_rads\n1\n2\n3\n", &opts).expect("reads");
        assert!(r.t_s_from_rate);
        assert_eq!(r.t_s, [0.0, 0.25, 0.5]);
        assert_eq!(r.rate_dps, [2.0, 4.0, 6.0]);
        // A `t_s` column wins over the rate.
        let r = read("t_s,gz_rads\n0,1\n1,2\n", &opts).expect("reads");
        assert!(!r.t_s_from_rate && r.t_s == [0.0, 1.0]);
        assert!(err("gz_rads\n3e38\n", &opts).contains(
            "r.csv:2: `gz_rads` x 2 = 600000000000000000000000000000000000000 is beyond"
        ));
        assert!(err("gz_rads\n1\n", &ReadOptions::rate("gz_rads", 0.0)).contains("--rate-scale 0"));
        let stopped = ReadOptions {
            rate_hz: Some(0.0),
            ..ReadOptions::rate("gz_rads", 1.0)
        };
        assert!(err("gz_rads\n1\n", &stopped).contains("--rate-hz 0: must be finite and > 0"));
    }

    /// 100 Hz with samples 20.00 ..= 29.99 s missing: one gap of 10.01 s from line 2001
    /// (t_s 19.99) to line 2002, 1000 samples missing; the period is still 10 ms.
    #[test]
    fn holes_count_the_gap_and_leave_the_period() {
        let t: Vec<f64> = (0..4000)
            .filter(|k| !(2000..3000).contains(k))
            .map(|k| k as f64 * 0.01)
            .collect();
        let h = Holes::of(&t, |i| i as u64 + 2);
        assert_eq!((h.count, h.samples_missing, h.steps), (1, 1000, 2999));
        let g = h.largest.expect("a gap");
        assert_eq!((g.start_line, g.line), (2001, 2002));
        assert!((g.t_s - 19.99).abs() < 1e-9 && (g.dt_s - 10.01).abs() < 1e-9);
        assert!((h.period_s() - 0.01).abs() < 1e-12 && !h.irregular());
        assert!((h.behind_s() - 10.0).abs() < 1e-9);
        let w = h.warning("r.csv", "HOW").expect("a warning");
        assert!(
            w.starts_with("r.csv: warning: 1 gap(s) in t_s")
                && w.contains("the largest 10.01 s from t_s = 19.99 s (line 2001) to line 2002")
                && w.contains("1000 samples missing")
                && w.contains("rate 100.0000 Hz")
                && w.ends_with("; HOW"),
            "{w}"
        );
        // The mean step would say 75 Hz.
        assert!((1.0 / mean_step_s(&t) - 75.0).abs() < 0.1);
        // Evenly spaced: nothing to say; jitter below 1.5 periods is no gap.
        let even: Vec<f64> = (0..500)
            .map(|k| k as f64 * 0.01 + if k % 2 == 1 { 0.004 } else { 0.0 })
            .collect();
        let h = Holes::of(&even, |i| i as u64 + 2);
        assert_eq!(h.count, 0);
        assert!(h.warning("r.csv", "HOW").is_none());
        assert!((h.period_s() - 0.01).abs() < 1e-5);
        // Bursty stamps (2 ms, 2 ms, 26 ms): irregular, the period is the mean step.
        let mut bursty = vec![0.0];
        for k in 0..999 {
            let last = bursty[bursty.len() - 1];
            bursty.push(last + if k % 3 == 2 { 0.026 } else { 0.002 });
        }
        let h = Holes::of(&bursty, |i| i as u64 + 2);
        assert!(h.irregular());
        assert!((h.period_s() - mean_step_s(&bursty)).abs() < 1e-12);
        assert!(h
            .warning("r.csv", "HOW")
            .expect("a warning")
            .contains("irregular t_s: 333 of 999 steps"));
        // Streamed against a nominal period known beforehand: the same.
        let mut f = HoleFinder::new(median_step_s(&t).expect("steps"));
        for (i, &x) in t.iter().enumerate() {
            f.push(x, i as u64 + 2);
        }
        assert_eq!(f.holes(), Holes::of(&t, |i| i as u64 + 2));
    }

    /// The lines of the gaps are the row reader's ([`Row::line`]), blank lines in the file
    /// or not, with or without the rows kept.
    #[test]
    fn gap_lines_are_the_readers() {
        let text = "t_s,rate_dps\n0,1\n\n0.1,1\n0.2,1\n\n\n0.5,1\n0.6,1\n";
        let mut rows =
            Rows::new("r.csv", text.as_bytes(), &ReadOptions::default()).expect("header");
        let mut lines = Vec::new();
        while let Some(row) = rows.next_row().expect("row") {
            lines.push(row.line);
        }
        assert_eq!(lines, [2, 4, 5, 8, 9], "blank lines are counted");
        for keep_rows in [false, true] {
            let opts = ReadOptions {
                keep_rows,
                ..ReadOptions::default()
            };
            let r = read(text, &opts).expect("reads");
            assert_eq!((0..5).map(|i| r.line(i)).collect::<Vec<_>>(), lines);
            let h = r.holes();
            let g = h.largest.expect("gap");
            assert_eq!((h.count, h.samples_missing), (1, 2));
            assert_eq!((g.start_line, g.line), (lines[2], lines[3]));
        }
    }

    /// A lone `\r` ends a line as it ends a record (the `csv` crate counts `\n` only): each
    /// row its own line, `\r\n` once, a gap across a lone `\r` between two lines, an
    /// error after one at its own line (the fuzz target's crash of 2026-11-30).
    #[test]
    fn a_lone_carriage_return_ends_a_line() {
        let d = ReadOptions::default();
        let lines = |text: &str| -> Vec<u64> {
            let mut rows = Rows::new("r.csv", text.as_bytes(), &d).expect("header");
            let mut v = Vec::new();
            while let Some(row) = rows.next_row().expect("row") {
                v.push(row.line);
            }
            v
        };
        assert_eq!(lines("t_s,rate_dps\r0,1\r0.1,1\r0.2,1\r"), [2, 3, 4]);
        assert_eq!(lines("t_s,rate_dps\r\n0,1\r\n0.1,1\r\n"), [2, 3]);
        assert_eq!(
            lines("t_s,rate_dps\n0,1\n0.1,1\r0.5,1\r\n\r\n0.6,1"),
            [2, 3, 4, 6]
        );
        assert_eq!(
            lines("t_s,rate_dps\n0,1\n\n\n1,2\r\n\r\n2,3\r\r3,4\n"),
            [2, 5, 7, 9]
        );
        for keep_rows in [false, true] {
            let opts = ReadOptions {
                keep_rows,
                ..ReadOptions::default()
            };
            let r = read("t_s,rate_dps\n0,1\n0.1,1\n0.2,1\r0.5,1\n0.6,1\n", &opts).expect("reads");
            assert_eq!(
                (0..5).map(|i| r.line(i)).collect::<Vec<_>>(),
                [2, 3, 4, 5, 6]
            );
            let g = r.holes().largest.expect("gap");
            assert_eq!((g.start_line, g.line), (4, 5));
        }
        assert!(err("t_s,rate_dps\r0,1\r0.1,x\r", &d)
            .starts_with("r.csv:3: `rate_dps` is not a number"));
        assert_eq!(
            err("t_s,rate_dps\r0,1\r0.1,1,2\r", &d),
            "r.csv:3: the row has 3 fields, the header 2"
        );
        // A CR-LF split across two reads counts once: every read one byte.
        let text = b"t_s,rate_dps\r\n0,1\r\n0.1,1\r\n0.2,1,5\r\n";
        let e = Record::from_reader("r.csv", OneByte(&text[..]), &d).expect_err("refused");
        assert_eq!(
            format!("{e:#}"),
            "r.csv:4: the row has 3 fields, the header 2"
        );
    }

    #[test]
    fn blank_lines_before_the_header_move_its_line() {
        let d = ReadOptions::default();
        assert_eq!(
            err("\n\nt_s,gyro\n0,1\n", &d),
            "r.csv:3: missing column `rate_dps` (the header has: t_s, gyro); the rate is read from --rate-column"
        );
        assert_eq!(
            err("\r\n\rrate_dps\n1\n", &d),
            "r.csv:3: missing column `t_s` (the header has: rate_dps); a record without time stamps needs its rate (--rate-hz)"
        );
        let r = read("\n\nt_s,rate_dps\n0,1\n\n0.1,2\n", &d).expect("read");
        assert_eq!((r.line(0), r.line(1)), (4, 6));
        assert_eq!(
            format!("{:#}", r.missing("temp_c")),
            "r.csv:3: missing column `temp_c` (the header has: t_s, rate_dps)"
        );
        assert!(err("\n\nt_s,rate_dps\n0,1\n0.1,x\n", &d)
            .starts_with("r.csv:5: `rate_dps` is not a number"));
        let e = Record::from_reader("r.csv", &b"\n\n\xfft_s,rate_dps\n0,1\n"[..], &d)
            .expect_err("refused");
        assert_eq!(
            format!("{e:#}"),
            "r.csv:3: cannot read the header: field 1 is not valid UTF-8 (its byte 0)"
        );
        assert_eq!(
            format!("{:#}", Record::default().missing("t_s")),
            ":1: missing column `t_s` (the header has: )"
        );
    }

    /// A reader that gives one byte per read.
    struct OneByte<R>(R);

    impl<R: std::io::Read> std::io::Read for OneByte<R> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let n = buf.len().min(1);
            self.0.read(&mut buf[..n])
        }
    }

    #[test]
    fn the_same_messages_for_every_option() {
        let d = ReadOptions::default();
        assert_eq!(
            err("t_s,gyro\n0,1\n", &d),
            "r.csv:1: missing column `rate_dps` (the header has: t_s, gyro); the rate is read from --rate-column"
        );
        assert_eq!(
            err("rate_dps\n1\n", &d),
            "r.csv:1: missing column `t_s` (the header has: rate_dps); a record without time stamps needs its rate (--rate-hz)"
        );
        let still = ReadOptions {
            still_column: Some("zupt".into()),
            ..ReadOptions::default()
        };
        assert_eq!(
            err("t_s,rate_dps\n0,1\n", &still),
            "r.csv:1: missing column `zupt` (the header has: t_s, rate_dps)"
        );
        let reference = ReadOptions {
            reference_column: Some("table_dps".into()),
            ..ReadOptions::default()
        };
        assert!(err("t_s,rate_dps\n0,1\n", &reference).contains("missing column `table_dps`"));
        assert!(err("t_s,rate_dps,zupt\n0,1,maybe\n", &still)
            .contains("r.csv:2: still flag \"maybe\" is not 1/0/true/false/empty"));
        assert!(err("t_s,rate_dps,moving\n0,1,2\n", &d)
            .contains("r.csv:2: `moving` = `2`: must be 0 or 1"));
        assert!(err("t_s,rate_dps\n0,1\n0,1\n", &d)
            .contains("r.csv:3: t_s = 0 does not increase (previous row 0)"));
        assert!(err("t_s,rate_dps\n0,1e39\n", &d).contains("beyond the single-precision range"));
        assert!(err("t_s,rate_dps\n0,inf\n", &d).contains("r.csv:2: `rate_dps` is not finite"));
        assert_eq!(
            err("t_s,rate_dps\n", &d),
            "r.csv: no data rows after the header"
        );
        assert_eq!(err("", &d), "r.csv: empty file (no header line)");
    }
}

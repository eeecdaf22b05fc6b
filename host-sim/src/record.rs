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

/// A time step larger than this many times the median step counts as a gap in the record.
pub const GAP_FACTOR: f64 = 1.5;

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

/// The error for a column the header lacks: file, line 1, the column and the header.
pub fn missing_column(name: &str, header: &csv::StringRecord, column: &str) -> anyhow::Error {
    anyhow!(
        "{name}:1: missing column `{column}` (the header has: {})",
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
    fn resolve(name: &str, header: &csv::StringRecord, opts: &ReadOptions) -> Result<Self> {
        let col = |want: &str| header.iter().position(|h| h.trim() == want);
        let need = |want: &str| col(want).ok_or_else(|| missing_column(name, header, want));
        let t_s = match (col("t_s"), opts.rate_hz) {
            (Some(c), _) => Some(c),
            (None, Some(_)) => None,
            (None, None) => {
                let e = missing_column(name, header, "t_s");
                bail!("{e}; a record without time stamps needs its rate (--rate-hz)");
            }
        };
        let rate = col(&opts.rate_column).ok_or_else(|| {
            let e = missing_column(name, header, &opts.rate_column);
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

/// Opens `path` for reading, decompressing a `.gz` file on the fly.
pub fn open_maybe_gz(path: &Path) -> Result<Box<dyn std::io::Read>> {
    let file = File::open(path).with_context(|| format!("{}: cannot open", path.display()))?;
    Ok(if path.extension().is_some_and(|e| e == "gz") {
        Box::new(flate2::read::GzDecoder::new(std::io::BufReader::new(file)))
    } else {
        Box::new(std::io::BufReader::new(file))
    })
}

/// A record read row by row: every row validated (finite numbers, `t_s` strictly
/// increasing) as it comes.
pub struct Rows<R: std::io::Read> {
    name: String,
    rdr: csv::Reader<R>,
    header: csv::StringRecord,
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
            .from_reader(input);
        let header = rdr
            .headers()
            .map_err(|e| anyhow!("{name}:1: cannot read the header: {e}"))?
            .clone();
        if header.is_empty() || (header.len() == 1 && header[0].is_empty()) {
            bail!("{name}: empty file (no header line)");
        }
        let cols = Columns::resolve(name, &header, opts)?;
        if let (None, Some(hz)) = (cols.t_s, opts.rate_hz) {
            if !(hz.is_finite() && hz > 0.0) {
                bail!("--rate-hz {hz}: must be finite and > 0");
            }
        }
        Ok(Self {
            name: name.to_string(),
            rdr,
            header,
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
        let more = self.rdr.read_record(&mut self.rec).map_err(|e| {
            let line = e.position().map_or(0, |p| p.line());
            anyhow!("{name}:{line}: {e}")
        })?;
        if !more {
            return Ok(None);
        }
        let rec = &self.rec;
        let line = rec.position().map_or(self.index + 2, |p| p.line());
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
}

/// A gap in time: no samples between `line - 1` and `line`.
pub struct Gap {
    /// Line of the first sample after the gap.
    pub line: u64,
    /// Length of the step, seconds.
    pub dt_s: f64,
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
            t_s_from_rate: c.t_s.is_none(),
            temp_c: c.temp_c.map(|_| Vec::new()),
            drift_dps: c.drift_dps.map(|_| Vec::new()),
            true_rate_dps: c.true_rate_dps.map(|_| Vec::new()),
            moving: c.moving.map(|_| Vec::new()),
            still: c.still.map(|_| Vec::new()),
            ..Self::default()
        };
        while let Some(row) = rows.next_row()? {
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
        missing_column(&self.name, &self.header, column)
    }

    /// Sample period: the mean step of `t_s`, `(t_last - t_first) / (n - 1)` (1 s for a
    /// one-sample record). The mean, not the median: some real recordings carry host arrival
    /// times in bursts (the MPU6050 set: median step 2 ms, mean 10 ms), where only the mean
    /// gives the sensor's rate; a gap lengthens it by the gap's share of the record.
    pub fn sample_period_s(&self) -> f64 {
        mean_step_s(&self.t_s)
    }

    /// Line of data row `i` (header = 1).
    pub fn line(&self, i: usize) -> u64 {
        self.rows
            .get(i)
            .and_then(|r| r.position())
            .map_or(i as u64 + 2, |p| p.line())
    }

    /// Steps in `t_s` larger than [`GAP_FACTOR`] times the median step.
    pub fn gaps(&self) -> Vec<Gap> {
        let mut dt: Vec<f64> = self.t_s.windows(2).map(|w| w[1] - w[0]).collect();
        if dt.is_empty() {
            return Vec::new();
        }
        let steps = dt.clone();
        let mid = dt.len() / 2;
        let median = *dt.select_nth_unstable_by(mid, f64::total_cmp).1;
        steps
            .iter()
            .enumerate()
            .filter(|(_, &d)| d > GAP_FACTOR * median)
            .map(|(i, &d)| Gap {
                line: self.line(i + 1),
                dt_s: d,
            })
            .collect()
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

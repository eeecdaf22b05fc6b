//! Reading the interchange CSV (`shared/spec/serial-protocols.md`, section 3) and writing
//! output files atomically.
//!
//! Every error names the file and, where there is one, the line (1-based, header = line 1).

use anyhow::{bail, Context, Result};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// One record, fully validated: every row has a finite `t_s` and `rate_dps`, and `t_s`
/// strictly increases.
pub struct Record {
    /// Header fields, as in the file.
    pub header: csv::StringRecord,
    /// Every data row, fields as in the file (so that output can repeat them exactly).
    pub rows: Vec<csv::StringRecord>,
    /// `t_s` of each row, seconds since the start of the record.
    pub t_s: Vec<f64>,
    /// `rate_dps` of each row, deg/s.
    pub rate_dps: Vec<f32>,
}

/// A time step larger than this many times the median step counts as a gap in the record.
pub const GAP_FACTOR: f64 = 1.5;

/// A gap in time: no samples between `line - 1` and `line`.
pub struct Gap {
    /// Line of the first sample after the gap.
    pub line: u64,
    /// Length of the step, seconds.
    pub dt_s: f64,
}

impl Record {
    /// Reads and validates an interchange CSV file.
    pub fn read(path: &Path) -> Result<Self> {
        let file = File::open(path).with_context(|| format!("{}: cannot open", path.display()))?;
        Self::from_reader(path, std::io::BufReader::new(file))
    }

    /// [`Record::read`] from any reader; `path` only names the input in messages (the fuzz
    /// target `fuzz/fuzz_targets/csv_record.rs` feeds it arbitrary bytes).
    pub fn from_reader<R: std::io::Read>(path: &Path, input: R) -> Result<Self> {
        let name = path.display();
        let (mut rdr, header) = csv_with_header(&name.to_string(), input)?;
        let col = |want: &str| header.iter().position(|h| h.trim() == want);
        let Some(t_col) = col("t_s") else {
            bail!(
                "{name}:1: missing column `t_s` (header: {})",
                header.iter().collect::<Vec<_>>().join(",")
            );
        };
        let Some(r_col) = col("rate_dps") else {
            bail!(
                "{name}:1: missing column `rate_dps` (header: {})",
                header.iter().collect::<Vec<_>>().join(",")
            );
        };
        let mut rows = Vec::new();
        let mut t_s = Vec::new();
        let mut rate_dps = Vec::new();
        for rec in rdr.records() {
            let rec = rec.map_err(|e| {
                let line = e.position().map_or(0, |p| p.line());
                anyhow::anyhow!("{name}:{line}: {e}")
            })?;
            let line = rec.position().map_or(0, |p| p.line());
            let t: f64 = parse_field(&rec, t_col, "t_s", path, line)?;
            let r: f32 = parse_field(&rec, r_col, "rate_dps", path, line)?;
            if let Some(&prev) = t_s.last() {
                if t <= prev {
                    bail!("{name}:{line}: t_s = {t} does not increase (previous row {prev})");
                }
            }
            t_s.push(t);
            rate_dps.push(r);
            rows.push(rec);
        }
        if rows.is_empty() {
            bail!("{name}: no data rows after the header");
        }
        Ok(Self {
            header,
            rows,
            t_s,
            rate_dps,
        })
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
                line: self.rows[i + 1].position().map_or(0, |p| p.line()),
                dt_s: d,
            })
            .collect()
    }
}

pub(crate) fn parse_field<T: std::str::FromStr + Into<f64> + Copy>(
    rec: &csv::StringRecord,
    col: usize,
    what: &str,
    path: &Path,
    line: u64,
) -> Result<T> {
    let name = path.display();
    let Some(raw) = rec.get(col) else {
        bail!(
            "{name}:{line}: missing field `{what}` (row has {} fields)",
            rec.len()
        );
    };
    let v: T = raw
        .trim()
        .parse()
        .map_err(|_| anyhow::anyhow!("{name}:{line}: `{what}` is not a number: {raw:?}"))?;
    if !v.into().is_finite() {
        if raw.trim().parse::<f64>().is_ok_and(f64::is_finite) {
            bail!("{name}:{line}: `{what}` = {raw:?} is beyond the single-precision range (|x| <= 3.4e38)");
        }
        bail!("{name}:{line}: `{what}` is not finite: {raw:?}");
    }
    Ok(v)
}

/// Opens `path` for reading, decompressing a `.gz` file on the fly.
pub(crate) fn open_maybe_gz(path: &Path) -> Result<Box<dyn std::io::Read>> {
    let file = File::open(path).with_context(|| format!("{}: cannot open", path.display()))?;
    Ok(if path.extension().is_some_and(|e| e == "gz") {
        Box::new(flate2::read::GzDecoder::new(std::io::BufReader::new(file)))
    } else {
        Box::new(std::io::BufReader::new(file))
    })
}

/// A CSV reader over `input` with its header read; refuses an empty file. `name` names the
/// file in messages. Every host-sim CSV reader starts here.
pub fn csv_with_header<R: std::io::Read>(
    name: &str,
    input: R,
) -> Result<(csv::Reader<R>, csv::StringRecord)> {
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .from_reader(input);
    let header = rdr
        .headers()
        .with_context(|| format!("{name}:1: cannot read the header"))?
        .clone();
    if header.is_empty() || (header.len() == 1 && header[0].is_empty()) {
        bail!("{name}: empty file (no header line)");
    }
    Ok((rdr, header))
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

/// Writes a file atomically: into a temporary file beside `path`, renamed over `path` only
/// when `fill` succeeds. On error nothing is left behind.
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
    tmp.persist(path).map_err(|e| {
        anyhow::anyhow!("{}: cannot rename into place: {}", path.display(), e.error)
    })?;
    Ok(())
}

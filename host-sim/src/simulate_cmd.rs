//! `host-sim simulate`: writes a simulated FOG record (interchange CSV or E-Core frames).
//!
//! Streaming: one sample is generated and written at a time through a buffered writer into
//! a temporary file, renamed over the output at the end ([`record::write_atomic`]), so
//! memory does not depend on `--duration-s` and an error leaves no output behind.
//! The record covers `0 <= t_s < duration_s`.
//!
//! Peak-memory check (release build), 10^5 and 10^7 samples:
//! ```text
//! /usr/bin/time -v target/release/host-sim simulate --gyro ecore2000 --duration-s 1000 \
//!     --seed 1 --output /tmp/a.csv      # "Maximum resident set size": 4056 kB
//! /usr/bin/time -v target/release/host-sim simulate --gyro ecore2000 --duration-s 100000 \
//!     --seed 1 --output /tmp/b.csv      # 4084 kB (576 MB of CSV, 10.7 s)
//! ```

use crate::gyro::Gyro;
use crate::record;
use crate::sim::{self, Simulator};
use anyhow::{bail, Context, Result};
use fog_core::frame::ecore;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};

/// Arguments of `host-sim simulate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The gyro: a built-in's name (`ecore2000`, `kvh1750`) or a gyro file
    /// (host_sim::gyro: datasheet units in every key; `host-sim gyro show ecore2000` prints
    /// a commented one).
    #[arg(long, aliases = ["model", "preset"], value_name = "NAME|FILE")]
    pub gyro: String,
    /// Length of the record, s.
    #[arg(long)]
    pub duration_s: f64,
    /// Seed: the same model, seed and rate give the same output, byte for byte.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// File to write.
    #[arg(long)]
    pub output: PathBuf,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Csv)]
    pub format: Format,
    /// Nominal sample rate, Hz (default: the model's `sample_rate_hz`).
    #[arg(long)]
    pub rate_hz: Option<f64>,
    /// Unit of the gyro family to simulate (overrides `[family] unit_seed`): its thermal
    /// and warm-up coefficients are the model's times `(1 + spread N(0,1))`.
    #[arg(long)]
    pub unit_seed: Option<u64>,
    /// Relative 1-sigma per-unit spread (overrides `[family] unit_spread`), e.g. 0.2. It
    /// spreads the unit's coefficients, not the record's start temperature: that is
    /// `--initial-c-range` (else the model's `initial_c` for every record).
    #[arg(long)]
    pub unit_spread: Option<f64>,
    /// Start temperature of each record (power-on), deg C, drawn uniformly in `LO,HI` from
    /// the record seed (overrides `[family] initial_c_range`), e.g. `10,35`.
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "LO,HI",
        allow_hyphen_values = true
    )]
    pub initial_c_range: Option<Vec<f64>>,
}

/// Output formats.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Interchange CSV: `t_s,rate_dps,temp_c,drift_dps,true_rate_dps` (+ `moving` when the
    /// model's `[motion]` is not static).
    Csv,
    /// E-Core 2000 binary frames, 8 bytes per sample (spec section 1), raw bytes 0.
    EcoreBin,
}

/// Header of the CSV output of a static model (`[motion]` at its default).
pub const CSV_HEADER: &str = "t_s,rate_dps,temp_c,drift_dps,true_rate_dps";

/// Header of the CSV output when the platform moves: `moving` is the ground truth (1 when
/// the platform moves, 0 when it is still; see [`sim::motion`]).
pub const CSV_HEADER_MOVING: &str = "t_s,rate_dps,temp_c,drift_dps,true_rate_dps,moving";

/// Writes `s` as one CSV row under [`CSV_HEADER`], or under [`CSV_HEADER_MOVING`] when
/// `moving_column` (shortest round-trip floats).
pub fn write_csv_row(
    w: &mut impl std::io::Write,
    s: &sim::Sample,
    moving_column: bool,
) -> std::io::Result<()> {
    write!(
        w,
        "{},{},{},{},{}",
        s.t_s, s.rate_dps, s.temp_c, s.drift_dps, s.true_rate_dps
    )?;
    if moving_column {
        write!(w, ",{}", u8::from(s.moving))?;
    }
    writeln!(w)
}

/// E-Core counts of `rate_dps` for a unit of `full_scale_dps`: rounded, saturated.
pub fn counts(rate_dps: f64, full_scale_dps: f64) -> i16 {
    let c = (rate_dps * f64::from(ecore::COUNTS_PER_FULL_SCALE) / full_scale_dps).round();
    c.clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16
}

/// Runs the command.
pub fn run(args: &Args) -> Result<()> {
    let gyro = Gyro::from_arg(&args.gyro)?;
    let mut model = gyro.sim_model();
    let source = if gyro.builtin {
        format!("gyro {}", gyro.name)
    } else {
        gyro.source.clone()
    };
    let rate_hz = match (args.rate_hz, model.sample_rate_hz) {
        (Some(r), _) | (None, Some(r)) => r,
        (None, None) => bail!("{source}: no sample_rate_hz; give --rate-hz"),
    };
    if !(args.duration_s.is_finite() && args.duration_s > 0.0) {
        bail!("--duration-s {}: must be finite and > 0", args.duration_s);
    }
    let full_scale_dps = match (args.format, model.full_scale_dps) {
        (Format::EcoreBin, None) => {
            bail!("{source}: --format ecore-bin needs full_scale_dps in the gyro file")
        }
        (_, fs) => fs.unwrap_or(0.0),
    };
    if let Some(u) = args.unit_seed {
        model.family.unit_seed = Some(u);
    }
    if let Some(s) = args.unit_spread {
        if !(s.is_finite() && s >= 0.0) {
            bail!("--unit-spread {s}: must be finite and >= 0");
        }
        model.family.unit_spread = s;
    }
    if let Some(r) = &args.initial_c_range {
        let [lo, hi] = r[..] else {
            bail!("--initial-c-range: give two temperatures LO,HI (deg C), e.g. 10,35");
        };
        model.family.initial_c_range = Some([lo, hi]);
        if let Err((key, why)) = model.family.check() {
            bail!("--initial-c-range {lo},{hi}: {key} {why}");
        }
    } else if model.family.unit_spread > 0.0 && model.family.initial_c_range.is_none() {
        eprintln!(
            "{source}: note: every record starts at {} deg C (the model's initial_c); --initial-c-range LO,HI draws it per record",
            model.temperature.initial_c
        );
    }
    let moving_column = !model.motion.is_static();
    let mut simulator = Simulator::new(&model, args.seed, rate_hz).context(source.clone())?;
    if let Some(end_s) = simulator.motion_file_end_s() {
        if end_s < args.duration_s {
            eprintln!(
                "{source}: warning: the motion file ends at {end_s} s; its last rate is held to {} s",
                args.duration_s
            );
        }
    }
    let expected = (args.duration_s / simulator.dt_s()).ceil() as u64;
    let bar = if std::io::stderr().is_terminal() {
        let b = ProgressBar::with_draw_target(Some(expected), ProgressDrawTarget::stderr());
        if let Ok(style) = ProgressStyle::with_template("{bar:40} {percent:>3}% {eta} left") {
            b.set_style(style);
        }
        b
    } else {
        ProgressBar::hidden()
    };
    let out = &args.output;
    if let Some(path) = &gyro.path {
        record::refuse_overwrite(path, out)?;
    }
    // The size, estimated from the first 64 rows (a CSV row's length varies little), said
    // when large and refused beyond the free space before anything is written.
    let per_row = match args.format {
        Format::EcoreBin => 8.0,
        Format::Csv => {
            let mut probe = simulator.clone();
            let mut buf = Vec::new();
            for _ in 0..64 {
                write_csv_row(&mut buf, &probe.next_sample(), moving_column)?;
            }
            buf.len() as f64 / 64.0
        }
    };
    let estimate = (expected as f64 * per_row).min(u64::MAX as f64) as u64;
    if estimate >= 100_000_000 {
        eprintln!(
            "{}: about {} to write ({expected} samples)",
            out.display(),
            human_bytes(estimate)
        );
    }
    check_free_space(out, estimate)?;
    let mut written = 0u64;
    record::write_atomic(out, |w| {
        let io = |e: std::io::Error| anyhow::anyhow!("{}: write failed: {e}", out.display());
        if args.format == Format::Csv {
            let header = if moving_column {
                CSV_HEADER_MOVING
            } else {
                CSV_HEADER
            };
            writeln!(w, "{header}").map_err(io)?;
        }
        loop {
            let s = simulator.next_sample();
            if s.t_s >= args.duration_s {
                break;
            }
            match args.format {
                Format::Csv => write_csv_row(w, &s, moving_column).map_err(io)?,
                Format::EcoreBin => w
                    .write_all(&ecore::encode(counts(s.rate_dps, full_scale_dps), [0; 4]))
                    .map_err(io)?,
            }
            written += 1;
            if written.is_multiple_of(4096) {
                bar.set_position(s.index);
            }
        }
        Ok(())
    })?;
    bar.finish_and_clear();
    eprintln!(
        "{source}: {written} samples at {rate_hz} Hz nominal, seed {}, {} dropped -> {}",
        args.seed,
        simulator.dropped(),
        out.display()
    );
    Ok(())
}

/// Refuses a write of about `bytes` to `path` when the file system holding it has less
/// free space (for the caller's process), so that a run never fills the disk and fails at
/// the end. Not checked where the platform gives no figure (non-Unix, or `statvfs` fails).
fn check_free_space(path: &Path, bytes: u64) -> Result<()> {
    #[cfg(unix)]
    {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        if let Ok(st) = rustix::fs::statvfs(&dir) {
            let free = st.f_bavail.saturating_mul(st.f_frsize);
            if bytes > free {
                bail!(
                    "{}: about {} to write, {} free in {}",
                    path.display(),
                    human_bytes(bytes),
                    human_bytes(free),
                    dir.display()
                );
            }
        }
    }
    #[cfg(not(unix))]
    let _ = (path, bytes);
    Ok(())
}

/// `bytes` as B, kB, MB, GB or TB (powers of 1000), 3 significant digits.
fn human_bytes(bytes: u64) -> String {
    let units = ["B", "kB", "MB", "GB", "TB", "PB", "EB"];
    let mut v = bytes as f64;
    let mut u = 0;
    while v >= 1000.0 && u + 1 < units.len() {
        v /= 1000.0;
        u += 1;
    }
    if u == 0 {
        format!("{bytes} B")
    } else {
        format!("{v:.3} {}", units[u])
    }
}

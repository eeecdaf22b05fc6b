//! `host-sim replay`: arguments, then the pipeline of [`crate::replay`]: the motion preset
//! (default; [`crate::replay::motion`]) or the streamed level-trend / paper presets
//! ([`crate::replay::stream`]).

use crate::gyro::Gyro;
use crate::record::ReadOptions;
use crate::record_args::RecordArgs;
use crate::replay::motion::{self, MotionOptions};
use crate::replay::stream::{self, IdPreset, InputFormat, Options, Outcome};
use crate::report;
use anyhow::{bail, Context, Result};
use std::path::PathBuf;

/// Arguments of `host-sim replay`.
#[derive(clap::Args, Debug)]
#[command(mut_arg("rate_hz", |a| a.help(crate::record_args::REPLAY_RATE_HZ_HELP)))]
pub struct Args {
    /// Recording to read: interchange CSV, E-Core binary capture or DSP-3000 lines.
    #[arg(long)]
    pub input: PathBuf,
    /// Input format.
    #[arg(long, value_enum, default_value_t = InputFormat::Auto)]
    pub format: InputFormat,
    /// The gyro when no `--identifier` gives it: a built-in's name, `ecore2000` (60 deg/s,
    /// 100 Hz) or `kvh1750` (490 deg/s, 1 kHz), or a gyro file (host_sim::gyro: its
    /// datasheet part, and its `[identified]` model when it has one); default: the built-in
    /// whose rate matches the record's.
    #[arg(long, alias = "sensor", value_name = "NAME|FILE")]
    pub gyro: Option<String>,
    /// Full scale of E-Core binary frames, deg/s (32768 counts); default: the sensor's.
    #[arg(long)]
    pub full_scale_dps: Option<f32>,
    /// Estimator: `motion` (default: the drift filter of an `--identifier` image or of the
    /// sensor's specification alone); `level-trend` and `paper` are the references
    /// (low-passes of the rate: they take rotation for drift).
    #[arg(long, value_enum, default_value_t = PresetArg::Motion)]
    pub preset: PresetArg,
    /// Per-sample CSV to write.
    #[arg(long)]
    pub output: PathBuf,
    /// Folder for the report (index.html, SVG figures, summary.json).
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// JSON summary to write (motion preset: with the scores when the record has truth).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Motion preset: an image (`identify --preset motion --save-identifier`: the gyro model
    /// fitted on calibration runs); default: `--gyro`'s `[identified]` model, else the model of
    /// its specification alone.
    #[arg(long)]
    pub identifier: Option<PathBuf>,
    /// Motion preset: column holding an external still flag (1/0, true/false; empty cells
    /// leave the detector in charge).
    #[arg(long)]
    pub still_column: Option<String>,
    /// The rate column and scale (motion preset) and the sample rate of a record without
    /// time stamps.
    #[command(flatten)]
    pub record: RecordArgs,
    /// Motion preset: the baselines' gated Kalman q, (deg/s)^2 per sample (default: tuned
    /// on `--validate`, else the identifier's level noise).
    #[arg(long, alias = "baseline-q", value_name = "Q_DPS2")]
    pub baseline_q_dps2: Option<f64>,
    /// Motion preset: records with truth (CSV files or folders) on which the baselines' q is
    /// tuned ([`crate::nav::tune_gated_q`]).
    #[arg(long)]
    pub validate: Vec<PathBuf>,
}

/// `--preset`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum PresetArg {
    /// The drift filter ([`crate::replay::motion`]).
    Motion,
    /// `presets::level_trend` (a low-pass of the rate: reference).
    LevelTrend,
    /// `presets::paper` (the paper's configuration: reference).
    Paper,
}

/// Runs the command.
pub fn run(args: &Args) -> Result<()> {
    if let Some(dir) = &args.report {
        if let (Ok(a), Ok(b)) = (args.input.canonicalize(), dir.canonicalize()) {
            if a == b {
                bail!("{}: the report folder is the input file", dir.display());
            }
        }
    }
    let gyro = args.gyro.as_deref().map(Gyro::from_arg).transpose()?;
    let sensor = match &gyro {
        Some(g) => Some(g.sensor()?.config),
        None => None,
    };
    let id_preset = match args.preset {
        PresetArg::Motion => None,
        PresetArg::LevelTrend => Some(IdPreset::LevelTrend),
        PresetArg::Paper => Some(IdPreset::Paper),
    };
    let Some(id_preset) = id_preset else {
        return run_motion(args, sensor, gyro.as_ref());
    };
    if args.identifier.is_some()
        || args.still_column.is_some()
        || args.record.rate_column != "rate_dps"
        || args.record.rate_scale != 1.0
        || args.baseline_q_dps2.is_some()
        || !args.validate.is_empty()
        || args.json.is_some()
    {
        bail!("--identifier, --still-column, --rate-column, --rate-scale, --baseline-q-dps2, --validate and --json need --preset motion");
    }
    let s = sensor.unwrap_or(fog_core::sensor::SensorConfig::ECORE_2000);
    let opts = Options {
        format: args.format,
        full_scale_dps: args.full_scale_dps.unwrap_or(s.full_scale_dps),
        rate_hz: args.record.rate_hz.unwrap_or(f64::from(s.sample_rate_hz)),
        preset: id_preset,
        collect: args.report.is_some(),
    };
    let Outcome {
        mut summary,
        collector,
    } = stream::replay(&args.input, &args.output, &opts, None, "")?;
    stream::print_summary(&summary)?;
    if let (Some(dir), Some(c)) = (&args.report, collector) {
        let index = report::write(dir, &mut summary, &c)?;
        eprintln!("{}: report -> {}", summary.input, index.display());
    }
    Ok(())
}

fn run_motion(
    args: &Args,
    sensor: Option<fog_core::sensor::SensorConfig>,
    gyro: Option<&Gyro>,
) -> Result<()> {
    // Before anything is written: no output may be an input (the record, the identifier,
    // the gyro file, the validation records) or another output.
    let mut inputs = vec![args.input.as_path()];
    inputs.extend(args.identifier.as_deref());
    inputs.extend(gyro.and_then(|g| g.path.as_deref()));
    inputs.extend(args.validate.iter().map(PathBuf::as_path));
    let mut outputs = vec![args.output.as_path()];
    outputs.extend(args.json.as_deref());
    crate::record::refuse_overwrite_all(&inputs, &outputs)?;
    if let Some(j) = &args.json {
        if j == &args.output || crate::record::same_file(j, &args.output) {
            bail!(
                "{}: --json and --output name the same file (one would destroy the other)",
                j.display()
            );
        }
    }
    let o = MotionOptions {
        identifier: args.identifier.clone(),
        sensor,
        gyro_image: match gyro {
            Some(g) if g.identified.is_some() => Some((g.image()?, g.image_words())),
            _ => None,
        },
        stream: Options {
            format: args.format,
            full_scale_dps: args.full_scale_dps.unwrap_or(0.0),
            rate_hz: args.record.rate_hz.unwrap_or(0.0),
            preset: IdPreset::LevelTrend,
            collect: false,
        },
        csv: ReadOptions {
            still_column: args.still_column.clone(),
            ..args.record.options()
        },
        baseline_q: args
            .baseline_q_dps2
            .map(|q| (q, "--baseline-q-dps2".to_string())),
        validate: args.validate.clone(),
        figures: args.report.is_some(),
    };
    let out = motion::replay(&args.input, &args.output, &o)?;
    motion::print_summary(&out.summary)?;
    if let Some(j) = &args.json {
        let text = serde_json::to_string_pretty(&out.summary)?;
        crate::record::write_atomic(j, |w| {
            std::io::Write::write_all(w, text.as_bytes())
                .with_context(|| format!("{}: write failed", j.display()))
        })?;
    }
    if let Some(dir) = &args.report {
        let index = report::motion::write(dir, &out)?;
        eprintln!("{}: report -> {}", out.summary.input, index.display());
    }
    Ok(())
}

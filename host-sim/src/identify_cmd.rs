//! `host-sim identify`: see [`crate::identify`].

use crate::identify::series::CsvFiles;
use crate::identify::{self, Act, Options, Preset, TrainerKind};
use crate::record;
use anyhow::{Context, Result};
use std::path::PathBuf;

/// Arguments of `host-sim identify`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Training records: CSV files or folders of them.
    #[arg(long, num_args = 1.., required = true)]
    pub train: Vec<PathBuf>,
    /// Validation records: CSV files or folders of them.
    #[arg(long, num_args = 1.., required = true)]
    pub validate: Vec<PathBuf>,
    /// Network layout and inputs (`paper` = the paper's exact configuration).
    #[arg(long, value_enum, default_value_t = Preset::LevelTrend)]
    pub preset: Preset,
    /// Trainer (default: the preset's: drls-parallel for paper, drls-sequential otherwise).
    #[arg(long, value_enum)]
    pub trainer: Option<TrainerKind>,
    /// Hidden neurons.
    #[arg(long, default_value_t = 30)]
    pub hidden: usize,
    /// Forgetting factor (default: the preset's, 0.63 for paper).
    #[arg(long)]
    pub lambda: Option<f32>,
    /// Keep `U` and the weights bounded (default: off for paper, on otherwise).
    #[arg(long)]
    pub guard: Option<bool>,
    /// Denoising levels.
    #[arg(long, default_value_t = 3)]
    pub levels: u32,
    /// Denoising block, samples.
    #[arg(long, default_value_t = 512)]
    pub block: usize,
    /// Wavelet neuron of the paper preset.
    #[arg(long, value_enum)]
    pub activation: Option<Act>,
    /// JSON report to write.
    #[arg(long)]
    pub json: PathBuf,
}

/// Options from the arguments.
pub fn options(a: &Args) -> Options {
    let mut o = match a.preset {
        Preset::Paper => Options::paper(),
        Preset::LevelTrend => Options::level_trend(),
    };
    if let Some(t) = a.trainer {
        o.trainer = t;
    }
    if let Some(l) = a.lambda {
        o.lambda = l;
    }
    if let Some(g) = a.guard {
        o.guard = g;
    }
    if let Some(act) = a.activation {
        o.activation = act;
    }
    o.hidden = a.hidden;
    o.levels = a.levels;
    o.block = a.block;
    o
}

/// Runs the command.
pub fn run(a: &Args) -> Result<()> {
    let train = CsvFiles::from_args(&a.train)?;
    let validate = CsvFiles::from_args(&a.validate)?;
    for p in train.0.iter().chain(&validate.0) {
        record::refuse_overwrite(p, &a.json)?;
    }
    let o = options(a);
    let report = identify::run(&o, &train, &validate)?;
    let text = serde_json::to_string_pretty(&report).context("report to JSON")?;
    record::write_atomic(&a.json, |w| {
        use std::io::Write;
        w.write_all(text.as_bytes())?;
        Ok(())
    })?;
    let f = |v: Option<f64>| v.map_or("null".to_string(), |x| format!("{x:.4}"));
    eprintln!(
        "identify: e_rel {} e_truth {} rms_err_truth {} deg/h; {} training / {} validation records -> {}",
        f(report.e_rel),
        f(report.e_truth),
        f(report.rms_err_truth_dph),
        report.train_records,
        report.validate_records,
        a.json.display()
    );
    Ok(())
}

//! `host-sim identify`: see [`crate::identify`].

use crate::gyro::Gyro;
use crate::identify::series::{report_holes, CsvFiles, RecordHoles};
use crate::identify::{self, Act, DrlsFormArg, LevelInput, Options, Preset, TrainerKind};
use crate::motion;
use crate::nav::NavRecord;
use crate::record;
use crate::record::ReadOptions;
use crate::record_args::{HolesSummary, RecordArgs};
use anyhow::{Context, Result};
use fog_core::image::Image;
use std::path::PathBuf;

/// The identifier's options, shared by `identify` and `reproduce`.
#[derive(clap::Args, Debug, Clone)]
pub struct IdentifierArgs {
    /// Estimator: `motion` (the drift filter the firmware runs; `identify`'s default),
    /// or a network layout and inputs (`paper` = the paper's exact configuration, the
    /// reference; `level-trend` is `reproduce`'s default).
    #[arg(long, value_enum)]
    pub preset: Option<Preset>,
    /// Trainer (default: the preset's: drls-parallel for paper, drls-sequential otherwise).
    #[arg(long, value_enum)]
    pub trainer: Option<TrainerKind>,
    /// Hidden neurons.
    #[arg(long, default_value_t = 30)]
    pub hidden: usize,
    /// Forgetting factor (default: the preset's, 0.63 for paper).
    #[arg(long)]
    pub lambda: Option<f32>,
    /// Keep `U <= 1` and `|w| <= 1e4` (default: off for paper, on otherwise).
    #[arg(long)]
    pub guard: Option<bool>,
    /// DRLS `U(0)` (default: the preset's).
    #[arg(long)]
    pub u0: Option<f32>,
    /// DRLS gain recursion: `gain` (eq. 15, `U` kept) or `energy` (eqs. 10-11, `S = 1/U`
    /// kept) (default: the preset's: energy for level-trend, as the firmware; gain otherwise).
    #[arg(long, value_enum)]
    pub drls_form: Option<DrlsFormArg>,
    /// Denoising levels.
    #[arg(long, default_value_t = 3)]
    pub levels: u32,
    /// Denoising block, samples.
    #[arg(long, default_value_t = 512)]
    pub block: usize,
    /// Wavelet neuron of the paper preset.
    #[arg(long, value_enum)]
    pub activation: Option<Act>,
    /// Level input of the level-trend preset: `mean10s` (trained bias and link), `kalman`
    /// (a random-walk Kalman filter with q/r tuned on the training records, frozen as the
    /// network's linear part), or a q/r value per sample for that filter.
    #[arg(long, value_parser = parse_level)]
    pub level: Option<LevelInput>,
    /// time-temp preset: memory of the per-power-on bias neuron, s.
    #[arg(long)]
    pub bias_memory_s: Option<f32>,
    /// time-temp preset: `U(0)` of the per-power-on warm-up neuron.
    #[arg(long)]
    pub warmup_u0: Option<f32>,
    /// level-bank preset: the level the network starts as (0..=5: memory 3, 10, 30, 100,
    /// 300, 1000 s).
    #[arg(long)]
    pub bank_from: Option<usize>,
    /// level-bank preset: train the neurons on T, temperature and its rate (default true).
    #[arg(long)]
    pub known_inputs: Option<bool>,
    /// level-bank preset: output from undelayed levels, training inputs delayed.
    #[arg(long)]
    pub undelayed_output: bool,
}

fn parse_level(s: &str) -> Result<LevelInput, String> {
    match s {
        "mean10s" => Ok(LevelInput::Mean10s),
        "kalman" => Ok(LevelInput::KalmanTuned),
        v => match v.parse::<f32>() {
            Ok(q) if q > 0.0 && q.is_finite() => Ok(LevelInput::Kalman { q_over_r: q }),
            _ => Err(format!(
                "expected `mean10s`, `kalman` or a q/r > 0, got {v:?}"
            )),
        },
    }
}

/// Arguments of `host-sim identify`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Training records: CSV files or folders of them (`--input` is the same).
    #[arg(long, alias = "input", num_args = 1.., required = true)]
    pub train: Vec<PathBuf>,
    /// Validation records: CSV files or folders of them (with `--preset motion`: optional,
    /// records with truth on which the trained identifier is scored beside the baselines;
    /// required by the other presets).
    #[arg(long, num_args = 1..)]
    pub validate: Vec<PathBuf>,
    /// The training (and, except with `--preset motion`, validation) records' rate column
    /// and scale, the sample rate of a record without `t_s`.
    #[command(flatten)]
    pub record: RecordArgs,
    /// Identifier options.
    #[command(flatten)]
    pub id: IdentifierArgs,
    /// JSON report to write (with `--preset motion`: the per-record training figures;
    /// the other presets: on stdout without it).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// `--preset motion`: the identifier image to write (fog_core::image); without it the
    /// model is fitted, described and scored, and no image written. An image that does not
    /// fit the firmware (host_sim::firmware_fit) is not written without `--force`.
    #[arg(long)]
    pub save_identifier: Option<PathBuf>,
    /// `--preset motion`: write the image (and the JSON) even when it does not fit the
    /// firmware; the verdict and its reasons are still printed and in the JSON.
    #[arg(long)]
    pub force: bool,
    /// `--preset motion`: the gyro: a built-in's name (`ecore2000`: 60 deg/s, 100 Hz;
    /// `kvh1750`: 490 deg/s, 1 kHz) or a gyro file (host_sim::gyro; its datasheet part).
    #[arg(
        long,
        alias = "sensor",
        value_name = "NAME|FILE",
        default_value = "ecore2000"
    )]
    pub gyro: String,
    /// `--preset motion`: also write the gyro file with what the calibration runs fitted
    /// (`[identified]`: the model in the image, in datasheet units) beside the image; the
    /// rest is `--gyro`'s. `replay --gyro` and `image --gyro` take it.
    #[arg(long, value_name = "FILE")]
    pub save_gyro: Option<PathBuf>,
    /// `--preset motion`: vehicle records with truth (`true_rate_dps`, `drift_dps`; CSV
    /// files or folders; other units than the training records') on which the fitted
    /// model's two least certain numbers (the temperature links' unit spread and the
    /// Gauss-Markov sigmas) are scaled by the least mean heading-error RMS with the filter's
    /// own stillness test (host_sim::motion::tune). Score the result on other records
    /// (`--validate`).
    #[arg(long, num_args = 1..)]
    pub tune_on: Vec<PathBuf>,
    /// `--preset motion`: static runs of the ONE unit the image is for, each from power-on
    /// (files or folders; at least 2): after the family's fit on the calibration runs (and
    /// `--tune-on`), the model is made that unit's: its turn-on, warm-up, white noise and
    /// the links its runs tell, the family's noise terms (host_sim::gyro_fit::fit_unit).
    #[arg(long, num_args = 1..)]
    pub unit_runs: Vec<PathBuf>,
    /// `--preset motion`: the filter's window, s (default 2; fog_core::drift_filter).
    #[arg(long)]
    pub window_s: Option<f32>,
    /// `--preset motion --validate`: the baselines' gated Kalman q, (deg/s)^2 per sample
    /// (default: tuned on the validation records).
    #[arg(long, alias = "baseline-q", value_name = "Q_DPS2")]
    pub baseline_q_dps2: Option<f64>,
}

/// Options from the arguments.
pub fn options(a: &IdentifierArgs) -> Options {
    let mut o = match a.preset.unwrap_or(Preset::LevelTrend) {
        Preset::Paper => Options::paper(),
        Preset::LevelTrend => Options::level_trend(),
        Preset::TimeTemp => Options::time_temp(),
        Preset::LevelBank => Options::level_bank(),
        // Not an `identify::run` preset: `run` sends it to `crate::motion`.
        Preset::Motion => Options::level_trend(),
    };
    o.undelayed_output = a.undelayed_output;
    if let Some(k) = a.known_inputs {
        o.known_inputs = k;
    }
    if let Some(b) = a.bank_from {
        o.bank_from = b.min(fog_core::features::BANK_MEMORIES_S.len() - 1);
    }
    if let Some(m) = a.bias_memory_s {
        o.bias_memory_s = m;
    }
    if let Some(u) = a.warmup_u0 {
        o.warmup_u0 = u;
    }
    if let Some(t) = a.trainer {
        o.trainer = t;
    }
    if let Some(l) = a.lambda {
        o.lambda = l;
    }
    if let Some(g) = a.guard {
        o.guard = g;
    }
    if let Some(u) = a.u0 {
        o.u0 = u;
    }
    if let Some(f) = a.drls_form {
        o.drls_form = f;
    }
    if let Some(act) = a.activation {
        o.activation = act;
    }
    if let Some(l) = a.level {
        o.level = l;
    }
    o.hidden = a.hidden;
    o.levels = a.levels;
    o.block = a.block;
    o
}

/// Writes a report as pretty JSON, atomically (on stdout without a path), and prints its
/// headline ([`identify::Report::headline`]).
pub fn write_report<T: serde::Serialize>(
    json: Option<&std::path::Path>,
    report: &T,
    headline: &identify::Report,
) -> Result<()> {
    use std::io::Write;
    let text = serde_json::to_string_pretty(report).context("report to JSON")?;
    match json {
        Some(json) => record::write_atomic(json, |w| {
            w.write_all(text.as_bytes())?;
            Ok(())
        })?,
        None => writeln!(std::io::stdout().lock(), "{text}").context("stdout: write failed")?,
    }
    eprintln!(
        "{} -> {}",
        headline.headline(),
        json.map_or("stdout".to_string(), |j| j.display().to_string())
    );
    Ok(())
}

/// Runs the command.
pub fn run(a: &Args) -> Result<()> {
    let preset = a.id.preset.unwrap_or(Preset::Motion);
    if preset == Preset::Motion {
        return run_motion(a);
    }
    if a.save_identifier.is_some() {
        anyhow::bail!("--save-identifier needs --preset motion (the default)");
    }
    if a.save_gyro.is_some() {
        anyhow::bail!("--save-gyro needs --preset motion (the default)");
    }
    if !a.tune_on.is_empty() {
        anyhow::bail!("--tune-on needs --preset motion (the default)");
    }
    if !a.unit_runs.is_empty() {
        anyhow::bail!("--unit-runs needs --preset motion (the default)");
    }
    if a.validate.is_empty() {
        anyhow::bail!(
            "--validate is required (the records it is scored on) by every preset but motion"
        );
    }
    let json = a.json.as_deref();
    let train = CsvFiles::from_args(&a.train, &a.record.options())?;
    let validate = CsvFiles::from_args(&a.validate, &a.record.options())?;
    if let Some(json) = json {
        for p in train.0.iter().chain(&validate.0) {
            record::refuse_overwrite(p, json)?;
        }
    }
    let report = identify::run(&options(&a.id), &train, &validate)?;
    // Every record's gaps in `t_s`, from the reads that trained and scored on it.
    let mut holes = train.holes()?;
    holes.extend(validate.holes()?);
    let holes = report_holes(&holes);
    /// The report with every record's gaps in `t_s`.
    #[derive(serde::Serialize)]
    struct WithHoles<'a> {
        #[serde(flatten)]
        report: &'a identify::Report,
        holes: Vec<HolesSummary>,
    }
    write_report(
        json,
        &WithHoles {
            report: &report,
            holes,
        },
        &report,
    )
}

/// `--tune-on`: the vehicle records with truth, each at `image`'s sample rate, and each
/// one's name and gaps in `t_s`.
fn read_vehicles(image: &Image, paths: &[PathBuf]) -> Result<(Vec<NavRecord>, Vec<RecordHoles>)> {
    let mut vehicles = Vec::new();
    let mut holes = Vec::new();
    for p in CsvFiles::from_args(paths, &ReadOptions::default())?.0 {
        let r = crate::replay::motion::read_truth_csv(image, &p)?;
        vehicles.push(r.truth);
        holes.push((p.display().to_string(), r.holes));
    }
    Ok((vehicles, holes))
}

/// `--preset motion`: trains on the static records and writes the identifier image.
fn run_motion(a: &Args) -> Result<()> {
    let out = a.save_identifier.as_deref();
    let gyro = Gyro::from_arg(&a.gyro)?;
    let sensor = gyro.sensor()?;
    if gyro.identified.is_some() {
        eprintln!(
            "{}: note: its [identified] model is not used: identify fits a new one on the calibration runs",
            gyro.source
        );
    }
    let train = CsvFiles::from_args(&a.train, &a.record.options())?;
    let validate = if a.validate.is_empty() {
        Vec::new()
    } else {
        CsvFiles::from_args(&a.validate, &ReadOptions::default())?.0
    };
    let tune_on = if a.tune_on.is_empty() {
        Vec::new()
    } else {
        CsvFiles::from_args(&a.tune_on, &ReadOptions::default())?.0
    };
    let unit_runs = if a.unit_runs.is_empty() {
        None
    } else {
        Some(CsvFiles::from_args(&a.unit_runs, &a.record.options())?)
    };
    let mut inputs: Vec<&std::path::Path> = train
        .0
        .iter()
        .chain(&validate)
        .chain(&tune_on)
        .chain(unit_runs.iter().flat_map(|u| &u.0))
        .map(PathBuf::as_path)
        .collect();
    inputs.extend(gyro.path.as_deref());
    let mut outputs: Vec<&std::path::Path> = out.into_iter().collect();
    outputs.extend(a.json.as_deref());
    outputs.extend(a.save_gyro.as_deref());
    record::refuse_overwrite_all(&inputs, &outputs)?;
    if let Some(g) = &a.save_gyro {
        if outputs[..outputs.len() - 1].contains(&g.as_path()) {
            anyhow::bail!(
                "{}: --save-gyro names the same file as another output",
                g.display()
            );
        }
    }
    let mut o = motion::TrainOptions::new(sensor.config);
    if let Some(w) = a.window_s {
        o.config.window_s = w;
        if !o.config.is_valid() {
            anyhow::bail!("--window-s {w}: must be finite and > 0");
        }
    }
    let trained = motion::train(&train, &o)?;
    // Every record's gaps in `t_s` come from the read that loaded it: the calibration runs'
    // here, the tune and validation vehicles' where they are read (records with truth at
    // the image's rate, the sensor's, when they lack `t_s`); the JSON lists them in that
    // order: runs, validation, tune.
    let train_holes = report_holes(&train.holes()?);
    // What the calibration runs showed, beside the gyro file's; the image carries the fit.
    eprintln!(
        "{}",
        motion::calibration::table(&trained.calibration, &sensor.config)
    );
    for w in &trained.calibration_warnings {
        eprintln!("WARNING: {w}");
    }
    let mut image = trained.image;
    let fitted_markov = image.model.markov;
    let mut tune_holes = Vec::new();
    let tuning = if a.tune_on.is_empty() {
        None
    } else {
        let (vehicles, holes) = read_vehicles(&image, &a.tune_on)?;
        tune_holes = report_holes(&holes);
        let (tuned, tuning) = motion::tune::tune(&image, &vehicles)?;
        eprintln!("{}", motion::tune::describe(&tuning));
        image = tuned;
        Some(tuning)
    };
    // The one unit's own runs make the family's model that unit's.
    let unit = match &unit_runs {
        None => None,
        Some(u) => {
            let personal = motion::personalize(&image, &fitted_markov, u, &sensor.config)?;
            eprintln!(
                "unit: the model made the unit's on its {} own runs ({})",
                u.0.len(),
                personal.describe()
            );
            image = personal.image;
            Some(personal)
        }
    };
    let bytes = motion::image_bytes(&image)?;
    eprint!(
        "{}",
        motion::show::text("model", &motion::show::describe(&image, &bytes))
    );
    let mut validate_holes = Vec::new();
    let validation = if a.validate.is_empty() {
        None
    } else {
        let q = a
            .baseline_q_dps2
            .map(|q| (q, "--baseline-q-dps2".to_string()));
        let v = crate::replay::motion::score_records(&image, &a.validate, q)?;
        let holes: Vec<RecordHoles> = v
            .records
            .iter()
            .map(|r| (r.record.clone(), r.holes))
            .collect();
        validate_holes = report_holes(&holes);
        crate::replay::motion::print_validation(&v)?;
        Some(v)
    };
    let holes: Vec<HolesSummary> = train_holes
        .into_iter()
        .chain(validate_holes)
        .chain(tune_holes)
        .collect();
    // What the firmware does with the image, said first; one that does not fit is not
    // written, nor the report, unless --force.
    let firmware = crate::firmware_fit::check_image(&image)?;
    eprint!("{}", firmware.text());
    if let Some(out) = out {
        firmware.refuse(out, a.force)?;
    }
    let forced = out.is_some() && a.force && !firmware.fits;
    if let Some(j) = &a.json {
        let text = serde_json::to_string_pretty(&serde_json::json!({
            "preset": "motion",
            "estimator": "drift filter (fog_core::drift_filter)",
            "sensor": sensor.name,
            "sensor_source": sensor.source,
            "gyro_file": a.save_gyro.as_ref().map(|p| p.display().to_string()),
            "calibration": trained.calibration,
            "calibration_warnings": trained.calibration_warnings,
            "fit": trained.fit,
            "model": motion::show::describe(&image, &bytes),
            "validation": validation,
            "tuning": tuning,
            "unit": unit,
            "holes": holes,
            "firmware": firmware,
            "written_with_force": forced,
        }))
        .context("report to JSON")?;
        record::write_atomic(j, |w| {
            use std::io::Write;
            w.write_all(text.as_bytes())?;
            Ok(())
        })?;
    }
    if let Some(out) = out {
        motion::write_image(out, &image, a.force)?;
    }
    if let Some(p) = &a.save_gyro {
        save_gyro(p, &gyro, &image, &train.0)?;
    }
    eprintln!(
        "drift filter: model fitted on {} calibration runs{} -> {}{}",
        train.0.len(),
        if tuning.is_some() {
            ", tuned on the tune vehicles"
        } else {
            ""
        },
        out.map_or(
            "no image written (--save-identifier FILE writes it)".to_string(),
            |o| o.display().to_string()
        ),
        validation
            .as_ref()
            .and_then(|v| v.headline.as_ref())
            .map_or(String::new(), |h| format!(
                "; over the {} {}: {}",
                h.records,
                h.records_are,
                h.verdict_line()
            ))
    );
    if let (true, Some(out)) = (forced, out) {
        eprintln!(
            "{}: WARNING: written because of --force, although the image does not fit the firmware: {}",
            out.display(),
            firmware.why()
        );
    }
    Ok(())
}

/// `--save-gyro`: `gyro` with `[identified]` set to `image`'s model.
fn save_gyro(path: &std::path::Path, gyro: &Gyro, image: &Image, runs: &[PathBuf]) -> Result<()> {
    let header = vec![
        format!(
            "{}: {}, with [identified]: the drift filter's model",
            gyro.name, gyro.source
        ),
        format!(
            "host-sim identify fitted on {} calibration runs ({}{}); the image holds it too.",
            runs.len(),
            runs.iter()
                .take(3)
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", "),
            if runs.len() > 3 { ", ..." } else { "" }
        ),
    ];
    let parts = crate::gyro::write::Parts {
        header,
        name: &gyro.name,
        model: gyro.model.clone(),
        drift_bound_dps: gyro.drift_bound_dps,
        temperature_column: gyro.temperature_column.as_deref(),
        identified: Some(crate::gyro::Identified {
            model: image.model,
            runs: image.trained_runs,
        }),
    };
    crate::gyro::write::save(path, &parts, &[])?;
    eprintln!("gyro file with the fitted model -> {}", path.display());
    Ok(())
}

//! The gyro file: one TOML file for one gyro, read by `simulate`, `gap`, `identify`,
//! `replay` and `image` (`--gyro NAME|FILE`), written by `identify --save-gyro`, `allan
//! --save-gyro` and `gap --save-gyro`. Every value is in the units of datasheets, with the
//! unit in the key (`dps` deg/s, `dph` deg/h, `deg_per_rth` deg/sqrt(h), `dph_per_rth`
//! deg/h/sqrt(h), `c` deg C, `s` seconds); the reader converts them exactly
//! ([`units`]: the decimal written, divided exactly, rounded once).
//!
//! # The datasheet part (top level; what a user writes)
//! ```toml
//! # My gyro, 200 Hz, +-100 deg/s (values from its datasheet; ASSUMED where marked)
//! name = "mygyro"                  # shown in messages and reports (default: the file's stem)
//! sample_rate_hz = 200.0           # output data rate, Hz
//! full_scale_dps = 100.0           # largest rate the unit reports, deg/s
//! quantum_dps = 0.0030517578125    # one output count, deg/s (absent or 0: floating point)
//! arw_deg_per_rth = 0.05           # angle random walk (white rate noise), deg/sqrt(h)
//! bias_instability_dph = 1.0       # bias instability B, deg/h (the Allan floor is 0.664 B)
//! rrw_dph_per_rth = 0.5            # rate random walk K, deg/h/sqrt(h)
//! drift_bound_dph = 30.0           # ASSUMED: the largest drift the unit can have, deg/h
//!
//! [temperature]
//! column = "temp_c"                # the records' case-temperature column (absent: none)
//! ```
//! Also at the top level: `quantization_mode` (`"round"`, the default: each rate sample
//! rounded to a count; `"angle"`: the integrated angle is, `Q = quantum_dps dt / sqrt(12)`)
//! and `rate_ramp_dph_per_h` (rate ramp R, deg/h per hour).
//!
//! Who needs what: `simulate` and `gap --gyro` take every key and section but
//! `drift_bound_dph`, `[temperature] column` and `[identified]` (a missing noise term is 0,
//! off; `sample_rate_hz` or `--rate-hz`); `identify`, `replay` and `image` need
//! `sample_rate_hz` (10 to 2000 Hz), `full_scale_dps`, `arw_deg_per_rth` (> 0) and
//! `drift_bound_dph`, and take `quantum_dps`, `[temperature] column` and `[identified]`;
//! they say which key is missing. `[temperature] column`: every reader takes the
//! temperature from a column named `temp_c` ([`crate::sensor`]); another name is refused.
//!
//! # What the simulator adds (optional sections; each key optional, 0 = off unless said)
//! - `[noise]`: `flicker_tau_min_s` (1), `flicker_tau_max_s` (1e5): the flicker bank behind
//!   the bias instability (flat within 2 % for tau in `[20 min, max / 10]`);
//!   `gm_sigma_dph`, `gm_tau_s` (100): a first-order Gauss-Markov term; `sine_amplitude_dph`,
//!   `sine_freq_hz`, `sine_phase_deg`: a sinusoidal drift.
//! - `[bias]`: `turn_on_dph` (fixed), `turn_on_sigma_dph` (per power-on, drawn from the
//!   seed), `warmup_dph` and `warmup_tau_s` (600): `warmup_dph exp(-t / warmup_tau_s)`.
//! - `[temperature]` beside `column`: the profile `initial_c` (25), `ramp_c_per_s`,
//!   `cycle_amplitude_c`, `cycle_period_s` (3600), `warmup_rise_c`, `warmup_tau_s` (900),
//!   and the links `reference_c` (25), `bias_dph_per_c` (drift per deg C from the
//!   reference), `shupe_dph_per_c_per_min` (drift per deg C/min of change).
//! - `[scale_factor]` (`error_ppm`, `quadratic_ppm_per_dps`), `[motion]` (profiles
//!   `constant`, `vehicle`, `turntable`, `file`; rates in deg/s), `[timing]`
//!   (`rate_error_ppm`, `jitter_rms_s`), `[faults]` (`drop_probability`,
//!   `spike_probability`, `spike_amplitude_dps`), `[family]` (`unit_seed`, `unit_spread`,
//!   `initial_c_range`, `warmup_rise_c_range`, `ramp_c_per_s_range`): as
//!   [`crate::sim::Model`]'s fields, unchanged.
//!
//! # What `identify` fitted (`[identified]`, written by `identify --save-gyro`)
//! The drift filter's gyro model ([`fog_core::gyro_model::GyroModel`]) fitted on `runs`
//! calibration runs: `arw_deg_per_rth`, `rrw_dph_per_rth`, `drift_bound_dph`,
//! `turn_on_dph` / `turn_on_sigma_dph` (family mean and unit spread), `warmup_dph` /
//! `warmup_sigma_dph` / `warmup_tau_min_s` / `warmup_tau_max_s`, `reference_c`, `temperature_dph_per_c` /
//! `temperature_sigma_dph_per_c`, `temperature_rate_dph_per_c_per_min` /
//! `temperature_rate_sigma_dph_per_c_per_min`, and up to three `[[identified.markov]]`
//! (`sigma_dph`, `tau_s`). `replay` and `image` run it as the drift filter's model (the
//! filter's settings at their defaults); without it they take the model of the datasheet
//! part alone ([`fog_core::gyro_model::GyroModel::for_sensor`]). `identify` fits a new one;
//! `simulate` does not simulate it (its unit-to-unit spreads and several Gauss-Markov terms
//! have no simulator counterpart) and says so.
//!
//! # Old formats
//! The sensor file (`noise_density_deg_rth`) and the model file (`[noise]
//! arw_dps_per_rthz`, deg/s units) are refused with a message naming each old key's new
//! name; `host-sim gyro convert --input OLD --output NEW` converts one ([`convert`]). A bad
//! file stops the command with one message `FILE:LINE:COL: ...`.
//!
//! The built-ins ([`BUILTIN`], `host-sim/gyros/*.toml`) are gyro files embedded in the
//! binary and read by the same code; each reproduces its fog-core sensor constant and the
//! simulator model of the old preset bit for bit (tests).

pub mod convert;
pub mod fitted;
mod parse;
pub mod units;
pub mod write;

use crate::sensor::SensorSpec;
use crate::sim::Model;
use anyhow::{anyhow, Result};
use fog_core::drift_filter::DriftFilterConfig;
use fog_core::gyro_model::GyroModel;
use fog_core::image::Image;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The built-in gyros: (name, file in the repository, its text).
pub const BUILTIN: [(&str, &str, &str); 2] = [
    (
        "ecore2000",
        "host-sim/gyros/ecore2000.toml",
        include_str!("../../gyros/ecore2000.toml"),
    ),
    (
        "kvh1750",
        "host-sim/gyros/kvh1750.toml",
        include_str!("../../gyros/kvh1750.toml"),
    ),
];

/// What the calibration runs fitted (`[identified]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Identified {
    /// The drift filter's model (its rate and quantum from the datasheet part).
    pub model: GyroModel,
    /// Calibration runs it was fitted on.
    pub runs: u32,
}

/// A gyro file read and checked.
#[derive(Debug, Clone)]
pub struct Gyro {
    /// `name` (default: the file's stem).
    pub name: String,
    /// Where it came from: the path as given, or `host-sim/gyros/NAME.toml` for a built-in.
    pub source: String,
    /// The file (None for a built-in).
    pub path: Option<PathBuf>,
    /// True for a built-in.
    pub builtin: bool,
    /// The simulator's model: the datasheet part and the simulator's sections.
    pub model: Model,
    /// `drift_bound_dph` in deg/s.
    pub drift_bound_dps: Option<f64>,
    /// `[temperature] column` (`Some("temp_c")` or None).
    pub temperature_column: Option<String>,
    /// `[identified]`.
    pub identified: Option<Identified>,
    /// Top-level keys the file gives (the estimator's required keys are checked on use).
    given: Vec<&'static str>,
    /// `FILE:LINE:COL` of each key given, by its path (`bias.warmup_dph`).
    places: BTreeMap<String, String>,
    /// Each value as written, by its path.
    literals: BTreeMap<String, String>,
}

impl Gyro {
    /// Parses and checks gyro-file text; `source` (the file name) starts every error
    /// message. A relative `[motion] file` is taken from `dir`.
    pub fn from_toml_str(text: &str, source: &str, dir: Option<&Path>) -> Result<Self> {
        parse::parse(text, source, dir)
    }

    /// Reads and checks a gyro file.
    pub fn load(path: &Path) -> Result<Self> {
        let source = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| anyhow!("{source}: {e}"))?;
        let mut g = Self::from_toml_str(&text, &source, path.parent())?;
        g.path = Some(path.to_path_buf());
        Ok(g)
    }

    /// The built-in `name` ([`BUILTIN`]), `None` when there is none of that name.
    pub fn builtin(name: &str) -> Option<Result<Self>> {
        let (_, file, text) = BUILTIN.iter().find(|b| b.0 == name)?;
        Some(Self::from_toml_str(text, file, None).map(|g| Self { builtin: true, ..g }))
    }

    /// The built-in `name`, an error naming the built-ins when there is none.
    pub fn builtin_named(name: &str) -> Result<Self> {
        Self::builtin(name).unwrap_or_else(|| Err(unknown(name)))
    }

    /// `--gyro NAME|FILE`: a built-in's name, else a path to a gyro file (an existing file,
    /// or any argument ending in `.toml`).
    pub fn from_arg(arg: &str) -> Result<Self> {
        if let Some(b) = Self::builtin(arg) {
            return b;
        }
        let path = Path::new(arg);
        if path.is_file() || arg.ends_with(".toml") {
            return Self::load(path);
        }
        Err(unknown(arg))
    }

    /// `FILE:LINE:COL` of the key at `path` when the file gives it, else the file.
    pub fn place(&self, path: &str) -> String {
        self.places
            .get(path)
            .cloned()
            .unwrap_or_else(|| self.source.clone())
    }

    /// The value at `path` as written in the file.
    pub fn literal(&self, path: &str) -> Option<&str> {
        self.literals.get(path).map(String::as_str)
    }

    /// True when the file gives the top-level key `key`.
    pub fn gives(&self, key: &str) -> bool {
        self.given.contains(&key)
    }

    /// The sensor as the drift filter and the stream readers take it (`identify`,
    /// `replay`, `image`): an error naming the file, the key and its place when the
    /// datasheet part lacks one they need or a value is out of their range.
    pub fn sensor(&self) -> Result<SensorSpec> {
        SensorSpec::from_gyro(self)
    }

    /// The drift image this file stands for: its `[identified]` model, else the model of
    /// the datasheet part alone ([`GyroModel::for_sensor`]); the filter at its default
    /// settings.
    pub fn image(&self) -> Result<Image> {
        let sensor = self.sensor()?.config;
        Ok(match &self.identified {
            Some(id) => Image {
                model: id.model,
                config: DriftFilterConfig::default(),
                full_scale_dps: sensor.full_scale_dps,
                trained_runs: id.runs,
            },
            None => crate::motion::untrained(&sensor),
        })
    }

    /// What [`Self::image`] holds, in words (for messages).
    pub fn image_words(&self) -> String {
        match &self.identified {
            Some(id) => format!(
                "{}'s [identified] model (fitted on {} calibration runs)",
                self.source, id.runs
            ),
            None => format!(
                "{}'s datasheet part alone (no calibration run)",
                self.source
            ),
        }
    }

    /// The simulator's model; a note on stderr when the file has an `[identified]` section
    /// (not simulated: module docs).
    pub fn sim_model(&self) -> Model {
        if self.identified.is_some() {
            eprintln!(
                "{}: note: [identified] (the drift filter's fitted model) is not simulated; the simulator takes the datasheet part and its own sections",
                self.source
            );
        }
        self.model.clone()
    }
}

/// The error for an argument that is neither a built-in nor a file.
fn unknown(arg: &str) -> anyhow::Error {
    let names: Vec<&str> = BUILTIN.iter().map(|b| b.0).collect();
    anyhow!(
        "unknown gyro {arg:?}: give a built-in ({}) or a path to a .toml gyro file",
        names.join(", ")
    )
}

/// The simulator model of a built-in gyro.
pub fn builtin_model(name: &str) -> Result<Model> {
    Gyro::builtin_named(name).map(|g| g.model)
}

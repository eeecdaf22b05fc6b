//! The FOG error model the simulator runs ([`Model`]), in deg/s, s and deg C, with the
//! unit in every field name.
//!
//! Users write it as a gyro file ([`crate::gyro`]: datasheet units, deg/h and
//! deg/sqrt(h)), which the reader converts into this model exactly. The TOML form of this
//! struct itself (`[noise] arw_dps_per_rthz = ...`) is the old model-file format, read only
//! by `host-sim gyro convert` ([`Model::from_toml_str`]).
//!
//! Every field is optional in a file; a missing one is 0 (the term is off) unless its doc
//! gives another default.

use anyhow::{bail, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

use super::family::Family;
use super::motion::{Profile, Turntable, Vehicle};

/// Earth's rotation rate, deg/s (sidereal: 360 deg / 86164.0905 s).
pub const EARTH_RATE_DPS: f64 = 360.0 / 86_164.090_5;

/// A complete FOG error model. Its file form: a gyro file ([`crate::gyro`]), e.g.
/// `host-sim/gyros/ecore2000.toml`.
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Model {
    /// Nominal output rate, Hz; `--rate-hz` overrides it. Required from one of the two.
    pub sample_rate_hz: Option<f64>,
    /// Output saturates at +/- this rate, deg/s (none when absent). Also the E-Core count
    /// scale: 32768 counts = full scale.
    pub full_scale_dps: Option<f64>,
    /// Quantization of the rate output.
    #[serde(default)]
    pub quantization: Quantization,
    /// Stochastic error terms.
    #[serde(default)]
    pub noise: Noise,
    /// Turn-on bias and the warm-up transient.
    #[serde(default)]
    pub bias: Bias,
    /// Temperature profile and the bias sensitivities to it.
    #[serde(default)]
    pub temperature: Temperature,
    /// Scale-factor error and nonlinearity, applied to the true rate.
    #[serde(default)]
    pub scale_factor: ScaleFactor,
    /// The true rate the gyro is subjected to (default: static gyro, no Earth rate).
    #[serde(default)]
    pub motion: Motion,
    /// Sample clock tolerance and jitter.
    #[serde(default)]
    pub timing: Timing,
    /// Dropped samples and spikes.
    #[serde(default)]
    pub faults: Faults,
    /// A gyro family: per-unit spread of the coefficients and per-record temperature
    /// conditions (all off by default).
    #[serde(default)]
    pub family: Family,
}

/// How the rate output is quantized.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum QuantMode {
    /// Each rate sample rounded to the nearest count: a white error of variance
    /// `quantum^2 / 12` (an ARW-like term `quantum * sqrt(dt / 12)` in the Allan variance).
    #[default]
    Round,
    /// Rounding with the residual carried to the next sample (the integrated angle is
    /// quantized): the `3 Q^2 / tau^2` term, `Q = quantum_dps * dt / sqrt(12)` deg.
    Angle,
}

/// `[quantization]`
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Quantization {
    /// One count, deg/s (0 = no quantization).
    pub quantum_dps: f64,
    /// `round` (default) or `angle`.
    pub mode: QuantMode,
}

/// `[noise]`
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Noise {
    /// Angle random walk N (white rate noise), deg/s/sqrt(Hz) (= deg/sqrt(h) / 60).
    pub arw_dps_per_rthz: f64,
    /// Bias instability B, deg/s: the Allan deviation floor is `0.664 B`.
    pub bias_instability_dps: f64,
    /// Shortest correlation time of the flicker bank, s (default 1). The floor is flat
    /// within 2 % for tau in `[20 flicker_tau_min_s, flicker_tau_max_s / 10]`.
    pub flicker_tau_min_s: f64,
    /// Longest correlation time of the flicker bank, s (default 1e5).
    pub flicker_tau_max_s: f64,
    /// Rate random walk K, deg/s/s/sqrt(Hz) = deg/s^1.5.
    pub rrw_dps_per_s_rthz: f64,
    /// Rate ramp R, deg/s per s.
    pub rate_ramp_dps_per_s: f64,
    /// Exponentially correlated (first-order Gauss-Markov) noise: standard deviation, deg/s.
    pub gm_sigma_dps: f64,
    /// Its correlation time, s (default 100).
    pub gm_tau_s: f64,
    /// Sinusoidal disturbance: amplitude, deg/s.
    pub sine_amplitude_dps: f64,
    /// Its frequency, Hz.
    pub sine_freq_hz: f64,
    /// Its phase at t = 0, deg.
    pub sine_phase_deg: f64,
}

impl Default for Noise {
    fn default() -> Self {
        Self {
            arw_dps_per_rthz: 0.0,
            bias_instability_dps: 0.0,
            flicker_tau_min_s: 1.0,
            flicker_tau_max_s: 1e5,
            rrw_dps_per_s_rthz: 0.0,
            rate_ramp_dps_per_s: 0.0,
            gm_sigma_dps: 0.0,
            gm_tau_s: 100.0,
            sine_amplitude_dps: 0.0,
            sine_freq_hz: 0.0,
            sine_phase_deg: 0.0,
        }
    }
}

/// `[bias]`
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Bias {
    /// Fixed turn-on bias, deg/s.
    pub turn_on_dps: f64,
    /// Random turn-on bias (run to run), standard deviation, deg/s: drawn once per seed.
    pub turn_on_sigma_dps: f64,
    /// Warm-up transient: bias `warmup_dps * exp(-t / warmup_tau_s)` after switch-on, deg/s.
    pub warmup_dps: f64,
    /// Its time constant, s (default 600).
    pub warmup_tau_s: f64,
}

impl Default for Bias {
    fn default() -> Self {
        Self {
            turn_on_dps: 0.0,
            turn_on_sigma_dps: 0.0,
            warmup_dps: 0.0,
            warmup_tau_s: 600.0,
        }
    }
}

/// `[temperature]`: `T(t) = initial_c + ramp_c_per_s t + cycle_amplitude_c sin(2 pi t /
/// cycle_period_s) + warmup_rise_c (1 - exp(-t / warmup_tau_s))`; each part is one of the
/// profiles (constant, ramp, cycle, warm-up) and they add.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Temperature {
    /// Temperature at switch-on, deg C (default 25).
    pub initial_c: f64,
    /// Ramp, deg C per s.
    pub ramp_c_per_s: f64,
    /// Cycle amplitude, deg C.
    pub cycle_amplitude_c: f64,
    /// Cycle period, s (default 3600).
    pub cycle_period_s: f64,
    /// Self-heating after switch-on: total rise, deg C.
    pub warmup_rise_c: f64,
    /// Its time constant, s (default 900).
    pub warmup_tau_s: f64,
    /// Temperature at which the temperature bias is zero, deg C (default 25).
    pub reference_c: f64,
    /// Bias sensitivity to temperature, deg/s per deg C: `k (T - reference_c)`.
    pub bias_dps_per_c: f64,
    /// Bias sensitivity to the temperature rate (Shupe effect), deg/s per (deg C/s).
    pub shupe_dps_per_c_per_s: f64,
}

impl Default for Temperature {
    fn default() -> Self {
        Self {
            initial_c: 25.0,
            ramp_c_per_s: 0.0,
            cycle_amplitude_c: 0.0,
            cycle_period_s: 3600.0,
            warmup_rise_c: 0.0,
            warmup_tau_s: 900.0,
            reference_c: 25.0,
            bias_dps_per_c: 0.0,
            shupe_dps_per_c_per_s: 0.0,
        }
    }
}

impl Temperature {
    /// Temperature, deg C, and its rate, deg C/s, at `t_s`.
    pub fn at(&self, t_s: f64) -> (f64, f64) {
        let w = std::f64::consts::TAU / self.cycle_period_s;
        let e = (-t_s / self.warmup_tau_s).exp();
        let temp_c = self.initial_c
            + self.ramp_c_per_s * t_s
            + self.cycle_amplitude_c * (w * t_s).sin()
            + self.warmup_rise_c * (1.0 - e);
        let dtemp_c_per_s = self.ramp_c_per_s
            + self.cycle_amplitude_c * w * (w * t_s).cos()
            + self.warmup_rise_c * e / self.warmup_tau_s;
        (temp_c, dtemp_c_per_s)
    }
}

/// `[scale_factor]`: sensed rate `w (1 + 1e-6 (error_ppm + quadratic_ppm_per_dps |w|))`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ScaleFactor {
    /// Scale-factor error, ppm.
    pub error_ppm: f64,
    /// Nonlinearity: scale-factor error growing with |rate|, ppm per deg/s.
    pub quadratic_ppm_per_dps: f64,
}

/// `[motion]`: the true inertial rate about the sensitive axis (profiles: see
/// [`super::motion`]).
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Motion {
    /// `constant` (default; also `sine`), `vehicle`, `turntable` or `file`.
    pub profile: Profile,
    /// Constant platform rate, deg/s (added to every profile).
    pub rate_dps: f64,
    /// Sinusoidal platform rate: amplitude, deg/s (added to every profile).
    pub sine_amplitude_dps: f64,
    /// Its frequency, Hz.
    pub sine_freq_hz: f64,
    /// Latitude, deg: adds Earth rate `EARTH_RATE_DPS sin(latitude)` (sensitive axis
    /// vertical). 0 (the default) adds nothing.
    pub latitude_deg: f64,
    /// `[motion.vehicle]`: statistics of the `vehicle` profile.
    pub vehicle: Vehicle,
    /// `[motion.turntable]`: the schedule of the `turntable` profile.
    pub turntable: Turntable,
    /// CSV of the `file` profile (`t_s,true_rate_dps`); relative to the model file.
    pub file: Option<PathBuf>,
}

impl Motion {
    /// True when the platform never moves (the default: records keep their 5 columns).
    pub fn is_static(&self) -> bool {
        self.profile == Profile::Constant && self.rate_dps == 0.0 && self.sine_amplitude_dps == 0.0
    }
}

/// `[timing]`
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Timing {
    /// Sample clock error: the true rate is `rate_hz (1 + 1e-6 rate_error_ppm)`.
    pub rate_error_ppm: f64,
    /// Timestamp jitter, standard deviation, s (clipped at 0.45 sample periods).
    pub jitter_rms_s: f64,
}

/// `[faults]`
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Faults {
    /// Probability that a sample is lost (a gap in `t_s`; no frame in `ecore-bin`).
    pub drop_probability: f64,
    /// Probability that a sample carries a spike.
    pub spike_probability: f64,
    /// Spike size, deg/s (random sign).
    pub spike_amplitude_dps: f64,
}

/// What a value must satisfy.
#[derive(Clone, Copy)]
enum Rule {
    Finite,
    NonNegative(&'static str),
    Positive,
    Probability,
    Range(f64, f64),
}

/// One single-value rule: (section, key, value, rule).
type Check = (&'static str, &'static str, f64, Rule);

/// The first rule a model breaks ([`Model::check`]), for the reader to place in its file.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Bad {
    /// A single value: (section, "" = top level; key; value; why).
    Value {
        section: &'static str,
        key: &'static str,
        value: f64,
        why: String,
    },
    /// `[[motion.turntable.step]]` number `index` (from 0).
    Step {
        index: usize,
        key: &'static str,
        why: String,
    },
    /// `profile = "file"` without `file`.
    NoMotionFile,
    /// `[family]`.
    Family { key: &'static str, why: String },
}

/// Why a negative noise density is refused.
const DENSITY: &str = "a noise density must be >= 0";
/// Why a negative size is refused.
const SIZE: &str = "must be >= 0";

impl Model {
    /// Reads and validates a file of the old model-file format ([`Self::from_toml_str`]).
    pub fn load(path: &Path) -> Result<Self> {
        let name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
        let mut model = Self::from_toml_str(&text, &name)?;
        if let (Some(f), Some(dir)) = (&model.motion.file, path.parent()) {
            if f.is_relative() {
                model.motion.file = Some(dir.join(f));
            }
        }
        Ok(model)
    }

    /// Parses and validates model TOML of the old model-file format (before the gyro file,
    /// [`crate::gyro`]); `name` (a file name) starts every error message. Read by `host-sim
    /// gyro convert` and the tests only: the commands read gyro files.
    pub fn from_toml_str(text: &str, name: &str) -> Result<Self> {
        let model: Model = toml::from_str(text).map_err(|e| {
            let line = e
                .span()
                .map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1);
            let at = line.map_or(String::new(), |l| format!(":{l}"));
            let msg = e.message().replace('\n', " ");
            anyhow::anyhow!("{name}{at}: {}{}", msg.trim(), unit_hint(&msg))
        })?;
        model.check().map_err(|bad| {
            let (at, what) = match &bad {
                Bad::Value {
                    section,
                    key,
                    value,
                    why,
                } => {
                    let sec = if section.is_empty() {
                        String::new()
                    } else {
                        format!("[{section}] ")
                    };
                    (
                        find_line(text, section, key),
                        format!("{sec}{key} = {value}: {why}"),
                    )
                }
                Bad::Step { index, key, why } => (
                    find_line_nth(text, "motion.turntable.step", *index, key),
                    format!("[[motion.turntable.step]] #{} {key}: {why}", index + 1),
                ),
                Bad::NoMotionFile => (
                    find_line(text, "motion", "profile"),
                    "[motion] profile = \"file\" needs `file = \"PATH.csv\"`".to_string(),
                ),
                Bad::Family { key, why } => (
                    find_line(text, "family", key),
                    format!("[family] {key}: {why}"),
                ),
            };
            let at = at.map_or(String::new(), |l| format!(":{l}"));
            anyhow::anyhow!("{name}{at}: {what}")
        })?;
        Ok(model)
    }

    /// Every rule a model must satisfy, the first one broken: single values in the order
    /// of [`KEYS`], then the ranges, the turntable's steps, the motion file, the family.
    pub(crate) fn check(&self) -> Result<(), Bad> {
        self.validate()
            .map_err(|(section, key, value, why)| Bad::Value {
                section,
                key,
                value,
                why,
            })?;
        self.motion
            .turntable
            .check()
            .map_err(|(index, key, why)| Bad::Step { index, key, why })?;
        if self.motion.profile == Profile::File && self.motion.file.is_none() {
            return Err(Bad::NoMotionFile);
        }
        self.family
            .check()
            .map_err(|(key, why)| Bad::Family { key, why })
    }

    /// Every single-value rule, section by section in the order of [`KEYS`]: (section,
    /// key, value, rule).
    fn checks(&self) -> Vec<Check> {
        [
            self.top_level_checks(),
            self.quantization_checks(),
            self.noise_checks(),
            self.bias_checks(),
            self.temperature_checks(),
            self.scale_factor_checks(),
            self.motion_checks(),
            self.vehicle_checks(),
            self.timing_checks(),
            self.faults_checks(),
        ]
        .concat()
    }

    /// The top-level keys' rules.
    fn top_level_checks(&self) -> Vec<Check> {
        use Rule::*;
        vec![
            (
                "",
                "sample_rate_hz",
                self.sample_rate_hz.unwrap_or(1.0),
                Positive,
            ),
            (
                "",
                "full_scale_dps",
                self.full_scale_dps.unwrap_or(1.0),
                Positive,
            ),
        ]
    }

    /// `[quantization]`'s rules.
    fn quantization_checks(&self) -> Vec<Check> {
        use Rule::*;
        vec![(
            "quantization",
            "quantum_dps",
            self.quantization.quantum_dps,
            NonNegative(SIZE),
        )]
    }

    /// `[noise]`'s rules.
    fn noise_checks(&self) -> Vec<Check> {
        use Rule::*;
        let n = &self.noise;
        vec![
            (
                "noise",
                "arw_dps_per_rthz",
                n.arw_dps_per_rthz,
                NonNegative(DENSITY),
            ),
            (
                "noise",
                "bias_instability_dps",
                n.bias_instability_dps,
                NonNegative(DENSITY),
            ),
            ("noise", "flicker_tau_min_s", n.flicker_tau_min_s, Positive),
            ("noise", "flicker_tau_max_s", n.flicker_tau_max_s, Positive),
            (
                "noise",
                "rrw_dps_per_s_rthz",
                n.rrw_dps_per_s_rthz,
                NonNegative(DENSITY),
            ),
            (
                "noise",
                "rate_ramp_dps_per_s",
                n.rate_ramp_dps_per_s,
                Finite,
            ),
            (
                "noise",
                "gm_sigma_dps",
                n.gm_sigma_dps,
                NonNegative(DENSITY),
            ),
            ("noise", "gm_tau_s", n.gm_tau_s, Positive),
            (
                "noise",
                "sine_amplitude_dps",
                n.sine_amplitude_dps,
                NonNegative(SIZE),
            ),
            ("noise", "sine_freq_hz", n.sine_freq_hz, NonNegative(SIZE)),
            ("noise", "sine_phase_deg", n.sine_phase_deg, Finite),
        ]
    }

    /// `[bias]`'s rules.
    fn bias_checks(&self) -> Vec<Check> {
        use Rule::*;
        let b = &self.bias;
        vec![
            ("bias", "turn_on_dps", b.turn_on_dps, Finite),
            (
                "bias",
                "turn_on_sigma_dps",
                b.turn_on_sigma_dps,
                NonNegative(SIZE),
            ),
            ("bias", "warmup_dps", b.warmup_dps, Finite),
            ("bias", "warmup_tau_s", b.warmup_tau_s, Positive),
        ]
    }

    /// `[temperature]`'s rules.
    fn temperature_checks(&self) -> Vec<Check> {
        use Rule::*;
        let t = &self.temperature;
        vec![
            ("temperature", "initial_c", t.initial_c, Range(-273.15, 1e3)),
            ("temperature", "ramp_c_per_s", t.ramp_c_per_s, Finite),
            (
                "temperature",
                "cycle_amplitude_c",
                t.cycle_amplitude_c,
                NonNegative(SIZE),
            ),
            ("temperature", "cycle_period_s", t.cycle_period_s, Positive),
            ("temperature", "warmup_rise_c", t.warmup_rise_c, Finite),
            ("temperature", "warmup_tau_s", t.warmup_tau_s, Positive),
            (
                "temperature",
                "reference_c",
                t.reference_c,
                Range(-273.15, 1e3),
            ),
            ("temperature", "bias_dps_per_c", t.bias_dps_per_c, Finite),
            (
                "temperature",
                "shupe_dps_per_c_per_s",
                t.shupe_dps_per_c_per_s,
                Finite,
            ),
        ]
    }

    /// `[scale_factor]`'s rules.
    fn scale_factor_checks(&self) -> Vec<Check> {
        use Rule::*;
        vec![
            (
                "scale_factor",
                "error_ppm",
                self.scale_factor.error_ppm,
                Range(-1e5, 1e5),
            ),
            (
                "scale_factor",
                "quadratic_ppm_per_dps",
                self.scale_factor.quadratic_ppm_per_dps,
                Finite,
            ),
        ]
    }

    /// `[motion]`'s rules (its vehicle: [`Self::vehicle_checks`]).
    fn motion_checks(&self) -> Vec<Check> {
        use Rule::*;
        let m = &self.motion;
        vec![
            ("motion", "rate_dps", m.rate_dps, Finite),
            (
                "motion",
                "sine_amplitude_dps",
                m.sine_amplitude_dps,
                NonNegative(SIZE),
            ),
            ("motion", "sine_freq_hz", m.sine_freq_hz, NonNegative(SIZE)),
            ("motion", "latitude_deg", m.latitude_deg, Range(-90.0, 90.0)),
        ]
    }

    /// `[motion.vehicle]`'s rules.
    fn vehicle_checks(&self) -> Vec<Check> {
        use Rule::*;
        let v = &self.motion.vehicle;
        vec![
            ("motion.vehicle", "align_s", v.align_s, NonNegative(SIZE)),
            ("motion.vehicle", "stop_min_s", v.stop_min_s, Positive),
            ("motion.vehicle", "stop_max_s", v.stop_max_s, Positive),
            ("motion.vehicle", "drive_min_s", v.drive_min_s, Positive),
            ("motion.vehicle", "drive_max_s", v.drive_max_s, Positive),
            ("motion.vehicle", "ramp_s", v.ramp_s, NonNegative(SIZE)),
            ("motion.vehicle", "speed_mps", v.speed_mps, Positive),
            (
                "motion.vehicle",
                "curvature_sigma_per_m",
                v.curvature_sigma_per_m,
                NonNegative(SIZE),
            ),
            (
                "motion.vehicle",
                "curvature_length_m",
                v.curvature_length_m,
                Positive,
            ),
            (
                "motion.vehicle",
                "road_rate_max_dps",
                v.road_rate_max_dps,
                NonNegative(SIZE),
            ),
            (
                "motion.vehicle",
                "turn_interval_s",
                v.turn_interval_s,
                Positive,
            ),
            (
                "motion.vehicle",
                "turn_rate_min_dps",
                v.turn_rate_min_dps,
                Positive,
            ),
            (
                "motion.vehicle",
                "turn_rate_max_dps",
                v.turn_rate_max_dps,
                Positive,
            ),
            (
                "motion.vehicle",
                "turn_angle_min_deg",
                v.turn_angle_min_deg,
                Positive,
            ),
            (
                "motion.vehicle",
                "turn_angle_max_deg",
                v.turn_angle_max_deg,
                Positive,
            ),
        ]
    }

    /// `[timing]`'s rules.
    fn timing_checks(&self) -> Vec<Check> {
        use Rule::*;
        vec![
            (
                "timing",
                "rate_error_ppm",
                self.timing.rate_error_ppm,
                Range(-1e5, 1e5),
            ),
            (
                "timing",
                "jitter_rms_s",
                self.timing.jitter_rms_s,
                NonNegative(SIZE),
            ),
        ]
    }

    /// `[faults]`'s rules.
    fn faults_checks(&self) -> Vec<Check> {
        use Rule::*;
        vec![
            (
                "faults",
                "drop_probability",
                self.faults.drop_probability,
                Probability,
            ),
            (
                "faults",
                "spike_probability",
                self.faults.spike_probability,
                Probability,
            ),
            (
                "faults",
                "spike_amplitude_dps",
                self.faults.spike_amplitude_dps,
                NonNegative(SIZE),
            ),
        ]
    }

    /// Checks every value ([`Self::checks`], then the ranges' order); the first bad one as
    /// (section, key, value, reason).
    #[allow(clippy::type_complexity)]
    fn validate(&self) -> Result<(), (&'static str, &'static str, f64, String)> {
        use Rule::*;
        let (n, v) = (&self.noise, &self.motion.vehicle);
        for (section, key, v, rule) in self.checks() {
            let why = match rule {
                _ if !v.is_finite() => Some("must be finite".to_string()),
                NonNegative(why) if v < 0.0 => Some(why.to_string()),
                Positive if v <= 0.0 => Some("must be > 0".to_string()),
                Probability if !(0.0..1.0).contains(&v) => {
                    Some("a probability must be in [0, 1)".to_string())
                }
                Range(lo, hi) if !(lo..=hi).contains(&v) => {
                    Some(format!("must be in [{lo}, {hi}]"))
                }
                _ => None,
            };
            if let Some(why) = why {
                return Err((section, key, v, why));
            }
        }
        for (lo, hi, lo_key, hi_key) in [
            (v.stop_min_s, v.stop_max_s, "stop_min_s", "stop_max_s"),
            (v.drive_min_s, v.drive_max_s, "drive_min_s", "drive_max_s"),
            (
                v.turn_rate_min_dps,
                v.turn_rate_max_dps,
                "turn_rate_min_dps",
                "turn_rate_max_dps",
            ),
            (
                v.turn_angle_min_deg,
                v.turn_angle_max_deg,
                "turn_angle_min_deg",
                "turn_angle_max_deg",
            ),
        ] {
            if hi < lo {
                return Err((
                    "motion.vehicle",
                    hi_key,
                    hi,
                    format!("must be >= {lo_key} ({lo})"),
                ));
            }
        }
        if n.flicker_tau_max_s <= n.flicker_tau_min_s {
            return Err((
                "noise",
                "flicker_tau_max_s",
                n.flicker_tau_max_s,
                format!("must be > flicker_tau_min_s ({})", n.flicker_tau_min_s),
            ));
        }
        Ok(())
    }
}

/// Every key a model file may hold, section by section ("" = top level).
pub const KEYS: &[(&str, &[&str])] = &[
    ("", &["sample_rate_hz", "full_scale_dps"]),
    ("quantization", &["quantum_dps", "mode"]),
    (
        "noise",
        &[
            "arw_dps_per_rthz",
            "bias_instability_dps",
            "flicker_tau_min_s",
            "flicker_tau_max_s",
            "rrw_dps_per_s_rthz",
            "rate_ramp_dps_per_s",
            "gm_sigma_dps",
            "gm_tau_s",
            "sine_amplitude_dps",
            "sine_freq_hz",
            "sine_phase_deg",
        ],
    ),
    (
        "bias",
        &[
            "turn_on_dps",
            "turn_on_sigma_dps",
            "warmup_dps",
            "warmup_tau_s",
        ],
    ),
    (
        "temperature",
        &[
            "initial_c",
            "ramp_c_per_s",
            "cycle_amplitude_c",
            "cycle_period_s",
            "warmup_rise_c",
            "warmup_tau_s",
            "reference_c",
            "bias_dps_per_c",
            "shupe_dps_per_c_per_s",
        ],
    ),
    ("scale_factor", &["error_ppm", "quadratic_ppm_per_dps"]),
    (
        "motion",
        &[
            "profile",
            "rate_dps",
            "sine_amplitude_dps",
            "sine_freq_hz",
            "latitude_deg",
            "file",
        ],
    ),
    (
        "motion.vehicle",
        &[
            "align_s",
            "stop_min_s",
            "stop_max_s",
            "drive_min_s",
            "drive_max_s",
            "ramp_s",
            "speed_mps",
            "curvature_sigma_per_m",
            "curvature_length_m",
            "road_rate_max_dps",
            "turn_interval_s",
            "turn_rate_min_dps",
            "turn_rate_max_dps",
            "turn_angle_min_deg",
            "turn_angle_max_deg",
        ],
    ),
    ("motion.turntable", &["repeat"]),
    (
        "motion.turntable.step",
        &["rate_dps", "duration_s", "angle_deg"],
    ),
    (
        "family",
        &[
            "unit_seed",
            "unit_spread",
            "initial_c_range",
            "warmup_rise_c_range",
            "ramp_c_per_s_range",
        ],
    ),
    ("timing", &["rate_error_ppm", "jitter_rms_s"]),
    (
        "faults",
        &[
            "drop_probability",
            "spike_probability",
            "spike_amplitude_dps",
        ],
    ),
];

/// For an "unknown field `x`" message: the known key `x` most likely meant, when `x` is that
/// key with its unit missing or wrong.
fn unit_hint(msg: &str) -> String {
    let Some(unknown) = unknown_field(msg) else {
        return String::new();
    };
    let stem = key_stem;
    let want = stem(unknown);
    let found = KEYS
        .iter()
        .flat_map(|(_, keys)| keys.iter())
        .find(|k| !want.is_empty() && stem(k) == want);
    match found {
        Some(k) if unknown == want => {
            format!(" (`{unknown}` has no unit; this model takes `{k}`)")
        }
        Some(k) => format!(" (wrong unit in `{unknown}`? this model takes `{k}`)"),
        None => String::new(),
    }
}

/// The key an "unknown field `x`" message (serde's) names: `x`.
pub(crate) fn unknown_field(msg: &str) -> Option<&str> {
    msg.split("unknown field `")
        .nth(1)
        .and_then(|r| r.split('`').next())
}

/// A key's name without its unit part (`arw_dps_per_rthz` -> `arw`): the words before the
/// first of [`UNIT_WORDS`] (the model file's and the gyro file's unit hints).
pub(crate) fn key_stem(k: &str) -> String {
    k.split('_')
        .take_while(|p| !UNIT_WORDS.contains(p))
        .collect::<Vec<_>>()
        .join("_")
}

/// Words that start the unit part of a key name.
const UNIT_WORDS: &[&str] = &[
    "dps",
    "dph",
    "deg",
    "rad",
    "c",
    "k",
    "s",
    "ms",
    "h",
    "hz",
    "ppm",
    "per",
    "rthz",
    "rth",
    "probability",
    "mrad",
    "urad",
    "arcsec",
];

/// Line (1-based) of `key = ...` in `[section]` (top level when `section` is empty).
fn find_line(text: &str, section: &str, key: &str) -> Option<usize> {
    let mut current = String::new();
    for (i, line) in text.lines().enumerate() {
        let l = line.trim();
        if let Some(h) = l.strip_prefix('[') {
            current = h.split(']').next().unwrap_or("").trim().to_string();
            continue;
        }
        let k = l.split('=').next().unwrap_or("").trim();
        if current == section && k == key && l.contains('=') {
            return Some(i + 1);
        }
    }
    None
}

/// Line (1-based) of `key = ...` in the `n`-th (from 0) `[[section]]` table, or of that
/// table's header when the key is absent.
fn find_line_nth(text: &str, section: &str, n: usize, key: &str) -> Option<usize> {
    let header = format!("[[{section}]]");
    let mut seen: Option<usize> = None;
    let mut header_line = None;
    for (i, line) in text.lines().enumerate() {
        let l = line.trim();
        if l.starts_with('[') {
            if l.replace(' ', "") == header {
                seen = Some(seen.map_or(0, |s| s + 1));
                if seen == Some(n) {
                    header_line = Some(i + 1);
                }
            } else if seen == Some(n) {
                break;
            }
            continue;
        }
        let k = l.split('=').next().unwrap_or("").trim();
        if seen == Some(n) && k == key && l.contains('=') {
            return Some(i + 1);
        }
    }
    header_line
}

/// Refuses a rate that is not a finite positive number.
pub fn check_rate_hz(rate_hz: f64) -> Result<f64> {
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        bail!("sample rate {rate_hz} Hz: must be finite and > 0");
    }
    Ok(rate_hz)
}

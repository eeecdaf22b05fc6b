//! FOG error-model simulator: a [`Model`] and a seed in, one [`Sample`] at a time out.
//!
//! Streaming: the state is a few numbers per error term, so memory does not grow with the
//! length of the record. The same model, seed and rate give the same samples, bit for bit,
//! on every platform (PCG-64 `Mcg128Xsl64` streams, ziggurat normals from `rand_distr`;
//! one stream per term, so switching a term on or off leaves the others' noise unchanged).
//!
//! # What a sample is
//! For slot `k` (sample period `dt = 1 / (rate_hz (1 + rate_error_ppm 1e-6))`), taken at
//! `t = k dt + jitter`:
//! ```text
//! true_rate_dps = motion(t) + EARTH_RATE_DPS sin(latitude)
//! sensed        = true_rate_dps (1 + 1e-6 (error_ppm + quadratic_ppm_per_dps |true_rate_dps|))
//! drift_dps     = (sensed - true_rate_dps)                  scale-factor error and nonlinearity
//!               + turn-on bias (fixed + random) + warm-up transient
//!               + bias instability (flicker bank) + rate random walk + rate ramp R t
//!               + Gauss-Markov noise + sinusoidal disturbance
//!               + bias_dps_per_c (T - reference_c) + shupe_dps_per_c_per_s dT/dt
//! rate_dps      = quantize(saturate(true_rate_dps + drift_dps + white + spike))
//! ```
//! `drift_dps` is therefore every error term except the white rate noise (ARW), the spikes
//! (isolated outliers, which a drift identifier should reject, not track), quantization and
//! saturation: `rate_dps - true_rate_dps - drift_dps` is white noise + spike + quantization
//! error. A dropped sample consumes its slot (the noise processes advance) and is not
//! returned: its absence is a gap in `t_s`.

pub mod family;
mod markov;
mod model;
pub mod motion;

pub use family::{realize, Family};
pub use markov::{
    flicker_adev, flicker_times_s, flicker_unit_var, gm_avar, GaussMarkov, FLICKER_FLOOR,
    FLICKER_PER_DECADE,
};
pub use model::{
    check_rate_hz, Bias, Faults, Model, Motion, Noise, QuantMode, Quantization, ScaleFactor,
    Temperature, Timing, EARTH_RATE_DPS, KEYS,
};
pub(crate) use model::{key_stem, unknown_field, Bad};
pub use motion::{Platform, PlatformState, Profile, RateTable, Turntable, TurntableStep, Vehicle};

use anyhow::{bail, Result};
use markov::Flicker;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use rand_pcg::Pcg64Mcg;

/// Names of the built-in gyros ([`crate::gyro::BUILTIN`]).
pub const PRESETS: &[&str] = &["ecore2000", "kvh1750"];

/// The simulator's model of a built-in gyro (`host-sim/gyros/NAME.toml`).
pub fn preset(name: &str) -> Result<Model> {
    crate::gyro::builtin_model(name)
}

/// One output sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Slot number (counts dropped slots too).
    pub index: u64,
    /// Time of the sample, s since switch-on.
    pub t_s: f64,
    /// Measured rate, deg/s (quantized and saturated).
    pub rate_dps: f64,
    /// Sensor temperature, deg C.
    pub temp_c: f64,
    /// Ground-truth drift, deg/s (see the module docs for the terms).
    pub drift_dps: f64,
    /// True inertial rate about the sensitive axis, deg/s.
    pub true_rate_dps: f64,
    /// Ground truth: the platform moves (see [`motion`]); always false for a static model.
    pub moving: bool,
}

/// Stream identifiers: one RNG per term.
#[derive(Clone, Copy)]
enum Stream {
    White = 1,
    Flicker,
    Rrw,
    Markov,
    TurnOn,
    Jitter,
    Drop,
    Spike,
    Motion,
}

fn stream(seed: u64, s: Stream) -> Pcg64Mcg {
    // seed_from_u64 expands through PCG-32, so nearby inputs give unrelated states.
    Pcg64Mcg::seed_from_u64(seed ^ (s as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

/// Sample-by-sample generator of a model.
#[derive(Debug, Clone)]
pub struct Simulator {
    model: Model,
    /// True sample period, s.
    dt_s: f64,
    /// White noise standard deviation per sample, deg/s.
    white_sigma_dps: f64,
    /// Rate random walk step standard deviation, deg/s.
    rrw_step_dps: f64,
    turn_on_dps: f64,
    earth_dps: f64,
    slot: u64,
    flicker: Flicker,
    markov: Option<GaussMarkov>,
    rrw_dps: f64,
    carry_dps: f64,
    dropped: u64,
    rng_white: Pcg64Mcg,
    rng_flicker: Pcg64Mcg,
    rng_rrw: Pcg64Mcg,
    rng_markov: Pcg64Mcg,
    rng_jitter: Pcg64Mcg,
    rng_drop: Pcg64Mcg,
    rng_spike: Pcg64Mcg,
    platform: Platform,
}

impl Simulator {
    /// Simulator of `model` (already validated: read from a gyro file, [`crate::gyro`]) at `rate_hz` nominal samples per second. The model's
    /// `[family]` section is applied first ([`realize`]: unit coefficients, this record's
    /// temperature conditions); [`Simulator::model`] returns the realized model.
    pub fn new(model: &Model, seed: u64, rate_hz: f64) -> Result<Self> {
        let rate_hz = check_rate_hz(rate_hz)?;
        let model = &realize(model, seed);
        let platform = Platform::new(&model.motion, stream(seed, Stream::Motion))?;
        let n = &model.noise;
        let dt_s = 1.0 / (rate_hz * (1.0 + 1e-6 * model.timing.rate_error_ppm));
        if n.bias_instability_dps > 0.0 && n.flicker_tau_min_s < 2.0 * dt_s {
            bail!(
                "[noise] flicker_tau_min_s = {} s is shorter than 2 sample periods ({} s)",
                n.flicker_tau_min_s,
                2.0 * dt_s
            );
        }
        if model.timing.jitter_rms_s > 0.2 * dt_s {
            bail!(
                "[timing] jitter_rms_s = {} s is more than 0.2 sample periods ({} s)",
                model.timing.jitter_rms_s,
                0.2 * dt_s
            );
        }
        let mut rng_flicker = stream(seed, Stream::Flicker);
        let mut rng_markov = stream(seed, Stream::Markov);
        let mut rng_turn_on = stream(seed, Stream::TurnOn);
        let z: f64 = rng_turn_on.sample(StandardNormal);
        let flicker = Flicker::new(
            n.bias_instability_dps,
            n.flicker_tau_min_s,
            n.flicker_tau_max_s,
            dt_s,
            &mut rng_flicker,
        );
        let markov = (n.gm_sigma_dps > 0.0)
            .then(|| GaussMarkov::new(n.gm_sigma_dps, n.gm_tau_s, dt_s, &mut rng_markov));
        Ok(Self {
            model: model.clone(),
            dt_s,
            white_sigma_dps: n.arw_dps_per_rthz / dt_s.sqrt(),
            rrw_step_dps: n.rrw_dps_per_s_rthz * dt_s.sqrt(),
            turn_on_dps: model.bias.turn_on_dps + model.bias.turn_on_sigma_dps * z,
            earth_dps: EARTH_RATE_DPS * model.motion.latitude_deg.to_radians().sin(),
            slot: 0,
            flicker,
            markov,
            rrw_dps: 0.0,
            carry_dps: 0.0,
            dropped: 0,
            rng_white: stream(seed, Stream::White),
            rng_flicker,
            rng_rrw: stream(seed, Stream::Rrw),
            rng_markov,
            rng_jitter: stream(seed, Stream::Jitter),
            rng_drop: stream(seed, Stream::Drop),
            rng_spike: stream(seed, Stream::Spike),
            platform,
        })
    }

    /// End of the `file` motion profile's time span, s (None for other profiles).
    pub fn motion_file_end_s(&self) -> Option<f64> {
        self.platform.file_end_s()
    }

    /// The model being simulated (after [`realize`]).
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// True sample period, s (the nominal one corrected by `rate_error_ppm`).
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// Samples dropped so far.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// The next delivered sample (dropped slots are skipped).
    pub fn next_sample(&mut self) -> Sample {
        loop {
            let s = self.slot_sample();
            let p = self.model.faults.drop_probability;
            if p > 0.0 && self.rng_drop.random::<f64>() < p {
                self.dropped += 1;
                continue;
            }
            return s;
        }
    }

    /// Computes slot `self.slot` and advances every process by one slot.
    fn slot_sample(&mut self) -> Sample {
        let m = &self.model;
        let k = self.slot;
        let mut jitter_s = 0.0;
        if m.timing.jitter_rms_s > 0.0 {
            let z: f64 = self.rng_jitter.sample(StandardNormal);
            let lo = if k == 0 { 0.0 } else { -0.45 * self.dt_s };
            jitter_s = (z * m.timing.jitter_rms_s).clamp(lo, 0.45 * self.dt_s);
        }
        let t_s = k as f64 * self.dt_s + jitter_s;

        // True rate and scale factor.
        let platform = self.platform.at(t_s);
        let true_rate_dps = platform.rate_dps + self.earth_dps;
        let sf = &m.scale_factor;
        let sf_error_dps =
            true_rate_dps * 1e-6 * (sf.error_ppm + sf.quadratic_ppm_per_dps * true_rate_dps.abs());

        // Drift terms.
        let n = &m.noise;
        let (temp_c, dtemp_c_per_s) = m.temperature.at(t_s);
        let te = &m.temperature;
        let drift_dps = sf_error_dps
            + self.turn_on_dps
            + m.bias.warmup_dps * (-t_s / m.bias.warmup_tau_s).exp()
            + self.flicker.value_dps()
            + self.rrw_dps
            + n.rate_ramp_dps_per_s * t_s
            + self.markov.as_ref().map_or(0.0, |g| g.x_dps)
            + n.sine_amplitude_dps
                * (std::f64::consts::TAU * n.sine_freq_hz * t_s + n.sine_phase_deg.to_radians())
                    .sin()
            + te.bias_dps_per_c * (temp_c - te.reference_c)
            + te.shupe_dps_per_c_per_s * dtemp_c_per_s;

        // White noise and spikes.
        let mut raw_dps = true_rate_dps + drift_dps;
        if self.white_sigma_dps > 0.0 {
            let z: f64 = self.rng_white.sample(StandardNormal);
            raw_dps += self.white_sigma_dps * z;
        }
        let f = &m.faults;
        if f.spike_probability > 0.0 && self.rng_spike.random::<f64>() < f.spike_probability {
            let sign = if self.rng_spike.random::<bool>() {
                1.0
            } else {
                -1.0
            };
            raw_dps += sign * f.spike_amplitude_dps;
        }
        if let Some(fs) = m.full_scale_dps {
            raw_dps = raw_dps.clamp(-fs, fs);
        }
        let q = m.quantization.quantum_dps;
        let rate_dps = if q > 0.0 {
            let v = match m.quantization.mode {
                QuantMode::Round => raw_dps,
                QuantMode::Angle => raw_dps + self.carry_dps,
            };
            let out = (v / q).round() * q;
            if m.quantization.mode == QuantMode::Angle {
                self.carry_dps = v - out;
            }
            out
        } else {
            raw_dps
        };

        // Advance the processes to the next slot.
        self.flicker.step(&mut self.rng_flicker);
        if let Some(g) = &mut self.markov {
            g.step(&mut self.rng_markov);
        }
        if self.rrw_step_dps > 0.0 {
            let z: f64 = self.rng_rrw.sample(StandardNormal);
            self.rrw_dps += self.rrw_step_dps * z;
        }
        self.slot += 1;
        Sample {
            index: k,
            t_s,
            rate_dps,
            temp_c,
            drift_dps,
            true_rate_dps,
            moving: platform.moving,
        }
    }
}

impl Iterator for Simulator {
    type Item = Sample;

    /// Never `None`: the stream is endless; stop on `t_s` or a count.
    fn next(&mut self) -> Option<Sample> {
        Some(self.next_sample())
    }
}

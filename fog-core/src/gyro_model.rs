//! The gyro model as data: the error terms of one gyro family and their unit-to-unit
//! spread, in the units of datasheets' SI cousins (deg/s, s, deg C).
//!
//! ```text
//! y(t) = w(t) + d(t) + v(t)                                output = true rate + drift + noise
//! d(t) = b(t) + sum_i g_i(t) + a e^(-t/tau_w) + c (T - T0) + c' dT/dt
//! ```
//! - `v`: white noise of density `white_dps_rthz` plus quantization `quantum_dps^2 / 12`;
//! - `b`: the level, turn-on bias (mean and spread over power-ons and units) walking as a
//!   random walk of density `rrw_dps_per_s_rthz` (rate random walk `K`);
//! - `g_i`: Gauss-Markov terms (bias instability), each `sigma`, `tau`; `sigma = 0`: absent;
//! - `a`: the warm-up amplitude at power-on (mean, spread), time constant `tau_w`: a unit's
//!   own, log-uniform between a least and a largest value (units differ in their warm-up's
//!   time constant as in its amplitude; equal bounds: one known time constant);
//! - `c`, `c'`: the temperature link and the temperature-rate (Shupe) link (mean, spread).
//!   `T0` is the model's reference temperature (absolute: on the generator's families a link
//!   of the change since power-on scored worse, docs/drift-filter.md).
//!
//! [`crate::drift_filter::DriftFilter`] is this model's Kalman filter; `host-sim identify`
//! fits it to calibration runs and writes it into the image.

use crate::sensor::SensorConfig;

/// Largest number of Gauss-Markov terms a model holds.
pub const MAX_MARKOV: usize = 3;

/// A first-order Gauss-Markov term: stationary standard deviation and correlation time.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MarkovTerm {
    /// Stationary standard deviation, deg/s (>= 0; 0: the term is absent).
    pub sigma_dps: f32,
    /// Correlation time, s (> 0 when `sigma_dps > 0`).
    pub tau_s: f32,
}

/// A mean and a spread (standard deviation) of one unit's constant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Spread {
    /// Family mean.
    pub mean: f32,
    /// Unit-to-unit standard deviation around it (>= 0).
    pub sigma: f32,
}

/// One gyro family's error model (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GyroModel {
    /// Output data rate, Hz (> 0).
    pub sample_rate_hz: f32,
    /// White noise (angle random walk) density, deg/s/sqrt(Hz) (> 0); 1 deg/sqrt(h) is
    /// 1/60 deg/s/sqrt(Hz).
    pub white_dps_rthz: f32,
    /// One output count, deg/s (0: no quantization).
    pub quantum_dps: f32,
    /// Gauss-Markov terms (bias instability).
    pub markov: [MarkovTerm; MAX_MARKOV],
    /// Rate random walk density `K`, deg/s/sqrt(s) (>= 0).
    pub rrw_dps_per_s_rthz: f32,
    /// Turn-on bias, deg/s.
    pub turn_on_dps: Spread,
    /// Warm-up amplitude at power-on, deg/s.
    pub warmup_dps: Spread,
    /// Least warm-up time constant, s (> 0).
    pub warmup_tau_min_s: f32,
    /// Largest warm-up time constant, s (>= `warmup_tau_min_s`).
    pub warmup_tau_max_s: f32,
    /// Temperature the link is taken from, deg C.
    pub temp_ref_c: f32,
    /// Temperature link, deg/s per deg C.
    pub temp_dps_per_c: Spread,
    /// Temperature-rate link, deg/s per (deg C/s).
    pub temp_rate_dps_per_c_per_s: Spread,
    /// Largest drift the family shows, deg/s (> 0): no estimate exceeds it.
    pub drift_bound_dps: f32,
}

impl GyroModel {
    /// The model a sensor's specification alone gives (no calibration run): its rate,
    /// white noise, quantum and drift bound; ASSUMED for the rest (a unit never
    /// calibrated): turn-on and warm-up spreads of a third of the bound each (mean 0),
    /// warm-up time constant 200 to 1800 s, no temperature link (mean and spread 0: a link is only
    /// learned from calibration runs), one Gauss-Markov term of a tenth of the bound at
    /// 300 s, rate random walk 1 deg/h/sqrt(h). Temperature reference 25 deg C.
    pub fn for_sensor(s: &SensorConfig) -> Self {
        let third = s.drift_bound_dps / 3.0;
        Self {
            sample_rate_hz: s.sample_rate_hz,
            white_dps_rthz: s.noise_density_dps_rthz,
            quantum_dps: s.quantum_dps,
            markov: [
                MarkovTerm {
                    sigma_dps: s.drift_bound_dps / 10.0,
                    tau_s: 300.0,
                },
                MarkovTerm::default(),
                MarkovTerm::default(),
            ],
            rrw_dps_per_s_rthz: 1.0 / 3600.0 / 60.0,
            turn_on_dps: Spread {
                mean: 0.0,
                sigma: third,
            },
            warmup_dps: Spread {
                mean: 0.0,
                sigma: third,
            },
            warmup_tau_min_s: 200.0,
            warmup_tau_max_s: 1800.0,
            temp_ref_c: 25.0,
            temp_dps_per_c: Spread::default(),
            temp_rate_dps_per_c_per_s: Spread::default(),
            drift_bound_dps: s.drift_bound_dps,
        }
    }

    /// Every field finite, rates, white noise, warm-up times and bound > 0, the rest >= 0;
    /// every present Gauss-Markov term with `tau > 0`; the warm-up's least time constant at
    /// most its largest.
    pub fn is_valid(&self) -> bool {
        let pos = |v: f32| v > 0.0 && v.is_finite();
        let nonneg = |v: f32| v >= 0.0 && v.is_finite();
        let spread = |s: Spread| s.mean.is_finite() && nonneg(s.sigma);
        pos(self.sample_rate_hz)
            && pos(self.white_dps_rthz)
            && nonneg(self.quantum_dps)
            && self
                .markov
                .iter()
                .all(|m| nonneg(m.sigma_dps) && (m.sigma_dps == 0.0 || pos(m.tau_s)))
            && nonneg(self.rrw_dps_per_s_rthz)
            && spread(self.turn_on_dps)
            && spread(self.warmup_dps)
            && pos(self.warmup_tau_min_s)
            && pos(self.warmup_tau_max_s)
            && self.warmup_tau_min_s <= self.warmup_tau_max_s
            && self.temp_ref_c.is_finite()
            && spread(self.temp_dps_per_c)
            && spread(self.temp_rate_dps_per_c_per_s)
            && pos(self.drift_bound_dps)
    }

    /// Sample period, s.
    pub fn sample_period_s(&self) -> f32 {
        1.0 / self.sample_rate_hz
    }

    /// Variance of one sample around the drift at rest, deg^2/s^2: white noise
    /// `N^2 * rate` plus quantization `quantum^2 / 12`.
    pub fn sample_var_dps2(&self) -> f32 {
        self.white_dps_rthz * self.white_dps_rthz * self.sample_rate_hz
            + self.quantum_dps * self.quantum_dps / 12.0
    }

    /// Clamp a drift estimate to the bound (NaN: 0).
    pub fn clamp_drift(&self, drift_dps: f32) -> f32 {
        if drift_dps.is_nan() {
            0.0
        } else {
            // Comparisons, not clamp (its panic path would be linked) nor max/min (calls
            // to fmaxf/fminf on the target).
            let b = self.drift_bound_dps;
            if drift_dps > b {
                b
            } else if drift_dps < -b {
                -b
            } else {
                drift_dps
            }
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// An E-Core-like 100 Hz family (test values, not a datasheet).
    pub(crate) fn ecore_like() -> GyroModel {
        let dph = 1.0 / 3600.0;
        GyroModel {
            sample_rate_hz: 100.0,
            white_dps_rthz: 0.067 / 60.0,
            quantum_dps: 60.0 / 32768.0,
            markov: [
                MarkovTerm {
                    sigma_dps: 1.0 * dph,
                    tau_s: 100.0,
                },
                MarkovTerm {
                    sigma_dps: 1.5 * dph,
                    tau_s: 1000.0,
                },
                MarkovTerm::default(),
            ],
            rrw_dps_per_s_rthz: 0.5 * dph / 60.0,
            turn_on_dps: Spread {
                mean: 0.0,
                sigma: 30.0 * dph,
            },
            warmup_dps: Spread {
                mean: 0.0,
                sigma: 25.0 * dph,
            },
            warmup_tau_min_s: 600.0,
            warmup_tau_max_s: 600.0,
            temp_ref_c: 25.0,
            temp_dps_per_c: Spread {
                mean: 0.0,
                sigma: 1.0 * dph,
            },
            temp_rate_dps_per_c_per_s: Spread::default(),
            drift_bound_dps: 150.0 * dph,
        }
    }

    #[test]
    fn the_test_model_is_valid_and_a_broken_one_is_not() {
        let m = ecore_like();
        assert!(m.is_valid());
        let mut bad = m;
        bad.markov[2] = MarkovTerm {
            sigma_dps: 1e-4,
            tau_s: 0.0,
        };
        assert!(!bad.is_valid());
        let mut bad = m;
        bad.warmup_tau_min_s = 700.0; // above the largest
        assert!(!bad.is_valid());
        let mut bad = m;
        bad.warmup_tau_min_s = 0.0;
        assert!(!bad.is_valid());
        let mut bad = m;
        bad.temp_dps_per_c.sigma = f32::NAN;
        assert!(!bad.is_valid());
        assert_eq!(m.clamp_drift(1.0), m.drift_bound_dps);
        assert_eq!(m.clamp_drift(f32::NAN), 0.0);
        assert!(GyroModel::for_sensor(&SensorConfig::ECORE_2000).is_valid());
        assert!(GyroModel::for_sensor(&SensorConfig::KVH_DSP_1750).is_valid());
    }
}

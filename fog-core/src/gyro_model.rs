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
//! - `a`: the warm-up amplitude at power-on (mean, spread), time constant `tau_w`;
//! - `c`, `c'`: the temperature link and the temperature-rate (Shupe) link (mean, spread).
//!
//! [`crate::drift_filter::DriftFilter`] is this model's Kalman filter; `host-sim identify`
//! fits it to calibration runs and writes it into the image.

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
    /// Warm-up time constant, s (> 0).
    pub warmup_tau_s: f32,
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
    /// Every field finite, rates, white noise, warm-up time and bound > 0, the rest >= 0;
    /// every present Gauss-Markov term with `tau > 0`.
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
            && pos(self.warmup_tau_s)
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
            drift_dps.clamp(-self.drift_bound_dps, self.drift_bound_dps)
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
            warmup_tau_s: 600.0,
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
        bad.temp_dps_per_c.sigma = f32::NAN;
        assert!(!bad.is_valid());
        assert_eq!(m.clamp_drift(1.0), m.drift_bound_dps);
        assert_eq!(m.clamp_drift(f32::NAN), 0.0);
    }
}

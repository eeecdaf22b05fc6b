//! A gyro's specification as data ([`SensorConfig`]): its rate, noise density, quantum, full
//! scale and drift bound, what the drift filter's model starts from without calibration
//! ([`crate::gyro_model::GyroModel::for_sensor`]) and the baselines' noise model.

/// A gyro's specification as data: what the drift filter's uncalibrated model, the bound on
/// the drift estimate and the image ([`crate::image`]) need. Values marked ASSUMED in the constants' docs are
/// plausible figures for the class, not datasheet values.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SensorConfig {
    /// Largest rate the sensor reports, deg/s (> 0).
    pub full_scale_dps: f32,
    /// One output count, deg/s (0: a floating-point output without quantization).
    pub quantum_dps: f32,
    /// Output data rate, Hz (> 0).
    pub sample_rate_hz: f32,
    /// White (angle random walk) noise density, deg/s/sqrt(Hz) (> 0); 1 deg/sqrt(h) is
    /// 1/60 deg/s/sqrt(Hz).
    pub noise_density_dps_rthz: f32,
    /// Largest drift the sensor can have, deg/s (> 0): worst-case turn-on bias plus warm-up
    /// plus thermal terms. No drift estimate ever exceeds it, so no state can subtract a
    /// rotation larger than it.
    pub drift_bound_dps: f32,
}

impl SensorConfig {
    /// KVH E-Core 2000, 60 deg/s unit. Full scale, quantum (60/32768 deg/s, one i16 count)
    /// and 100 Hz from `shared/spec/serial-protocols.md` section 1 (a public driver, not a
    /// datasheet). ASSUMED (as the simulator's preset `host-sim/presets/ecore2000.toml`):
    /// white noise 4 deg/h/sqrt(Hz) = 0.00111 deg/s/sqrt(Hz); drift bound 30 deg/h = about
    /// 4 sigma of the assumed 5 deg/h turn-on bias plus 3 deg/h warm-up plus thermal terms.
    pub const ECORE_2000: Self = Self {
        full_scale_dps: 60.0,
        quantum_dps: 60.0 / 32768.0,
        sample_rate_hz: 100.0,
        noise_density_dps_rthz: 0.001_111_11,
        drift_bound_dps: 30.0 / 3600.0,
    };

    /// KVH DSP-1750-like FOG IMU axis: +-490 deg/s, 1 kHz (the rate of the real log in
    /// `shared/data/real/kvh1750_fog_yoos`, which peaks at 327 deg/s). ASSUMED (no datasheet
    /// in the project): angle increments as floating point (quantum 0), white noise
    /// 0.012 deg/sqrt(h) = 0.0002 deg/s/sqrt(Hz), drift bound 20 deg/h.
    pub const KVH_DSP_1750: Self = Self {
        full_scale_dps: 490.0,
        quantum_dps: 0.0,
        sample_rate_hz: 1000.0,
        noise_density_dps_rthz: 0.012 / 60.0,
        drift_bound_dps: 20.0 / 3600.0,
    };

    /// All fields finite, rates, noise and bound > 0, quantum >= 0.
    pub fn is_valid(&self) -> bool {
        let pos = |v: f32| v > 0.0 && v.is_finite();
        pos(self.full_scale_dps)
            && pos(self.sample_rate_hz)
            && pos(self.noise_density_dps_rthz)
            && pos(self.drift_bound_dps)
            && self.quantum_dps >= 0.0
            && self.quantum_dps.is_finite()
    }

    /// Sample period, s.
    pub fn sample_period_s(&self) -> f32 {
        1.0 / self.sample_rate_hz
    }

    /// Variance of one sample at rest around its drift, deg^2/s^2: white noise
    /// `density^2 * rate` plus quantization `quantum^2 / 12`.
    pub fn sample_var_dps2(&self) -> f32 {
        self.noise_density_dps_rthz * self.noise_density_dps_rthz * self.sample_rate_hz
            + self.quantum_dps * self.quantum_dps / 12.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: SensorConfig = SensorConfig::ECORE_2000;

    #[test]
    fn noise_model() {
        // 4 deg/h/sqrt(Hz) at 100 Hz: 40 deg/h per sample, plus the count's 1/sqrt(12).
        let expect = (0.001_111_11f32 * 10.0).powi(2) + (60.0f32 / 32768.0).powi(2) / 12.0;
        assert!((S.sample_var_dps2() - expect).abs() < 1e-9);
        assert!(SensorConfig::KVH_DSP_1750.is_valid());
    }
}

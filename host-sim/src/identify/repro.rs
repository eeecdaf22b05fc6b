//! A reproduction of the paper's section 5 with the simulator: many 1800-s records taken
//! "at different times, sample periods and conditions", split into training and validation.
//!
//! The paper had 265 real E-Core-2000 records (180 train, 85 check). Here each record is a
//! simulator run with its own seed and its own conditions, drawn from a documented
//! distribution by a seeded generator (so the set is reproducible):
//!
//! | condition | distribution | why |
//! |---|---|---|
//! | sample period | 5 / 10 / 20 ms with probability 0.2 / 0.6 / 0.2 | "different sample periods" |
//! | angle random walk | U(0.05, 0.15) deg/sqrt(h) (`nominal`, `stochastic`); U(0.02, 0.04) (`quiet`) | 30-90 deg/h per sample at 100 Hz: the E-Core-like noise; `quiet` is a better gyro |
//! | bias instability | U(1, 2) deg/h | "bias stability below 2 deg/h" |
//! | turn-on bias | N(0, 20 deg/h) per record | run-to-run bias, the bulk of a ~17 deg/h drift RMS |
//! | warm-up transient | U(0, 6) deg/h, time constant U(300, 900) s | switch-on |
//! | temperature | start U(15, 35) C, self-heating U(0, 8) C, ramp U(-2, 2) C per 1800 s; sensitivity and Shupe as the `ecore2000` preset | "different conditions" |
//! | Gauss-Markov drift (`stochastic` only) | 17 deg/h, correlation time U(100, 1000) s | drift that no model of T predicts |
//!
//! Everything else is the `ecore2000` preset (quantization 60/32768 deg/s, rate random walk).

use super::series::{Records, Series};
use crate::sim::{self, Model, Simulator};
use anyhow::Result;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

/// Condition sets.
#[derive(clap::ValueEnum, Clone, Copy, Debug, serde::Serialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Group {
    /// E-Core nominal: the noise, smooth (thermal, warm-up, flicker) drift.
    Nominal,
    /// Nominal plus a 17 deg/h Gauss-Markov drift.
    Stochastic,
    /// Nominal drift with a quieter gyro (12-24 deg/h per sample at 100 Hz).
    Quiet,
}

/// One simulated record: its model, seed and rate.
#[derive(Debug, Clone)]
pub struct Spec {
    /// Simulator model with this record's conditions.
    pub model: Model,
    /// Simulator seed.
    pub seed: u64,
    /// Sample rate, Hz.
    pub rate_hz: f64,
}

/// Simulated records, generated on demand (one in memory at a time).
pub struct SimRecords {
    /// The records' specifications.
    pub specs: Vec<Spec>,
    /// Duration of each record, s.
    pub duration_s: f64,
}

const DPH: f64 = 1.0 / 3600.0;

impl SimRecords {
    /// Records `first..first + count` of `group`'s set (the index decides seed and
    /// conditions, so training and validation sets never share a record).
    pub fn new(group: Group, first: usize, count: usize, duration_s: f64) -> Result<Self> {
        let base = sim::preset("ecore2000")?;
        let specs = (first..first + count)
            .map(|i| {
                let mut rng =
                    Pcg64Mcg::seed_from_u64(0x5EC5_0000 + i as u64 + 1_000_000 * group as u64);
                let mut m = base.clone();
                let u: f64 = rng.random();
                let rate_hz = if u < 0.2 {
                    200.0
                } else if u < 0.8 {
                    100.0
                } else {
                    50.0
                };
                m.sample_rate_hz = Some(rate_hz);
                let arw_deg_rth = match group {
                    Group::Quiet => rng.random_range(0.02..0.04),
                    _ => rng.random_range(0.05..0.15),
                };
                m.noise.arw_dps_per_rthz = arw_deg_rth / 60.0;
                m.noise.bias_instability_dps = rng.random_range(1.0..2.0) * DPH;
                m.bias.turn_on_dps = 0.0;
                m.bias.turn_on_sigma_dps = 20.0 * DPH;
                m.bias.warmup_dps = rng.random_range(0.0..6.0) * DPH;
                m.bias.warmup_tau_s = rng.random_range(300.0..900.0);
                m.temperature.initial_c = rng.random_range(15.0..35.0);
                m.temperature.reference_c = 25.0;
                m.temperature.warmup_rise_c = rng.random_range(0.0..8.0);
                m.temperature.ramp_c_per_s = rng.random_range(-2.0..2.0) / 1800.0;
                if group == Group::Stochastic {
                    m.noise.gm_sigma_dps = 17.0 * DPH;
                    m.noise.gm_tau_s = rng.random_range(100.0..1000.0);
                }
                Spec {
                    model: m,
                    seed: 2007_0000 + i as u64,
                    rate_hz,
                }
            })
            .collect();
        Ok(Self { specs, duration_s })
    }
}

impl Records for SimRecords {
    fn len(&self) -> usize {
        self.specs.len()
    }

    fn get(&self, i: usize) -> Result<Series> {
        let spec = &self.specs[i];
        let mut sim = Simulator::new(&spec.model, spec.seed, spec.rate_hz)?;
        let n = (self.duration_s * spec.rate_hz).round() as usize;
        let mut s = Series {
            name: format!("sim seed {} at {} Hz", spec.seed, spec.rate_hz),
            t_s: Vec::with_capacity(n),
            rate_dps: Vec::with_capacity(n),
            drift_dps: Some(Vec::with_capacity(n)),
            temp_c: Some(Vec::with_capacity(n)),
            ..Default::default()
        };
        for _ in 0..n {
            let x = sim.next_sample();
            s.t_s.push(x.t_s);
            s.rate_dps.push(x.rate_dps as f32);
            if let Some(d) = s.drift_dps.as_mut() {
                d.push(x.drift_dps as f32);
            }
            if let Some(c) = s.temp_c.as_mut() {
                c.push(x.temp_c as f32);
            }
        }
        Ok(s)
    }
}

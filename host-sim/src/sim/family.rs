//! A gyro family: units that share their thermal and warm-up coefficients up to a per-unit
//! spread, and records whose temperature conditions vary, so that the thermal terms can be
//! identified from many records.
//!
//! `[family]` (every key optional; all off by default, so a model without it is simulated
//! exactly as before):
//! - `unit_seed` (`--unit-seed`): which unit. With `unit_spread > 0`, each of the unit's
//!   coefficients `bias.warmup_dps`, `bias.warmup_tau_s`, `temperature.bias_dps_per_c`,
//!   `temperature.shupe_dps_per_c_per_s` and `temperature.warmup_tau_s` is the model's value
//!   times `(1 + unit_spread z)`, `z ~ N(0, 1)` drawn from the unit seed (one draw per
//!   coefficient, in that order). Time constants keep a factor of at least 0.1 (ASSUMED
//!   floor, so that they stay > 0).
//! - `unit_spread` (`--unit-spread`): relative 1-sigma spread, e.g. 0.2.
//! - `initial_c_range`, `warmup_rise_c_range`, `ramp_c_per_s_range`: `[lo, hi]`; each record
//!   (the simulator's `--seed`, the power-on) draws its ambient start temperature,
//!   self-heating rise and slow ambient ramp uniformly in the range.
//!
//! The turn-on bias is random per power-on already (`bias.turn_on_sigma_dps`, drawn from the
//! record seed). Which coefficients spread, the normal spread and the uniform conditions are
//! ASSUMPTIONS of this simulator, not measured properties of a gyro family.

use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use rand_pcg::Pcg64Mcg;
use serde::{Deserialize, Serialize};

use super::Model;

/// `[family]`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Family {
    /// The unit drawn from the family (None: the model's nominal coefficients).
    pub unit_seed: Option<u64>,
    /// Relative 1-sigma per-unit spread of the coefficients (0 = every unit nominal).
    pub unit_spread: f64,
    /// Ambient temperature at switch-on, deg C, uniform in `[lo, hi]` per record.
    pub initial_c_range: Option<[f64; 2]>,
    /// Self-heating rise after switch-on, deg C, uniform in `[lo, hi]` per record.
    pub warmup_rise_c_range: Option<[f64; 2]>,
    /// Slow ambient ramp, deg C/s, uniform in `[lo, hi]` per record.
    pub ramp_c_per_s_range: Option<[f64; 2]>,
}

const UNIT_STREAM: u64 = 0xF0A1_7E5D_0000_0001;
const RECORD_STREAM: u64 = 0xF0A1_7E5D_0000_0002;

impl Family {
    /// Checks the values; on error (key, reason).
    pub(crate) fn check(&self) -> Result<(), (&'static str, String)> {
        if !(self.unit_spread.is_finite() && self.unit_spread >= 0.0) {
            return Err((
                "unit_spread",
                format!("= {}: must be finite and >= 0", self.unit_spread),
            ));
        }
        for (key, r) in [
            ("initial_c_range", self.initial_c_range),
            ("warmup_rise_c_range", self.warmup_rise_c_range),
            ("ramp_c_per_s_range", self.ramp_c_per_s_range),
        ] {
            if let Some([lo, hi]) = r {
                if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                    return Err((key, format!("= [{lo}, {hi}]: needs finite lo <= hi")));
                }
            }
        }
        if let Some([lo, hi]) = self.initial_c_range {
            if lo < -273.15 || hi > 1e3 {
                return Err((
                    "initial_c_range",
                    format!("= [{lo}, {hi}]: must be in [-273.15, 1000]"),
                ));
            }
        }
        Ok(())
    }

    /// True when the section changes nothing.
    pub fn is_off(&self) -> bool {
        (self.unit_seed.is_none() || self.unit_spread == 0.0)
            && self.initial_c_range.is_none()
            && self.warmup_rise_c_range.is_none()
            && self.ramp_c_per_s_range.is_none()
    }
}

/// The concrete model of the family's unit `model.family.unit_seed` in the record (power-on)
/// `record_seed`: coefficients spread, temperature conditions drawn. A model whose family
/// is off comes back unchanged.
pub fn realize(model: &Model, record_seed: u64) -> Model {
    let f = model.family;
    let mut m = model.clone();
    if let (Some(unit), true) = (f.unit_seed, f.unit_spread > 0.0) {
        let mut rng = Pcg64Mcg::seed_from_u64(unit ^ UNIT_STREAM);
        let mut factor = |floor: f64| -> f64 {
            let z: f64 = rng.sample(StandardNormal);
            (1.0 + f.unit_spread * z).max(floor)
        };
        m.bias.warmup_dps *= factor(f64::NEG_INFINITY);
        m.bias.warmup_tau_s *= factor(0.1);
        m.temperature.bias_dps_per_c *= factor(f64::NEG_INFINITY);
        m.temperature.shupe_dps_per_c_per_s *= factor(f64::NEG_INFINITY);
        m.temperature.warmup_tau_s *= factor(0.1);
    }
    let mut rng = Pcg64Mcg::seed_from_u64(record_seed ^ RECORD_STREAM);
    let mut draw = |r: Option<[f64; 2]>, v: &mut f64| {
        if let Some([lo, hi]) = r {
            *v = lo + (hi - lo) * rng.random::<f64>();
        }
    };
    draw(f.initial_c_range, &mut m.temperature.initial_c);
    draw(f.warmup_rise_c_range, &mut m.temperature.warmup_rise_c);
    draw(f.ramp_c_per_s_range, &mut m.temperature.ramp_c_per_s);
    m
}

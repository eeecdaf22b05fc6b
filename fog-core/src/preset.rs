//! The estimator an identifier image names: one [`MotionEstimator`] (window or per-sample
//! level) or the dual ([`Arrangement::Dual`]), with an optional Gauss-Markov state, or a
//! bank arrangement ([`Arrangement::is_bank`]: the level as the sensor's Allan noise model,
//! [`crate::bank::LevelBank`], beside a per-sample estimator that is the detector's drift
//! reference).
//!
//! The dual runs two estimators of the same model and configuration side by side on the
//! same samples, each with its own stillness detector:
//! - `rest` = per-sample level with rollback + Gauss-Markov ([`LevelUpdate::Sample`]),
//! - `hold` = window level + Gauss-Markov (the "hybrid", [`LevelUpdate::Window`]).
//!
//! Its drift is `rest`'s while `rest` flags the sample still (after its fast gate), and
//! `hold`'s otherwise: at rest the per-sample level follows the bias wander; from the
//! first sample `rest` sees as moving, the output is the window level, which no sample of
//! an unreleased window ever reached. At a sample with an external still flag the output
//! is `rest`'s (the flag is trusted: the per-sample level holds no suspect sample, so the
//! window level's protection buys nothing). Neither estimator learns from a moving sample, so a
//! rotation in motion never moves the estimate (tested). Cost: two estimators' state, two
//! detectors and level steps per sample; the model inputs and the network (once per
//! window) are computed once and shared (the two estimators hold the same model).

use crate::bank::{BankConfig, LevelBank};
use crate::motion::{LevelUpdate, MotionConfig, MotionError, MotionEstimator, MotionModel};
use crate::motion::{MotionOutput, MotionStats};

/// How the level learns: the image's update-mode byte (format version 2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Arrangement {
    /// One estimator, level per released window ([`LevelUpdate::Window`]); the
    /// arrangement of a version-1 image.
    Window,
    /// One estimator, level per still sample with rollback ([`LevelUpdate::Sample`]).
    Sample,
    /// Per-sample level at rest, window level in motion (module docs); with an external
    /// still flag, the per-sample level throughout.
    Dual,
    /// The level is the sensor's Allan noise model ([`crate::bank::LevelBank`]: random
    /// walk + one Gauss-Markov state per decade of correlation time), updated at every
    /// sample the per-sample estimator flags still (after its fast gate), never rolled
    /// back, and the output in motion too; the image's Gauss-Markov fields carry the
    /// bank's `B` (sigma) and longest correlation time (tau).
    Bank,
    /// [`Arrangement::Bank`] protected as the dual is: the per-sample bank is rolled back
    /// with the per-sample estimator when a window fails, and from the first sample that
    /// estimator flags moving the output is a second bank that only released window means
    /// reached (one window late). With an external still flag both are the plain bank.
    BankDual,
    /// [`Arrangement::Bank`] guarded by the window test alone: when the detector fails a
    /// window, the bank goes back to that window's start (its samples come out; the
    /// windows before it stay), and the bank is the output at rest and in motion. Less
    /// protection than [`Arrangement::BankDual`] (the window before a failed one is kept),
    /// less still data lost at each stop. With an external still flag, the plain bank.
    BankGuarded,
    /// [`Arrangement::Dual`] whose second state is the unit's own temperature link
    /// ([`MotionEstimator::with_thermal`]: `c (T - T0)`, learned at rest, followed in
    /// motion) instead of a Gauss-Markov state; the image's Gauss-Markov fields carry the
    /// coefficient's prior standard deviation (sigma, deg/s per deg C) and tau 0. The
    /// product's default (docs/unit-fit.md: the least heading error on three of four
    /// measured vehicle families and the least static error on all three).
    #[default]
    DualThermal,
}

impl Arrangement {
    /// The image's byte: 0 window, 1 sample, 2 dual, 3 bank, 4 bank-dual, 5 bank-guarded.
    pub const fn to_byte(self) -> u8 {
        match self {
            Self::Window => 0,
            Self::Sample => 1,
            Self::Dual => 2,
            Self::Bank => 3,
            Self::BankDual => 4,
            Self::BankGuarded => 5,
            Self::DualThermal => 6,
        }
    }

    /// The arrangement of an image byte (`None`: not one).
    pub const fn from_byte(b: u8) -> Option<Self> {
        match b {
            0 => Some(Self::Window),
            1 => Some(Self::Sample),
            2 => Some(Self::Dual),
            3 => Some(Self::Bank),
            4 => Some(Self::BankDual),
            5 => Some(Self::BankGuarded),
            6 => Some(Self::DualThermal),
            _ => None,
        }
    }

    /// One of the bank arrangements (the image's Gauss-Markov fields are the bank's).
    pub const fn is_bank(self) -> bool {
        matches!(self, Self::Bank | Self::BankDual | Self::BankGuarded)
    }
}

/// The Gauss-Markov state beside the level ([`MotionEstimator::with_gauss_markov`]):
/// `sigma_dps` = 0 is off.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GaussMarkov {
    /// Standard deviation of the state, deg/s (>= 0, finite; 0 = off).
    pub sigma_dps: f32,
    /// Correlation time, s (> 0, finite, when `sigma_dps` > 0).
    pub tau_s: f32,
}

impl GaussMarkov {
    /// No Gauss-Markov state.
    pub const OFF: Self = Self {
        sigma_dps: 0.0,
        tau_s: 0.0,
    };

    /// The bank these fields carry in the bank arrangements ([`Arrangement::is_bank`]):
    /// `B` = sigma, longest correlation time = tau, random walk `q_rw_dps2_per_s` (the
    /// level's).
    pub const fn bank(&self, q_rw_dps2_per_s: f32) -> BankConfig {
        BankConfig {
            q_rw_dps2_per_s,
            b_dps: self.sigma_dps,
            tau_max_s: self.tau_s,
        }
    }

    /// Off, or a finite sigma > 0 with a finite tau > 0.
    pub fn is_valid(&self) -> bool {
        (self.sigma_dps == 0.0 && self.tau_s == 0.0)
            || (self.sigma_dps.is_finite()
                && self.sigma_dps > 0.0
                && self.tau_s.is_finite()
                && self.tau_s > 0.0)
    }
}

/// The estimator of an [`Arrangement`] (module docs). No heap; the dual holds two
/// [`MotionEstimator`]s.
#[derive(Debug, Clone)]
pub struct PresetEstimator {
    /// The only estimator (window or sample), or the dual's per-sample one.
    rest: MotionEstimator,
    /// The dual's window estimator or the bank arrangements' levels, in one slot (the
    /// larger of the two sizes, not their sum: the firmware's stack holds it).
    second: SecondSlot,
}

/// What sits beside `rest`.
#[derive(Debug, Clone)]
#[allow(clippy::large_enum_variant)] // no heap: the slot is the point
enum SecondSlot {
    /// Window or sample: nothing.
    None,
    /// The dual's window estimator.
    Hold(MotionEstimator),
    /// The bank arrangements ([`Arrangement::is_bank`]).
    Bank(BankLevel),
}

/// How a bank arrangement guards its level against the detector's false stills.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Guard {
    /// [`Arrangement::Bank`]: never rolled back.
    None,
    /// [`Arrangement::BankDual`]: back to the previous window's start; the held bank in
    /// motion.
    Dual,
    /// [`Arrangement::BankGuarded`]: back to the failed window's start.
    Window,
}

/// A bank arrangement's level and its window bookkeeping (as the per-sample estimator's).
#[derive(Debug, Clone)]
struct BankLevel {
    /// Per still sample (the per-sample estimator's flags); rolled back per [`Guard`].
    level: LevelBank,
    /// `BankDual`: per released window mean (one window late), the output in motion.
    hold: LevelBank,
    guard: Guard,
    since_prev: u32,
    since_now: u32,
    // A sample of the current window carried an external still flag.
    external: bool,
}

impl PresetEstimator {
    /// An estimator at power-on for `arrangement`, with the Gauss-Markov state `gm` in
    /// each of its estimators.
    pub fn new(
        model: MotionModel,
        cfg: MotionConfig,
        arrangement: Arrangement,
        gm: GaussMarkov,
    ) -> Result<Self, MotionError> {
        // Built in place (setters, no builder moves, no clone): the firmware's setup
        // holds no extra copy of an estimator on its stack.
        let mut p = Self {
            rest: MotionEstimator::new(model, cfg)?,
            second: SecondSlot::None,
        };
        let update = match arrangement {
            Arrangement::Window => LevelUpdate::Window,
            Arrangement::Sample
            | Arrangement::Dual
            | Arrangement::DualThermal
            | Arrangement::Bank
            | Arrangement::BankDual
            | Arrangement::BankGuarded => LevelUpdate::Sample,
        };
        p.rest.set_level_update(update);
        if arrangement.is_bank() {
            // The per-sample estimator (random-walk level, no Gauss-Markov state) is the
            // detector's drift reference; the bank is the output's level.
            let s = &cfg.sensor;
            let level = LevelBank::new(
                gm.bank(cfg.level_q_dps2_per_s),
                s.drift_bound_dps,
                s.sample_var_dps2(),
                s.sample_rate_hz,
            )
            .ok_or(MotionError::BadBank)?;
            p.second = SecondSlot::Bank(BankLevel {
                hold: level.clone(),
                guard: match arrangement {
                    Arrangement::BankDual => Guard::Dual,
                    Arrangement::BankGuarded => Guard::Window,
                    _ => Guard::None,
                },
                level,
                since_prev: 0,
                since_now: 0,
                external: false,
            });
            return Ok(p);
        }
        // A dual-thermal without a prior (sigma <= 0) gets no temperature state: the dual's
        // level alone, named Dual by `arrangement()`. Not refused here: an early return in
        // this function costs the firmware a copy of the stage on its stack (HIL: 22,052 B
        // instead of 15,796); the image parser refuses such an image (`fog_core::image`).
        let thermal = arrangement == Arrangement::DualThermal;
        if thermal {
            p.rest.set_thermal(gm.sigma_dps);
        } else {
            p.rest.set_gauss_markov(gm.sigma_dps, gm.tau_s);
        }
        if arrangement == Arrangement::Dual || thermal {
            p.second = SecondSlot::Hold(MotionEstimator::new(model, cfg)?);
            // Set up in the slot (no move of a built estimator; the slot was just filled).
            if let SecondSlot::Hold(h) = &mut p.second {
                h.set_level_update(LevelUpdate::Window);
                if thermal {
                    h.set_thermal(gm.sigma_dps);
                } else {
                    h.set_gauss_markov(gm.sigma_dps, gm.tau_s);
                }
            }
        }
        Ok(p)
    }

    /// On-line refinement of the model ([`MotionEstimator::with_online_refinement`]) in
    /// the per-sample (or only) estimator. In the dual the window estimator takes that
    /// estimator's `m(x)` (shared, [`PresetEstimator::push`]), so both use the refined
    /// model. Off by default.
    pub fn with_online_refinement(
        mut self,
        trainer: crate::train::Drls<{ crate::motion::MOTION_L }>,
    ) -> Self {
        self.rest = self.rest.with_online_refinement(trainer);
        self
    }

    /// Which arrangement this is.
    pub fn arrangement(&self) -> Arrangement {
        match (&self.second, self.rest.level_update()) {
            (SecondSlot::Bank(b), _) => match b.guard {
                Guard::None => Arrangement::Bank,
                Guard::Dual => Arrangement::BankDual,
                Guard::Window => Arrangement::BankGuarded,
            },
            (SecondSlot::Hold(_), _) if self.rest.has_thermal() => Arrangement::DualThermal,
            (SecondSlot::Hold(_), _) => Arrangement::Dual,
            (_, LevelUpdate::Window) => Arrangement::Window,
            (_, LevelUpdate::Sample) => Arrangement::Sample,
        }
    }

    /// Back to power-on (both estimators). Keeps the model.
    pub fn restart(&mut self) {
        self.rest.restart();
        match &mut self.second {
            SecondSlot::None => {}
            SecondSlot::Hold(h) => h.restart(),
            SecondSlot::Bank(b) => {
                b.level.restart();
                b.hold.restart();
                b.since_prev = 0;
                b.since_now = 0;
                b.external = false;
            }
        }
    }

    /// One sample (as [`MotionEstimator::push`]): `rate_dps`, `temp_c` (NaN: none),
    /// `external_still` (overrides both detectors when `Some`). In the dual, the output is
    /// `rest`'s when it flags the sample still or the sample carries an external flag (the
    /// flag is trusted), else `hold`'s drift, compensated rate, level and model term (with
    /// `rest`'s still flag). A non-finite rate is refused by both and counted.
    pub fn push(
        &mut self,
        rate_dps: f32,
        temp_c: f32,
        external_still: Option<bool>,
    ) -> Result<MotionOutput, MotionError> {
        if let SecondSlot::Bank(b) = &mut self.second {
            let (o, _) = self
                .rest
                .push_shared(rate_dps, temp_c, external_still, None)?;
            // At the per-sample estimator's window starts, the bank's checkpoint (before this
            // sample reaches it).
            if b.guard != Guard::None && self.rest.window_started() {
                b.level.checkpoint();
                b.since_prev = b.since_now;
                b.since_now = 0;
                b.external = false;
            }
            b.external |= external_still.is_some();
            b.level.predict();
            b.since_prev = b.since_prev.saturating_add(1);
            b.since_now = b.since_now.saturating_add(1);
            if o.still {
                b.level.update(rate_dps - o.model_dps);
            }
            // A window the detector failed takes its samples (`Dual`: and the previous
            // window's) out of the level; a window with an external flag is the flag's (its
            // still samples were still: nothing to undo).
            if self.rest.window_failed() && !b.external {
                match b.guard {
                    Guard::None => {}
                    Guard::Dual => b.level.rollback(b.since_prev),
                    Guard::Window => b.level.rollback_window(b.since_now),
                }
                b.since_prev = 0;
                b.since_now = 0;
            }
            if b.guard == Guard::Dual && self.rest.window_ended() {
                b.hold.predict_many(self.rest.window_samples());
                if let Some((z, r)) = self.rest.released_window() {
                    b.hold.update_mean(z, r);
                }
            }
            // At rest the per-sample bank; from the first sample flagged moving, the bank
            // that only released windows reached (as the dual), unless an external flag
            // decides: it is trusted, so the per-sample bank holds no suspect sample.
            let level = if o.still || external_still.is_some() || b.guard != Guard::Dual {
                b.level.estimate_dps()
            } else {
                b.hold.estimate_dps()
            };
            // The safety net (MotionOutput::verified): when the per-sample estimator holds,
            // its drift (before the first released window: tentative or 0; after `stale_s`,
            // what was verified at the last rest) is the output, not the bank's.
            let drift = if o.verified {
                self.rest.config().sensor.clamp_drift(level + o.model_dps)
            } else {
                o.drift_dps
            };
            return Ok(MotionOutput {
                drift_dps: drift,
                compensated_dps: rate_dps - drift,
                level_dps: level,
                ..o
            });
        }
        let (o, x) = match self
            .rest
            .push_shared(rate_dps, temp_c, external_still, None)
        {
            Ok(v) => v,
            Err(e) => {
                // Counted by both (the same check refuses it in both).
                if let SecondSlot::Hold(h) = &mut self.second {
                    let _ = h.push(rate_dps, temp_c, external_still);
                }
                return Err(e);
            }
        };
        let SecondSlot::Hold(h) = &mut self.second else {
            return Ok(o);
        };
        // The twin's inputs and model term (the same model, evaluated at the same window
        // starts): the window estimator does not evaluate the network again.
        let held = h.push_shared(rate_dps, temp_c, external_still, Some((x, o.model_dps)));
        // An external flag is trusted (as in the bank arrangements): the per-sample level
        // then holds no suspect sample, so it stays the output in motion too.
        Ok(match held {
            Ok((h, _)) if !o.still && external_still.is_none() => {
                MotionOutput { still: false, ..h }
            }
            _ => o,
        })
    }

    /// The configuration (the same for both estimators).
    pub fn config(&self) -> &MotionConfig {
        self.rest.config()
    }

    /// The model (the same for both estimators).
    pub fn model(&self) -> &MotionModel {
        self.rest.model()
    }

    /// Counters of the per-sample (or only) estimator: its still flags are the output's.
    pub fn stats(&self) -> &MotionStats {
        self.rest.stats()
    }

    /// The per-sample (or only) estimator.
    pub fn rest(&self) -> &MotionEstimator {
        &self.rest
    }

    /// The dual's window estimator (`None` unless [`Arrangement::Dual`]).
    pub fn hold(&self) -> Option<&MotionEstimator> {
        match &self.second {
            SecondSlot::Hold(h) => Some(h),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::still::SensorConfig;

    const S: SensorConfig = SensorConfig::ECORE_2000;
    const GM: GaussMarkov = GaussMarkov {
        sigma_dps: 3.0 / 3600.0,
        tau_s: 4.0,
    };

    use crate::test_noise::Noise;

    fn make(a: Arrangement, gm: GaussMarkov) -> PresetEstimator {
        let model = MotionModel::standard(1800.0).expect("test");
        PresetEstimator::new(model, MotionConfig::for_sensor(S), a, gm).expect("test")
    }

    /// Rest 60 s, then turns of `turn_dps` for 30 s and stops of 30 s; a drifting bias.
    fn rate(k: usize, turn_dps: f32, z: &mut Noise) -> (f32, bool) {
        let moving = k >= 6000 && (k / 3000).is_multiple_of(2);
        let t = k as f32 * 0.01;
        let bias = (3.0 + 1.5 * (t / 40.0).sin()) / 3600.0;
        let turn = if moving { turn_dps } else { 0.0 };
        (
            bias + turn + S.sample_var_dps2().sqrt() * z.normal12(),
            moving,
        )
    }

    /// The safety net on a static record: a unit far noisier than its family (10x, beyond
    /// the noise reference's margin) fails its first window (presumed still at power-on),
    /// so nothing is verified and, from that window's end, nothing is subtracted; over the
    /// record it is no worse than no compensation. A model that predicts a drift the unit
    /// does not have (weights at 20 deg/h) is not subtracted either. The same unit at the
    /// family's noise is found still and compensated, verified.
    #[test]
    fn a_static_unit_never_found_still_is_not_compensated() {
        let mut model = MotionModel::standard(1800.0).expect("test");
        model.weights = [20.0 / 3600.0 / crate::motion::MOTION_L as f32; crate::motion::MOTION_L];
        let drift = 5.0 / 3600.0;
        for (scale, want_still) in [(10.0f32, false), (1.0, true)] {
            let mut p =
                PresetEstimator::new(model, MotionConfig::for_sensor(S), Arrangement::Dual, GM)
                    .expect("test");
            let w = p.rest.window_samples() as usize;
            let mut z = Noise(21);
            let (mut still, mut verified, mut late_drift2) = (0usize, 0usize, 0.0f64);
            let (mut err2, mut none2) = (0.0f64, 0.0f64);
            for k in 0..60_000 {
                let x = drift + scale * S.sample_var_dps2().sqrt() * z.normal12();
                let o = p.push(x, f32::NAN, None).expect("test");
                if k >= w {
                    still += usize::from(o.still);
                    late_drift2 += f64::from(o.drift_dps).powi(2);
                }
                verified += usize::from(o.verified);
                err2 += f64::from(o.drift_dps - drift).powi(2);
                none2 += f64::from(drift).powi(2);
                assert_eq!(o.compensated_dps, x - o.drift_dps);
            }
            assert!(err2 <= none2, "{scale}x: {err2} vs {none2}");
            if want_still {
                assert!(
                    still > 50_000 && verified > 50_000,
                    "{scale}x: {still} {verified}"
                );
            } else {
                assert_eq!((still, verified, late_drift2), (0, 0, 0.0), "{scale}x");
            }
        }
    }

    #[test]
    fn dual_is_the_two_estimators_switched_by_the_rest_flag() {
        // The reference: the two estimators built by hand (what host-sim's nav_baselines
        // example ran before this type existed), output switched on the per-sample one's
        // still flag.
        let model = MotionModel::standard(1800.0).expect("test");
        let cfg = MotionConfig::for_sensor(S);
        let base = MotionEstimator::new(model, cfg).expect("test");
        let mut est = base
            .clone()
            .with_level_update(LevelUpdate::Sample)
            .with_gauss_markov(GM.sigma_dps, GM.tau_s);
        let mut hold = base
            .with_level_update(LevelUpdate::Window)
            .with_gauss_markov(GM.sigma_dps, GM.tau_s);
        let mut dual = make(Arrangement::Dual, GM);
        assert_eq!(dual.arrangement(), Arrangement::Dual);
        let mut z = Noise(3);
        let (mut from_hold, mut from_rest) = (0, 0);
        for k in 0..40_000usize {
            let (x, _) = rate(k, 15.0, &mut z);
            let temp = 25.0 + k as f32 * 1.0e-4;
            let h = hold.push(x, temp, None).expect("test");
            let e = est.push(x, temp, None).expect("test");
            let want = if e.still { e.drift_dps } else { h.drift_dps };
            if e.still {
                from_rest += 1;
            } else if h.drift_dps != e.drift_dps {
                from_hold += 1;
            }
            let o = dual.push(x, temp, None).expect("test");
            assert_eq!(o.drift_dps.to_bits(), want.to_bits(), "{k}");
            assert_eq!(o.still, e.still);
        }
        // Both branches were taken, with different values.
        assert!(
            from_rest > 10_000 && from_hold > 1_000,
            "{from_rest} {from_hold}"
        );
        assert!(dual.push(f32::NAN, 0.0, None).is_err());
        assert_eq!(dual.stats().rejected, 1);
        assert_eq!(dual.hold().map(|h| h.stats().rejected), Some(1));
    }

    #[test]
    fn dual_with_an_external_flag_is_the_per_sample_estimator() {
        // A trusted flag: the output is the per-sample estimator's at every flagged sample,
        // moving ones included; where the flag is absent, the dual switches as before.
        let model = MotionModel::standard(1800.0).expect("test");
        let cfg = MotionConfig::for_sensor(S);
        let mut est = MotionEstimator::new(model, cfg)
            .expect("test")
            .with_level_update(LevelUpdate::Sample)
            .with_gauss_markov(GM.sigma_dps, GM.tau_s);
        let mut dual = make(Arrangement::Dual, GM);
        let mut z = Noise(5);
        let mut moving_flagged = 0;
        for k in 0..40_000usize {
            let (x, moving) = rate(k, 15.0, &mut z);
            let flag = (k < 30_000).then_some(!moving);
            let e = est.push(x, 25.0, flag).expect("test");
            let o = dual.push(x, 25.0, flag).expect("test");
            if flag.is_some() {
                assert_eq!(o.drift_dps.to_bits(), e.drift_dps.to_bits(), "{k}");
                moving_flagged += usize::from(moving);
            }
            assert_eq!(o.still, e.still, "{k}");
        }
        assert!(moving_flagged > 1_000, "{moving_flagged}");
    }

    #[test]
    fn single_arrangements_are_the_plain_estimator() {
        let model = MotionModel::standard(1800.0).expect("test");
        let cfg = MotionConfig::for_sensor(S);
        for (a, u) in [
            (Arrangement::Window, LevelUpdate::Window),
            (Arrangement::Sample, LevelUpdate::Sample),
        ] {
            let mut p = make(a, GaussMarkov::OFF);
            assert_eq!(p.arrangement(), a);
            assert!(p.hold().is_none());
            let mut e = MotionEstimator::new(model, cfg)
                .expect("test")
                .with_level_update(u);
            let mut z = Noise(9);
            for k in 0..20_000usize {
                let (x, _) = rate(k, 10.0, &mut z);
                let (o, r) = (p.push(x, f32::NAN, None), e.push(x, f32::NAN, None));
                assert_eq!(o, r, "{a:?} {k}");
            }
        }
    }

    #[test]
    fn dual_rotation_in_motion_never_moves_the_estimate() {
        assert_rotation_ignored(Arrangement::Dual, GM);
        // Without a temperature (NaN) the thermal state is unobserved: the dual's level.
        assert_rotation_ignored(
            Arrangement::DualThermal,
            GaussMarkov {
                sigma_dps: 1.0 / 3600.0,
                tau_s: 0.0,
            },
        );
    }

    /// The unit's temperature link learned at rest and followed in motion: a drift of
    /// 2 deg/h + 1 deg/h per deg C of a temperature that rises 0.5 deg C per minute (within
    /// the 30-deg/h bound over the 20 min), with drives of 20 deg/s. In the drives (past the
    /// first stop) the dual-thermal's drift stays within 1.5 deg/h RMS of the truth
    /// (measured 1.21, most of it the bias's 1.5-deg/h sine, frozen in motion by both); the
    /// dual (Gauss-Markov second state) is at least 1.5x further off (measured 2.08).
    #[test]
    fn dual_thermal_follows_the_units_temperature_in_motion() {
        let k_dps_per_c = 1.0 / 3600.0;
        let run = |a: Arrangement, gm: GaussMarkov| {
            let mut p = make(a, gm);
            let mut z = Noise(33);
            let (mut e2, mut n) = (0.0f64, 0u32);
            for k in 0..120_000usize {
                let (x, moving) = rate(k, 20.0, &mut z);
                let t = k as f32 * 0.01;
                let temp_c = 20.0 + t / 120.0;
                let bias = (3.0 + 1.5 * (t / 40.0).sin()) / 3600.0;
                let drift = 2.0 / 3600.0 + k_dps_per_c * (temp_c - 20.0);
                let o = p.push(x + drift, temp_c, None).expect("test");
                if moving && k > 12_000 {
                    e2 += f64::from((o.drift_dps - bias - drift) * 3600.0).powi(2);
                    n += 1;
                }
            }
            (e2 / f64::from(n)).sqrt()
        };
        let thermal = run(
            Arrangement::DualThermal,
            GaussMarkov {
                sigma_dps: 1.0 / 3600.0,
                tau_s: 0.0,
            },
        );
        let dual = run(Arrangement::Dual, GM);
        assert!(thermal < 1.5, "dual-thermal {thermal} deg/h");
        assert!(
            dual > 1.5 * thermal,
            "dual {dual} vs dual-thermal {thermal} deg/h"
        );
    }

    /// With the still flags given (as the motion module's tests do): identical outputs, bit
    /// for bit, with and without turns of 20 deg/s in the drives. With its own detectors:
    /// bounded, never still in motion (the output there learns only from released still
    /// windows, or from still calls), and at rest (from 10 s into each stop) within
    /// 1.5 deg/h RMS of the wandering bias (the untrained model: the level does it all); a
    /// non-finite rate refused and counted.
    fn assert_rotation_ignored(arrangement: Arrangement, gm: GaussMarkov) {
        let (mut a, mut b) = (make(arrangement, gm), make(arrangement, gm));
        let mut z = Noise(17);
        for k in 0..40_000usize {
            let (x, moving) = rate(k, 0.0, &mut z);
            let turn = if moving { 20.0 } else { 0.0 };
            let oa = a.push(x, f32::NAN, Some(!moving)).expect("test");
            let ob = b.push(x + turn, f32::NAN, Some(!moving)).expect("test");
            assert_eq!(oa.drift_dps.to_bits(), ob.drift_dps.to_bits(), "{k}");
        }
        let mut d = make(arrangement, gm);
        let mut z = Noise(5);
        let (mut e2, mut n) = (0.0f64, 0u32);
        for k in 0..60_000usize {
            let (x, moving) = rate(k, 10.0, &mut z);
            let o = d.push(x, f32::NAN, None).expect("test");
            assert!(o.drift_dps.abs() <= S.drift_bound_dps);
            let t = k as f32 * 0.01;
            let bias = (3.0 + 1.5 * (t / 40.0).sin()) / 3600.0;
            if !moving && k % 3000 > 1000 && k > 5000 {
                e2 += f64::from((o.drift_dps - bias) * 3600.0).powi(2);
                n += 1;
            }
            if moving {
                assert!(!o.still, "{arrangement:?} {k}");
            }
        }
        let rms_dph = (e2 / f64::from(n)).sqrt();
        assert!(rms_dph < 1.5, "{arrangement:?} {rms_dph}");
        assert!(d.push(f32::NAN, 0.0, None).is_err());
        assert_eq!(d.stats().rejected, 1);
    }

    #[test]
    fn gauss_markov_validity() {
        assert!(GaussMarkov::OFF.is_valid());
        assert!(GM.is_valid());
        for (s, t) in [
            (-1.0, 1.0),
            (1.0, 0.0),
            (f32::NAN, 1.0),
            (1.0, f32::INFINITY),
            (0.0, 1.0),
        ] {
            let g = GaussMarkov {
                sigma_dps: s,
                tau_s: t,
            };
            assert!(!g.is_valid(), "{s} {t}");
        }
        for a in [
            Arrangement::Window,
            Arrangement::Sample,
            Arrangement::Dual,
            Arrangement::Bank,
            Arrangement::BankDual,
            Arrangement::BankGuarded,
            Arrangement::DualThermal,
        ] {
            assert_eq!(Arrangement::from_byte(a.to_byte()), Some(a));
            assert_eq!(
                a.is_bank(),
                (3..=5).contains(&a.to_byte()),
                "{a:?}: the bank arrangements are bytes 3..=5"
            );
        }
        assert_eq!(Arrangement::from_byte(7), None);
    }

    /// B 1.5 deg/h, states up to 10^4 s.
    const BANK: GaussMarkov = GaussMarkov {
        sigma_dps: 1.5 / 3600.0,
        tau_s: 10_000.0,
    };

    #[test]
    fn bank_is_the_level_bank_on_rate_minus_model_when_still() {
        // With the external flag (trusted): no rollback, and the output at every sample is
        // a LevelBank updated with rate - m at every still sample and predicted at every
        // sample, in motion too.
        let mut model = MotionModel::standard(1800.0).expect("test");
        for (i, w) in model.weights.iter_mut().enumerate() {
            *w = 1e-4 * (i as f32 - 7.0);
        }
        let cfg = MotionConfig::for_sensor(S);
        let bank = BANK.bank(cfg.level_q_dps2_per_s);
        for a in [Arrangement::BankDual, Arrangement::BankGuarded] {
            let mut p = PresetEstimator::new(model, cfg, a, BANK).expect("test");
            assert_eq!(p.arrangement(), a);
            let mut r =
                LevelBank::new(bank, S.drift_bound_dps, S.sample_var_dps2(), 100.0).expect("test");
            let mut z = Noise(11);
            let mut nonzero_m = 0;
            for k in 0..30_000usize {
                let (x, moving) = rate(k, 12.0, &mut z);
                let o = p.push(x, 25.0, Some(!moving)).expect("test");
                r.predict();
                if !moving {
                    r.update(x - o.model_dps);
                }
                // The external flag is trusted: verified from the first still sample; that
                // sample's output is the tentative per-sample level (0 at power-on) + m.
                let want = if o.verified {
                    S.clamp_drift(r.estimate_dps() + o.model_dps)
                } else {
                    assert_eq!(k, 0, "{a:?}");
                    S.clamp_drift(o.model_dps)
                };
                assert_eq!(o.drift_dps.to_bits(), want.to_bits(), "{a:?} {k}");
                assert_eq!(o.still, !moving);
                nonzero_m += (o.model_dps != 0.0) as u32;
            }
            assert!(nonzero_m > 1000);
        }
        // With its own detector: at samples it flags still the per-sample bank, elsewhere
        // the bank of released windows (and within 3 deg/h of the bias there). The plain
        // bank: the per-sample bank at every sample, updated at every still call.
        let mut plain = PresetEstimator::new(model, cfg, Arrangement::Bank, BANK).expect("test");
        assert_eq!(plain.arrangement(), Arrangement::Bank);
        let mut r =
            LevelBank::new(bank, S.drift_bound_dps, S.sample_var_dps2(), 100.0).expect("test");
        let mut z = Noise(11);
        for k in 0..30_000usize {
            let (x, _) = rate(k, 12.0, &mut z);
            let rest_level = plain.rest.level().0;
            let o = plain.push(x, 25.0, None).expect("test");
            r.predict();
            if o.still {
                r.update(x - o.model_dps);
            }
            // Before the first released window: the per-sample level's tentative drift.
            let want = if o.verified {
                S.clamp_drift(r.estimate_dps() + o.model_dps)
            } else {
                S.clamp_drift(rest_level + o.model_dps)
            };
            assert_eq!(o.drift_dps.to_bits(), want.to_bits(), "{k}");
        }
        let mut p = PresetEstimator::new(model, cfg, Arrangement::BankDual, BANK).expect("test");
        let mut z = Noise(11);
        let mut from_hold = 0;
        for k in 0..30_000usize {
            let (x, moving) = rate(k, 12.0, &mut z);
            let rest_level = p.rest.level().0;
            let o = p.push(x, 25.0, None).expect("test");
            let SecondSlot::Bank(b) = &p.second else {
                panic!("bank")
            };
            let level = if o.still { &b.level } else { &b.hold };
            let want = if o.verified {
                S.clamp_drift(level.estimate_dps() + o.model_dps)
            } else {
                S.clamp_drift(rest_level + o.model_dps)
            };
            assert_eq!(o.drift_dps.to_bits(), want.to_bits(), "{k}");
            if moving {
                from_hold += 1;
                let t = k as f32 * 0.01;
                let bias = (3.0 + 1.5 * (t / 40.0).sin()) / 3600.0;
                assert!(((o.drift_dps - bias) * 3600.0).abs() < 3.0, "{k}");
            }
        }
        assert!(from_hold > 1000, "{from_hold}");
        // A bad bank is refused.
        let bad = GaussMarkov {
            sigma_dps: 1.0 / 3600.0,
            tau_s: 0.5,
        };
        assert!(PresetEstimator::new(model, cfg, Arrangement::Bank, bad).is_err());
    }

    #[test]
    fn bank_guarded_takes_out_a_failed_windows_samples_and_no_others() {
        // A slow ramp from the middle of a window, every 60 s: the fast gate passes its
        // first samples, the window test then fails windows that hold still calls. The
        // rule: at every window end the level is a LevelBank updated with the still calls
        // of the windows that did not fail (the windows before a failed one stay).
        let model = MotionModel::standard(1800.0).expect("test");
        let cfg = MotionConfig::for_sensor(S);
        let mut p = PresetEstimator::new(model, cfg, Arrangement::BankGuarded, BANK).expect("test");
        assert_eq!(p.arrangement(), Arrangement::BankGuarded);
        let w = p.rest.window_samples() as usize;
        let input = |k: usize, z: &mut Noise| {
            let t = k as f32 * 0.01;
            let bias = (3.0 + 1.5 * (t / 40.0).sin()) / 3600.0;
            let c = k % 6000;
            let ramp_dps = if c > 3050 {
                0.0005 * (c - 3050) as f32
            } else {
                0.0
            };
            bias + ramp_dps + S.sample_var_dps2().sqrt() * z.normal12()
        };
        let mut z = Noise(23);
        let n = 36_000usize;
        extern crate std;
        use std::vec::Vec;
        let (mut x, mut still, mut m, mut level) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let mut failed = std::vec![false; n / w + 1];
        for k in 0..n {
            let xk = input(k, &mut z);
            let rest_level = p.rest.level().0;
            let o = p.push(xk, 25.0, None).expect("test");
            if p.rest.window_failed() {
                assert_eq!(k % w, w - 1, "a window ends at its last sample");
                failed[k / w] = true;
            }
            x.push(xk);
            still.push(o.still);
            m.push(o.model_dps);
            level.push(o.level_dps);
            // The output is the bank at rest and in motion (once a released window verified
            // it); before, the per-sample level's tentative drift at a presumed still
            // sample, or nothing.
            let want = if o.verified {
                S.clamp_drift(o.level_dps + o.model_dps)
            } else if o.drift_dps == 0.0 {
                0.0
            } else {
                S.clamp_drift(rest_level + o.model_dps)
            };
            assert_eq!(o.drift_dps.to_bits(), want.to_bits(), "{k}");
        }
        let bank = BANK.bank(cfg.level_q_dps2_per_s);
        let mut r =
            LevelBank::new(bank, S.drift_bound_dps, S.sample_var_dps2(), 100.0).expect("test");
        let mut dropped = 0;
        for k in 0..n {
            r.predict();
            if still[k] && !failed[k / w] {
                r.update(x[k] - m[k]);
            }
            dropped += (still[k] && failed[k / w]) as u32;
            if k % w == w - 1 {
                let err_dph = (level[k] - r.estimate_dps()) * 3600.0;
                assert!(err_dph.abs() < 1e-3, "{k}: {err_dph} deg/h");
            }
        }
        // The ramp's first samples were flagged still and then taken out.
        assert!(dropped > 50, "{dropped}");
    }

    #[test]
    fn bank_rotation_in_motion_never_moves_the_estimate() {
        for arrangement in [
            Arrangement::Bank,
            Arrangement::BankDual,
            Arrangement::BankGuarded,
        ] {
            assert_rotation_ignored(arrangement, BANK);
        }
    }
}

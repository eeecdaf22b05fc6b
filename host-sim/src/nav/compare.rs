//! An identifier beside the causal baselines on one record with truth: the table of
//! `replay` and `identify` (stderr, JSON, report).

use super::{
    AlignmentBias, DetectorAcc, DetectorScores, DriftEstimator, GatedKalman, HeadingAcc, NavRecord,
    NavScores, NoCompensation, SelfCalConfig, SelfCalKalman, ThermalKalman, ThermalKalmanConfig,
};
use serde::Serialize;

/// How the baselines are set up.
#[derive(Debug, Clone, Serialize)]
pub struct BaselineConfig {
    /// Random walk of the gated Kalman filters' bias per sample, (deg/s)^2 (the
    /// self-calibrated one's too: see [`compare`]).
    pub q_dps2: f64,
    /// Where `q_dps2` came from (`--baseline-q-dps2`, tuned on validation records, or the
    /// identifier's own level noise).
    pub q_source: String,
    /// White-noise variance per sample, (deg/s)^2 (the sensor configuration's).
    pub r_dps2: f64,
    /// Release delay, samples (the detector's window): the baselines learn from a sample
    /// flagged still only this many samples later, and only if the flag is still then too,
    /// as the identifier's level does (a window reaches it one window late, only if the
    /// next window passed), so that the flag's lag at the onset of motion reaches neither.
    /// Their estimate at sample k is their state after sample `k - release_samples - 1`.
    /// 0: no delay.
    pub release_samples: usize,
}

/// [`BaselineConfig::release_samples`] around an estimator.
struct Released<E> {
    inner: E,
    delay: usize,
    buf: std::collections::VecDeque<(f64, f64, Option<f64>, bool)>,
    est: f64,
}

impl<E: DriftEstimator> DriftEstimator for Released<E> {
    fn name(&self) -> String {
        self.inner.name()
    }
    fn push(&mut self, t_s: f64, rate_dps: f64, temp_c: Option<f64>, still: bool) -> f64 {
        self.buf.push_back((t_s, rate_dps, temp_c, still));
        if self.buf.len() > self.delay {
            if let Some((t, r, c, s)) = self.buf.pop_front() {
                self.est = self.inner.push(t, r, c, s && still);
            }
        }
        self.est
    }
}

fn released<E: DriftEstimator + 'static>(inner: E, delay: usize) -> Box<dyn DriftEstimator> {
    Box::new(Released {
        inner,
        delay,
        buf: std::collections::VecDeque::with_capacity(delay + 1),
        est: 0.0,
    })
}

/// Name of the no-compensation row.
pub const NO_COMPENSATION: &str = "no compensation";

/// Name of the last row: the gated Kalman filter with its own, alignment-calibrated
/// detector ([`SelfCalKalman`]).
pub const SELFCAL_LABEL: &str = "gated Kalman, own detector (alignment-calibrated)";

/// One row of the table.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// Estimator.
    pub name: String,
    /// Its scores.
    pub scores: NavScores,
}

/// The table and the detector's rates.
#[derive(Debug, Clone, Serialize)]
pub struct Comparison {
    /// The identifier first, then none, alignment bias, gated Kalman, thermal Kalman, gated
    /// Kalman with its own detector ([`SELFCAL_LABEL`]).
    pub rows: Vec<Row>,
    /// The still flags (the identifier's, shared by every baseline but the last, which has
    /// its own detector) against `moving`.
    pub detector: DetectorScores,
    /// Whether the record has a `moving` column (without it the detector rates count every
    /// sample as still).
    pub moving_known: bool,
    /// The baselines' setup.
    pub baselines: BaselineConfig,
}

/// A comparison and the heading error of each row, per sample (for the figure).
#[derive(Debug, Clone)]
pub struct Compared {
    /// Scores.
    pub table: Comparison,
    /// Heading error per sample, deg, in the order of `table.rows`.
    pub heading_deg: Vec<Vec<f64>>,
}

/// Rows of the table: the identifier and five baselines.
pub const ROWS: usize = 6;

/// One sample with its truth, as [`Comparer::push`] takes it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthSample {
    /// Seconds since power-on.
    pub t_s: f64,
    /// Measured rate, deg/s.
    pub rate_dps: f64,
    /// Sensor temperature, deg C.
    pub temp_c: Option<f64>,
    /// True platform + Earth rate, deg/s.
    pub true_rate_dps: f64,
    /// True drift, deg/s.
    pub drift_dps: f64,
    /// Ground truth: the platform moves.
    pub moving: bool,
}

/// [`compare`] sample by sample, in constant memory: the identifier's drift and still flag
/// and the record's truth in, each row's heading error out.
pub struct Comparer {
    labels: [String; ROWS],
    baselines: [Box<dyn DriftEstimator>; ROWS - 1],
    heading: [HeadingAcc; ROWS],
    detector: DetectorAcc,
    moving_known: bool,
    cfg: BaselineConfig,
}

impl Comparer {
    /// The identifier `name` beside the five baselines of [`compare`]; `moving_known`: the
    /// record has a `moving` column.
    pub fn new(name: &str, moving_known: bool, cfg: BaselineConfig) -> Self {
        let thermal = ThermalKalmanConfig {
            q_dps2: cfg.q_dps2,
            r_dps2: cfg.r_dps2,
            ..ThermalKalmanConfig::default()
        };
        Self {
            labels: [
                name.to_string(),
                NO_COMPENSATION.into(),
                "alignment bias (initial still mean, held)".into(),
                "gated random-walk Kalman (ZARU)".into(),
                "gated Kalman + temperature regression".into(),
                SELFCAL_LABEL.into(),
            ],
            baselines: [
                Box::new(NoCompensation),
                released(AlignmentBias::default(), cfg.release_samples),
                released(
                    GatedKalman::new(cfg.q_dps2, cfg.r_dps2),
                    cfg.release_samples,
                ),
                released(ThermalKalman::new(thermal), cfg.release_samples),
                Box::new(SelfCalKalman::new(SelfCalConfig::with_q(cfg.q_dps2))),
            ],
            heading: Default::default(),
            detector: DetectorAcc::default(),
            moving_known,
            cfg,
        }
    }

    /// Row labels, in the table's order.
    pub fn labels(&self) -> &[String; ROWS] {
        &self.labels
    }

    /// One sample: the identifier's drift estimate (deg/s) and still flag for it; returns
    /// each row's heading error at it, deg.
    pub fn push(&mut self, s: &TruthSample, drift_dps: f64, still: bool) -> [f64; ROWS] {
        let mut out = [0.0; ROWS];
        for (k, acc) in self.heading.iter_mut().enumerate() {
            let d = match k.checked_sub(1).and_then(|b| self.baselines.get_mut(b)) {
                Some(e) => e.push(s.t_s, s.rate_dps, s.temp_c, still),
                None => drift_dps,
            };
            out[k] = acc.push(
                s.t_s,
                s.rate_dps - d,
                s.true_rate_dps,
                d,
                s.drift_dps,
                s.moving,
            );
        }
        self.detector.push(s.moving, still);
        out
    }

    /// The table.
    pub fn finish(self) -> Comparison {
        Comparison {
            rows: self
                .labels
                .into_iter()
                .zip(&self.heading)
                .map(|(name, h)| Row {
                    name,
                    scores: h.scores(),
                })
                .collect(),
            detector: self.detector.scores(),
            moving_known: self.moving_known,
            baselines: self.cfg,
        }
    }
}

/// Scores the identifier (`name`, its drift per sample `drift_dps`) and the five causal
/// baselines on `rec` ([`Comparer`]): the first four with the still flags `still` (the
/// identifier's; samples beyond them count as moving), released `cfg.release_samples`
/// late; the last, [`SelfCalKalman`], with its own detector calibrated on the record's
/// first [`super::selfcal::ALIGN_S`] s (ASSUMED still: a vehicle's alignment) and its own
/// release. Its `q` is the other gated filters' `cfg.q_dps2` (one q for every baseline, so
/// the row differs from the gated Kalman's by the detector alone; a q tuned for it with its
/// own detector: [`super::tune_selfcal_q`]). `moving_known`: the record has a `moving`
/// column.
pub fn compare(
    rec: &NavRecord,
    name: &str,
    drift_dps: &[f64],
    still: &[bool],
    moving_known: bool,
    cfg: BaselineConfig,
) -> Compared {
    let mut c = Comparer::new(name, moving_known, cfg);
    let mut heading_deg: Vec<Vec<f64>> = (0..ROWS).map(|_| Vec::with_capacity(rec.len())).collect();
    for k in 0..rec.len() {
        let s = TruthSample {
            t_s: rec.t_s[k],
            rate_dps: rec.rate_dps[k],
            temp_c: rec.temp_c.as_ref().and_then(|t| t.get(k).copied()),
            true_rate_dps: rec.true_rate_dps[k],
            drift_dps: rec.drift_dps[k],
            moving: rec.moving[k],
        };
        let d = drift_dps.get(k).copied().unwrap_or(0.0);
        let h = c.push(&s, d, still.get(k).copied().unwrap_or(false));
        for (v, x) in heading_deg.iter_mut().zip(h) {
            v.push(x);
        }
    }
    Compared {
        table: c.finish(),
        heading_deg,
    }
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("-".into(), |x| format!("{x:.digits$}"))
}

/// The table as text: headline first (the identifier's heading-error RMS against the best
/// baseline, [`NO_COMPENSATION`] not a candidate), then one line per estimator, then the
/// detector's rates.
pub fn table(c: &Comparison) -> String {
    let mut o = String::new();
    if let Some((id, rest)) = c.rows.split_first() {
        if let Some(best) = rest
            .iter()
            .filter(|r| r.name != NO_COMPENSATION)
            .min_by(|a, b| {
                a.scores
                    .heading_rms_deg
                    .total_cmp(&b.scores.heading_rms_deg)
            })
        {
            o += &format!(
                "heading error RMS: {} {:.4} deg, best causal baseline ({}) {:.4} deg ({:+.1} %)\n",
                id.name,
                id.scores.heading_rms_deg,
                best.name,
                best.scores.heading_rms_deg,
                100.0 * (id.scores.heading_rms_deg / best.scores.heading_rms_deg - 1.0)
            );
        }
    }
    o += &format!(
        "{:<50} {:>12} {:>12} {:>12} {:>12} {:>12}\n",
        "estimator", "heading RMS", "heading end", "e_truth", "e still", "e moving"
    );
    o += &format!(
        "{:<50} {:>12} {:>12} {:>12} {:>12} {:>12}\n",
        "", "deg", "deg", "deg/h", "deg/h", "deg/h"
    );
    for r in &c.rows {
        let s = &r.scores;
        o += &format!(
            "{:<50} {:>12.4} {:>12.4} {:>12} {:>12} {:>12}\n",
            r.name,
            s.heading_rms_deg,
            s.heading_final_deg,
            opt(s.e_truth_dph, 3),
            opt(s.e_truth_still_dph, 3),
            opt(s.e_truth_moving_dph, 3)
        );
    }
    let pct = |v: Option<f64>| v.map_or("-".into(), |x| format!("{:.2} %", 100.0 * x));
    o += &format!(
        "detector: false-still {} of {} moving samples, missed-still {} of {} still samples{}\n",
        pct(c.detector.false_still_rate),
        c.detector.moving_samples,
        pct(c.detector.missed_still_rate),
        c.detector.still_samples,
        if c.moving_known {
            ""
        } else {
            " (no `moving` column: every sample counted as still)"
        }
    );
    o += &format!(
        "baselines: q {:.3e} (deg/s)^2 per sample from {}, r {:.3e} (deg/s)^2; same still flags as the identifier, released {} samples late as its level (the last row: own detector and r, from the first {} s)\n",
        c.baselines.q_dps2,
        c.baselines.q_source,
        c.baselines.r_dps2,
        c.baselines.release_samples,
        super::selfcal::ALIGN_S
    );
    o
}

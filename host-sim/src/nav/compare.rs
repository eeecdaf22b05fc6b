//! An identifier beside the causal baselines on one record with truth: the table of
//! `replay` and `identify` (stderr, JSON, report).

use super::{
    run, AlignmentBias, DetectorAcc, DetectorScores, DriftEstimator, GatedKalman, NavRecord,
    NavScores, NoCompensation, SelfCalConfig, SelfCalKalman, ThermalKalman, ThermalKalmanConfig,
};
use serde::Serialize;

/// How the baselines are set up.
#[derive(Debug, Clone, Serialize)]
pub struct BaselineConfig {
    /// Random walk of the gated Kalman filters' bias per sample, (deg/s)^2 (the
    /// self-calibrated one's too: see [`compare`]).
    pub q_dps2: f64,
    /// Where `q_dps2` came from (`--baseline-q`, tuned on validation records, or the
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

fn released<'a, E: DriftEstimator + 'a>(inner: E, delay: usize) -> Box<dyn DriftEstimator + 'a> {
    Box::new(Released {
        inner,
        delay,
        buf: std::collections::VecDeque::with_capacity(delay + 1),
        est: 0.0,
    })
}

/// Drift estimates computed beforehand (an identifier already run over the record),
/// replayed as a [`DriftEstimator`] (one per push, in order; 0 past the end).
pub struct Precomputed<'a> {
    name: &'a str,
    drift_dps: &'a [f64],
    k: usize,
}

impl<'a> Precomputed<'a> {
    /// Replays `drift_dps` (deg/s, one per sample) under `name`.
    pub fn new(name: &'a str, drift_dps: &'a [f64]) -> Self {
        Self {
            name,
            drift_dps,
            k: 0,
        }
    }
}

impl DriftEstimator for Precomputed<'_> {
    fn name(&self) -> String {
        self.name.into()
    }
    fn push(&mut self, _: f64, _: f64, _: Option<f64>, _: bool) -> f64 {
        let d = self.drift_dps.get(self.k).copied().unwrap_or(0.0);
        self.k += 1;
        d
    }
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

/// Scores the identifier (`name`, its drift per sample `drift_dps`) and the five causal
/// baselines on `rec`: the first four with the still flags `still` (the identifier's),
/// released `cfg.release_samples` late; the last, [`SelfCalKalman`], with its own detector
/// calibrated on the record's first [`super::selfcal::ALIGN_S`] s (ASSUMED still: a
/// vehicle's alignment) and its own release. Its `q` is the other gated filters' `cfg.q_dps2`
/// (one q for every baseline, so the row differs from the gated Kalman's by the detector
/// alone; a q tuned for it with its own detector: [`super::tune_selfcal_q`]).
/// `moving_known`: the record has a `moving` column.
pub fn compare(
    rec: &NavRecord,
    name: &str,
    drift_dps: &[f64],
    still: &[bool],
    moving_known: bool,
    cfg: BaselineConfig,
) -> Compared {
    let thermal = ThermalKalmanConfig {
        q_dps2: cfg.q_dps2,
        r_dps2: cfg.r_dps2,
        ..ThermalKalmanConfig::default()
    };
    let mut ests: Vec<Box<dyn DriftEstimator + '_>> = vec![
        Box::new(Precomputed::new(name, drift_dps)),
        Box::new(NoCompensation),
        released(AlignmentBias::default(), cfg.release_samples),
        released(
            GatedKalman::new(cfg.q_dps2, cfg.r_dps2),
            cfg.release_samples,
        ),
        released(ThermalKalman::new(thermal), cfg.release_samples),
        Box::new(SelfCalKalman::new(SelfCalConfig::with_q(cfg.q_dps2))),
    ];
    let labels = [
        name.to_string(),
        NO_COMPENSATION.into(),
        "alignment bias (initial still mean, held)".into(),
        "gated random-walk Kalman (ZARU)".into(),
        "gated Kalman + temperature regression".into(),
        SELFCAL_LABEL.into(),
    ];
    let mut rows = Vec::new();
    let mut heading_deg = Vec::new();
    for (e, label) in ests.iter_mut().zip(labels) {
        let r = run(rec, e.as_mut(), still);
        rows.push(Row {
            name: label,
            scores: r.scores,
        });
        heading_deg.push(r.heading_deg);
    }
    let mut det = DetectorAcc::default();
    for (k, &m) in rec.moving.iter().enumerate() {
        det.push(m, still.get(k).copied().unwrap_or(false));
    }
    Compared {
        table: Comparison {
            rows,
            detector: det.scores(),
            moving_known,
            baselines: cfg,
        },
        heading_deg,
    }
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("-".into(), |x| format!("{x:.digits$}"))
}

/// The table as text: headline first (the identifier's heading-error RMS against the best
/// baseline), then one line per estimator, then the detector's rates.
pub fn table(c: &Comparison) -> String {
    let mut o = String::new();
    if let Some((id, rest)) = c.rows.split_first() {
        if let Some(best) = rest.iter().min_by(|a, b| {
            a.scores
                .heading_rms_deg
                .total_cmp(&b.scores.heading_rms_deg)
        }) {
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

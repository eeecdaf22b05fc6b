//! The evidence test's (`tests/motion_evidence.rs`) f32 entry points, delegating to
//! [`crate::nav`], the one home of the scores and baselines: heading error
//! ([`crate::nav::HeadingAcc`], trapezoid rule), the alignment baseline
//! ([`crate::nav::AlignmentBias`]) and the detector's rates ([`crate::nav::DetectorAcc`]).

use crate::nav::{AlignmentBias, DetectorAcc, DriftEstimator, HeadingAcc};
use serde::Serialize;

/// Heading error `e(t) = integral of (compensated - true rate) dt`, deg.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Heading {
    /// RMS of `e` over the record, deg.
    pub rms_deg: f64,
    /// `e` at the end, deg.
    pub final_deg: f64,
    /// Largest `|e|`, deg.
    pub max_abs_deg: f64,
}

/// Heading error of `compensated_dps` against `true_rate_dps`, samples `dt_s` apart
/// ([`HeadingAcc`]).
pub fn heading(compensated_dps: &[f32], true_rate_dps: &[f32], dt_s: f64) -> Heading {
    let mut acc = HeadingAcc::new();
    for (k, (&c, &t)) in compensated_dps.iter().zip(true_rate_dps).enumerate() {
        acc.push(k as f64 * dt_s, f64::from(c), f64::from(t), 0.0, 0.0, false);
    }
    let s = acc.scores();
    Heading {
        rms_deg: s.heading_rms_deg,
        final_deg: s.heading_final_deg,
        max_abs_deg: s.heading_max_abs_deg,
    }
}

/// The rate compensated by the alignment bias ([`AlignmentBias`]) with the first `align`
/// samples flagged still.
pub fn alignment_bias(rate_dps: &[f32], align: usize) -> Vec<f32> {
    let mut a = AlignmentBias::default();
    rate_dps
        .iter()
        .enumerate()
        .map(|(k, &x)| {
            let b = a.push(0.0, f64::from(x), None, k < align);
            (f64::from(x) - b) as f32
        })
        .collect()
}

/// How the detector did against the truth (`|true rate| > 0` = moving).
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct DetectorScore {
    /// Moving samples flagged still / moving samples.
    pub false_still: f64,
    /// Still samples flagged moving / still samples.
    pub missed_still: f64,
}

/// Scores still flags against the true rate ([`DetectorAcc`]).
pub fn detector_score(still: &[bool], true_rate_dps: &[f32]) -> DetectorScore {
    let mut acc = DetectorAcc::default();
    for (&s, &t) in still.iter().zip(true_rate_dps) {
        acc.push(t != 0.0, s);
    }
    let d = acc.scores();
    DetectorScore {
        false_still: d.false_still_rate.unwrap_or(0.0),
        missed_still: d.missed_still_rate.unwrap_or(0.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn delegates_to_nav() {
        // Trapezoid: 1 deg/s error over 99 steps of 0.01 s.
        let h = heading(&[1.0; 100], &[0.0; 100], 0.01);
        assert!((h.final_deg - 0.99).abs() < 1e-9);
        assert!((h.max_abs_deg - 0.99).abs() < 1e-9);
        let a = alignment_bias(&[2.0, 2.0, 2.0, 5.0], 2);
        assert_eq!(a, vec![2.0, 0.0, 0.0, 3.0]);
        let d = detector_score(&[true, false, true, true], &[0.0, 0.0, 1.0, 2.0]);
        assert_eq!(d.false_still, 1.0);
        assert_eq!(d.missed_still, 0.5);
    }
}

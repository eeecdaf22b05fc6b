//! Figures a navigator reads for the motion identifier's evidence (`docs/motion.md`): heading
//! error, the alignment-bias baseline and the detector's error rates. (The project-wide
//! scores and baselines of the `replay`/`identify` reports belong to the `nav` module.)

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

/// Heading error of `compensated_dps` against `true_rate_dps` (rectangle rule, step `dt_s`).
pub fn heading(compensated_dps: &[f32], true_rate_dps: &[f32], dt_s: f64) -> Heading {
    let (mut e, mut sum2, mut max) = (0.0f64, 0.0f64, 0.0f64);
    let n = compensated_dps.len().min(true_rate_dps.len());
    for k in 0..n {
        e += (f64::from(compensated_dps[k]) - f64::from(true_rate_dps[k])) * dt_s;
        sum2 += e * e;
        max = max.max(e.abs());
    }
    Heading {
        rms_deg: (sum2 / n.max(1) as f64).sqrt(),
        final_deg: e,
        max_abs_deg: max,
    }
}

/// The alignment-bias baseline: the mean rate of the first `align` samples (the initial
/// still period), held; during the alignment the running mean so far (causal).
pub fn alignment_bias(rate_dps: &[f32], align: usize) -> Vec<f32> {
    let (mut sum, mut n) = (0.0f64, 0usize);
    rate_dps
        .iter()
        .enumerate()
        .map(|(k, &x)| {
            let b = if n > 0 { sum / n as f64 } else { 0.0 };
            if k < align {
                sum += f64::from(x);
                n += 1;
            }
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

/// Scores still flags against the true rate.
pub fn detector_score(still: &[bool], true_rate_dps: &[f32]) -> DetectorScore {
    let (mut moving, mut fs, mut resting, mut ms) = (0u64, 0u64, 0u64, 0u64);
    for (s, t) in still.iter().zip(true_rate_dps) {
        if *t != 0.0 {
            moving += 1;
            fs += u64::from(*s);
        } else {
            resting += 1;
            ms += u64::from(!*s);
        }
    }
    DetectorScore {
        false_still: fs as f64 / moving.max(1) as f64,
        missed_still: ms as f64 / resting.max(1) as f64,
    }
}

/// RMS of `estimate - truth` over `from..`, deg/h, and `e_truth` = that over RMS(truth)
/// (the definition of `host-sim identify`).
pub fn truth_error(estimate_dps: &[f32], truth_dps: &[f32], from: usize) -> (f64, f64) {
    let (mut se, mut st, mut n) = (0.0f64, 0.0f64, 0usize);
    for (y, t) in estimate_dps.iter().zip(truth_dps).skip(from) {
        let (y, t) = (f64::from(*y), f64::from(*t));
        se += (y - t) * (y - t);
        st += t * t;
        n += 1;
    }
    let n = n.max(1) as f64;
    (
        (se / n).sqrt() * 3600.0,
        (se / st.max(f64::MIN_POSITIVE)).sqrt(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heading_integrates_the_error() {
        let h = heading(&[1.0; 100], &[0.0; 100], 0.01);
        assert!((h.final_deg - 1.0).abs() < 1e-9);
        assert!((h.max_abs_deg - 1.0).abs() < 1e-9);
        let a = alignment_bias(&[2.0, 2.0, 2.0, 5.0], 2);
        assert_eq!(a, vec![2.0, 0.0, 0.0, 3.0]);
        let d = detector_score(&[true, false, true, true], &[0.0, 0.0, 1.0, 2.0]);
        assert_eq!(d.false_still, 1.0);
        assert_eq!(d.missed_still, 0.5);
    }
}

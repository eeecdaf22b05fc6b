//! The static records' random-walk baseline: a random-walk Kalman filter given every sample
//! as still ([`GatedKalman`] with all flags true), `r` the record's own white noise per
//! sample (`var(first differences) / 2`: from the whole record, not causal), `q` picked on a
//! set of static records with a drift truth by the least mean e_truth over a log grid.
//! `unit_family` picks `q` on the very static-test records (an oracle); `drift_filter_eval`
//! also on the family's calibration runs (`train/`: the issue's "q from the calibration
//! runs").

use host_sim::nav::{self, GatedKalman, NavRecord};

/// q grid, (deg/s)^2 per sample: 1e-20..1e-6, 4 points per decade.
pub const STATIC_Q_GRID: (f64, f64, usize) = (1e-20, 1e-6, 4);

/// e_truth = RMS(estimate - drift) / RMS(drift) (no compensation: 1).
pub fn e_truth(est_dps: &[f64], drift_dps: &[f64]) -> f64 {
    let rms = |v: &mut dyn Iterator<Item = f64>| {
        let (mut s, mut n) = (0.0, 0usize);
        for x in v {
            s += x * x;
            n += 1;
        }
        (s / n.max(1) as f64).sqrt()
    };
    rms(&mut est_dps.iter().zip(drift_dps).map(|(e, d)| e - d))
        / rms(&mut drift_dps.iter().copied())
}

/// `var(first differences) / 2` of the rate: the white noise per sample of a static record
/// (a slow drift adds next to nothing to the differences).
pub fn diff_var_dps2(rate: &[f64]) -> f64 {
    let n = rate.len().saturating_sub(1).max(1) as f64;
    let d = || rate.windows(2).map(|w| w[1] - w[0]);
    let m = d().sum::<f64>() / n;
    d().map(|x| (x - m) * (x - m)).sum::<f64>() / n / 2.0
}

/// The baseline's drift estimate on `rec` with `q_dps2` and `r_dps2` (the record's own:
/// [`diff_var_dps2`]).
pub fn estimate(rec: &NavRecord, q_dps2: f64, r_dps2: f64) -> Vec<f64> {
    let still = vec![true; rec.len()];
    nav::run(rec, &mut GatedKalman::new(q_dps2, r_dps2), &still).drift_est_dps
}

/// A q picked on a grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Picked {
    /// The q with the least mean e_truth, (deg/s)^2 per sample.
    pub q_dps2: f64,
    /// That mean e_truth.
    pub mean_e_truth: f64,
    /// Every point of the grid: (q, mean e_truth).
    pub grid: Vec<(f64, f64)>,
}

/// The q of [`STATIC_Q_GRID`] with the least mean e_truth on `recs` ([`nav::least_mean`]:
/// ties to the smaller q). None when no record or no q scores.
pub fn pick_q(recs: &[&NavRecord]) -> Option<Picked> {
    let g = STATIC_Q_GRID;
    // Each record's own r, once.
    let with_r: Vec<(&NavRecord, f64)> = recs
        .iter()
        .map(|r| (*r, diff_var_dps2(&r.rate_dps)))
        .collect();
    let t = nav::least_mean(&with_r, &nav::log_grid(g.0, g.1, g.2), |q, (rec, r)| {
        e_truth(&estimate(rec, q, *r), &rec.drift_dps)
    })?;
    Some(Picked {
        q_dps2: t.q_dps2,
        mean_e_truth: t.heading_rms_deg,
        grid: t.grid,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn e_truth_is_0_for_the_truth_and_1_for_no_compensation() {
        let drift = [0.01, -0.02, 0.03, 0.005];
        assert_eq!(e_truth(&drift, &drift), 0.0);
        assert!((e_truth(&[0.0; 4], &drift) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn diff_var_is_the_white_variance_of_a_constant_rate_plus_noise() {
        // Independent draws of variance 1/3 (uniform on -1..1) around a bias: var(diff)/2 = 1/3.
        let mut x: u64 = 12345;
        let rate: Vec<f64> = (0..200_000)
            .map(|_| {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                0.5 + ((x >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
            })
            .collect();
        let v = diff_var_dps2(&rate);
        assert!((v - 1.0 / 3.0).abs() < 0.01, "{v}");
    }
}

//! Dedicated detection tests: decisions that use what the record carries, each a statistic
//! computed the same way on the real record and on every baseline simulation (the null).
//!
//! - `temperature`, `rate_ramp`, `warmup`: likelihood-ratio tests with the baseline's noise
//!   refitted under each model ([`super::drift`]).
//! - `sinusoid`: a periodogram test. Whole record on a zero-filled time line, 2x padded FFT;
//!   each bin's power over the median power of its 256-bin chunk (so coloured noise does not
//!   matter); statistic: ln of the largest ratio above 4 cycles per block; its null a Gumbel
//!   law ([`LINE_GUMBEL_SCALE`]).
//! - `scale_factor`: 5-s means of the rate less the reference regressed on `[1, t,
//!   reference]`: `ln(SSE without / with the reference)`, AR(1) errors (Cochrane-Orcutt)
//!   so that a slow noise term (a Gauss-Markov wander) does not pass for a slow motion; it
//!   also needs the reference coefficient's `|t| > 3` ([`SF_MIN_T`]).
//! - `dropouts`: the time stamps: missing sample slots in the whole record against the
//!   simulations' ([`dropouts_outcome`]); not run when the time stamps are bursty.
//! - `spikes`: outliers (5-point running-median residuals beyond [`SPIKE_TEST_SIGMAS`]
//!   robust sigma) in the whole record against the simulations'
//!   ([`spikes_outcome`]): the candidate is fitted on the fit blocks only, so a few spikes
//!   that all fall in the held-out blocks are otherwise missed.
//!
//! The drift, line and Markov tests give the normal score `z` of their p-value; the others
//! `z = (real - mean_null) / sd_null` (sd floored at a tenth of the null mean and at
//! [`SD_FLOOR`]). A test *passes* when `z` exceeds its threshold ([`THRESHOLDS`]).
//! Short Gauss-Markov correlation times have no test of their own: the PSD group of the gap
//! measure sees them, and without a user model the `markov` candidate is the baseline
//! refitted jointly with the GM term.

use super::effects::Effect;
use super::features::{mean, median};
use serde::Serialize;

/// Window length of the time-domain tests, s.
pub const WINDOW_S: f64 = 5.0;

/// z thresholds per test.
pub const THRESHOLDS: [(Effect, f64); 9] = [
    (Effect::Quantization, 3.0),
    (Effect::Temperature, 2.5),
    (Effect::Dropouts, 3.0),
    (Effect::Spikes, 3.0),
    (Effect::RateRamp, 2.5),
    (Effect::ScaleFactor, 3.0),
    (Effect::Sinusoid, 2.5),
    (Effect::Warmup, 2.5),
    (Effect::Markov, 2.5),
];

/// z given to a lattice found by the quantization test (certain evidence; ranked above a
/// test just past its threshold, below a strong one).
pub const LATTICE_Z: f64 = 5.0;

/// Absolute floor of a test's null standard deviation (ln statistics: 0.001 is a 0.1 %
/// change of a residual sum of squares; a tenth of the null mean floors it too).
pub const SD_FLOOR: f64 = 0.001;

/// Threshold of one test.
pub fn threshold(e: Effect) -> f64 {
    THRESHOLDS
        .iter()
        .find(|(k, _)| *k == e)
        .map_or(f64::INFINITY, |(_, z)| *z)
}

/// One test's outcome.
#[derive(Debug, Clone, Serialize)]
pub struct Test {
    /// The effect it tests for.
    pub effect: Effect,
    /// What was computed, in words.
    pub test: String,
    /// The real record's statistic.
    pub statistic: f64,
    /// Null statistics: mean.
    pub null_mean: f64,
    /// Null: standard deviation (floored).
    pub null_sd: f64,
    /// Null: largest.
    pub null_max: f64,
    /// Null values (simulations).
    pub nulls: usize,
    /// `(statistic - null_mean) / null_sd`.
    pub z: f64,
    /// Threshold on z.
    pub threshold: f64,
    /// `z > threshold`.
    pub passed: bool,
    /// Where the evidence is (e.g. the line's frequency, the transient's time constant).
    pub detail: String,
}

/// Builds a test outcome from the real statistic and the null values.
pub fn outcome(effect: Effect, test: &str, real: f64, nulls: &[f64], detail: String) -> Test {
    let v: Vec<f64> = nulls.iter().copied().filter(|x| x.is_finite()).collect();
    let m = mean(&v);
    let sd = if v.len() > 1 {
        (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
    } else {
        0.0
    };
    // Floor: a tenth of the null mean's magnitude, and `SD_FLOOR` absolute.
    let sd = sd.max(0.1 * m.abs()).max(SD_FLOOR);
    let null_max = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let z = if real.is_finite() {
        (real - m) / sd
    } else {
        0.0
    };
    let threshold = threshold(effect);
    Test {
        effect,
        test: test.to_string(),
        statistic: real,
        null_mean: m,
        null_sd: sd,
        null_max,
        nulls: v.len(),
        z,
        threshold,
        passed: z > threshold,
        detail,
    }
}

/// Window means on a fixed time grid (`w_s` windows from t = 0): NaN where empty.
pub fn window_means(t_s: &[f64], y: &[f64], w_s: f64, n_win: usize) -> Vec<f64> {
    let mut s = vec![0.0; n_win];
    let mut c = vec![0usize; n_win];
    for (&t, &v) in t_s.iter().zip(y) {
        let k = (t / w_s) as usize;
        if k < n_win {
            s[k] += v;
            c[k] += 1;
        }
    }
    s.iter()
        .zip(&c)
        .map(|(&s, &c)| if c > 0 { s / c as f64 } else { f64::NAN })
        .collect()
}

/// Rate of change of a window series, per s: centred difference of a `smooth`-window
/// moving average (NaN windows skipped in the average).
pub fn rate_of_change(x: &[f64], w_s: f64, smooth: usize) -> Vec<f64> {
    let n = x.len();
    let h = smooth / 2;
    let sm: Vec<f64> = (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(h), (i + h + 1).min(n));
            let v: Vec<f64> = x[a..b].iter().copied().filter(|v| v.is_finite()).collect();
            if v.is_empty() {
                f64::NAN
            } else {
                mean(&v)
            }
        })
        .collect();
    (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(h), (i + h).min(n - 1));
            if b > a {
                (sm[b] - sm[a]) / ((b - a) as f64 * w_s)
            } else {
                0.0
            }
        })
        .collect()
}

/// Least squares on the valid rows: residual sum of squares of `y` on the columns.
fn sse(y: &[f64], cols: &[&[f64]]) -> f64 {
    let p = cols.len();
    let mut a = vec![vec![0.0; p + 1]; p];
    let rows: Vec<usize> = (0..y.len())
        .filter(|&i| y[i].is_finite() && cols.iter().all(|c| c[i].is_finite()))
        .collect();
    for &i in &rows {
        for r in 0..p {
            for c in 0..p {
                a[r][c] += cols[r][i] * cols[c][i];
            }
            a[r][p] += cols[r][i] * y[i];
        }
    }
    let Some(beta) = solve(a) else {
        return f64::NAN;
    };
    rows.iter()
        .map(|&i| {
            let f: f64 = (0..p).map(|r| beta[r] * cols[r][i]).sum();
            (y[i] - f).powi(2)
        })
        .sum()
}

/// Solves the augmented normal equations (Gauss-Jordan, partial pivoting); `None` if
/// singular.
pub fn solve(mut a: Vec<Vec<f64>>) -> Option<Vec<f64>> {
    let p = a.len();
    let scale = a
        .iter()
        .enumerate()
        .map(|(i, r)| r[i].abs())
        .fold(0.0, f64::max);
    for c in 0..p {
        let piv = (c..p).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        a.swap(c, piv);
        let d = a[c][c];
        if d.abs() <= 1e-13 * scale || d == 0.0 {
            return None;
        }
        for v in a[c].iter_mut() {
            *v /= d;
        }
        let rc = a[c].clone();
        for (i, ai) in a.iter_mut().enumerate() {
            if i != c {
                let f = ai[c];
                for (v, r) in ai.iter_mut().zip(&rc) {
                    *v -= f * r;
                }
            }
        }
    }
    Some(a.iter().map(|r| r[p]).collect())
}

/// Nested-model statistic with an AR(1) error model (Cochrane-Orcutt): the lag-1
/// autocorrelation `rho` of the full model's OLS residuals (clamped to [0, 0.98]); every
/// series quasi-differenced (`x[i] - rho x[i-1]`); `ln(SSE_small / SSE_full)` on the
/// transformed rows. A drift that merely wanders (random walk, flicker) leaves strongly
/// autocorrelated residuals and is discounted; rows with a NaN are dropped.
fn ar1_nested(y: &[f64], small: &[&[f64]], extra: &[&[f64]]) -> f64 {
    let rows: Vec<usize> = (0..y.len())
        .filter(|&i| y[i].is_finite() && small.iter().chain(extra).all(|c| c[i].is_finite()))
        .collect();
    let pick = |x: &[f64]| rows.iter().map(|&i| x[i]).collect::<Vec<f64>>();
    let yv = pick(y);
    let sv: Vec<Vec<f64>> = small.iter().map(|c| pick(c)).collect();
    let ev: Vec<Vec<f64>> = extra.iter().map(|c| pick(c)).collect();
    let full: Vec<&[f64]> = sv.iter().chain(&ev).map(|v| v.as_slice()).collect();
    let Some(r) = resid(&yv, &full) else {
        return 0.0;
    };
    let den: f64 = r.iter().map(|v| v * v).sum();
    let rho = if den > 0.0 {
        (r.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / den).clamp(0.0, 0.98)
    } else {
        0.0
    };
    let qd = |x: &[f64]| -> Vec<f64> { x.windows(2).map(|w| w[1] - rho * w[0]).collect() };
    let yq = qd(&yv);
    let sq: Vec<Vec<f64>> = sv.iter().map(|v| qd(v)).collect();
    let eq: Vec<Vec<f64>> = ev.iter().map(|v| qd(v)).collect();
    let small_q: Vec<&[f64]> = sq.iter().map(|v| v.as_slice()).collect();
    let full_q: Vec<&[f64]> = sq.iter().chain(&eq).map(|v| v.as_slice()).collect();
    let (s0, s1) = (sse(&yq, &small_q), sse(&yq, &full_q));
    if s0 > 0.0 && s1 > 0.0 {
        (s0 / s1).ln()
    } else {
        0.0
    }
}

/// Least-squares residuals of `y` on the columns (all rows finite); `None` if singular.
fn resid(y: &[f64], cols: &[&[f64]]) -> Option<Vec<f64>> {
    let p = cols.len();
    let mut a = vec![vec![0.0; p + 1]; p];
    for i in 0..y.len() {
        for r in 0..p {
            for c in 0..p {
                a[r][c] += cols[r][i] * cols[c][i];
            }
            a[r][p] += cols[r][i] * y[i];
        }
    }
    let beta = solve(a)?;
    Some(
        (0..y.len())
            .map(|i| y[i] - (0..p).map(|r| beta[r] * cols[r][i]).sum::<f64>())
            .collect(),
    )
}

/// Line statistic: ln of the largest periodogram bin over its 256-bin chunk's median,
/// above `f_min_hz`; and that bin's frequency, Hz.
pub fn line_stat(t_s: &[f64], y: &[f64], dt_s: f64, f_min_hz: f64) -> (f64, f64) {
    use rustfft::num_complex::Complex;
    let n_line = ((t_s.last().copied().unwrap_or(0.0) / dt_s).round() as usize) + 1;
    let nfft = n_line.next_power_of_two() * 2;
    let m = mean(y);
    let mut buf = vec![Complex::new(0.0, 0.0); nfft];
    for (&t, &v) in t_s.iter().zip(y) {
        let k = ((t / dt_s).round() as usize).min(nfft - 1);
        buf[k].re = v - m;
    }
    let mut planner = rustfft::FftPlanner::<f64>::new();
    planner.plan_fft_forward(nfft).process(&mut buf);
    let p: Vec<f64> = buf[..nfft / 2].iter().map(|c| c.norm_sqr()).collect();
    let k_lo = ((f_min_hz * nfft as f64 * dt_s).ceil() as usize).max(1);
    let (r, k) = chunk_peak(&p, k_lo, p.len());
    (r.max(1e-300).ln(), k as f64 / (nfft as f64 * dt_s))
}

/// Bins of the chunks whose median is a line's local noise level.
pub const LINE_CHUNK: usize = 256;

/// The periodogram bin in `k_lo..k_hi` (a `k_hi` past `p` is `p`'s end) furthest above its
/// [`LINE_CHUNK`]-bin chunk's median: (that ratio, the bin); `(0, 0)` when none has a
/// positive median. The line test and the sinusoid candidate's fit both look for a line
/// this way, so that a coloured noise's low-frequency power is not taken for one.
pub fn chunk_peak(p: &[f64], k_lo: usize, k_hi: usize) -> (f64, usize) {
    let k_hi = k_hi.min(p.len());
    let mut best = (0.0f64, 0);
    let mut k0 = 0;
    while k0 < k_hi {
        let k1 = (k0 + LINE_CHUNK).min(p.len());
        if k1 > k_lo {
            let med = median(&p[k0..k1]);
            if med > 0.0 {
                for (k, &v) in p.iter().enumerate().take(k1.min(k_hi)).skip(k0.max(k_lo)) {
                    let r = v / med;
                    if r > best.0 {
                        best = (r, k);
                    }
                }
            }
        }
        k0 = k1;
    }
    best
}

/// The tests' statistics of one series.
pub struct EvStats {
    /// Window means of the rate, deg/s.
    pub y_w: Vec<f64>,
    /// Line statistic and its frequency, Hz.
    pub line: (f64, f64),
    /// Scale-factor statistic (when the record has a reference rate).
    pub sf: Option<f64>,
}

/// Computes the statistics of one series.
pub fn stats(
    t_s: &[f64],
    y: &[f64],
    dt_s: f64,
    block_s: f64,
    t_w: &[f64],
    ref_w: Option<&[f64]>,
) -> EvStats {
    let y_w = window_means(t_s, y, WINDOW_S, t_w.len());
    let t_total = t_w.len() as f64 * WINDOW_S;
    EvStats {
        sf: ref_w.map(|r| {
            let one = vec![1.0; y_w.len()];
            let t_n: Vec<f64> = t_w.iter().map(|t| t / t_total.max(WINDOW_S)).collect();
            ar1_nested(&y_w, &[&one, &t_n], &[r])
        }),
        line: line_stat(t_s, y, dt_s, 4.0 / block_s),
        y_w,
    }
}

/// Floor of the dropouts test's null standard deviation, sample slots: with simulations
/// that never drop, one missing slot in regular time stamps gives z = 3.3 (> the threshold
/// 3): a sample missing from a clock-driven record is evidence by itself.
pub const DROPOUT_SD_FLOOR: f64 = 0.3;

/// The dropouts test: missing sample slots in the whole record against the simulations'
/// (a count: the null sd is floored at the Poisson sd `sqrt(mean)` and at
/// [`DROPOUT_SD_FLOOR`]).
pub fn dropouts_outcome(missing: f64, null: &[f64]) -> Test {
    count_outcome(
        outcome(
            Effect::Dropouts,
            "time stamps: missing sample slots (steps > 1.5 periods) in the whole record vs the simulations'",
            missing,
            null,
            format!("{missing:.0} missing slots"),
        ),
        missing,
        DROPOUT_SD_FLOOR,
    )
}

/// A count test's outcome: the null sd floored at the Poisson sd `sqrt(mean)` and at
/// `sd_floor`, then z and the verdict again.
fn count_outcome(mut t: Test, count: f64, sd_floor: f64) -> Test {
    let sd = t.null_sd.max(t.null_mean.max(0.0).sqrt()).max(sd_floor);
    t.null_sd = sd;
    t.z = (count - t.null_mean) / sd;
    t.passed = t.z > t.threshold;
    t
}

/// The spikes test counts 5-point running-median residuals beyond this many robust sigma
/// (the `spikes` candidate's 6 are about 4 standard deviations of Gaussian noise, ~10 per
/// 180 000 samples in the simulations; 10 are about 6.6, none).
pub const SPIKE_TEST_SIGMAS: f64 = 10.0;

/// Floor of the spikes test's null standard deviation, outliers: as
/// [`DROPOUT_SD_FLOOR`], one outlier against simulations that have none gives z = 3.3
/// (> the threshold 3).
pub const SPIKE_SD_FLOOR: f64 = 0.3;

/// The spikes test: outliers (5-point running-median residuals beyond
/// [`SPIKE_TEST_SIGMAS`] robust sigma) in
/// the whole record against the simulations' (a count: the null sd is floored at the
/// Poisson sd `sqrt(mean)` and at [`SPIKE_SD_FLOOR`]).
pub fn spikes_outcome(count: f64, null: &[f64]) -> Test {
    count_outcome(
        outcome(
            Effect::Spikes,
            &format!("outliers: 5-point running-median residuals beyond {SPIKE_TEST_SIGMAS} robust sigma in the whole record vs the simulations'"),
            count,
            null,
            format!("{count:.0} outliers"),
        ),
        count,
        SPIKE_SD_FLOOR,
    )
}

/// The scale-factor test also needs the reference coefficient's `|t|` (AR(1) errors) above
/// this.
pub const SF_MIN_T: f64 = 3.0;

/// The tests other than the drift tests: the real statistics against the simulations'.
///
/// `missing`: the whole record's missing sample slots (steps longer than 1.5 periods) and
/// the simulations'; `None` when the time stamps are bursty (gaps not measurable).
/// `spikes`: the whole record's outlier count and the simulations'.
pub fn run(
    real: &EvStats,
    sims: &[EvStats],
    missing: Option<(f64, &[f64])>,
    spikes: (f64, &[f64]),
) -> Vec<Test> {
    let mut out = Vec::new();
    if let Some((m, null)) = missing {
        out.push(dropouts_outcome(m, null));
    }
    out.push(spikes_outcome(spikes.0, spikes.1));
    if let Some(r) = real.sf {
        let nulls: Vec<f64> = sims.iter().filter_map(|s| s.sf).collect();
        // F = (rows - 3)(SSE ratio - 1) of one added column is the reference coefficient's
        // t squared under the AR(1) errors.
        let rows = real
            .y_w
            .iter()
            .filter(|v| v.is_finite())
            .count()
            .saturating_sub(4) as f64;
        let t_sf = (rows * (r.exp() - 1.0)).max(0.0).sqrt();
        let mut sf = outcome(
            Effect::ScaleFactor,
            "5-s means of the rate less the reference, AR(1) errors (Cochrane-Orcutt): ln(SSE[1, t] / SSE[1, t, reference]); passes when z exceeds the threshold and the reference's |t| > 3",
            r,
            &nulls,
            format!("|t| {t_sf:.1}"),
        );
        // As for the ramp: the simulations' null lacks any slow noise term the baseline
        // missed (a Gauss-Markov wander, a warm-up), which correlates by chance with a slow
        // motion; the coefficient must also be significant on its own (markov-203004,
        // warmup-206001, dropouts-208002 of the calibration set 200001 passed with |t| 1.6,
        // 2.2, 2.7 without this).
        sf.passed &= t_sf > SF_MIN_T;
        out.push(sf);
    }
    let nulls: Vec<f64> = sims.iter().map(|s| s.line.0).collect();
    out.push(line_outcome(real.line, &nulls));
    out
}

/// Gumbel scale of the line statistic in units of `1 / x`, `x = exp(null mean) ln 2` the
/// null's typical largest bin over its chunk's mean power. The largest of `M` exponential
/// bins is `ln M` plus a standard Gumbel variable (scale 1); the noisy 256-bin median widens
/// it. Measured on white-noise records of 45,000 to 360,000 samples by
/// `python3 scripts/line_stat_null.py --draws 400`: 1.13 to 1.23; the test's false alarms at
/// z > 2.5 with this value and the mean of 12 simulations are printed there.
pub const LINE_GUMBEL_SCALE: f64 = 1.2;

/// The sinusoid test: the statistic's null is a Gumbel law (the largest of many periodogram
/// bins) whose mean is the simulations' mean and whose scale is [`LINE_GUMBEL_SCALE`]
/// `/ x`; `z` is the normal score of its upper tail. The scale is measured on white noise;
/// a baseline whose spectrum is steep within a 256-bin chunk (a strong random walk at the
/// lowest frequencies) may spread the null wider. (The generic mean and standard
/// deviation of 12 simulations, floored at a tenth of the mean, put the threshold about 0.75
/// above the null mean where the 0.5 % point is about 0.4 above it.)
fn line_outcome(real: (f64, f64), nulls: &[f64]) -> Test {
    let mut t = outcome(
        Effect::Sinusoid,
        "periodogram (whole record, 2x padded): ln(largest bin / median of its 256-bin chunk) above 4 cycles per block; null Gumbel (mean: the simulations' mean)",
        real.0,
        nulls,
        format!("{:.4} Hz", real.1),
    );
    if t.nulls == 0 || !real.0.is_finite() {
        // No location: no evidence either way.
        t.z = 0.0;
        t.passed = false;
        return t;
    }
    let beta = LINE_GUMBEL_SCALE / (t.null_mean.exp() * std::f64::consts::LN_2);
    let mu = t.null_mean - EULER_GAMMA * beta;
    let p = -(-(-(real.0 - mu) / beta).exp()).exp_m1();
    t.null_sd = beta * std::f64::consts::PI / 6f64.sqrt();
    t.z = super::drift::z_of_p(p);
    t.passed = t.z > t.threshold;
    t
}

/// The Euler-Mascheroni constant (the standard Gumbel law's mean).
const EULER_GAMMA: f64 = 0.577_215_664_901_532_9;

#[cfg(test)]
mod tests {
    use super::*;

    /// The line test's z is the normal score of the Gumbel tail: at the null's mean the
    /// tail is the Gumbel law's above its mean (0.43, z 0.18); each scale step past the
    /// location divides the tail by about e.
    #[test]
    fn line_test_z_is_the_gumbel_tail() {
        let m: f64 = 3.0;
        let nulls = [m - 0.1, m, m + 0.1];
        let beta = LINE_GUMBEL_SCALE / (m.exp() * std::f64::consts::LN_2);
        let at_mean = line_outcome((m, 1.0), &nulls);
        let p_mean = 1.0 - (-(-EULER_GAMMA).exp()).exp();
        assert!((at_mean.z - super::super::drift::z_of_p(p_mean)).abs() < 1e-9);
        assert!(!at_mean.passed);
        // 6 scales above the location: p = 1 - exp(-e^-6) = 0.00248, z 2.81 > 2.5.
        let s = m - EULER_GAMMA * beta + 6.0 * beta;
        let far = line_outcome((s, 1.0), &nulls);
        let p = -(-(-6f64).exp()).exp_m1();
        assert!(
            (far.z - super::super::drift::z_of_p(p)).abs() < 1e-9,
            "{}",
            far.z
        );
        assert!(far.passed && (far.z - 2.81).abs() < 0.01, "{}", far.z);
        // No simulations: no location, no evidence.
        let none = line_outcome((s, 1.0), &[]);
        assert!(none.z == 0.0 && !none.passed);
    }
}

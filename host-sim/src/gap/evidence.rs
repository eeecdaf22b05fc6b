//! Dedicated detection tests: decisions that use what the record carries, each a statistic
//! computed the same way on the real record and on every baseline simulation (the null).
//!
//! - `temperature`: the drift against the recorded channel, beyond a ramp and a warm-up:
//!   30-s means of the rate regressed on `[1, t, exp(-t/tau)]` with and without `[temp_c,
//!   d temp_c / dt]` (rate of change from 30-s smoothed window means, central difference;
//!   `tau` the warm-up test's), AR(1) errors (Cochrane-Orcutt); statistic `ln(SSE_without /
//!   SSE_with)`. The null: the baseline simulations with the same channel (which does not
//!   drive them) **and** the real record against [`SURROGATES`] phase-randomised copies of
//!   the channel (same spectrum, cannot drive it).
//! - `rate_ramp`: 30-s means; the OLS slope's t with an AR(1) variance, `ln(1 + t^2)`; it
//!   also needs `|t| > 3` ([`RAMP_MIN_STAT`]).
//! - `sinusoid`: a periodogram test. Whole record on a zero-filled time line, 2x padded FFT;
//!   each bin's power over the median power of its 256-bin chunk (so coloured noise does not
//!   matter); statistic: ln of the largest ratio above 4 cycles per block.
//! - `warmup`: a time-domain test. 10-s window means, AR(1) errors (Cochrane-Orcutt): SSE
//!   of `c + r t` over SSE of `c + r t + A exp(-t / tau)`, tau on a 16-per-decade grid from
//!   one window to the record length; statistic ln of the largest ratio (a ramp alone gives
//!   nothing; a transient does). It passes only when its tau is at most a third of the
//!   record ([`WARMUP_TAU_MAX_SHARE`]): a slower curvature is a ramp over a wander, and a
//!   ramp record then falls to the ramp test.
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
//! The drift tests are nested (a passed temperature test first; then warm-up or ramp,
//! whichever is further past its threshold; the decision is in `mod.rs`). Each test gives
//! `z = (real - mean_null) / sd_null` (sd floored at a tenth of the null mean and at
//! [`SD_FLOOR`]); it *passes* when `z` exceeds its threshold ([`THRESHOLDS`], calibrated on
//! the calibration records of `scripts/gap_indep_gen.py`, first seeds 1, 700001, 720001,
//! and for the AR(1) warm-up and scale-factor tests, the dropouts test and the `|t|` floor
//! 200001 and 300001; never on the evaluation records; see docs/gap.md). Short Gauss-Markov correlation times have
//! no test of their own: the PSD group of the gap measure sees them, and without a user
//! model the `markov` candidate is the baseline refitted jointly with the GM term.

use super::effects::Effect;
use super::features::{mean, median};
use serde::Serialize;

/// Window length of the time-domain tests, s.
pub const WINDOW_S: f64 = 5.0;

/// z thresholds per test.
pub const THRESHOLDS: [(Effect, f64); 7] = [
    (Effect::Temperature, 2.5),
    (Effect::Dropouts, 3.0),
    (Effect::Spikes, 3.0),
    (Effect::RateRamp, 3.0),
    (Effect::ScaleFactor, 3.0),
    (Effect::Sinusoid, 2.5),
    (Effect::Warmup, 3.0),
];

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
    /// Null values (simulations, then surrogates).
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

/// Window length of the temperature test's regression, s (5-s means averaged by six).
pub const TEMP_WINDOW_S: f64 = 30.0;

/// Averages consecutive groups of `k` values (a group with a NaN is NaN).
fn aggregate(x: &[f64], k: usize) -> Vec<f64> {
    x.chunks(k)
        .filter(|c| c.len() == k)
        .map(|c| c.iter().sum::<f64>() / k as f64)
        .collect()
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

/// Temperature statistic on [`TEMP_WINDOW_S`] means (from the 5-s means): what `[T,
/// dT/dt]` add to `[1, t, exp(-t/tau)]` (`ar1_nested`, AR(1) errors), `tau_s` the series'
/// own best warm-up time constant (from [`warmup_stat`]; 0 = no exponential column): the
/// channel must explain the drift **beyond** a ramp and a warm-up transient, so a drift that
/// is merely a transient does not pass because the channel also rises at power-on.
pub fn temperature_stat(y_w: &[f64], temp_w: &[f64], dtemp_w: &[f64], tau_s: f64) -> f64 {
    let k = (TEMP_WINDOW_S / WINDOW_S).round().max(1.0) as usize;
    let (y, tw, dw) = (
        aggregate(y_w, k),
        aggregate(temp_w, k),
        aggregate(dtemp_w, k),
    );
    let n = y.len();
    let w = k as f64 * WINDOW_S;
    let tc: Vec<f64> = (0..n).map(|i| i as f64 / n as f64).collect();
    let one = vec![1.0; n];
    let ex: Vec<f64> = (0..n)
        .map(|i| (-((i as f64 + 0.5) * w) / tau_s.max(1e-9)).exp())
        .collect();
    let tv: Vec<f64> = {
        let v: Vec<f64> = tw.iter().copied().filter(|x| x.is_finite()).collect();
        let m = mean(&v);
        tw.iter().map(|x| x - m).collect()
    };
    if tau_s > 0.0 {
        ar1_nested(&y, &[&one, &tc, &ex], &[&tv, &dw])
    } else {
        ar1_nested(&y, &[&one, &tc], &[&tv, &dw])
    }
}

/// Window length of the warm-up test's regression, s (5-s means averaged by two): short
/// enough that the generator's fastest warm-up (tau 60 s) spans six windows.
pub const WARMUP_WINDOW_S: f64 = 10.0;

/// A warm-up is a transient that decays within the record: the test's best time constant
/// must be at most this share of the record. A longer one is a slow curvature of the drift
/// that a ramp (or the random walk) explains as well; the `warmup` candidate's grid stops
/// at the same point. The independent generator draws warm-up taus of 60-600 s in 1800 s
/// records (at most a third).
pub const WARMUP_TAU_MAX_SHARE: f64 = 1.0 / 3.0;

/// Warm-up statistic on [`WARMUP_WINDOW_S`] means (from the 5-s means `y_w`): the largest,
/// over tau on a 16-per-decade grid from one window to the record length, of what
/// `exp(-t/tau)` adds to `[1, t]` (`ar1_nested`: AR(1) errors by Cochrane-Orcutt, so a
/// drift that merely wanders, flicker or random walk, is discounted, and a line is removed
/// in both models, so a ramp alone gives nothing); and that best tau, s. The grid runs past
/// [`WARMUP_TAU_MAX_SHARE`] of the record so that a slow curvature (a ramp over a walk) is
/// seen as such: its best tau lands there and the test does not pass (see [`run`]).
pub fn warmup_stat(y_w: &[f64], _t_w: &[f64], t_total_s: f64) -> (f64, f64) {
    let k = (WARMUP_WINDOW_S / WINDOW_S).round().max(1.0) as usize;
    let y = aggregate(y_w, k);
    let n = y.len();
    if n < 8 {
        return (0.0, 0.0);
    }
    let w = k as f64 * WINDOW_S;
    let t_c: Vec<f64> = (0..n).map(|i| (i as f64 + 0.5) * w).collect();
    let t_n: Vec<f64> = t_c.iter().map(|t| t / t_total_s.max(w)).collect();
    let one = vec![1.0; n];
    let mut best = (0.0, 0.0);
    let mut tau = w;
    while tau <= t_total_s {
        let e: Vec<f64> = t_c.iter().map(|t| (-t / tau).exp()).collect();
        let s = ar1_nested(&y, &[&one, &t_n], &[&e]);
        if s.is_finite() && s > best.0 {
            best = (s, tau);
        }
        tau *= 10f64.powf(1.0 / 16.0);
    }
    best
}

/// The warm-up test's best tau if it is a warm-up's (at most [`WARMUP_TAU_MAX_SHARE`] of
/// the record), else 0 (no exponential column in the temperature test).
pub fn warmup_tau(tau_s: f64, t_total_s: f64) -> f64 {
    if tau_s > 0.0 && tau_s <= WARMUP_TAU_MAX_SHARE * t_total_s * 1.0001 {
        tau_s
    } else {
        0.0
    }
}

/// Window length of the ramp test, s: long enough that white noise averages out of the
/// window means, short enough to leave 60 windows in 1800 s.
pub const RAMP_WINDOW_S: f64 = 30.0;

/// Ramp statistic on `RAMP_WINDOW_S` means (built from the 5-s means `y_w`): the OLS
/// slope's t-statistic with a noise-aware variance, `|b| / se(b)`, where `se(b)` comes from
/// the residuals' AR(1) model (lag-1 autocorrelation `rho` of the residuals, clamped to
/// [0, 0.95], variance inflation `(1 + rho) / (1 - rho)`): a random walk's residuals are
/// strongly autocorrelated, so its apparent trend is discounted; a ramp over white and
/// flicker noise keeps its full t. Returned as `ln(1 + t^2)`, scale-free, compared with the
/// simulations (the null: the same baseline, random walk included).
pub fn ramp_stat(y_w: &[f64]) -> f64 {
    let k = (RAMP_WINDOW_S / WINDOW_S).round().max(1.0) as usize;
    let yw: Vec<f64> = y_w
        .chunks(k)
        .filter(|c| c.len() == k)
        .map(|c| {
            let v: Vec<f64> = c.iter().copied().filter(|x| x.is_finite()).collect();
            if v.is_empty() {
                f64::NAN
            } else {
                mean(&v)
            }
        })
        .filter(|x| x.is_finite())
        .collect();
    let n = yw.len();
    if n < 8 {
        return 0.0;
    }
    let tm = (n as f64 - 1.0) / 2.0;
    let ym = mean(&yw);
    let sxx: f64 = (0..n).map(|i| (i as f64 - tm).powi(2)).sum();
    let b = (0..n).map(|i| (i as f64 - tm) * (yw[i] - ym)).sum::<f64>() / sxx;
    let r: Vec<f64> = (0..n).map(|i| yw[i] - ym - b * (i as f64 - tm)).collect();
    let s2 = r.iter().map(|v| v * v).sum::<f64>() / (n as f64 - 2.0);
    let c1 = r.windows(2).map(|w| w[0] * w[1]).sum::<f64>()
        / r.iter().map(|v| v * v).sum::<f64>().max(1e-300);
    let rho = c1.clamp(0.0, 0.95);
    let se2 = s2 / sxx * (1.0 + rho) / (1.0 - rho);
    if se2 > 0.0 {
        (1.0 + b * b / se2).ln()
    } else {
        0.0
    }
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
    const CHUNK: usize = 256;
    let k_lo = ((f_min_hz * nfft as f64 * dt_s).ceil() as usize).max(1);
    let mut best = (0.0f64, 0.0);
    let mut k0 = 0;
    while k0 < p.len() {
        let k1 = (k0 + CHUNK).min(p.len());
        if k1 > k_lo {
            let med = median(&p[k0..k1]);
            if med > 0.0 {
                for (k, &v) in p.iter().enumerate().take(k1).skip(k0.max(k_lo)) {
                    let r = v / med;
                    if r > best.0 {
                        best = (r, k as f64 / (nfft as f64 * dt_s));
                    }
                }
            }
        }
        k0 = k1;
    }
    (best.0.max(1e-300).ln(), best.1)
}

/// The tests' statistics of one series.
pub struct EvStats {
    /// Window means of the rate, deg/s.
    pub y_w: Vec<f64>,
    /// Temperature statistic (when the record has `temp_c`).
    pub temp: Option<f64>,
    /// Warm-up statistic and its tau, s.
    pub warm: (f64, f64),
    /// Line statistic and its frequency, Hz.
    pub line: (f64, f64),
    /// Ramp statistic ([`ramp_stat`]).
    pub ramp: f64,
    /// Scale-factor statistic (when the record has a reference rate).
    pub sf: Option<f64>,
}

/// Computes the statistics of one series (`temp`: the record's window temperatures and
/// their rate of change).
pub fn stats(
    t_s: &[f64],
    y: &[f64],
    dt_s: f64,
    block_s: f64,
    t_w: &[f64],
    temp: Option<(&[f64], &[f64])>,
    ref_w: Option<&[f64]>,
) -> EvStats {
    let y_w = window_means(t_s, y, WINDOW_S, t_w.len());
    let t_total = t_w.len() as f64 * WINDOW_S;
    let warm = warmup_stat(&y_w, t_w, t_total);
    EvStats {
        sf: ref_w.map(|r| {
            let one = vec![1.0; y_w.len()];
            let t_n: Vec<f64> = t_w.iter().map(|t| t / t_total.max(WINDOW_S)).collect();
            ar1_nested(&y_w, &[&one, &t_n], &[r])
        }),
        temp: temp.map(|(tw, dw)| temperature_stat(&y_w, tw, dw, warmup_tau(warm.1, t_total))),
        warm,
        line: line_stat(t_s, y, dt_s, 4.0 / block_s),
        ramp: ramp_stat(&y_w),
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

/// The ramp test also needs `ln(1 + t^2) > ` this (`|t| > 3`).
pub const RAMP_MIN_STAT: f64 = std::f64::consts::LN_10;

/// Surrogate temperature channels in the false-alarm null.
pub const SURROGATES: usize = 8;

/// A phase-randomised copy of a window series (NaNs filled by the mean): the line through
/// the end points is removed (no wrap-around jump), the Fourier phases are drawn uniformly
/// (deterministic `seed`), the amplitudes kept, the line added back. Same spectrum and
/// slowness as the channel, but it cannot drive the rate.
pub fn phase_randomised(x: &[f64], seed: u64) -> Vec<f64> {
    use rand::{Rng, SeedableRng};
    use rustfft::num_complex::Complex;
    let n = x.len();
    if n < 4 {
        return x.to_vec();
    }
    let v: Vec<f64> = x.iter().copied().filter(|x| x.is_finite()).collect();
    let m = mean(&v);
    let xf: Vec<f64> = x
        .iter()
        .map(|&x| if x.is_finite() { x } else { m })
        .collect();
    let (a, b) = (xf[0], xf[n - 1]);
    let line = |i: usize| a + (b - a) * i as f64 / (n - 1) as f64;
    let mut buf: Vec<Complex<f64>> = (0..n).map(|i| Complex::new(xf[i] - line(i), 0.0)).collect();
    let mut planner = rustfft::FftPlanner::<f64>::new();
    planner.plan_fft_forward(n).process(&mut buf);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    for k in 1..n.div_ceil(2) {
        let ph = rng.random::<f64>() * std::f64::consts::TAU;
        let c = Complex::from_polar(buf[k].norm(), ph);
        buf[k] = c;
        buf[n - k] = c.conj();
    }
    planner.plan_fft_inverse(n).process(&mut buf);
    (0..n).map(|i| buf[i].re / n as f64 + line(i)).collect()
}

/// The tests: the real statistics against the simulations' (and, for temperature, against
/// surrogate channels on the real record).
///
/// `missing`: the whole record's missing sample slots (steps longer than 1.5 periods) and
/// the simulations'; `None` when the time stamps are bursty (gaps not measurable).
/// `spikes`: the whole record's outlier count and the simulations'.
pub fn run(
    real: &EvStats,
    sims: &[EvStats],
    temp_w: Option<&[f64]>,
    missing: Option<(f64, &[f64])>,
    spikes: (f64, &[f64]),
) -> Vec<Test> {
    let mut out = Vec::new();
    if let Some((m, null)) = missing {
        out.push(dropouts_outcome(m, null));
    }
    out.push(spikes_outcome(spikes.0, spikes.1));
    if let (Some(tw), Some(r)) = (temp_w, real.temp) {
        let mut nulls: Vec<f64> = sims.iter().filter_map(|s| s.temp).collect();
        for k in 0..SURROGATES {
            let sg = phase_randomised(tw, 0x7e3a_5c01 + k as u64);
            let dsg = rate_of_change(&sg, WINDOW_S, 6);
            let t_total = real.y_w.len() as f64 * WINDOW_S;
            nulls.push(temperature_stat(
                &real.y_w,
                &sg,
                &dsg,
                warmup_tau(real.warm.1, t_total),
            ));
        }
        out.push(outcome(
            Effect::Temperature,
            "5-s means regressed on [1, t, exp(-t/tau), temp_c, d temp_c/dt] (tau: the warm-up test's): ln(SSE without / with the temperature terms); null: simulations with the same channel + the real rate against 8 phase-randomised surrogate channels",
            r,
            &nulls,
            String::new(),
        ));
    }
    let nulls: Vec<f64> = sims.iter().map(|s| s.ramp).collect();
    let mut ramp = outcome(
        Effect::RateRamp,
        "30-s means: OLS slope t-statistic with an AR(1) variance from the residuals, ln(1 + t^2); passes when z exceeds the threshold and |t| > 3",
        real.ramp,
        &nulls,
        format!("|t| {:.1}", (real.ramp.exp() - 1.0).max(0.0).sqrt()),
    );
    // The simulations' null can be narrow (a dozen draws of a noise mix whose walk the AR(1)
    // variance discounts strongly): the slope must also be significant on its own.
    ramp.passed &= real.ramp > RAMP_MIN_STAT;
    out.push(ramp);
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
    let nulls: Vec<f64> = sims.iter().map(|s| s.warm.0).collect();
    let t_total = real.y_w.len() as f64 * WINDOW_S;
    let slow = warmup_tau(real.warm.1, t_total) == 0.0;
    let mut warm = outcome(
        Effect::Warmup,
        "10-s means, AR(1) errors (Cochrane-Orcutt): ln(SSE[1, t] / SSE[1, t, exp(-t/tau)]), best tau from one window to the record length; passes when z exceeds the threshold and tau <= a third of the record",
        real.warm.0,
        &nulls,
        format!(
            "tau {:.0} s{}",
            real.warm.1,
            if slow {
                " (> a third of the record: a slow curvature, not a warm-up)"
            } else {
                ""
            }
        ),
    );
    warm.passed &= !slow;
    out.push(warm);
    let nulls: Vec<f64> = sims.iter().map(|s| s.line.0).collect();
    out.push(outcome(
        Effect::Sinusoid,
        "periodogram (whole record, 2x padded): ln(largest bin / median of its 256-bin chunk) above 4 cycles per block",
        real.line.0,
        &nulls,
        format!("{:.4} Hz", real.line.1),
    ));
    out
}

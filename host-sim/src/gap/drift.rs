//! The drift effects (`rate_ramp`, `warmup`, `temperature`) fitted **together with the
//! baseline's noise** on the whole record, and tested by likelihood ratio.
//!
//! # Data
//! Means of the rate over `W`-s windows ([`WINDOW_S`]; longer for long records, so that at
//! most [`MAX_WINDOWS`] remain), first-differenced: the unknown constant bias drops out and
//! a rate random walk becomes stationary. Windows left empty by dropouts are filled by linear
//! interpolation between their neighbours.
//!
//! # Noise
//! White (N, deg/s/sqrt(Hz)), flicker (B, deg/s, Allan floor 0.664 B) and rate random walk
//! (K, deg/s/sqrt(s)), as the simulator defines them. The autocovariance of the differenced
//! window means at lag `k` is, exactly (continuous time):
//! - white: `N^2 / W * (2, -1, 0, ...)`;
//! - random walk: `K^2 W * (2/3, 1/6, 0, ...)`;
//! - flicker, one-sided PSD `h / f` with `h = B^2 / pi`: `h g(k)`, where
//!   `g(k) = 4 int_0^inf sin^4(x) cos(2 k x) / x^3 dx = 2 sum_j a_j m_j^2 ln m_j` over the
//!   cosine expansion `sin^4(x) cos(2kx) = sum_j a_j cos(m_j x)` ([`flicker_g`]; `g(0) = 4 ln 2`,
//!   twice the Allan variance `2 ln 2 h`).
//!
//! # Models and statistic
//! Model `c`: `d = X_c beta + e`, `e ~ N(0, Sigma(N, B, K))` with `X_c` the effect's
//! differenced window regressors (none for the null). The Gaussian likelihood is maximised
//! over `beta` (generalised least squares), the overall noise scale (in closed form) and the
//! three terms' shares (Nelder-Mead on two logits). Every model refits its own noise, so a
//! drift that the null's random walk would absorb is not lost, and the record's own slow
//! wander is in the null. The statistic is `LR_c = 2 (l_c - l_0)`.
//!
//! # p-values
//! `rate_ramp` (one regressor: `t`) and `temperature` (two: `temp_c` and its rate of change)
//! against chi-square with 1 and 2 degrees of freedom (Wilks). `warmup` (`exp(-t / tau)`,
//! `tau` on a grid) is the largest over its grid: its p-value is the chi-square(1) tail
//! times the grid's effective number of tests, measured by a parametric bootstrap of the
//! fitted null ([`BOOT_DRAWS`] draws of whitened Gaussian noise, noise fixed at the null
//! fit).
//!
//! # Which drift
//! Among the drift tests that pass, the model with the largest `l_c - p_c ln(n) / 2`
//! (Bayesian information criterion; `p_c` counts `tau` for the warm-up) is named.

use super::effects::Effect;
use super::evidence::{self, Test};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;
use statrs::distribution::{ChiSquared, ContinuousCDF, Normal};
use std::collections::BTreeMap;

/// Shortest window, s (ASSUMED: the drifts tested change over minutes; 10 s keeps the warm-up
/// grid's shortest time constant, two windows, below the 60 s a warm-up takes at least).
pub const WINDOW_S: f64 = 10.0;

/// Most windows (the likelihood's cost grows with their cube).
pub const MAX_WINDOWS: usize = 360;

/// Parametric-bootstrap draws for the warm-up grid's effective number of tests.
pub const BOOT_DRAWS: usize = 2000;

/// Warm-up time constants per decade.
pub const WARMUP_TAUS_PER_DECADE: f64 = 8.0;

/// A warm-up time constant is tested up to this share of the record (a slower curvature is
/// a ramp over a wander).
pub const WARMUP_TAU_MAX_SHARE: f64 = 0.5;

/// `g(k)` of the flicker autocovariance (module doc), exact.
pub fn flicker_g(k: usize) -> f64 {
    let k = k as f64;
    let m2l = |m: f64| {
        let m = m.abs();
        if m <= 0.0 {
            0.0
        } else {
            m * m * m.ln()
        }
    };
    let s = 0.375 * m2l(2.0 * k) - 0.25 * (m2l(2.0 * k + 2.0) + m2l(2.0 * k - 2.0))
        + 0.0625 * (m2l(2.0 * k + 4.0) + m2l(2.0 * k - 4.0));
    2.0 * s
}

/// Autocovariance of differenced `w_s`-s window means per unit term, lags `0..n`: white
/// (`N^2 = 1`), flicker (`B^2 = 1`), random walk (`K^2 = 1`).
pub fn unit_acov(n: usize, w_s: f64) -> [Vec<f64>; 3] {
    let mut white = vec![0.0; n];
    let mut rw = vec![0.0; n];
    white[0] = 2.0 / w_s;
    rw[0] = 2.0 / 3.0 * w_s;
    if n > 1 {
        white[1] = -1.0 / w_s;
        rw[1] = w_s / 6.0;
    }
    let h = 1.0 / std::f64::consts::PI;
    let flicker = (0..n).map(|k| h * flicker_g(k)).collect();
    [white, flicker, rw]
}

/// Window means of a record for the drift tests.
#[derive(Debug, Clone)]
pub struct Windows {
    /// Window length, s.
    pub w_s: f64,
    /// Window start times, s.
    pub start_s: Vec<f64>,
    /// Means of the rate, deg/s (empty windows interpolated).
    pub rate: Vec<f64>,
    /// Means of the temperature, deg C, and its rate of change, deg C/s.
    pub temp: Option<(Vec<f64>, Vec<f64>)>,
    /// Windows that were empty.
    pub filled: usize,
}

fn fill(mut v: Vec<f64>) -> (Vec<f64>, usize) {
    let n = v.len();
    let ok: Vec<usize> = (0..n).filter(|&i| v[i].is_finite()).collect();
    let missing = n - ok.len();
    if ok.is_empty() {
        return (vec![0.0; n], missing);
    }
    for i in 0..n {
        if v[i].is_finite() {
            continue;
        }
        let next = ok.iter().position(|&j| j > i);
        v[i] = match next {
            None => v[ok[ok.len() - 1]],
            Some(0) => v[ok[0]],
            Some(p) => {
                let (a, b) = (ok[p - 1], ok[p]);
                v[a] + (v[b] - v[a]) * (i - a) as f64 / (b - a) as f64
            }
        };
    }
    (v, missing)
}

impl Windows {
    /// Window means of `rate_dps` (and `temp_c`) over a record of `t_total_s`.
    pub fn new(t_s: &[f64], rate_dps: &[f64], temp_c: Option<&[f64]>, t_total_s: f64) -> Self {
        let w_s = WINDOW_S.max(t_total_s / MAX_WINDOWS as f64);
        let n_win = ((t_total_s / w_s).floor() as usize).max(1);
        let (rate, filled) = fill(evidence::window_means(t_s, rate_dps, w_s, n_win));
        let temp = temp_c.map(|tc| {
            let (tw, _) = fill(evidence::window_means(t_s, tc, w_s, n_win));
            // Rate of change over 3 windows (30 s at the shortest window).
            let dtw = evidence::rate_of_change(&tw, w_s, 3)
                .into_iter()
                .map(|v| if v.is_finite() { v } else { 0.0 })
                .collect();
            (tw, dtw)
        });
        Windows {
            w_s,
            start_s: (0..n_win).map(|k| k as f64 * w_s).collect(),
            rate,
            temp,
            filled,
        }
    }
}

fn diff(v: &[f64]) -> Vec<f64> {
    v.windows(2).map(|w| w[1] - w[0]).collect()
}

/// One model's maximum-likelihood fit.
#[derive(Debug, Clone, Serialize)]
pub struct NoiseFit {
    /// Log-likelihood (up to a constant shared by every model of the same data).
    pub loglik: f64,
    /// White noise, deg/s/sqrt(Hz).
    pub arw_dps_per_rthz: f64,
    /// Flicker, deg/s.
    pub bias_instability_dps: f64,
    /// Random walk, deg/s/sqrt(s).
    pub rrw_dps_per_s_rthz: f64,
    /// Regression coefficients (the model's regressors, in order).
    pub beta: Vec<f64>,
    /// Their standard errors (inverse Fisher information at the fit).
    pub beta_se: Vec<f64>,
    #[serde(skip)]
    u: [f64; 2],
}

/// The differenced data of one record and the unit autocovariances.
pub struct Problem {
    d: Vec<f64>,
    unit: [Vec<f64>; 3],
}

/// The Durbin-Levinson factorisation of a stationary covariance (autocovariance `r`,
/// lags `0..n`): the one-step predictors of every order and their error variances, in
/// O(n^2). Whitening with it equals the forward solve with the Cholesky factor.
struct Durbin {
    /// Row `t` (`t (t - 1) / 2` onwards): the order-`t` predictor `phi_{t,1..t}`.
    phi: Vec<f64>,
    /// Prediction error variances.
    v: Vec<f64>,
}

impl Durbin {
    fn new(r: &[f64]) -> Option<Self> {
        let n = r.len();
        let mut phi = vec![0.0; n * (n + 1) / 2];
        let mut v = vec![0.0; n];
        if n == 0 || r[0] <= 0.0 || !r[0].is_finite() {
            return None;
        }
        v[0] = r[0];
        let row = |t: usize| t * t.saturating_sub(1) / 2;
        for t in 1..n {
            let (prev, cur) = (row(t - 1), row(t));
            let acc: f64 = (1..t).map(|j| phi[prev + j - 1] * r[t - j]).sum();
            let k = (r[t] - acc) / v[t - 1];
            for j in 1..t {
                phi[cur + j - 1] = phi[prev + j - 1] - k * phi[prev + t - j - 1];
            }
            phi[cur + t - 1] = k;
            v[t] = v[t - 1] * (1.0 - k * k);
            if v[t] <= 0.0 || !v[t].is_finite() {
                return None;
            }
        }
        Some(Durbin { phi, v })
    }

    /// The standardised innovations of `x` (`L^-1 x`).
    fn whiten(&self, x: &[f64]) -> Vec<f64> {
        let n = self.v.len();
        (0..n)
            .map(|t| {
                let base = t * t.saturating_sub(1) / 2;
                let p: f64 = (1..=t).map(|j| self.phi[base + j - 1] * x[t - j]).sum();
                (x[t] - p) / self.v[t].sqrt()
            })
            .collect()
    }
}

struct Whitened {
    f: Durbin,
    logdet_half: f64,
    z: Vec<f64>,
}

impl Problem {
    /// The differenced window means of `rate` (window length `w_s`).
    pub fn new(rate: &[f64], w_s: f64) -> Self {
        let d = diff(rate);
        let unit = unit_acov(d.len(), w_s);
        Problem { d, unit }
    }

    fn shares(u: [f64; 2]) -> [f64; 3] {
        let e = [
            u[0].clamp(-30.0, 30.0).exp(),
            u[1].clamp(-30.0, 30.0).exp(),
            1.0,
        ];
        let s: f64 = e.iter().sum();
        [e[0] / s, e[1] / s, e[2] / s]
    }

    fn whiten(&self, u: [f64; 2]) -> Option<Whitened> {
        let p = Self::shares(u);
        let n = self.d.len();
        let r: Vec<f64> = (0..n)
            .map(|k| {
                (0..3)
                    .map(|j| p[j] * self.unit[j][k] / self.unit[j][0])
                    .sum()
            })
            .collect();
        let f = Durbin::new(&r)?;
        let logdet_half = 0.5 * f.v.iter().map(|v| v.ln()).sum::<f64>();
        let z = f.whiten(&self.d);
        Some(Whitened { f, logdet_half, z })
    }

    /// Profile log-likelihood at the share logits `u` with regressors `x` (differenced).
    fn eval(&self, u: [f64; 2], x: &[Vec<f64>]) -> Option<NoiseFit> {
        let n = self.d.len();
        let w = self.whiten(u)?;
        let zx: Vec<Vec<f64>> = x.iter().map(|c| w.f.whiten(c)).collect();
        let p = zx.len();
        let mut beta = vec![0.0; p];
        let mut ginv = vec![vec![0.0; p]; p];
        if p > 0 {
            let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
            let mut a: Vec<Vec<f64>> = (0..p)
                .map(|i| {
                    let mut row: Vec<f64> = (0..p).map(|j| dot(&zx[i], &zx[j])).collect();
                    row.push(dot(&zx[i], &w.z));
                    row
                })
                .collect();
            beta = evidence::solve(a.clone())?;
            for (k, g) in ginv.iter_mut().enumerate() {
                for (i, r) in a.iter_mut().enumerate() {
                    r[p] = if i == k { 1.0 } else { 0.0 };
                }
                *g = evidence::solve(a.clone())?;
            }
        }
        let q: f64 = (0..n)
            .map(|i| w.z[i] - (0..p).map(|c| zx[c][i] * beta[c]).sum::<f64>())
            .map(|e| e * e)
            .sum();
        let s2 = q / n as f64;
        if s2.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let loglik = -0.5 * (n as f64 * s2.ln() + n as f64) - w.logdet_half;
        let sh = Self::shares(u);
        let c: Vec<f64> = (0..3).map(|j| s2 * sh[j] / self.unit[j][0]).collect();
        Some(NoiseFit {
            loglik,
            arw_dps_per_rthz: c[0].sqrt(),
            bias_instability_dps: c[1].sqrt(),
            rrw_dps_per_s_rthz: c[2].sqrt(),
            beta_se: (0..p).map(|k| (s2 * ginv[k][k]).max(0.0).sqrt()).collect(),
            beta,
            u,
        })
    }

    /// Maximum likelihood with regressors `x`, from the share logits `start`.
    pub fn fit(&self, x: &[Vec<f64>], start: &[[f64; 2]]) -> Option<NoiseFit> {
        let f = |u: [f64; 2]| self.eval(u, x).map_or(f64::INFINITY, |r| -r.loglik);
        let best = start
            .iter()
            .map(|&u| (u, f(u)))
            .min_by(|a, b| a.1.total_cmp(&b.1))?
            .0;
        let u = nelder_mead(&f, best, 2.0, 200);
        self.eval(u, x)
    }

    /// The null fit: a 5 x 5 grid of starting shares, then Nelder-Mead.
    pub fn fit_null(&self) -> Option<NoiseFit> {
        self.fit(&[], &share_grid().collect::<Vec<_>>())
    }

    /// Whitened regressors and data at the share logits `u` (the null's, for the
    /// bootstrap).
    fn whitened(&self, u: [f64; 2], x: &[Vec<f64>]) -> Option<(Vec<Vec<f64>>, Vec<f64>)> {
        let w = self.whiten(u)?;
        Some((x.iter().map(|c| w.f.whiten(c)).collect(), w.z))
    }
}

/// Starting share logits on a 5 x 5 grid (shares from about e^-8 to e^8 of the third).
fn share_grid() -> impl Iterator<Item = [f64; 2]> {
    const G: [f64; 5] = [-8.0, -3.0, 0.0, 3.0, 8.0];
    G.iter().flat_map(|&a| G.iter().map(move |&b| [a, b]))
}

/// Nelder-Mead minimisation in two dimensions.
fn nelder_mead(f: &dyn Fn([f64; 2]) -> f64, x0: [f64; 2], step: f64, iters: usize) -> [f64; 2] {
    let mut s = [x0, [x0[0] + step, x0[1]], [x0[0], x0[1] + step]];
    let mut v = [f(s[0]), f(s[1]), f(s[2])];
    for _ in 0..iters {
        let mut idx = [0, 1, 2];
        idx.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
        s = [s[idx[0]], s[idx[1]], s[idx[2]]];
        v = [v[idx[0]], v[idx[1]], v[idx[2]]];
        if (v[2] - v[0]).abs() < 1e-7 * (1.0 + v[0].abs()) {
            break;
        }
        let c = [(s[0][0] + s[1][0]) / 2.0, (s[0][1] + s[1][1]) / 2.0];
        let at = |t: f64| [c[0] + t * (s[2][0] - c[0]), c[1] + t * (s[2][1] - c[1])];
        let xr = at(-1.0);
        let fr = f(xr);
        if fr < v[0] {
            let xe = at(-2.0);
            let fe = f(xe);
            if fe < fr {
                s[2] = xe;
                v[2] = fe;
            } else {
                s[2] = xr;
                v[2] = fr;
            }
        } else if fr < v[1] {
            s[2] = xr;
            v[2] = fr;
        } else {
            let xc = if fr < v[2] { at(-0.5) } else { at(0.5) };
            let fc = f(xc);
            if fc < v[2].min(fr) {
                s[2] = xc;
                v[2] = fc;
            } else {
                for k in 1..3 {
                    s[k] = [(s[0][0] + s[k][0]) / 2.0, (s[0][1] + s[k][1]) / 2.0];
                    v[k] = f(s[k]);
                }
            }
        }
    }
    let k = (0..3).min_by(|&a, &b| v[a].total_cmp(&v[b])).unwrap_or(0);
    s[k]
}

/// Named parameters, in the simulator's units.
pub type Params = BTreeMap<String, f64>;

/// 95 % intervals of named parameters.
pub type Intervals = BTreeMap<String, [f64; 2]>;

/// One drift model's result.
#[derive(Debug, Clone, Serialize)]
pub struct DriftModel {
    /// The effect.
    pub effect: Effect,
    /// `2 (l_c - l_0)`.
    pub lr: f64,
    /// Its p-value.
    pub p_value: f64,
    /// Free parameters beyond the null (the warm-up's tau counted).
    pub params: usize,
    /// `l_c - params ln(n) / 2`.
    pub bic_score: f64,
    /// The fit.
    pub fit: NoiseFit,
    /// The warm-up's time constant, s.
    pub tau_s: Option<f64>,
    /// The warm-up's 95 % profile-likelihood intervals (`warmup_profile`, projections of the
    /// joint region): amplitude (deg/s) and time constant (s).
    pub warmup_ci95: Option<WarmupIntervals>,
    /// The ramp's and the temperature links' 95 % profile-likelihood intervals, one per
    /// coefficient in the fit's order (`coef_profile`: the noise re-fitted at every point;
    /// the two links' are projections of their joint region).
    pub coef_ci95: Option<Vec<[f64; 2]>>,
}

/// 95 % profile-likelihood intervals of the warm-up.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct WarmupIntervals {
    /// Amplitude, deg/s.
    pub amplitude_dps: [f64; 2],
    /// Time constant, s: the grid cells (33 % wide) whose point passes.
    pub tau_s: [f64; 2],
}

/// Half the 95 % quantiles of chi-square(1) and chi-square(2): the log-likelihood drop
/// that bounds the joint 95 % likelihood-ratio region of an effect's 1 or 2 parameters.
/// Every stated interval is that region's projection on one parameter, so all the
/// effect's parameters lie inside their intervals together with at least 95 % probability
/// (asymptotically); with one parameter it is the usual profile interval.
const PROFILE_DROP_95: [f64; 2] = [1.920_729, 2.995_732];

/// The drop for an effect of `k` parameters (1 or 2; more are held at 2's).
pub(super) fn profile_drop_95(k: usize) -> f64 {
    PROFILE_DROP_95[k.clamp(1, 2) - 1]
}

/// The warm-up's 95 % profile-likelihood intervals. The amplitude's standard error at the
/// best tau ignores how uncertain tau is (amplitude and tau trade off), so the interval is
/// taken over every tau of the grid instead: at the fitted noise shares `u`, each tau's
/// regression gives the concentrated log-likelihood of any amplitude `A` in closed form,
/// `L_tau(A) = -n/2 ln(q(A)/n) + const` with `q(A) = q_min + (A - beta)^2 / ginv`; the
/// interval is the hull of the amplitudes with `L_tau(A) >= L_best - 3.00` over the grid,
/// and the tau interval the hull of the grid cells whose point has `L_tau(beta) >= L_best -
/// 3.00`: the projections of the joint 95 % region of (A, tau) (`PROFILE_DROP_95`). The
/// noise shares are held at the fit's (not re-optimised per tau).
fn warmup_profile(
    prob: &Problem,
    u: [f64; 2],
    taus: &[f64],
    xs: &[Vec<f64>],
) -> Option<WarmupIntervals> {
    let n = prob.d.len() as f64;
    let fits: Vec<(f64, NoiseFit)> = taus
        .iter()
        .zip(xs)
        .filter_map(|(&t, x)| prob.eval(u, std::slice::from_ref(x)).map(|f| (t, f)))
        .collect();
    let best = fits
        .iter()
        .map(|(_, f)| f.loglik)
        .fold(f64::NEG_INFINITY, f64::max);
    let (mut a, mut t) = (
        [f64::INFINITY, f64::NEG_INFINITY],
        [f64::INFINITY, f64::NEG_INFINITY],
    );
    for (tau, f) in &fits {
        let r = 2.0 * (f.loglik - best + profile_drop_95(2)) / n;
        let (Some(&beta), Some(&se)) = (f.beta.first(), f.beta_se.first()) else {
            continue;
        };
        if r < 0.0 || !se.is_finite() {
            continue;
        }
        // q_min = n s2 and ginv = se^2 / s2: (A - beta)^2 <= n (e^r - 1) se^2.
        let half = se * (n * r.exp_m1()).sqrt();
        a = [a[0].min(beta - half), a[1].max(beta + half)];
        t = [t[0].min(*tau), t[1].max(*tau)];
    }
    // Each grid point stands for its cell, half a grid step either side.
    let half_step = 10f64.powf(0.5 / WARMUP_TAUS_PER_DECADE);
    (a[0] <= a[1]).then_some(WarmupIntervals {
        amplitude_dps: a,
        tau_s: [t[0] / half_step, t[1] * half_step],
    })
}

/// Doublings of the step outward from the Wald half-width before a side of a profile
/// interval is called unbounded, and bisections once it is bracketed.
const PROFILE_DOUBLINGS: usize = 10;
const PROFILE_BISECTIONS: usize = 10;

/// The 95 % profile-likelihood interval of coefficient `k` of the model with regressors
/// `x` fitted as `f`: the coefficient held at `b`, the other coefficients, the noise scale
/// and the three noise shares re-fitted (from the fit's shares), and the interval the `b`
/// whose log-likelihood is within `profile_drop_95(x.len())` of the fit's (1.92 for one
/// coefficient; 3.00 for two, the projection of their joint region). The Wald interval
/// (`1.96` standard errors at the fitted noise) ignores how a drift and the record's own
/// slow noise trade off; re-fitting the noise at each `b` lets the random walk and flicker
/// take what they can of a different drift, which widens the interval where they can. Each
/// side: doubling steps from the Wald half-width until the drop passes that, then
/// bisection; the outer end of the last bracket is kept. A side never bracketed (the
/// likelihood flat over `2^10` Wald half-widths) is infinite. `None` without a finite,
/// positive standard error.
fn coef_profile(prob: &Problem, x: &[Vec<f64>], k: usize, f: &NoiseFit) -> Option<[f64; 2]> {
    let beta = *f.beta.get(k)?;
    let se = *f.beta_se.get(k)?;
    let xk = x.get(k)?;
    if !(se.is_finite() && se > 0.0) {
        return None;
    }
    let rest: Vec<Vec<f64>> = x
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != k)
        .map(|(_, c)| c.clone())
        .collect();
    let target = f.loglik - profile_drop_95(x.len());
    // The fit's shares and the null's grid: a share the fit drove to nothing (a flat
    // likelihood in its logit) is tried again at every point.
    let starts: Vec<[f64; 2]> = std::iter::once(f.u).chain(share_grid()).collect();
    // One problem for every point: its data are the record less `b` times the regressor.
    let mut held = Problem {
        d: prob.d.clone(),
        unit: prob.unit.clone(),
    };
    let mut passes = |b: f64| -> bool {
        for ((h, d), x) in held.d.iter_mut().zip(&prob.d).zip(xk) {
            *h = d - b * x;
        }
        held.fit(&rest, &starts).is_some_and(|g| g.loglik >= target)
    };
    let mut out = [beta, beta];
    for (end, sign) in out.iter_mut().zip([-1.0, 1.0]) {
        let (mut inside, mut step) = (0.0, 1.96 * se);
        let mut outside = None;
        for _ in 0..PROFILE_DOUBLINGS {
            if passes(beta + sign * step) {
                inside = step;
                step *= 2.0;
            } else {
                outside = Some(step);
                break;
            }
        }
        *end = match outside {
            Some(mut out_step) => {
                for _ in 0..PROFILE_BISECTIONS {
                    let mid = 0.5 * (inside + out_step);
                    if passes(beta + sign * mid) {
                        inside = mid;
                    } else {
                        out_step = mid;
                    }
                }
                beta + sign * out_step
            }
            None => sign * f64::INFINITY,
        };
    }
    Some(out)
}

/// The drift tests of one record.
#[derive(Debug, Clone, Serialize)]
pub struct DriftTests {
    /// Window length, s.
    pub window_s: f64,
    /// Differenced windows.
    pub n: usize,
    /// Windows filled by interpolation.
    pub filled: usize,
    /// The null (baseline noise only).
    pub null: NoiseFit,
    /// Each drift model.
    pub models: Vec<DriftModel>,
    /// The warm-up grid's effective number of tests (bootstrap).
    pub warmup_effective_tests: f64,
}

fn chi2_sf(x: f64, k: f64) -> f64 {
    ChiSquared::new(k).map_or(1.0, |c| c.sf(x.max(0.0)))
}

/// One-sided normal score of a p-value (p clamped to [1e-300, 1 - 1e-16]: finite scores;
/// 0 for a NaN p).
pub fn z_of_p(p: f64) -> f64 {
    if p.is_nan() {
        return 0.0;
    }
    let p = p.clamp(1e-300, 1.0 - 1e-16);
    -Normal::standard().inverse_cdf(p)
}

impl DriftTests {
    /// Runs the three drift tests on `w` (deterministic: the bootstrap uses `seed`).
    pub fn run(w: &Windows, seed: u64) -> Option<Self> {
        if w.rate.len() < 12 {
            return None;
        }
        let prob = Problem::new(&w.rate, w.w_s);
        let n = prob.d.len();
        let null = prob.fit_null()?;
        let start = [null.u];
        let ln_n = (n as f64).ln();
        let mut models = Vec::new();
        let t_total = w.start_s.len() as f64 * w.w_s;
        // `p_of`: the p-value of the model's likelihood ratio.
        let model =
            |effect, k: usize, tau: Option<f64>, fit: NoiseFit, p_of: &dyn Fn(f64) -> f64| {
                let lr = (2.0 * (fit.loglik - null.loglik)).max(0.0);
                DriftModel {
                    effect,
                    lr,
                    p_value: p_of(lr),
                    params: k,
                    bic_score: fit.loglik - k as f64 * ln_n / 2.0,
                    fit,
                    tau_s: tau,
                    warmup_ci95: None,
                    coef_ci95: None,
                }
            };
        // Ramp: the differenced window means of t are W each.
        let x_ramp = vec![vec![w.w_s; n]];
        if let Some(f) = prob.fit(&x_ramp, &start) {
            let ci = coef_profile(&prob, &x_ramp, 0, &f).map(|c| vec![c]);
            let mut m = model(Effect::RateRamp, 1, None, f, &|lr| chi2_sf(lr, 1.0));
            m.coef_ci95 = ci;
            models.push(m);
        }
        // Temperature.
        if let Some((tw, dtw)) = &w.temp {
            let x = vec![diff(tw), diff(dtw)];
            let usable = x.iter().all(|c| c.iter().any(|v| v.abs() > 0.0));
            if usable {
                if let Some(f) = prob.fit(&x, &start) {
                    let ci: Option<Vec<[f64; 2]>> =
                        (0..2).map(|k| coef_profile(&prob, &x, k, &f)).collect();
                    let mut m = model(Effect::Temperature, 2, None, f, &|lr| chi2_sf(lr, 2.0));
                    m.coef_ci95 = ci;
                    models.push(m);
                }
            }
        }
        // Warm-up: the grid at the null's noise, the best few refitted.
        let tau_lo = 2.0 * w.w_s;
        let tau_hi = WARMUP_TAU_MAX_SHARE * t_total;
        let mut taus = Vec::new();
        let mut tau = tau_lo;
        while tau <= tau_hi {
            taus.push(tau);
            tau *= 10f64.powf(1.0 / WARMUP_TAUS_PER_DECADE);
        }
        let regress = |tau: f64| -> Vec<f64> {
            let m: Vec<f64> = w
                .start_s
                .iter()
                .map(|&a| tau / w.w_s * ((-a / tau).exp() - (-(a + w.w_s) / tau).exp()))
                .collect();
            diff(&m)
        };
        let xs: Vec<Vec<f64>> = taus.iter().map(|&t| regress(t)).collect();
        let mut eff = 1.0;
        if let Some((zx, zn)) = prob.whitened(null.u, &xs) {
            let s2 = zn.iter().map(|v| v * v).sum::<f64>() / n as f64;
            let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
            let norms: Vec<f64> = zx.iter().map(|c| dot(c, c)).collect();
            let score = |z: &[f64], s2: f64| -> Vec<f64> {
                zx.iter()
                    .zip(&norms)
                    .map(|(c, &nn)| {
                        if nn > 0.0 {
                            dot(c, z).powi(2) / nn / s2
                        } else {
                            0.0
                        }
                    })
                    .collect()
            };
            let real = score(&zn, s2);
            let mut order: Vec<usize> = (0..taus.len()).collect();
            order.sort_by(|&a, &b| real[b].total_cmp(&real[a]));
            // Effective tests: P(max over the grid > c) / P(chi2_1 > c) at the bootstrap's
            // 95th percentile of the maximum.
            let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
            let mut maxes: Vec<f64> = (0..BOOT_DRAWS)
                .map(|_| {
                    let z: Vec<f64> = (0..n)
                        .map(|_| -> f64 { StandardNormal.sample(&mut rng) })
                        .collect();
                    score(&z, 1.0).into_iter().fold(0.0, f64::max)
                })
                .collect();
            maxes.sort_by(|a, b| a.total_cmp(b));
            let c95 = maxes[(0.95 * BOOT_DRAWS as f64) as usize];
            eff = (0.05 / chi2_sf(c95, 1.0)).max(1.0);
            let mut best: Option<(f64, NoiseFit)> = None;
            for &i in order.iter().take(3) {
                if let Some(f) = prob.fit(std::slice::from_ref(&xs[i]), &start) {
                    if best.as_ref().is_none_or(|(_, b)| f.loglik > b.loglik) {
                        best = Some((taus[i], f));
                    }
                }
            }
            if let Some((tau, f)) = best {
                let ci = warmup_profile(&prob, f.u, &taus, &xs);
                let mut m = model(Effect::Warmup, 2, Some(tau), f, &|lr| {
                    (eff * chi2_sf(lr, 1.0)).min(1.0)
                });
                m.warmup_ci95 = ci;
                models.push(m);
            }
        }
        Some(DriftTests {
            window_s: w.w_s,
            n,
            filled: w.filled,
            null,
            models,
            warmup_effective_tests: eff,
        })
    }

    /// The tests as [`Test`] outcomes (`z`: the p-value's one-sided normal score).
    pub fn outcomes(&self) -> Vec<Test> {
        self.models
            .iter()
            .map(|m| {
                let z = z_of_p(m.p_value);
                let threshold = evidence::threshold(m.effect);
                let (what, detail) = match m.effect {
                    Effect::RateRamp => (
                        "whole record, differenced window means, noise (N, B, K) refitted: likelihood ratio of a slope, chi-square(1)".to_string(),
                        format!("slope {:.4} +- {:.4} deg/h/h (1 sigma)", m.fit.beta[0] * 3600.0 * 3600.0, m.fit.beta_se[0] * 3600.0 * 3600.0),
                    ),
                    Effect::Temperature => (
                        "whole record, differenced window means, noise (N, B, K) refitted: likelihood ratio of [temp_c, d temp_c/dt], chi-square(2)".to_string(),
                        format!(
                            "{:.4} +- {:.4} deg/h/C, {:.4} +- {:.4} deg/h/(C/s)",
                            m.fit.beta[0] * 3600.0,
                            m.fit.beta_se[0] * 3600.0,
                            m.fit.beta[1] * 3600.0,
                            m.fit.beta_se[1] * 3600.0
                        ),
                    ),
                    _ => (
                        format!("whole record, differenced window means, noise (N, B, K) refitted: largest likelihood ratio of exp(-t/tau) over tau, chi-square(1) tail x {:.2} effective tests (parametric bootstrap)", self.warmup_effective_tests),
                        format!("tau {:.0} s, amplitude {:.3} +- {:.3} deg/h", m.tau_s.unwrap_or(0.0), m.fit.beta[0] * 3600.0, m.fit.beta_se[0] * 3600.0),
                    ),
                };
                Test {
                    effect: m.effect,
                    test: what,
                    statistic: m.lr,
                    null_mean: m.params.min(2) as f64,
                    null_sd: (2.0 * m.params.min(2) as f64).sqrt(),
                    null_max: f64::NAN,
                    nulls: 0,
                    z,
                    threshold,
                    passed: z > threshold,
                    detail,
                }
            })
            .collect()
    }

    /// The drift effect to name among the passed tests: the largest BIC score.
    pub fn pick(&self, tests: &[Test]) -> Option<Effect> {
        self.models
            .iter()
            .filter(|m| tests.iter().any(|t| t.effect == m.effect && t.passed))
            .max_by(|a, b| a.bic_score.total_cmp(&b.bic_score))
            .map(|m| m.effect)
    }

    /// The named drift effect's parameters (the simulator's units) and 95 % intervals.
    pub fn params(&self, e: Effect) -> Option<(Params, Intervals)> {
        let m = self.models.iter().find(|m| m.effect == e)?;
        let mut p = BTreeMap::new();
        let mut ci = BTreeMap::new();
        // The profile interval where there is one, else the Wald interval (of the joint
        // region's projection).
        let mut put = |k: &str, i: usize| {
            let (v, se) = (m.fit.beta[i], m.fit.beta_se[i]);
            p.insert(k.to_string(), v);
            let profile = m.coef_ci95.as_ref().and_then(|c| c.get(i)).copied();
            let half = (2.0 * profile_drop_95(m.params)).sqrt() * se;
            ci.insert(k.to_string(), profile.unwrap_or([v - half, v + half]));
        };
        match e {
            Effect::RateRamp => put("rate_ramp_dps_per_s", 0),
            Effect::Temperature => {
                put("bias_dps_per_c", 0);
                put("bias_dps_per_c_per_s", 1);
            }
            Effect::Warmup => {
                put("warmup_dps", 0);
                p.insert("warmup_tau_s".into(), m.tau_s.unwrap_or(0.0));
                if let Some(w) = m.warmup_ci95 {
                    ci.insert("warmup_dps".into(), w.amplitude_dps);
                    ci.insert("warmup_tau_s".into(), w.tau_s);
                }
            }
            _ => return None,
        }
        Some((p, ci))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// White noise plus a warm-up `A exp(-t / tau)`: the 95 % profile intervals hold the
    /// true amplitude and time constant on at least 7 of 8 records, and the amplitude's is
    /// never narrower than the Wald interval at the best tau (which ignores tau's
    /// uncertainty).
    #[test]
    fn warmup_profile_intervals_cover_the_truth() {
        let (hz, dur_s, sigma) = (10.0, 1800.0, 0.02);
        let (a_dps, tau_s) = (8.0 / 3600.0, 150.0);
        let mut covered = 0;
        for seed in 0..8u64 {
            let mut rng = rand_pcg::Pcg64::seed_from_u64(1000 + seed);
            let n = (dur_s * hz) as usize;
            let t: Vec<f64> = (0..n).map(|k| k as f64 / hz).collect();
            let r: Vec<f64> = t
                .iter()
                .map(|&x| {
                    let e: f64 = StandardNormal.sample(&mut rng);
                    a_dps * (-x / tau_s).exp() + sigma * e
                })
                .collect();
            let w = Windows::new(&t, &r, None, dur_s);
            let d = DriftTests::run(&w, seed).expect("tests");
            let (p, ci) = d.params(Effect::Warmup).expect("warm-up fitted");
            let m = d
                .models
                .iter()
                .find(|m| m.effect == Effect::Warmup)
                .expect("model");
            let wald = 1.96 * m.fit.beta_se[0];
            let amp = ci["warmup_dps"];
            let taus = ci["warmup_tau_s"];
            assert!(
                amp[1] - amp[0] >= 2.0 * wald * (1.0 - 1e-9),
                "{amp:?} vs +-{wald}"
            );
            assert!(amp[0] <= p["warmup_dps"] && p["warmup_dps"] <= amp[1]);
            if (amp[0]..=amp[1]).contains(&a_dps) && (taus[0]..=taus[1]).contains(&tau_s) {
                covered += 1;
            }
        }
        assert!(covered >= 7, "covered {covered} of 8");
    }

    /// White noise and a rate random walk plus a ramp: the ramp's 95 % profile interval
    /// (noise re-fitted at every point) is never narrower than the Wald interval, holds the
    /// fit, and holds the true ramp on at least 7 of 8 records (measured 8; the Wald
    /// interval 6: the fit drives the random walk to nothing on 6 of the 8).
    #[test]
    fn ramp_profile_intervals_cover_the_truth() {
        let (hz, dur_s, sigma, k_rw) = (5.0, 900.0, 0.02, 3e-5);
        let ramp = 20.0 / 3600.0 / 3600.0; // 20 deg/h per h
        let mut covered = 0;
        for seed in 0..8u64 {
            let mut rng = rand_pcg::Pcg64::seed_from_u64(2000 + seed);
            let n = (dur_s * hz) as usize;
            let t: Vec<f64> = (0..n).map(|k| k as f64 / hz).collect();
            let mut walk = 0.0;
            let r: Vec<f64> = t
                .iter()
                .map(|&x| {
                    let (e, w): (f64, f64) = (
                        StandardNormal.sample(&mut rng),
                        StandardNormal.sample(&mut rng),
                    );
                    walk += k_rw * w / hz.sqrt();
                    ramp * x + walk + sigma * e
                })
                .collect();
            let w = Windows::new(&t, &r, None, dur_s);
            let d = DriftTests::run(&w, seed).expect("tests");
            let (p, ci) = d.params(Effect::RateRamp).expect("ramp fitted");
            let m = d
                .models
                .iter()
                .find(|m| m.effect == Effect::RateRamp)
                .expect("model");
            let wald = 1.96 * m.fit.beta_se[0];
            let c = ci["rate_ramp_dps_per_s"];
            let v = p["rate_ramp_dps_per_s"];
            assert!(c[0] <= v - wald * (1.0 - 1e-9) && v + wald * (1.0 - 1e-9) <= c[1]);
            if (c[0]..=c[1]).contains(&ramp) {
                covered += 1;
            }
        }
        assert!(covered >= 7, "covered {covered} of 8");
    }

    /// `g(k)` against numerical integration of `4 sin^4(x) cos(2kx) / x^3`.
    #[test]
    fn flicker_g_matches_the_integral() {
        assert!((flicker_g(0) - 4.0 * std::f64::consts::LN_2).abs() < 1e-12);
        for k in 0..6 {
            let f = |x: f64| {
                if x < 1e-9 {
                    0.0
                } else {
                    4.0 * x.sin().powi(4) * (2.0 * k as f64 * x).cos() / x.powi(3)
                }
            };
            // Simpson on [0, 400] with a fine step, plus the tail's average (oscillating
            // cosine products average out; sin^4 averages 3/8 when k = 0).
            let (a, b, m) = (0.0, 400.0, 800_000);
            let h = (b - a) / m as f64;
            let mut s = f(a) + f(b);
            for i in 1..m {
                s += f(a + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
            }
            let mut num = s * h / 3.0;
            if k == 0 {
                num += 4.0 * 0.375 / (2.0 * b * b);
            }
            assert!(
                (num - flicker_g(k)).abs() < 1e-4,
                "k {k}: numeric {num}, closed form {}",
                flicker_g(k)
            );
        }
    }
}

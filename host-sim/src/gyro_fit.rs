//! Fits a [`GyroModel`] to a family's static calibration runs: the family values and their
//! unit-to-unit spread.
//!
//! 1. White noise and quantum: the runs' measurements ([`crate::motion::calibration`]),
//!    the median density.
//! 2. The deterministic part on 10-s means, pooled over the runs: per run a level `b` and a
//!    warm-up amplitude `a` (times `e^(-t/tau_w)`), shared by every run the temperature link
//!    `c (T - T0)` and the temperature-rate link `c' dT/dt` (the family's), by least squares
//!    for each `tau_w` of a log grid 30..3000 s; `tau_w` is the one with the least residual.
//!    `dT/dt` is the drift filter's own causal estimate (first-order average of the slope,
//!    time constant [`fog_core::drift_filter::DriftFilterConfig::temp_rate_tau_s`]).
//!    `T0` = 25 C (ASSUMED reference). Without a temperature column the links are left out
//!    (mean 0, spread 0).
//! 3. Family mean and spread: of `b` and `a` the mean and standard deviation over the runs
//!    (each run a unit's power-on); of `c` and `c'` the shared value and the scatter of each
//!    run's own fit less what the fit's own error explains (white residuals assumed, so an
//!    upper bound where they are correlated; `fog-lab drift_filter_eval` scales it on tune
//!    vehicles), capped where the link alone would reach a third of the largest drift the
//!    runs showed at their largest temperature offset (rate).
//! 4. The stochastic part: the runs' Allan variance after their deterministic part, averaged
//!    over the runs, fitted (relative least squares, every coefficient >= 0) by white noise,
//!    rate random walk and Gauss-Markov terms at 30, 300 and 3000 s (a flicker floor is a
//!    sum of Gauss-Markov terms one per decade; ASSUMED correlation times). Terms fitted at
//!    zero are absent.
//! 5. Drift bound: 1.5x the largest |10-s mean| of the runs (as the gyro file's learned
//!    bound), at least the file's.

use crate::allan;
use crate::identify::series::Series;
use crate::motion::calibration::Calibration;
use anyhow::{bail, Result};
use fog_core::gyro_model::{GyroModel, MarkovTerm, Spread, MAX_MARKOV};
use serde::Serialize;

/// Temperature the links are taken from, deg C (ASSUMED).
pub const TEMP_REF_C: f64 = 25.0;
/// Length of the means the deterministic part is fitted on, s.
const BIN_S: f64 = 10.0;
/// Correlation times of the Gauss-Markov terms tried, s (ASSUMED: one per decade).
const MARKOV_TAUS_S: [f64; MAX_MARKOV] = [30.0, 300.0, 3000.0];
/// A unit's warm-up time constant is taken to lie within this factor of the family's best
/// one, log-uniform (ASSUMED: units differ in their warm-up's time constant; one fitted
/// time constant extrapolated through a long drive was the largest error of the filter on
/// the generator's families, docs/drift-filter.md).
pub const WARMUP_TAU_RATIO: f64 = 3.0;

/// Time constant of the temperature-rate estimate, s (the drift filter's default).
const TEMP_RATE_TAU_S: f64 = 60.0;

/// One run's deterministic coefficients.
#[derive(Debug, Clone, Serialize)]
pub struct RunFit {
    /// The record.
    pub name: String,
    /// Level, deg/h.
    pub level_dph: f64,
    /// Warm-up amplitude, deg/h.
    pub warmup_dph: f64,
    /// Temperature link, deg/h per deg C.
    pub temp_dph_per_c: f64,
    /// Temperature-rate link, deg/h per deg C/min.
    pub temp_rate_dph_per_c_per_min: f64,
}

/// What the fit found, for the report and the JSON.
#[derive(Debug, Clone, Serialize)]
pub struct GyroFitReport {
    /// Warm-up time constant chosen, s.
    pub warmup_tau_s: f64,
    /// Per run.
    pub runs: Vec<RunFit>,
    /// The averaged Allan deviation after the deterministic part: (tau s, deg/h).
    pub adev_dph: Vec<(f64, f64)>,
    /// The fitted terms' Allan deviation at the same taus, deg/h.
    pub fit_adev_dph: Vec<(f64, f64)>,
    /// Whether the runs had a temperature column.
    pub temperature: bool,
}

#[derive(Clone)]
struct Bins {
    t_s: Vec<f64>,
    y: Vec<f64>,
    temp_off: Vec<f64>,
    temp_rate: Vec<f64>,
}

fn bins(s: &Series) -> Bins {
    let dt = s.sample_period_s();
    let per = ((BIN_S / dt).round() as usize).max(1);
    let mut out = Bins {
        t_s: Vec::new(),
        y: Vec::new(),
        temp_off: Vec::new(),
        temp_rate: Vec::new(),
    };
    let mut rate = 0.0;
    let mut prev: Option<f64> = None;
    for (i, chunk) in s.rate_dps.chunks(per).enumerate() {
        if chunk.len() < per / 2 {
            break;
        }
        let start = i * per;
        let n = chunk.len() as f64;
        let t = s.t_s.get(start).copied().unwrap_or(0.0) + 0.5 * n * dt;
        let y = chunk.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
        let temp = s.temp_c.as_ref().map(|tc| {
            tc[start..start + chunk.len()]
                .iter()
                .map(|&v| f64::from(v))
                .sum::<f64>()
                / n
        });
        let temp = temp.map_or(0.0, |t| t - TEMP_REF_C);
        if let Some(p) = prev {
            let slope = (temp - p) / (n * dt);
            let a = (n * dt / TEMP_RATE_TAU_S).min(1.0);
            rate += a * (slope - rate);
        }
        prev = Some(temp);
        out.t_s.push(t);
        out.y.push(y);
        out.temp_off.push(temp);
        out.temp_rate.push(rate);
    }
    out
}

/// The normal equations `A x = b` of a least-squares fit, accumulated an equation at a time.
struct NormalEquations {
    a: Vec<Vec<f64>>,
    b: Vec<f64>,
}

impl NormalEquations {
    /// `k` unknowns, no equation yet.
    fn new(k: usize) -> Self {
        Self {
            a: vec![vec![0.0; k]; k],
            b: vec![0.0; k],
        }
    }

    /// Dense `rows` with their targets `y`.
    fn of_rows<const K: usize>(rows: &[[f64; K]], y: &[f64]) -> Self {
        let mut ne = Self::new(K);
        for (r, &v) in rows.iter().zip(y) {
            let entries: Vec<(usize, f64)> = r.iter().copied().enumerate().collect();
            ne.add(&entries, v, 1.0);
        }
        ne
    }

    /// Adds the equation `sum_i v_i x_i / scale = y` given by its `entries` `(i, v_i)` (the
    /// others 0): `scale` 1 for a plain row; the measured value, with `y` 1, for a relative
    /// one.
    fn add(&mut self, entries: &[(usize, f64)], y: f64, scale: f64) {
        for &(i, vi) in entries {
            self.b[i] += vi * y / scale;
            for &(j, vj) in entries {
                self.a[i][j] += vi * vj / (scale * scale);
            }
        }
    }

    /// The solution ([`solve_dyn`]).
    fn solve(&self) -> Option<Vec<f64>> {
        self.solve_for(self.b.clone())
    }

    /// The solution with a small ridge on the diagonal (collinear columns stay finite).
    fn solve_ridged(&self) -> Option<Vec<f64>> {
        let mut a = self.a.clone();
        for (i, row) in a.iter_mut().enumerate() {
            row[i] += 1e-9 * row[i].abs() + 1e-15;
        }
        solve_dyn(a, self.b.clone())
    }

    /// `A x = rhs` for another right-hand side (a unit one: a column of `A^-1`).
    fn solve_for(&self, rhs: Vec<f64>) -> Option<Vec<f64>> {
        solve_dyn(self.a.clone(), rhs)
    }
}

/// Least squares with a small ridge (collinear columns stay finite); `rows` of `K` values.
fn least_squares<const K: usize>(rows: &[[f64; K]], y: &[f64]) -> Option<[f64; K]> {
    NormalEquations::of_rows(rows, y)
        .solve_ridged()?
        .try_into()
        .ok()
}

/// Sampling variances of the two link coefficients of a 4-column fit of `y`: the
/// least-squares variance with the residual's lag-1 autocorrelation `rho` taken in as
/// `(1 + rho) / (1 - rho)` (an AR(1) residual's variance inflation of a mean).
fn sampling_var(rows: &[[f64; 4]], y: &[f64], x: &[f64; 4]) -> [f64; 2] {
    let n = rows.len() as f64;
    let resid: Vec<f64> = rows
        .iter()
        .zip(y)
        .map(|(r, v)| v - r.iter().zip(x).map(|(a, b)| a * b).sum::<f64>())
        .collect();
    let sse: f64 = resid.iter().map(|e| e * e).sum();
    let lag1: f64 = resid.windows(2).map(|w| w[0] * w[1]).sum();
    let rho = if sse > 0.0 {
        (lag1 / sse).clamp(0.0, 0.95)
    } else {
        0.0
    };
    let s2 = sse / (n - 4.0).max(1.0) * (1.0 + rho) / (1.0 - rho);
    let ne = NormalEquations::of_rows(rows, y);
    let mut out = [f64::INFINITY; 2];
    for (o, k) in out.iter_mut().zip([2usize, 3]) {
        let mut e = vec![0.0; 4];
        e[k] = 1.0;
        if let Some(col) = ne.solve_for(e) {
            *o = s2 * col[k];
        }
    }
    out
}

fn rows(b: &Bins, tau_s: f64, temperature: bool) -> Vec<[f64; 4]> {
    (0..b.t_s.len())
        .map(|i| {
            let w = (-b.t_s[i] / tau_s).exp();
            if temperature {
                [1.0, w, b.temp_off[i], b.temp_rate[i]]
            } else {
                [1.0, w, 0.0, 0.0]
            }
        })
        .collect()
}

/// The pooled fit at `tau_s`: per run a level and a warm-up amplitude, the temperature and
/// temperature-rate links shared by every run (the family's). Returns
/// `(per-run [b, a], [c, c'], sse)`.
fn pooled(
    binned: &[Bins],
    tau_s: f64,
    temperature: bool,
) -> Option<(Vec<[f64; 2]>, [f64; 2], f64)> {
    let r = binned.len();
    let k = 2 * r + if temperature { 2 } else { 0 };
    let mut ne = NormalEquations::new(k);
    let row_of = |run: usize, x: &[f64; 4]| -> Vec<(usize, f64)> {
        let mut v = vec![(2 * run, x[0]), (2 * run + 1, x[1])];
        if temperature {
            v.push((2 * r, x[2]));
            v.push((2 * r + 1, x[3]));
        }
        v
    };
    for (run, b) in binned.iter().enumerate() {
        for (x, &y) in rows(b, tau_s, temperature).iter().zip(&b.y) {
            ne.add(&row_of(run, x), y, 1.0);
        }
    }
    let x = ne.solve_ridged()?;
    let shared = if temperature {
        [x[2 * r], x[2 * r + 1]]
    } else {
        [0.0, 0.0]
    };
    let per_run: Vec<[f64; 2]> = (0..r).map(|i| [x[2 * i], x[2 * i + 1]]).collect();
    let mut sse = 0.0;
    for (run, b) in binned.iter().enumerate() {
        for (x, &y) in rows(b, tau_s, temperature).iter().zip(&b.y) {
            let f = per_run[run][0] * x[0]
                + per_run[run][1] * x[1]
                + shared[0] * x[2]
                + shared[1] * x[3];
            sse += (y - f) * (y - f);
        }
    }
    Some((per_run, shared, sse))
}

/// Least power-on scatter of one unit's level the random-effects fit assumes, deg/s
/// (ASSUMED 1 deg/h: a few runs cannot show a smaller one reliably).
const POWER_ON_FLOOR_DPS: f64 = 1.0 / 3600.0;

/// Least number of one unit's runs whose levels are taken to tell its link
/// ([`unit_links`]): their scatter around the centre and the link needs a degree of
/// freedom left (with 2 runs the link fits both levels exactly; measured: docs/
/// drift-filter.md "The unit's own runs").
const MIN_RUNS_FOR_LEVELS: usize = 3;

/// ONE unit's runs at warm-up time constant `tau_s`: one warm-up amplitude and the links
/// shared by the runs, and each run's level the unit's centre plus a power-on deviation of
/// standard deviation `power_on_dps` (a random effect: a penalty row per run; `None`: one
/// shared level). Runs at different ambient temperatures then tell the temperature link
/// from their levels, which free per-run levels ([`pooled`]) absorb; runs of different
/// self-heating tell the temperature-rate link from the warm-up, which a free per-run
/// amplitude absorbs when the two share a time constant (the unit's warm-up is taken to be
/// the same at every power-on, ASSUMED: the generator's is; measured in docs/
/// drift-filter.md "The unit's own runs"). Returns the links `[c, c']`, the runs' mean
/// residuals (their level deviations from the centre plus what the fit leaves), and the
/// bins' residual variance.
fn unit_random_effects(
    binned: &[Bins],
    tau_s: f64,
    power_on_dps: Option<f64>,
    bin_var: f64,
) -> Option<([f64; 2], Vec<f64>, f64)> {
    let r = binned.len();
    // Unknowns: per run b_r, then the warm-up a, c, c', centre.
    let (warmup, link, centre) = (r, r + 1, r + 3);
    let k = r + 4;
    // The unknown run `run`'s level is read from.
    let level_of = |run: usize| {
        if power_on_dps.is_some() {
            run
        } else {
            centre
        }
    };
    let mut ne = NormalEquations::new(k);
    for (run, b) in binned.iter().enumerate() {
        let level = level_of(run);
        for (x, &y) in rows(b, tau_s, true).iter().zip(&b.y) {
            ne.add(
                &[
                    (level, x[0]),
                    (warmup, x[1]),
                    (link, x[2]),
                    (link + 1, x[3]),
                ],
                y,
                1.0,
            );
        }
        match power_on_dps {
            // (b_r - centre) / sigma_p = 0 on the scale of a bin's residual.
            Some(sp) => ne.add(&[(run, 1.0), (centre, -1.0)], 0.0, sp / bin_var.sqrt()),
            None => ne.add(&[(run, 1.0)], 0.0, 1.0),
        }
    }
    let x = ne.solve_ridged()?;
    let mut sse = 0.0;
    let mut n = 0usize;
    let mut means = Vec::with_capacity(r);
    for (run, b) in binned.iter().enumerate() {
        let level = x[level_of(run)];
        let mut sum = 0.0;
        let rs = rows(b, tau_s, true);
        for (row, &y) in rs.iter().zip(&b.y) {
            let f = level * row[0] + x[warmup] * row[1] + x[link] * row[2] + x[link + 1] * row[3];
            sse += (y - f) * (y - f);
            sum += y - f + level - x[centre];
            n += 1;
        }
        means.push(sum / rs.len().max(1) as f64);
    }
    let var = sse / (n as f64 - k as f64).max(1.0);
    Some(([x[link], x[link + 1]], means, var))
}

/// The links of ONE unit from its own runs ([`unit_random_effects`]): a first fit with one
/// shared level gives the runs' level deviations, whose scatter (at least
/// [`POWER_ON_FLOOR_DPS`]) is the power-on deviation of the second fit. Standard errors by
/// the jackknife over runs (each run left out in turn). `None` with fewer than
/// [`MIN_RUNS_FOR_LEVELS`] runs (the caller then takes the runs' free-level estimate).
fn unit_links(binned: &[Bins], tau_s: f64) -> Option<LinkEstimate> {
    let once = |bs: &[Bins]| -> Option<[f64; 2]> {
        let (_, means, var) = unit_random_effects(bs, tau_s, None, 1.0)?;
        let n = means.len() as f64;
        let m = means.iter().sum::<f64>() / n;
        // Degrees of freedom: the runs less the centre and the link their levels fit.
        let scatter = means.iter().map(|d| (d - m) * (d - m)).sum::<f64>() / (n - 2.0).max(1.0);
        let sp = scatter.sqrt().max(POWER_ON_FLOOR_DPS);
        Some(unit_random_effects(bs, tau_s, Some(sp), var)?.0)
    };
    let n = binned.len();
    if n < MIN_RUNS_FOR_LEVELS {
        return None;
    }
    let all = once(binned)?;
    let mut leave: Vec<[f64; 2]> = Vec::with_capacity(n);
    for i in 0..n {
        let rest: Vec<Bins> = binned
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != i)
            .map(|(_, b)| b.clone())
            .collect();
        leave.push(once(&rest)?);
    }
    let nf = n as f64;
    let se = |k: usize| {
        let m = leave.iter().map(|l| l[k]).sum::<f64>() / nf;
        ((nf - 1.0) / nf * leave.iter().map(|l| (l[k] - m) * (l[k] - m)).sum::<f64>()).sqrt()
    };
    Some([(all[0], se(0)), (all[1], se(1))])
}

/// The spread of a per-unit constant around `mean` from per-run estimates `v` and their
/// sampling variances `se2` (method of moments: the estimates' scatter less what their
/// own error explains, at least 0).
fn unit_spread(mean: f64, v: &[f64], se2: &[f64]) -> Spread {
    let n = v.len() as f64;
    let scatter = v.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0).max(1.0);
    let own = se2.iter().sum::<f64>() / n;
    Spread {
        mean: mean as f32,
        sigma: (scatter - own).max(0.0).sqrt() as f32,
    }
}

fn mean_sd(v: &[f64]) -> Spread {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let var = if v.len() > 1 {
        v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0)
    } else {
        m * m
    };
    Spread {
        mean: m as f32,
        sigma: var.sqrt() as f32,
    }
}

/// Allan variance of a Gauss-Markov term of variance 1 and correlation time `t_s`.
fn markov_avar(tau_s: f64, t_s: f64) -> f64 {
    let x = tau_s / t_s;
    if x < 1e-3 {
        return 2.0 * tau_s / (3.0 * t_s);
    }
    (2.0 * t_s / tau_s) * (1.0 - (3.0 - 4.0 * (-x).exp() + (-2.0 * x).exp()) / (2.0 * x))
}

/// Basis of the stochastic fit at `tau_s`: white, rate random walk, Gauss-Markov terms.
fn basis(tau_s: f64) -> [f64; 2 + MAX_MARKOV] {
    let mut out = [0.0; 2 + MAX_MARKOV];
    out[0] = 1.0 / tau_s;
    out[1] = tau_s / 3.0;
    for (o, t) in out[2..].iter_mut().zip(MARKOV_TAUS_S) {
        *o = markov_avar(tau_s, t);
    }
    out
}

/// Non-negative relative least squares over every subset of the terms (32 subsets).
fn fit_avar(points: &[(f64, f64)]) -> [f64; 2 + MAX_MARKOV] {
    const K: usize = 2 + MAX_MARKOV;
    let mut best = ([0.0; K], f64::INFINITY);
    for mask in 1u32..(1 << K) {
        let idx: Vec<usize> = (0..K).filter(|i| mask & (1 << i) != 0).collect();
        // Normal equations of the chosen columns, rows weighted by 1/avar.
        let mut ne = NormalEquations::new(idx.len());
        for &(tau, avar) in points {
            let f = basis(tau);
            let entries: Vec<(usize, f64)> =
                idx.iter().enumerate().map(|(i, &ci)| (i, f[ci])).collect();
            ne.add(&entries, 1.0, avar);
        }
        let Some(x) = ne.solve() else { continue };
        if x.iter().any(|&v| v < 0.0) {
            continue;
        }
        let mut coef = [0.0; K];
        for (&ci, v) in idx.iter().zip(x) {
            coef[ci] = v;
        }
        let cost: f64 = points
            .iter()
            .map(|&(tau, avar)| {
                let f: f64 = basis(tau).iter().zip(&coef).map(|(a, b)| a * b).sum();
                (f / avar - 1.0).powi(2)
            })
            .sum();
        if cost < best.1 {
            best = (coef, cost);
        }
    }
    best.0
}

/// Gaussian elimination with partial pivoting; `None` when singular or not finite.
#[allow(clippy::needless_range_loop)] // the elimination reads clearest with indices
fn solve_dyn(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let k = b.len();
    for c in 0..k {
        let p = (c..k).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[p][c].abs() < 1e-300 {
            return None;
        }
        a.swap(c, p);
        b.swap(c, p);
        for r in c + 1..k {
            let f = a[r][c] / a[c][c];
            for q in c..k {
                a[r][q] -= f * a[c][q];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = vec![0.0; k];
    for c in (0..k).rev() {
        let s: f64 = (c + 1..k).map(|q| a[c][q] * x[q]).sum();
        x[c] = (b[c] - s) / a[c][c];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Fits the family's model to its calibration `runs` (module docs); `cal` is their
/// measurement, `file_bound_dps` the gyro file's drift bound.
pub fn fit(
    runs: &[Series],
    cal: &Calibration,
    file_bound_dps: f64,
) -> Result<(GyroModel, GyroFitReport)> {
    fit_with(runs, cal, file_bound_dps, None)
}

/// The model of ONE unit from its own static `runs` (each a power-on) and its `family`'s
/// model. The temperature links: the family's prior (mean, unit spread) and the runs' own
/// estimate (`unit_links`: the runs' levels as the unit's centre plus a power-on
/// deviation, so runs at different ambient temperatures tell the link from their levels
/// where the self-heating and the warm-up look alike within a run, and one warm-up shared by
/// the runs, so runs of different self-heating tell the temperature-rate link; its standard
/// error by the jackknife over runs) weighed by their precisions. Then the runs' level and warm-up fitted again
/// with the links held there, and [`personalize`]; the links' spread is the combination's
/// (at least [`UNIT_SPREAD_FLOOR`] of the family's).
pub fn fit_unit(
    runs: &[Series],
    cal: &Calibration,
    file_bound_dps: f64,
    family: &GyroModel,
) -> Result<(GyroModel, GyroFitReport)> {
    let binned: Vec<Bins> = runs.iter().map(bins).collect();
    check_runs(runs, &binned)?;
    let own = if runs.iter().all(|s| s.temp_c.is_some()) {
        let tau_w = warmup_tau(&binned, true)?;
        match unit_links(&binned, tau_w) {
            Some(l) => Some(l),
            None => Some(free_links(runs, &binned, tau_w)?),
        }
    } else {
        None
    };
    let prior = [family.temp_dps_per_c, family.temp_rate_dps_per_c_per_s];
    let mut links = prior;
    if let Some(own) = own {
        for ((l, p), (est, se)) in links.iter_mut().zip(&prior).zip(own) {
            let pv = f64::from(p.sigma) * f64::from(p.sigma);
            let ev = se * se;
            if pv > 0.0 && ev > 0.0 {
                let w = pv / (pv + ev);
                *l = Spread {
                    mean: (f64::from(p.mean) + w * (est - f64::from(p.mean))) as f32,
                    sigma: (pv * ev / (pv + ev)).sqrt() as f32,
                };
            }
        }
    }
    let held = [f64::from(links[0].mean), f64::from(links[1].mean)];
    let (unit, report) = fit_binned(runs, binned, cal, file_bound_dps, Some(held))?;
    let mut m = personalize(family, &unit);
    m.temp_dps_per_c = floored(links[0], prior[0]);
    m.temp_rate_dps_per_c_per_s = floored(links[1], prior[1]);
    Ok((m, report))
}

/// The shared links' estimate and standard error: `[(deg/s per deg C, se), (deg/s per
/// deg C/s, se)]`.
type LinkEstimate = [(f64, f64); 2];

/// Refuses fewer than 2 runs and a run shorter than 60 s (6 bins).
fn check_runs(runs: &[Series], binned: &[Bins]) -> Result<()> {
    if runs.len() < 2 {
        bail!(
            "{} calibration run(s): the model's unit-to-unit spread needs at least 2",
            runs.len()
        );
    }
    if let Some((s, _)) = runs.iter().zip(binned).find(|(_, b)| b.t_s.len() < 6) {
        bail!(
            "{}: shorter than 60 s, too short to fit a warm-up on",
            s.name
        );
    }
    Ok(())
}

/// The warm-up time constant: least residual of [`pooled`] summed over the runs, on a log
/// grid 30..3000 s.
fn warmup_tau(binned: &[Bins], temperature: bool) -> Result<f64> {
    let mut best: Option<(f64, f64)> = None;
    for i in 0..=24 {
        let tau = 30.0 * 100f64.powf(i as f64 / 24.0);
        let sse = pooled(binned, tau, temperature).map_or(f64::INFINITY, |p| p.2);
        if best.is_none_or(|(_, e)| sse < e) {
            best = Some((tau, sse));
        }
    }
    match best {
        Some((tau, _)) => Ok(tau),
        None => bail!("no warm-up time constant fits the calibration runs"),
    }
}

/// Each run's own fit at `tau_w` (level, warm-up and, with `temperature`, its own links)
/// and the sampling variances of its links.
fn own_fits(
    runs: &[Series],
    binned: &[Bins],
    tau_w: f64,
    temperature: bool,
) -> Result<Vec<([f64; 4], [f64; 2])>> {
    let mut own = Vec::with_capacity(runs.len());
    for (s, b) in runs.iter().zip(binned) {
        let x_rows = rows(b, tau_w, temperature);
        let Some(x) = least_squares(&x_rows, &b.y) else {
            bail!("{}: the deterministic part cannot be fitted", s.name);
        };
        own.push((x, sampling_var(&x_rows, &b.y, &x)));
    }
    Ok(own)
}

/// The links shared by the runs with free levels ([`pooled`] at `tau_w`) and their standard
/// error from the scatter of each run's own fit, at least the runs' mean sampling error,
/// over the number of runs.
fn free_links(runs: &[Series], binned: &[Bins], tau_w: f64) -> Result<LinkEstimate> {
    let Some((_, shared, _)) = pooled(binned, tau_w, true) else {
        bail!("the deterministic part cannot be fitted on the calibration runs");
    };
    let own = own_fits(runs, binned, tau_w, true)?;
    let n = own.len() as f64;
    let one = |k: usize| {
        let v: Vec<f64> = own.iter().map(|o| o.0[k + 2]).collect();
        let m = v.iter().sum::<f64>() / n;
        let scatter = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0).max(1.0);
        let sampling = own.iter().map(|o| o.1[k]).sum::<f64>() / n;
        (shared[k], (scatter.max(sampling) / n).sqrt())
    };
    Ok([one(0), one(1)])
}

/// [`fit`], with the temperature links fitted (`None`) or held at `links` (deg/s per deg C,
/// deg/s per deg C/s).
fn fit_with(
    runs: &[Series],
    cal: &Calibration,
    file_bound_dps: f64,
    links: Option<[f64; 2]>,
) -> Result<(GyroModel, GyroFitReport)> {
    let binned: Vec<Bins> = runs.iter().map(bins).collect();
    check_runs(runs, &binned)?;
    fit_binned(runs, binned, cal, file_bound_dps, links)
}

/// [`fit_with`] on the runs' bins (`binned[i]` of `runs[i]`, checked by [`check_runs`]).
fn fit_binned(
    runs: &[Series],
    mut binned: Vec<Bins>,
    cal: &Calibration,
    file_bound_dps: f64,
    links: Option<[f64; 2]>,
) -> Result<(GyroModel, GyroFitReport)> {
    let has_temp = runs.iter().all(|s| s.temp_c.is_some());
    // Held links: their part taken out of the means, the links not fitted.
    let held = links.filter(|_| has_temp);
    if let Some([c, c_rate]) = held {
        for b in &mut binned {
            for i in 0..b.y.len() {
                b.y[i] -= c * b.temp_off[i] + c_rate * b.temp_rate[i];
            }
        }
    }
    let temperature = has_temp && held.is_none();
    let tau_w = warmup_tau(&binned, temperature)?;
    let Some((per_run, shared_fit, _)) = pooled(&binned, tau_w, temperature) else {
        bail!("the deterministic part cannot be fitted on the calibration runs");
    };
    let shared = held.unwrap_or(shared_fit);
    // Each run's own links (free), for their unit-to-unit spread around the shared ones.
    let own = own_fits(runs, &binned, tau_w, temperature)?;
    let coefs: Vec<(String, [f64; 4])> = runs
        .iter()
        .zip(&per_run)
        .map(|(s, p)| (s.name.clone(), [p[0], p[1], shared[0], shared[1]]))
        .collect();
    let col = |k: usize| coefs.iter().map(|(_, x)| x[k]).collect::<Vec<f64>>();
    let (turn_on, warmup) = (mean_sd(&col(0)), mean_sd(&col(1)));
    let (temp, temp_rate) = if temperature {
        let pick = |k: usize| own.iter().map(|o| o.0[k]).collect::<Vec<f64>>();
        let se = |k: usize| own.iter().map(|o| o.1[k]).collect::<Vec<f64>>();
        // A link's spread is capped where its term alone, at the largest temperature offset
        // (rate) the runs saw, would reach a third of the largest drift they showed: a
        // spread beyond it is a term the runs never showed (ASSUMED cap; an ill-determined
        // per-run link otherwise passes as unit-to-unit spread).
        let drift_max = cal.drift_abs_max_dph / 3600.0;
        let largest = |f: &dyn Fn(&Bins) -> &Vec<f64>| {
            binned
                .iter()
                .flat_map(|b| f(b).iter().map(|v| v.abs()))
                .fold(0.0f64, f64::max)
        };
        let cap = |sp: Spread, reach: f64| {
            let limit = if reach > 0.0 {
                drift_max / (3.0 * reach)
            } else {
                0.0
            };
            Spread {
                sigma: sp.sigma.min(limit as f32),
                ..sp
            }
        };
        (
            cap(
                unit_spread(shared[0], &pick(2), &se(0)),
                largest(&|b| &b.temp_off),
            ),
            cap(
                unit_spread(shared[1], &pick(3), &se(1)),
                largest(&|b| &b.temp_rate),
            ),
        )
    } else {
        (Spread::default(), Spread::default())
    };
    // Stochastic part: Allan variance of each run minus its deterministic part, averaged.
    let mut avar_sum: Vec<(f64, f64, usize)> = Vec::new();
    for ((s, b), (_, x)) in runs.iter().zip(&binned).zip(&coefs) {
        let dt = s.sample_period_s();
        let per = ((BIN_S / dt).round() as usize).max(1);
        let resid: Vec<f64> = s
            .rate_dps
            .iter()
            .enumerate()
            .map(|(k, &y)| {
                let i = (k / per).min(b.t_s.len() - 1);
                let t = s.t_s[k];
                let det =
                    x[0] + x[1] * (-t / tau_w).exp() + x[2] * b.temp_off[i] + x[3] * b.temp_rate[i];
                f64::from(y) - det
            })
            .collect();
        let n = resid.len();
        let mut ms = Vec::new();
        let mut m = ((1.0 / dt).round() as usize).max(1);
        while m * 8 <= n {
            ms.push(m);
            m *= 2;
        }
        for p in allan::oadev(&resid, dt, &ms) {
            match avar_sum
                .iter_mut()
                .find(|(t, _, _)| (t / p.tau_s - 1.0).abs() < 1e-6)
            {
                Some(e) => {
                    e.1 += p.adev_dps * p.adev_dps;
                    e.2 += 1;
                }
                None => avar_sum.push((p.tau_s, p.adev_dps * p.adev_dps, 1)),
            }
        }
    }
    let points: Vec<(f64, f64)> = avar_sum
        .iter()
        .filter(|(_, v, c)| *c == runs.len() && *v > 0.0)
        .map(|(t, v, c)| (*t, v / *c as f64))
        .collect();
    if points.len() < 3 {
        bail!("the calibration runs are too short for an Allan fit (fewer than 3 taus from 1 s)");
    }
    let coef = fit_avar(&points);
    let mut markov = [MarkovTerm::default(); MAX_MARKOV];
    for ((m, &v), t) in markov.iter_mut().zip(&coef[2..]).zip(MARKOV_TAUS_S) {
        if v > 0.0 {
            *m = MarkovTerm {
                sigma_dps: v.sqrt() as f32,
                tau_s: t as f32,
            };
        }
    }
    let quantum = {
        let mut q: Vec<f64> = cal.runs.iter().filter_map(|r| r.quantum_dps).collect();
        q.sort_by(f64::total_cmp);
        q.get(q.len() / 2).copied().unwrap_or(0.0)
    };
    let bound = crate::motion::calibration::drift_bound_dph(cal, file_bound_dps) / 3600.0;
    let model = GyroModel {
        sample_rate_hz: cal.rate_hz as f32,
        white_dps_rthz: (cal.noise_median_deg_rth / 60.0) as f32,
        quantum_dps: quantum as f32,
        markov,
        rrw_dps_per_s_rthz: coef[1].sqrt() as f32,
        turn_on_dps: turn_on,
        warmup_dps: warmup,
        warmup_tau_min_s: (tau_w / WARMUP_TAU_RATIO) as f32,
        warmup_tau_max_s: (tau_w * WARMUP_TAU_RATIO) as f32,
        temp_dps_per_c: temp,
        temp_rate_dps_per_c_per_s: temp_rate,
        temp_ref_c: TEMP_REF_C as f32,
        drift_bound_dps: bound as f32,
    };
    if !model.is_valid() {
        bail!("the fitted model is not valid: {model:?}");
    }
    let dph = 3600.0;
    let report = GyroFitReport {
        warmup_tau_s: tau_w,
        runs: coefs
            .iter()
            .map(|(name, x)| RunFit {
                name: name.clone(),
                level_dph: x[0] * dph,
                warmup_dph: x[1] * dph,
                temp_dph_per_c: x[2] * dph,
                temp_rate_dph_per_c_per_min: x[3] * dph / 60.0,
            })
            .collect(),
        adev_dph: points.iter().map(|&(t, v)| (t, v.sqrt() * dph)).collect(),
        fit_adev_dph: points
            .iter()
            .map(|&(t, _)| {
                let f: f64 = basis(t).iter().zip(&coef).map(|(a, b)| a * b).sum();
                (t, f.sqrt() * dph)
            })
            .collect(),
        temperature: has_temp,
    };
    Ok((model, report))
}

/// Least spread of a unit's own constant as a fraction of the family's
/// ([`personalize`]): a few runs of one unit cannot show a spread reliably (ASSUMED 0.25;
/// measured: docs/drift-filter.md "The unit's own runs").
pub const UNIT_SPREAD_FLOOR: f32 = 0.25;

/// A unit's `spread` with its sigma at least [`UNIT_SPREAD_FLOOR`] of the family's.
fn floored(spread: Spread, family: Spread) -> Spread {
    Spread {
        mean: spread.mean,
        sigma: spread.sigma.max(UNIT_SPREAD_FLOOR * family.sigma),
    }
}

/// The model of ONE unit: `unit` is the fit of that unit's own static runs (each a
/// power-on; [`fit_unit`]), `family` the family's (fitted on other units' runs, maybe tuned
/// on vehicles). The unit's runs give what they measure: its turn-on centre and power-on
/// scatter, its warm-up (amplitude and time constant), its white noise and the drift bound
/// it showed (the larger of both). From the family: the Gauss-Markov terms, the rate random
/// walk (a few 30-min runs fit them worse than many) and the temperature links, mean and
/// unit spread (a few runs of one unit cannot tell them from its warm-up; the filter adapts
/// them within the spread on line). The unit's turn-on and warm-up spreads are at least
/// [`UNIT_SPREAD_FLOOR`] of the family's.
pub fn personalize(family: &GyroModel, unit: &GyroModel) -> GyroModel {
    GyroModel {
        markov: family.markov,
        rrw_dps_per_s_rthz: family.rrw_dps_per_s_rthz,
        turn_on_dps: floored(unit.turn_on_dps, family.turn_on_dps),
        warmup_dps: floored(unit.warmup_dps, family.warmup_dps),
        temp_ref_c: family.temp_ref_c,
        temp_dps_per_c: family.temp_dps_per_c,
        temp_rate_dps_per_c_per_s: family.temp_rate_dps_per_c_per_s,
        drift_bound_dps: unit.drift_bound_dps.max(family.drift_bound_dps),
        ..*unit
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs of a family with a shared temperature link, per-run levels and warm-ups.
    fn family_runs(c_dps_per_c: f64) -> Vec<Series> {
        runs_of(8, 12345, c_dps_per_c, |r| {
            (
                (r as f64 - 3.5) * 8.0,
                if r % 2 == 0 { 20.0 } else { -15.0 },
            )
        })
    }

    /// `count` runs of link `c_dps_per_c`, run `r`'s (level, warm-up) deg/h from `lw`;
    /// warm-up time constant 400 s, self-heating 8 C with time constant 900 s.
    fn runs_of(
        count: usize,
        seed: u64,
        c_dps_per_c: f64,
        lw: impl Fn(usize) -> (f64, f64),
    ) -> Vec<Series> {
        runs_with(count, seed, c_dps_per_c, lw, 900.0)
    }

    /// Standard normal draws (Box-Muller on a 64-bit LCG) from `seed`.
    fn normals(seed: u64) -> impl FnMut() -> f64 {
        let mut state = seed;
        move || {
            let mut u = || {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            let (a, b) = (u(), u());
            (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
        }
    }

    /// [`runs_of`] with the self-heating's time constant `thermal_tau_s`; run `r` starts
    /// at an ambient of 5 + 4 r deg C.
    fn runs_with(
        count: usize,
        seed: u64,
        c_dps_per_c: f64,
        lw: impl Fn(usize) -> (f64, f64),
        thermal_tau_s: f64,
    ) -> Vec<Series> {
        let mut normal = normals(seed);
        let dph = 1.0 / 3600.0;
        (0..count)
            .map(|r| {
                let fs = 10.0;
                let (level, warm) = lw(r);
                let (level, warm) = (level * dph, warm * dph);
                let ambient = 5.0 + 4.0 * r as f64;
                let n = (1800.0 * fs) as usize;
                let t_s: Vec<f64> = (0..n).map(|k| k as f64 / fs).collect();
                let temp: Vec<f64> = t_s
                    .iter()
                    .map(|t| ambient + 8.0 * (1.0 - (-t / thermal_tau_s).exp()))
                    .collect();
                let rate: Vec<f32> = t_s
                    .iter()
                    .zip(&temp)
                    .map(|(t, tc)| {
                        (level
                            + warm * (-t / 400.0).exp()
                            + c_dps_per_c * (tc - 25.0)
                            + 0.002 * normal()) as f32
                    })
                    .collect();
                Series {
                    name: format!("run{r}"),
                    t_s,
                    rate_dps: rate,
                    drift_dps: None,
                    temp_c: Some(temp.iter().map(|&v| v as f32).collect()),
                    still: None,
                    true_rate_dps: None,
                    holes: None,
                }
            })
            .collect()
    }

    #[test]
    fn the_shared_link_and_the_warm_up_are_found() {
        let c = 1.5 / 3600.0;
        let runs = family_runs(c);
        let cal = crate::motion::calibration::measure(&runs).expect("measure");
        let (m, rep) = fit(&runs, &cal, 30.0 / 3600.0).expect("fit");
        let c_fit = f64::from(m.temp_dps_per_c.mean);
        assert!(
            (c_fit / c - 1.0).abs() < 0.1,
            "link {} dph/C",
            c_fit * 3600.0
        );
        assert!(
            (250.0..650.0).contains(&rep.warmup_tau_s),
            "tau {}",
            rep.warmup_tau_s
        );
        // White noise 0.002 deg/s at 10 Hz: density 0.002 / sqrt(10).
        let n = f64::from(m.white_dps_rthz);
        assert!((n / (0.002 / 10f64.sqrt()) - 1.0).abs() < 0.05, "{n}");
        assert!(m.is_valid());
    }

    #[test]
    fn a_units_own_runs_give_its_warm_up_and_turn_on() {
        // The family: 8 units (warm-ups +20 / -15 deg/h, link 1.5 deg/h/C). The unit: three
        // power-ons with its own warm-up of +35 deg/h, levels near +30 deg/h, its link 10 %
        // above the family's (strong: its runs tell it).
        let dph = 1.0 / 3600.0;
        let fam = family_runs(1.5 * dph);
        let cal = crate::motion::calibration::measure(&fam).expect("measure");
        let (family, _) = fit(&fam, &cal, 30.0 * dph).expect("family fit");
        // Power-on levels scattered, not trending with the runs' ambient (5, 9, 13 C): a
        // level rising with the ambient is a larger link.
        let unit = runs_of(3, 777, 1.65 * dph, |r| (30.0 + [0.0, 2.0, -1.0][r], 35.0));
        let cal_u = crate::motion::calibration::measure(&unit).expect("measure");
        let (m, _) = fit_unit(&unit, &cal_u, 30.0 * dph, &family).expect("unit fit");
        let warm = f64::from(m.warmup_dps.mean) / dph;
        assert!(
            (warm / 35.0 - 1.0).abs() < 0.15,
            "unit warm-up {warm} deg/h"
        );
        let fam_warm = f64::from(family.warmup_dps.mean) / dph;
        assert!(
            (fam_warm / 35.0 - 1.0).abs() > 0.5,
            "family warm-up {fam_warm}"
        );
        let level = f64::from(m.turn_on_dps.mean) / dph;
        assert!((level - 30.3).abs() < 3.0, "unit turn-on {level} deg/h");
        let link = f64::from(m.temp_dps_per_c.mean) / dph;
        assert!((link / 1.65 - 1.0).abs() < 0.15, "unit link {link} deg/h/C");
        // Spreads at least the floor of the family's; noise terms the family's.
        assert!(m.turn_on_dps.sigma >= UNIT_SPREAD_FLOOR * family.turn_on_dps.sigma);
        assert!(m.warmup_dps.sigma >= UNIT_SPREAD_FLOOR * family.warmup_dps.sigma);
        assert_eq!(m.markov, family.markov);
        assert_eq!(m.rrw_dps_per_s_rthz, family.rrw_dps_per_s_rthz);
        assert!(m.is_valid());
    }

    /// The family fitted on [`family_runs`] of link 1.5 deg/h per C, its link's prior set
    /// wide: mean 1.5, spread 1.5 deg/h per C.
    fn family_of_wide_link() -> GyroModel {
        let dph = 1.0 / 3600.0;
        let fam = family_runs(1.5 * dph);
        let cal = crate::motion::calibration::measure(&fam).expect("measure");
        let (mut family, _) = fit(&fam, &cal, 30.0 * dph).expect("family fit");
        family.temp_dps_per_c = Spread {
            mean: (1.5 * dph) as f32,
            sigma: (1.5 * dph) as f32,
        };
        family
    }

    #[test]
    fn a_units_link_is_told_from_its_warm_up_by_its_levels() {
        // The unit's warm-up and self-heating share their time constant (400 s): within a
        // run the link and the warm-up look alike. Its four power-ons start 4 C apart
        // (5..17 C), their levels scatter by 1.5 deg/h around 30 deg/h: the levels carry
        // the link (3 deg/h/C, twice the family's mean, inside its wide prior).
        let dph = 1.0 / 3600.0;
        let family = family_of_wide_link();
        let power_on = [1.0, -2.0, 1.5, -0.5];
        let unit = runs_with(4, 4242, 3.0 * dph, |r| (30.0 + power_on[r], 25.0), 400.0);
        let cal_u = crate::motion::calibration::measure(&unit).expect("measure");
        let (m, _) = fit_unit(&unit, &cal_u, 30.0 * dph, &family).expect("unit fit");
        let link = f64::from(m.temp_dps_per_c.mean) / dph;
        assert!((link / 3.0 - 1.0).abs() < 0.15, "unit link {link} deg/h/C");
        assert!(m.is_valid());
    }

    #[test]
    fn a_units_rate_link_is_told_from_its_warm_up_by_its_self_heating() {
        // Conditions of the generator's f100 vehicle 18 (its four calibration runs): a
        // warm-up of -25.6 deg/h at 778 s, self-heating by 4-12 C at 370-1250 s, a
        // temperature-rate link of 13 deg/h per C/min on the true dT/dt beside a link of
        // 1.5 deg/h per C, a Gauss-Markov drift of 2 deg/h at 300 s. Within a run the rate
        // link's term looks like a part of the warm-up; a warm-up the same at every
        // power-on leaves it to the rate link to explain how the runs' early drifts differ
        // with their self-heating.
        let dph = 1.0 / 3600.0;
        let mut family = family_of_wide_link();
        family.temp_rate_dps_per_c_per_s = Spread {
            mean: 0.0,
            sigma: (20.0 * dph * 60.0) as f32,
        };
        let rate_link = 13.0 * dph * 60.0;
        // (ambient C, self-heating C, its time constant s, power-on deviation deg/h)
        let runs = [
            (28.7, 10.7, 576.0, 1.0),
            (25.8, 11.9, 699.0, -2.0),
            (7.0, 4.3, 1250.0, 1.5),
            (29.0, 5.4, 373.0, -0.5),
        ];
        let mut normal = normals(777);
        let fs = 10.0;
        let n = (1800.0 * fs) as usize;
        let unit: Vec<Series> = runs
            .iter()
            .enumerate()
            .map(|(r, &(ambient, heat, tau_th, power_on))| {
                let t_s: Vec<f64> = (0..n).map(|k| k as f64 / fs).collect();
                let temp = |t: f64| ambient + heat * (1.0 - (-t / tau_th).exp());
                let mut gm = 0.0;
                let a = (-1.0 / (300.0 * fs)).exp();
                let rate_dps: Vec<f32> = t_s
                    .iter()
                    .map(|&t| {
                        let dtemp = heat / tau_th * (-t / tau_th).exp();
                        gm = a * gm + (1.0 - a * a).sqrt() * 2.0 * dph * normal();
                        ((30.0 + power_on - 25.6 * (-t / 778.0).exp()) * dph
                            + 1.5 * dph * (temp(t) - 25.0)
                            + rate_link * dtemp
                            + gm
                            + 0.002 * normal()) as f32
                    })
                    .collect();
                Series {
                    name: format!("heated{r}"),
                    temp_c: Some(t_s.iter().map(|&t| temp(t) as f32).collect()),
                    t_s,
                    rate_dps,
                    drift_dps: None,
                    still: None,
                    true_rate_dps: None,
                    holes: None,
                }
            })
            .collect();
        let cal_u = crate::motion::calibration::measure(&unit).expect("measure");
        let (m, _) = fit_unit(&unit, &cal_u, 30.0 * dph, &family).expect("unit fit");
        let got = f64::from(m.temp_rate_dps_per_c_per_s.mean) / (dph * 60.0);
        // The estimate is low (6.3 here): the link multiplies the causal estimate of dT/dt,
        // which lags the true rate the drift follows; a fit on central differences finds
        // 12.4 but then disagrees with the filter's own column (measured worse: docs/
        // drift-filter.md). Free per-run warm-ups found 2.0.
        assert!(
            got > 0.4 * 13.0 && got < 1.25 * 13.0,
            "unit rate link {got} deg/h per C/min"
        );
        assert!(m.is_valid());
    }

    #[test]
    fn one_run_is_refused() {
        let runs = family_runs(0.0);
        let cal = crate::motion::calibration::measure(&runs[..1]).expect("measure");
        assert!(fit(&runs[..1], &cal, 30.0 / 3600.0).is_err());
    }

    #[test]
    fn markov_avar_has_its_limits() {
        // tau << T: K^2 tau / 3 with K^2 = 2 sigma^2 / T; tau >> T: 2 sigma^2 T / tau.
        let t = 100.0;
        assert!((markov_avar(0.01, t) / (2.0 * 0.01 / (3.0 * t)) - 1.0).abs() < 1e-3);
        assert!((markov_avar(1e6, t) / (2.0 * t / 1e6) - 1.0).abs() < 1e-3);
        assert!((markov_avar(0.2, t) / (2.0 * 0.2 / (3.0 * t)) - 1.0).abs() < 1e-2);
    }

    #[test]
    fn the_avar_fit_finds_its_terms() {
        // White 1e-6 / tau, a Gauss-Markov term of variance 4e-8 at 300 s.
        let pts: Vec<(f64, f64)> = (0..12)
            .map(|i| {
                let tau = 2f64.powi(i);
                (tau, 1e-6 / tau + 4e-8 * markov_avar(tau, 300.0))
            })
            .collect();
        let c = fit_avar(&pts);
        assert!((c[0] / 1e-6 - 1.0).abs() < 1e-6, "{c:?}");
        assert!((c[3] / 4e-8 - 1.0).abs() < 1e-6, "{c:?}");
        assert!(c[1] < 1e-20 && c[2] < 1e-20 && c[4] < 1e-20, "{c:?}");
    }
}

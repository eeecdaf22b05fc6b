//! The gap's features: what is compared between a record and the model's simulations.
//!
//! A record is cut in time into [`BLOCKS`] equal blocks; features are computed on a selection
//! of blocks (the held-out blocks for scoring, all blocks for "where"), so that the same
//! numbers come from the real record and from every simulation:
//! - `adev`: ln of the overlapping Allan deviation pooled over the selected blocks (AVAR
//!   summed over the blocks' second differences), octave taus with `4 m <= block length`;
//! - `psd`: Welch PSD (Hann, 50 % overlap, mean and linear trend removed per segment) over the
//!   selected blocks; per log-spaced frequency band, ln of the mean PSD and ln of the peak
//!   over the mean (a spectral line);
//! - `time`: each selected block cut in [`TIME_WINDOWS`]: the window's mean minus the
//!   selection's mean; and `wander_ln`, ln of the mean square of those (so that a model
//!   that wanders too much is penalised, not only one that wanders too little);
//! - `dist`: the values less their local mean (blocks cut in [`DIST_WINDOWS`]), scaled by
//!   the robust sigma (1.4826 MAD): excess kurtosis, counts beyond 5 and 10 sigma, the
//!   Kolmogorov-Smirnov distance to the normal law, ln(distinct values / samples) and the
//!   number of missing sample slots (time steps longer than 1.5 periods);
//! - `drift`: each selected block cut in [`DRIFT_WINDOWS`] windows; ln of the mean squared
//!   difference of window means per lag bin ([`DRIFT_LAG_EDGES`], in block lengths), lags
//!   from 0.3 block to across the record: the structure that tells a bounded drift
//!   (Gauss-Markov: flat beyond its correlation time) from an unbounded one (random walk:
//!   linear in the lag; ramp: quadratic), which a quarter-block ADEV cannot see.

use anyhow::{bail, Result};
use rustfft::{num_complex::Complex, FftPlanner};
use serde::Serialize;

/// Blocks the record is cut into (even = fit, odd = held out).
pub const BLOCKS: usize = 6;
/// Time windows per block for the `time` features.
pub const TIME_WINDOWS: usize = 4;
/// Windows per block whose mean is removed before the `dist` features.
pub const DIST_WINDOWS: usize = 16;
/// Windows per block for the `drift` features (window-mean variogram).
pub const DRIFT_WINDOWS: usize = 8;
/// Lag bins of the `drift` features, in block lengths: `[lo, hi)`. Lags below 0.3 block are
/// left to the ADEV (which reaches a quarter block); lags of 1 block and more come from
/// window pairs in different blocks (the selected blocks are 2 apart, so these lags are
/// 1.125-2.875, 3.125-4.875 blocks, ... for every-other-block selections).
pub const DRIFT_LAG_EDGES: [f64; 8] = [0.3, 0.55, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
/// Frequency bands of the `psd` features.
pub const BANDS: usize = 10;
/// Fewest samples per block.
pub const MIN_BLOCK_SAMPLES: usize = 2048;

/// Feature group.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Group {
    /// Allan deviation per tau.
    Adev,
    /// PSD per band.
    Psd,
    /// Time windows.
    Time,
    /// Value distribution.
    Dist,
    /// Variogram of window means across the selected blocks (drift structure at lags up
    /// to the record length).
    Drift,
    /// A candidate's own held-out check (`super::check`): not one of [`GROUPS`], in the gap
    /// only where a candidate's features carry it.
    Check,
}

/// The groups, in order.
pub const GROUPS: [Group; 5] = [
    Group::Adev,
    Group::Psd,
    Group::Time,
    Group::Dist,
    Group::Drift,
];

/// One lag bin of the `drift` features: `[lo, hi)` in block lengths, and its window pairs
/// `(i, j, lag in block lengths)`.
pub type DriftBin = ((f64, f64), Vec<(usize, usize, f64)>);

/// The window pairs of the `drift` features for a block selection: per lag bin (those with
/// at least one pair), the bin's `[lo, hi)` in block lengths and the pairs as indices into
/// the selected windows (block-major, [`DRIFT_WINDOWS`] per selected block) with their lag
/// in block lengths. Depends on the selection only, so every series gets the same bins.
pub fn drift_pairs(sel: &[bool]) -> Vec<DriftBin> {
    let w = DRIFT_WINDOWS as f64;
    let pos: Vec<f64> = (0..sel.len())
        .filter(|&b| sel[b])
        .flat_map(|b| (0..DRIFT_WINDOWS).map(move |k| b as f64 + k as f64 / w))
        .collect();
    DRIFT_LAG_EDGES
        .windows(2)
        .map(|e| {
            let mut pairs = Vec::new();
            for i in 0..pos.len() {
                for j in i + 1..pos.len() {
                    let lag = pos[j] - pos[i];
                    if lag >= e[0] - 1e-9 && lag < e[1] - 1e-9 {
                        pairs.push((i, j, lag));
                    }
                }
            }
            ((e[0], e[1]), pairs)
        })
        .filter(|(_, p)| !p.is_empty())
        .collect()
}

/// What a feature is, with the range of tau (s), frequency (Hz) or time (s) it covers.
/// Floor of a count feature's spread: one event (a count's spread is at least
/// `sqrt(max(median, 1))`, the Poisson spread of a mean of at least 1).
pub const COUNT_SD_FLOOR: f64 = 1.0;

#[derive(Debug, Clone, Serialize)]
pub struct Def {
    /// Group.
    pub group: Group,
    /// Name, e.g. `adev_ln@tau=1.28s`.
    pub label: String,
    /// Range covered: tau_s, freq_hz or time_s (none for the distribution).
    pub range: Option<(f64, f64)>,
    /// Smallest spread used to normalise it (a count: beside its Poisson floor).
    pub floor: f64,
    /// A count (spread at least the larger of `sqrt(median)` and `floor`).
    pub count: bool,
}

/// Where the features come from in a record: the blocks' time spans and the analysis sizes.
#[derive(Debug, Clone)]
pub struct Layout {
    /// Nominal sample period, s.
    pub dt_s: f64,
    /// Record length, s (last time + one period).
    pub t_total_s: f64,
    /// Averaging factors of the ADEV.
    pub ms: Vec<usize>,
    /// Welch segment length, samples.
    pub nseg: usize,
    /// Bands as bin ranges `[lo, hi)`.
    pub bands: Vec<(usize, usize)>,
}

impl Layout {
    /// The layout of a record with times `t_s` (from 0) and period `dt_s`.
    pub fn new(t_s: &[f64], dt_s: f64) -> Result<Self> {
        let need = BLOCKS * MIN_BLOCK_SAMPLES;
        let t_total_s = t_s.last().copied().unwrap_or(0.0) + dt_s;
        if t_s.len() < need {
            bail!(
                "{} samples ({:.0} s at {:.4} Hz) is too short: the held-out split needs at least {} samples ({:.0} s at this rate)",
                t_s.len(),
                t_total_s,
                1.0 / dt_s,
                need,
                need as f64 * dt_s
            );
        }
        let probe = Self {
            dt_s,
            t_total_s,
            ms: Vec::new(),
            nseg: 0,
            bands: Vec::new(),
        };
        let nmin = probe
            .ranges(t_s)
            .iter()
            .map(|r| r.1 - r.0)
            .min()
            .unwrap_or(0);
        if nmin < MIN_BLOCK_SAMPLES {
            bail!(
                "a sixth of the record holds only {nmin} samples (gaps?): each of the {BLOCKS} blocks needs {MIN_BLOCK_SAMPLES}"
            );
        }
        let ms: Vec<usize> = (0..30)
            .map(|k| 1usize << k)
            .take_while(|&m| 4 * m <= nmin)
            .collect();
        let mut nseg = 1024usize;
        while nseg > nmin / 4 {
            nseg /= 2;
        }
        let top = (nseg / 2) as f64;
        let mut edges: Vec<usize> = (0..=BANDS)
            .map(|i| top.powf(i as f64 / BANDS as f64).round() as usize)
            .collect();
        edges.dedup();
        let bands = edges
            .windows(2)
            .map(|w| (w[0], w[1] + usize::from(w[1] == nseg / 2)))
            .collect();
        Ok(Self {
            dt_s,
            t_total_s,
            ms,
            nseg,
            bands,
        })
    }

    /// Time span of block `b`, s.
    pub fn block_span(&self, b: usize) -> (f64, f64) {
        let l = self.t_total_s / BLOCKS as f64;
        (b as f64 * l, (b + 1) as f64 * l)
    }

    /// Sample index ranges `[lo, hi)` of the blocks in a series with times `t_s`.
    pub fn ranges(&self, t_s: &[f64]) -> Vec<(usize, usize)> {
        let l = self.t_total_s / BLOCKS as f64;
        let mut out = Vec::with_capacity(BLOCKS);
        let mut lo = 0;
        for b in 0..BLOCKS {
            let end = (b + 1) as f64 * l;
            let hi = if b + 1 == BLOCKS {
                t_s.len()
            } else {
                lo + t_s[lo..].partition_point(|&t| t < end)
            };
            out.push((lo, hi));
            lo = hi;
        }
        out
    }

    /// Frequency of Welch bin `k`, Hz.
    pub fn freq_hz(&self, k: usize) -> f64 {
        k as f64 / (self.nseg as f64 * self.dt_s)
    }

    /// The definitions of the features of a selection (same order as [`Layout::features`]).
    pub fn defs(&self, sel: &[bool]) -> Vec<Def> {
        let mut d = Vec::new();
        for &m in &self.ms {
            let tau = m as f64 * self.dt_s;
            d.push(Def {
                group: Group::Adev,
                label: format!("adev_ln@tau={tau:.4}s"),
                range: Some((tau / 2f64.sqrt(), tau * 2f64.sqrt())),
                floor: 0.01,
                count: false,
            });
        }
        for &(lo, hi) in &self.bands {
            let r = Some((self.freq_hz(lo), self.freq_hz(hi)));
            d.push(Def {
                group: Group::Psd,
                label: format!("psd_ln@{:.4}-{:.4}Hz", self.freq_hz(lo), self.freq_hz(hi)),
                range: r,
                floor: 0.01,
                count: false,
            });
            d.push(Def {
                group: Group::Psd,
                label: format!(
                    "psd_peak_ln@{:.4}-{:.4}Hz",
                    self.freq_hz(lo),
                    self.freq_hz(hi)
                ),
                range: r,
                floor: 0.01,
                count: false,
            });
        }
        for b in (0..BLOCKS).filter(|&b| sel[b]) {
            let (a, z) = self.block_span(b);
            let w = (z - a) / TIME_WINDOWS as f64;
            for k in 0..TIME_WINDOWS {
                let r = Some((a + k as f64 * w, a + (k + 1) as f64 * w));
                d.push(Def {
                    group: Group::Time,
                    label: format!(
                        "mean@{:.0}-{:.0}s",
                        a + k as f64 * w,
                        a + (k + 1) as f64 * w
                    ),
                    range: r,
                    floor: 1e-12,
                    count: false,
                });
            }
        }
        d.push(Def {
            group: Group::Time,
            label: "wander_ln".to_string(),
            range: None,
            floor: 0.01,
            count: false,
        });
        let dist = |label: &str, floor: f64, count: bool| Def {
            group: Group::Dist,
            label: label.to_string(),
            range: None,
            floor,
            count,
        };
        d.push(dist("excess_kurtosis", 0.01, false));
        d.push(dist("count_beyond_5sigma", COUNT_SD_FLOOR, true));
        d.push(dist("count_beyond_10sigma", COUNT_SD_FLOOR, true));
        d.push(dist("ks_distance_to_normal", 0.001, false));
        d.push(dist("distinct_fraction_ln", 0.01, false));
        d.push(dist("missing_slots", COUNT_SD_FLOOR, true));
        let l = self.t_total_s / BLOCKS as f64;
        for ((lo, hi), _) in drift_pairs(sel) {
            d.push(Def {
                group: Group::Drift,
                label: format!("drift_ln@lag={:.0}-{:.0}s", lo * l, hi * l),
                range: Some((lo * l, hi * l)),
                floor: 0.01,
                count: false,
            });
        }
        d
    }

    /// Means of the [`DRIFT_WINDOWS`] windows of each selected block (block-major; NaN for
    /// an empty window).
    pub fn drift_window_means(&self, t_s: &[f64], y: &[f64], sel: &[bool]) -> Vec<f64> {
        let ranges = self.ranges(t_s);
        let mut out = Vec::new();
        for (b, &(lo, hi)) in ranges.iter().enumerate() {
            if !sel[b] {
                continue;
            }
            let (a, z) = self.block_span(b);
            let w = (z - a) / DRIFT_WINDOWS as f64;
            for k in 0..DRIFT_WINDOWS {
                let (ta, tz) = (a + k as f64 * w, a + (k + 1) as f64 * w);
                let i0 = lo + t_s[lo..hi].partition_point(|&t| t < ta);
                let i1 = lo + t_s[lo..hi].partition_point(|&t| t < tz);
                out.push(if i1 > i0 { mean(&y[i0..i1]) } else { f64::NAN });
            }
        }
        out
    }

    /// The `drift` variogram of a series on a selection: per bin of [`drift_pairs`], the
    /// mean of `(m_j - m_i)^2` over its window pairs, (deg/s)^2.
    pub fn drift_variogram(&self, t_s: &[f64], y: &[f64], sel: &[bool]) -> Vec<f64> {
        let m = self.drift_window_means(t_s, y, sel);
        drift_pairs(sel)
            .iter()
            .map(|(_, pairs)| {
                let v: Vec<f64> = pairs
                    .iter()
                    .map(|&(i, j, _)| (m[j] - m[i]).powi(2))
                    .filter(|v| v.is_finite())
                    .collect();
                mean(&v)
            })
            .collect()
    }

    /// The features of the selected blocks of a series (see the module docs).
    /// `y`: the rate less the reference; `raw`: the rate as measured (for the distinct
    /// values, i.e. quantization).
    pub fn features(
        &self,
        t_s: &[f64],
        y: &[f64],
        raw: &[f64],
        sel: &[bool],
        fft: &mut Fft,
    ) -> Vec<f64> {
        let ranges = self.ranges(t_s);
        let chosen: Vec<(usize, usize)> = ranges
            .iter()
            .enumerate()
            .filter(|(b, _)| sel[*b])
            .map(|(_, r)| *r)
            .collect();
        let mut f = Vec::new();
        // ADEV.
        for (v, _) in pooled_avar(y, &chosen, self.dt_s, &self.ms) {
            f.push(0.5 * v.max(1e-300).ln());
        }
        // PSD.
        let psd = self.welch(y, &chosen, fft);
        for &(lo, hi) in &self.bands {
            let s = &psd[lo..hi.min(psd.len())];
            let mean = s.iter().sum::<f64>() / s.len().max(1) as f64;
            let peak = s.iter().copied().fold(0.0, f64::max);
            f.push(mean.max(1e-300).ln());
            f.push((peak / mean.max(1e-300)).max(1e-300).ln());
        }
        // Time windows.
        let n_before_time = f.len();
        let all: Vec<f64> = chosen
            .iter()
            .flat_map(|&(a, b)| y[a..b].iter().copied())
            .collect();
        let grand = mean(&all);
        for (b, &(lo, hi)) in ranges.iter().enumerate() {
            if !sel[b] {
                continue;
            }
            let (a, z) = self.block_span(b);
            let w = (z - a) / TIME_WINDOWS as f64;
            for k in 0..TIME_WINDOWS {
                let (ta, tz) = (a + k as f64 * w, a + (k + 1) as f64 * w);
                let i0 = lo + t_s[lo..hi].partition_point(|&t| t < ta);
                let i1 = lo + t_s[lo..hi].partition_point(|&t| t < tz);
                let seg = &y[i0..i1];
                f.push(if seg.is_empty() {
                    f64::NAN
                } else {
                    mean(seg) - grand
                });
            }
        }
        // Wander: ln of the mean square of the window means (relative to the selection's).
        let nt = f.len() - n_before_time;
        let ms2 = f[n_before_time..]
            .iter()
            .filter(|v| v.is_finite())
            .map(|v| v * v)
            .sum::<f64>()
            / nt.max(1) as f64;
        f.push(ms2.max(1e-300).ln());
        // Distribution.
        let r: Vec<f64> = dist_windows(y, &chosen).concat();
        let sigma = robust_sigma(&r);
        let n = r.len().max(1) as f64;
        f.push(excess_kurtosis(&r));
        f.push(r.iter().filter(|x| x.abs() > 5.0 * sigma).count() as f64);
        f.push(r.iter().filter(|x| x.abs() > 10.0 * sigma).count() as f64);
        // KS distance on a fine histogram (bins of 0.01 sigma over +-8 sigma): O(n).
        const KS_BINS: usize = 1600;
        let mut hist = vec![0usize; KS_BINS + 2];
        for x in &r {
            let u = (x / sigma + 8.0) / 16.0 * KS_BINS as f64;
            let k = if u < 0.0 {
                0
            } else {
                (u as usize + 1).min(KS_BINS + 1)
            };
            hist[k] += 1;
        }
        let mut ks = 0.0f64;
        let mut cum = 0usize;
        for (k, h) in hist.iter().enumerate().take(KS_BINS + 1) {
            let lo = cum as f64 / n;
            cum += h;
            let hi = cum as f64 / n;
            let x = -8.0 + 16.0 * k as f64 / KS_BINS as f64;
            let p = normal_cdf(x);
            ks = ks
                .max((hi - p).abs())
                .max((lo - normal_cdf(x - 0.01)).abs());
        }
        f.push(ks);
        // Distinct values among the first 8192 samples of each selected block.
        let mut v: Vec<f64> = chosen
            .iter()
            .flat_map(|&(a, b)| raw[a..b.min(a + 8192)].iter().copied())
            .collect();
        let nv = v.len().max(1) as f64;
        v.sort_unstable_by(f64::total_cmp);
        v.dedup();
        f.push((v.len() as f64 / nv).ln());
        let mut missing = 0.0;
        for &(lo, hi) in &chosen {
            for w in t_s[lo..hi].windows(2) {
                let k = ((w[1] - w[0]) / self.dt_s).round();
                if k > 1.0 {
                    missing += k - 1.0;
                }
            }
        }
        f.push(missing);
        // Drift: ln of the window-mean variogram per lag bin.
        for v in self.drift_variogram(t_s, y, sel) {
            f.push(v.max(1e-300).ln());
        }
        f
    }

    /// Welch PSD (one-sided, (deg/s)^2/Hz) over the chosen ranges: `nseg / 2 + 1` bins.
    pub fn welch(&self, y: &[f64], chosen: &[(usize, usize)], fft: &mut Fft) -> Vec<f64> {
        let nseg = self.nseg;
        let plan = fft.plan(nseg);
        let win: Vec<f64> = (0..nseg)
            .map(|i| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / nseg as f64).cos())
            .collect();
        let wss: f64 = win.iter().map(|w| w * w).sum();
        let mut acc = vec![0.0f64; nseg / 2 + 1];
        let mut count = 0usize;
        let mut buf = vec![Complex::new(0.0, 0.0); nseg];
        // Least-squares line over i = 0..nseg: centre and scale of i.
        let ic = (nseg as f64 - 1.0) / 2.0;
        let sxx: f64 = (0..nseg).map(|i| (i as f64 - ic).powi(2)).sum();
        for &(lo, hi) in chosen {
            let mut s = lo;
            while s + nseg <= hi {
                let seg = &y[s..s + nseg];
                let m = mean(seg);
                let slope = seg
                    .iter()
                    .enumerate()
                    .map(|(i, v)| (i as f64 - ic) * (v - m))
                    .sum::<f64>()
                    / sxx;
                for (i, c) in buf.iter_mut().enumerate() {
                    *c = Complex::new((seg[i] - m - slope * (i as f64 - ic)) * win[i], 0.0);
                }
                plan.process(&mut buf);
                for (k, a) in acc.iter_mut().enumerate() {
                    let one_sided = if k == 0 || k == nseg / 2 { 1.0 } else { 2.0 };
                    *a += one_sided * buf[k].norm_sqr() * self.dt_s / wss;
                }
                count += 1;
                s += nseg / 2;
            }
        }
        for a in &mut acc {
            *a /= count.max(1) as f64;
        }
        acc
    }
}

/// FFT plans, cached by length.
pub struct Fft {
    planner: FftPlanner<f64>,
}

impl Default for Fft {
    fn default() -> Self {
        Self {
            planner: FftPlanner::new(),
        }
    }
}

impl Fft {
    /// Forward FFT of length `n`.
    pub fn plan(&mut self, n: usize) -> std::sync::Arc<dyn rustfft::Fft<f64>> {
        self.planner.plan_fft_forward(n)
    }
}

/// Overlapping AVAR pooled over `ranges` (each its own phase series, mean removed) at each
/// `m`: (AVAR, second differences summed).
pub fn pooled_avar(
    y: &[f64],
    ranges: &[(usize, usize)],
    dt_s: f64,
    ms: &[usize],
) -> Vec<(f64, usize)> {
    let mut acc = vec![(0.0f64, 0usize); ms.len()];
    for &(lo, hi) in ranges {
        let phase = crate::allan::phase_from_rate(&y[lo..hi], dt_s);
        for (j, &m) in ms.iter().enumerate() {
            if let Some((v, n)) = crate::allan::oavar_phase(&phase, dt_s, m) {
                acc[j].0 += v * n as f64;
                acc[j].1 += n;
            }
        }
    }
    acc.into_iter()
        .map(|(s, n)| (if n > 0 { s / n as f64 } else { f64::NAN }, n))
        .collect()
}

/// The `dist` features' residual of `y` on `ranges`: each range cut in [`DIST_WINDOWS`]
/// windows, each less its mean; one vector per window.
pub fn dist_windows(y: &[f64], ranges: &[(usize, usize)]) -> Vec<Vec<f64>> {
    let mut out = Vec::with_capacity(ranges.len() * DIST_WINDOWS);
    for &(lo, hi) in ranges {
        let n = hi - lo;
        for k in 0..DIST_WINDOWS {
            let (a, b) = (lo + n * k / DIST_WINDOWS, lo + n * (k + 1) / DIST_WINDOWS);
            let m = mean(&y[a..b]);
            out.push(y[a..b].iter().map(|x| x - m).collect());
        }
    }
    out
}

/// Excess kurtosis `m4 / m2^2 - 3` of values with mean 0 (0 when they are constant).
pub fn excess_kurtosis(r: &[f64]) -> f64 {
    let n = r.len().max(1) as f64;
    let m2 = r.iter().map(|x| x * x).sum::<f64>() / n;
    let m4 = r.iter().map(|x| x.powi(4)).sum::<f64>() / n;
    if m2 > 0.0 {
        m4 / (m2 * m2) - 3.0
    } else {
        0.0
    }
}

/// Mean (0 when empty).
pub fn mean(x: &[f64]) -> f64 {
    if x.is_empty() {
        0.0
    } else {
        x.iter().sum::<f64>() / x.len() as f64
    }
}

/// Median (NaN when empty).
pub fn median(x: &[f64]) -> f64 {
    quantile(x, 0.5)
}

/// Quantile `p` with linear interpolation (NaN when empty; NaNs dropped).
pub fn quantile(x: &[f64], p: f64) -> f64 {
    let mut v: Vec<f64> = x.iter().copied().filter(|v| !v.is_nan()).collect();
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let h = p.clamp(0.0, 1.0) * (v.len() - 1) as f64;
    let (i, fr) = (h.floor() as usize, h - h.floor());
    if i + 1 < v.len() {
        v[i] + fr * (v[i + 1] - v[i])
    } else {
        v[i]
    }
}

/// 1.4826 times the median absolute value (the standard deviation when that is 0).
pub fn robust_sigma(r: &[f64]) -> f64 {
    let mut a: Vec<f64> = r.iter().map(|x| x.abs()).filter(|x| !x.is_nan()).collect();
    if a.is_empty() {
        return 1e-300;
    }
    let mid = a.len() / 2;
    let s = 1.4826 * *a.select_nth_unstable_by(mid, f64::total_cmp).1;
    if s > 0.0 {
        s
    } else {
        let m2 = r.iter().map(|x| x * x).sum::<f64>() / r.len().max(1) as f64;
        m2.sqrt().max(1e-300)
    }
}

/// Standard normal CDF.
pub fn normal_cdf(x: f64) -> f64 {
    0.5 * (1.0 + statrs::function::erf::erf(x / std::f64::consts::SQRT_2))
}

/// Median and spread of each feature over simulations (`sims[seed][feature]`). The time
/// windows' spreads are pooled (root mean variance over the windows): with few simulations
/// a per-window spread is too noisy for drift processes.
pub fn stats(defs: &[Def], sims: &[&Vec<f64>]) -> Vec<(f64, f64)> {
    let mut st = stats_raw(defs, sims);
    let tv: Vec<f64> = defs
        .iter()
        .zip(&st)
        .filter(|(d, _)| d.group == Group::Time && d.range.is_some())
        .map(|(_, s)| s.1 * s.1)
        .collect();
    if !tv.is_empty() {
        let pooled = mean(&tv).sqrt();
        for (d, s) in defs.iter().zip(st.iter_mut()) {
            if d.group == Group::Time && d.range.is_some() {
                s.1 = pooled.max(d.floor);
            }
        }
    }
    st
}

fn stats_raw(defs: &[Def], sims: &[&Vec<f64>]) -> Vec<(f64, f64)> {
    (0..defs.len())
        .map(|j| {
            let v: Vec<f64> = sims
                .iter()
                .map(|s| s[j])
                .filter(|x| x.is_finite())
                .collect();
            let med = median(&v);
            let n = v.len() as f64;
            let mu = mean(&v);
            let sd = if v.len() > 1 {
                (v.iter().map(|x| (x - mu) * (x - mu)).sum::<f64>() / (n - 1.0)).sqrt()
            } else {
                0.0
            };
            let floor = if defs[j].count {
                med.max(0.0).sqrt().max(defs[j].floor)
            } else {
                defs[j].floor
            };
            (med, sd.max(floor))
        })
        .collect()
}

/// Normalised differences `(x - median) / spread` (0 where not finite).
pub fn zscores(x: &[f64], st: &[(f64, f64)]) -> Vec<f64> {
    x.iter()
        .zip(st)
        .map(|(v, (m, s))| {
            let z = (v - m) / s;
            if z.is_finite() {
                z
            } else {
                0.0
            }
        })
        .collect()
}

/// The scalar gap: the largest over groups of the mean squared z-score in the group.
pub fn gap(defs: &[Def], z: &[f64]) -> f64 {
    group_gaps(defs, z)
        .iter()
        .map(|g| g.1)
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max)
}

/// Per-group gaps, in [`GROUPS`] order, then [`Group::Check`]'s where `defs` hold it.
pub fn group_gaps(defs: &[Def], z: &[f64]) -> Vec<(Group, f64)> {
    let check = defs.iter().any(|d| d.group == Group::Check);
    GROUPS
        .iter()
        .chain(check.then_some(&Group::Check))
        .map(|&g| {
            let v: Vec<f64> = defs
                .iter()
                .zip(z)
                .filter(|(d, _)| d.group == g)
                .map(|(_, z)| z * z)
                .collect();
            (g, mean(&v))
        })
        .collect()
}

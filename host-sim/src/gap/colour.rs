//! The record's own colour above the effects' band: a spectral shaping of the fitted
//! baseline's white-noise term, fitted on the record's fit blocks and simulated in every
//! simulation of the baseline and its candidates (issue 43: "a baseline that reproduces the
//! record").
//!
//! A real sensor's output passes a digital filter (decimation, low-pass) and its mechanics
//! may resonate: the ADIS16405's PSD falls to 0.43 of its 1-3 Hz level at 50 Hz on run 4 x
//! and rises 13-fold at 19.5-20 Hz on run 1 z. The Gaussian baseline (white, flicker,
//! random walk) is flat there, so that colour dominated the held-out gap in every round.
//!
//! # Boundary
//! Only frequencies at or above [`BOUNDARY_OF_NYQUIST`] times the Nyquist frequency are
//! shaped (4 Hz at 100 Hz): every vocabulary effect other than white noise and a line lives
//! below it (a ramp, warm-up, temperature link: below 0.01 Hz; a Gauss-Markov term of
//! `T >= 1 s` is 1/630 of its plateau at 4 Hz, the real-noise benchmark's (`T` 30 s) 0.04 %
//! of the ADIS white level there; flicker of the ADIS's 25 deg/h 0.4 % of it). Below the
//! boundary the gain is exactly 1: the shaping cannot absorb any of them. A line above the
//! boundary is not absorbed either: the gain is a running median over
//! [`MEDIAN_BINS`] Welch bins.
//!
//! # Fit
//! On the fit blocks' Welch PSD (the gap's own segment length): the gain at each bin is its
//! running median over the PSD's median in the reference band (half the boundary to the
//! boundary), where the white term alone is assumed (the baseline's level). It is used only
//! when the departure is significant: the record's shaped band cut in cells of
//! [`MEDIAN_BINS`] bins, each cell's mean ln(PSD / reference) over its spread (from the
//! differences of neighbouring cells, robust), `sum z^2` more than [`GATE_SDS`] standard
//! deviations above its chi-square mean. A white record keeps the flat baseline.
//!
//! # Simulation
//! The white term (`N / sqrt(dt)` per sample) is drawn on its own stream, transformed,
//! multiplied by the square root of the gain (linear between bins) and transformed back
//! (circular, over a power-of-two length at least the record): below the boundary its PSD
//! is the baseline's, above it the record's shape.

use super::features::{median, Fft, Layout};
use crate::sim::{flicker_times_s, flicker_unit_var, Noise};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rustfft::num_complex::Complex;
use serde::Serialize;

/// The shaped band starts at this share of the Nyquist frequency (module docs).
pub const BOUNDARY_OF_NYQUIST: f64 = 0.08;

/// Welch bins in the gain's running median and in a gate cell.
pub const MEDIAN_BINS: usize = 9;

/// The smallest power gain above the boundary, as a share of the white level.
pub const MIN_GAIN: f64 = 0.01;

/// The gate: `sum z^2` over the cells must exceed its chi-square mean by this many standard
/// deviations.
pub const GATE_SDS: f64 = 5.0;

/// The shaping of the white-noise term.
#[derive(Debug, Clone, Serialize)]
pub struct Colour {
    /// Shaped band's lower edge, Hz.
    pub boundary_hz: f64,
    /// Bin spacing of `power_gain`, Hz.
    pub df_hz: f64,
    /// The white term's power in the reference band over the fitted baseline's `2 N^2` (its
    /// ARW fitted on the short-tau Allan variance, which the colour biases): the baseline's
    /// ARW is multiplied by its square root, and kept when a candidate refits the noise.
    pub white_level: f64,
    /// Power gain |H(f)|^2 at `k df_hz`, `k = 0 ..`: 1 below `boundary_hz`.
    #[serde(skip)]
    pub power_gain: Vec<f64>,
    /// Smallest and largest power gain above the boundary, and where (Hz).
    pub min_gain: (f64, f64),
    /// See `min_gain`.
    pub max_gain: (f64, f64),
    /// The gate's statistic: `(sum z^2 - cells) / sqrt(2 cells)`.
    pub gate_sds: f64,
    /// Cells of the gate.
    pub cells: usize,
}

/// The fit's outcome: the shaping when the gate passed, and the gate's figure either way.
#[derive(Debug, Clone, Serialize)]
pub struct ColourFit {
    /// The shaping (None: the departure is not significant, the baseline stays flat).
    pub colour: Option<Colour>,
    /// The gate's statistic.
    pub gate_sds: f64,
    /// Why no shaping.
    pub detail: String,
}

/// One-sided PSD, (deg/s)^2/Hz, of the model's noise terms other than white noise at
/// `f_hz`: the flicker bank (its Gauss-Markov terms), the rate random walk and a
/// Gauss-Markov term (continuous-time forms).
pub fn other_terms_psd(n: &Noise, f_hz: f64) -> f64 {
    let w = std::f64::consts::TAU * f_hz;
    let gm = |var: f64, t: f64| 4.0 * var * t / (1.0 + (w * t).powi(2));
    let mut s = 0.0;
    if n.bias_instability_dps > 0.0 {
        let (lo, hi) = (n.flicker_tau_min_s, n.flicker_tau_max_s);
        let times = flicker_times_s(lo, hi);
        let var = flicker_unit_var(&times, lo, hi) * n.bias_instability_dps.powi(2);
        s += times.iter().map(|&t| gm(var, t)).sum::<f64>();
    }
    if n.rrw_dps_per_s_rthz > 0.0 && f_hz > 0.0 {
        s += 2.0 * n.rrw_dps_per_s_rthz.powi(2) / (w * w);
    }
    if n.gm_sigma_dps > 0.0 && n.gm_tau_s > 0.0 {
        s += gm(n.gm_sigma_dps.powi(2), n.gm_tau_s);
    }
    s
}

impl Colour {
    /// Fits the shaping on the fit blocks `ranges` of `y` (period `layout.dt_s`) against the
    /// baseline's noise terms `noise`: the white level in the reference band (half the
    /// boundary to the boundary) and the shape above the boundary, both of the record's
    /// PSD less the model's other terms.
    pub fn fit(
        y: &[f64],
        ranges: &[(usize, usize)],
        layout: &Layout,
        noise: &Noise,
        fft: &mut Fft,
    ) -> ColourFit {
        let psd = layout.welch(y, ranges, fft);
        let df = layout.freq_hz(1);
        let nyq = 0.5 / layout.dt_s;
        let boundary = BOUNDARY_OF_NYQUIST * nyq;
        let k_b = (boundary / df).ceil() as usize;
        let k_r = (0.5 * boundary / df).floor().max(1.0) as usize;
        let none = |gate: f64, detail: String| ColourFit {
            colour: None,
            gate_sds: gate,
            detail,
        };
        let white = 2.0 * noise.arw_dps_per_rthz.powi(2);
        if k_b + 2 * MEDIAN_BINS >= psd.len() || k_b <= k_r + 2 || white.is_nan() || white <= 0.0 {
            return none(
                f64::NAN,
                "too few Welch bins above the boundary, or no white noise, to fit a shape".into(),
            );
        }
        let other: Vec<f64> = (0..psd.len())
            .map(|k| other_terms_psd(noise, k as f64 * df))
            .collect();
        // The record's white level: its PSD less the other terms in the reference band.
        let less: Vec<f64> = psd.iter().zip(&other).map(|(p, o)| p - o).collect();
        let level = median(&less[k_r..k_b]) / white;
        if !(level.is_finite() && level > 0.0) {
            return none(f64::NAN, "no white power in the reference band".into());
        }
        let ln_r: Vec<f64> = psd
            .iter()
            .zip(&other)
            .map(|(p, o)| (p.max(1e-300) / (white * level + o)).ln())
            .collect();
        // Gate: cells of MEDIAN_BINS bins from the boundary up.
        let cells: Vec<f64> = ln_r[k_b..]
            .chunks_exact(MEDIAN_BINS)
            .map(|c| c.iter().sum::<f64>() / MEDIAN_BINS as f64)
            .collect();
        let diffs: Vec<f64> = cells.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
        let sd = 1.4826 * median(&diffs) / std::f64::consts::SQRT_2;
        if cells.len() < 4 || !(sd.is_finite() && sd > 0.0) {
            return none(f64::NAN, "too few cells above the boundary".into());
        }
        let n = cells.len() as f64;
        let chi2: f64 = cells.iter().map(|c| (c / sd).powi(2)).sum();
        let gate = (chi2 - n) / (2.0 * n).sqrt();
        if gate.is_nan() || gate <= GATE_SDS {
            return none(
                gate,
                format!("the PSD above {boundary:.3} Hz departs from the baseline's by {gate:.1} sd (<= {GATE_SDS}): white baseline kept"),
            );
        }
        // Power gain of the white term: `level` below the boundary; above, the running
        // median of the record's PSD less the other terms over the white level.
        let shape: Vec<f64> = less.iter().map(|v| v / white).collect();
        let half = MEDIAN_BINS / 2;
        let mut power_gain = vec![1.0; psd.len()];
        for (k, g) in power_gain.iter_mut().enumerate().skip(k_b) {
            let lo = k.saturating_sub(half);
            let hi = (k + half + 1).min(psd.len());
            *g = (median(&shape[lo..hi]) / level).max(MIN_GAIN);
        }
        let (mut min_gain, mut max_gain) = ((f64::INFINITY, 0.0), (0.0, 0.0));
        for (k, &g) in power_gain.iter().enumerate().skip(k_b) {
            if g < min_gain.0 {
                min_gain = (g, k as f64 * df);
            }
            if g > max_gain.0 {
                max_gain = (g, k as f64 * df);
            }
        }
        ColourFit {
            colour: Some(Colour {
                boundary_hz: k_b as f64 * df,
                df_hz: df,
                white_level: level,
                power_gain,
                min_gain,
                max_gain,
                gate_sds: gate,
                cells: cells.len(),
            }),
            gate_sds: gate,
            detail: String::new(),
        }
    }

    /// The power gain at `f_hz` (linear between bins; the last bin's beyond).
    pub fn gain_at(&self, f_hz: f64) -> f64 {
        let x = (f_hz.abs() / self.df_hz).max(0.0);
        let k = x.floor() as usize;
        let g = &self.power_gain;
        if k + 1 >= g.len() {
            return g.last().copied().unwrap_or(1.0);
        }
        let w = x - k as f64;
        g[k] + w * (g[k + 1] - g[k])
    }

    /// The shaped term's variance over the white term's: the gain's mean over the bins of
    /// [`Colour::shaped_white`]'s transform for `n` samples of period `dt_s`.
    pub fn variance_gain(&self, n: usize, dt_s: f64) -> f64 {
        let len = n.max(2).next_power_of_two();
        let df = 1.0 / (len as f64 * dt_s);
        (0..len)
            .map(|j| self.gain_at(j.min(len - j) as f64 * df))
            .sum::<f64>()
            / len as f64
    }

    /// `n` samples of white noise of standard deviation `sigma_dps` shaped by the gain,
    /// sample period `dt_s`, from `seed`'s own stream.
    pub fn shaped_white(&self, sigma_dps: f64, n: usize, dt_s: f64, seed: u64) -> Vec<f64> {
        let len = n.max(2).next_power_of_two();
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed ^ 0x00C0_10C0_43A5_F00D);
        let mut buf: Vec<Complex<f64>> = (0..len)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut rng);
                Complex::new(sigma_dps * z, 0.0)
            })
            .collect();
        let mut planner = rustfft::FftPlanner::<f64>::new();
        planner.plan_fft_forward(len).process(&mut buf);
        let df = 1.0 / (len as f64 * dt_s);
        for (j, c) in buf.iter_mut().enumerate() {
            let k = j.min(len - j);
            *c *= self.gain_at(k as f64 * df).sqrt();
        }
        planner.plan_fft_inverse(len).process(&mut buf);
        buf.iter().take(n).map(|c| c.re / len as f64).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    /// `n` samples at 100 Hz: white noise of sd 0.3 deg/s, through a two-pole resonator at
    /// 20 Hz (`resonate`) or as it is.
    fn record(n: usize, seed: u64, resonate: bool) -> Vec<f64> {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let (r, w) = (0.9f64, std::f64::consts::TAU * 20.0 / 100.0);
        let (a1, a2) = (2.0 * r * w.cos(), -r * r);
        let (mut y1, mut y2) = (0.0, 0.0);
        (0..n)
            .map(|_| {
                let e: f64 = StandardNormal.sample(&mut rng);
                let e = 0.3 * e;
                if !resonate {
                    return e;
                }
                let y = e + a1 * y1 + a2 * y2;
                y2 = y1;
                y1 = y;
                y
            })
            .collect()
    }

    fn white_model(sd_dps: f64, dt_s: f64) -> Noise {
        Noise {
            arw_dps_per_rthz: sd_dps * dt_s.sqrt(),
            ..Default::default()
        }
    }

    fn fit_of(y: &[f64]) -> (ColourFit, Layout) {
        let dt = 0.01;
        let t: Vec<f64> = (0..y.len()).map(|k| k as f64 * dt).collect();
        let layout = Layout::new(&t, dt).expect("layout");
        let ranges: Vec<(usize, usize)> = layout.ranges(&t).into_iter().step_by(2).collect();
        let f = Colour::fit(
            y,
            &ranges,
            &layout,
            &white_model(0.3, dt),
            &mut Fft::default(),
        );
        (f, layout)
    }

    /// White records keep the white baseline: the gate does not pass on any of 8.
    #[test]
    fn white_noise_keeps_a_white_baseline() {
        for seed in 0..8 {
            let (f, _) = fit_of(&record(60_000, 10 + seed, false));
            assert!(f.colour.is_none(), "seed {seed}: gate {}", f.gate_sds);
            assert!(f.gate_sds < GATE_SDS, "{}", f.gate_sds);
        }
    }

    /// A resonance above the boundary is found, the gain is 1 below the boundary, and the shaped white noise reproduces the record's PSD above
    /// it within 15 % in every 1-Hz band from 4 to 49 Hz.
    #[test]
    fn a_resonance_is_fitted_and_reproduced() {
        let y = record(60_000, 3, true);
        let (f, layout) = fit_of(&y);
        let c = f.colour.expect("the gate passes on a resonance");
        assert!((c.boundary_hz - 4.0).abs() < 0.2, "{}", c.boundary_hz);
        assert!(
            (c.max_gain.1 - 20.0).abs() < 1.5,
            "peak at {} Hz",
            c.max_gain.1
        );
        let below: Vec<f64> = (0..40).map(|k| c.gain_at(k as f64 * 0.1)).collect();
        assert!(below.iter().all(|g| *g == 1.0), "{below:?}");
        // The record's white level is its PSD below the boundary over 2 N^2.
        let mut fft = Fft::default();
        let all = [(0, y.len())];
        let real = layout.welch(&y, &all, &mut fft);
        let sim = c.shaped_white(0.3 * c.white_level.sqrt(), y.len(), 0.01, 99);
        let shaped = layout.welch(&sim, &all, &mut fft);
        let df = layout.freq_hz(1);
        for lo in 4..49 {
            let band = |p: &[f64]| -> f64 {
                let (a, b) = ((lo as f64 / df) as usize, ((lo + 1) as f64 / df) as usize);
                p[a..b].iter().sum::<f64>()
            };
            let r = band(&shaped) / band(&real);
            assert!((r - 1.0).abs() < 0.15, "{lo}-{} Hz: {r}", lo + 1);
        }
    }
}

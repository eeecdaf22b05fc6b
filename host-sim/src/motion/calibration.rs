//! What the static calibration runs show about the user's gyro, measured before training
//! (`identify --preset motion`), printed beside the gyro file's values and folded into
//! the image: the unit is never the datasheet.
//!
//! Per run (every sample at rest, from power-on):
//! - **rate**, Hz: from `t_s` (the mean step with the gaps left out, so a hole does not
//!   move it, as [`Series::sample_period_s`]; `identify` reports the gaps);
//! - **white noise**: from first differences, `var(diff) / 2` = one sample's white-noise
//!   plus quantization variance (drift and slow noise cancel in a difference); as a density
//!   `sqrt((var - q^2/12) / rate)`, deg/sqrt(h);
//! - **quantum**: the smallest step between distinct output values, when every value is a
//!   multiple of it (else none: a floating-point output);
//! - **drift range**: the least and largest 10-s mean of the rate, deg/h (white noise
//!   averages down to 0.08 deg/h for the E-Core);
//! - **Allan deviation**: non-overlapping, at octave cluster times from 1 s; its minimum
//!   (the bias-instability floor, 0.664 B) and where it is.
//!
//! For the family: the median, least and largest noise density; the largest |drift|.
//! The model the image carries is fitted on the runs ([`crate::gyro_fit`]: white noise :=
//! the family's median; the drift bound := the larger of the file's and [`DRIFT_MARGIN`]
//! times the largest |drift| seen). Where a measured value and the file's disagree beyond
//! [`DISAGREE_FACTOR`] (noise) or 1 % (rate), a warning says so ([`warnings`]: a rate in
//! rad/s read as deg/s shows as noise 57x below the file's).

use crate::identify::series::Series;
use anyhow::{bail, Result};
use fog_core::sensor::SensorConfig;
use serde::Serialize;

/// The image's drift bound is at least this many times the largest |10-s mean drift| of
/// the calibration runs (ASSUMED: 1.5, room for a unit beyond the runs' spread).
pub const DRIFT_MARGIN: f64 = 1.5;

/// The image's drift bound, deg/h: [`DRIFT_MARGIN`] times the runs' largest |drift|, at
/// least the gyro file's bound `file_bound_dps`.
pub fn drift_bound_dph(cal: &Calibration, file_bound_dps: f64) -> f64 {
    (cal.drift_abs_max_dph * DRIFT_MARGIN).max(file_bound_dps * 3600.0)
}

/// A measured noise density this many times above or below the gyro file's is warned
/// about (ASSUMED: 2; a family spreads 0.5x to 3x around its nominal).
pub const DISAGREE_FACTOR: f64 = 2.0;
/// Averaging time of the drift range, s.
pub const DRIFT_MEAN_S: f64 = 10.0;

/// What one calibration run shows.
#[derive(Debug, Clone, Serialize)]
pub struct RunStats {
    /// The record.
    pub name: String,
    /// Samples.
    pub samples: usize,
    /// Sample rate from `t_s`, Hz.
    pub rate_hz: f64,
    /// One sample's white-noise plus quantization standard deviation, deg/s.
    pub sample_sigma_dps: f64,
    /// White-noise density (quantization taken out), deg/sqrt(h).
    pub noise_deg_rth: f64,
    /// Output step, deg/s (`None`: not quantized, or not measurable).
    pub quantum_dps: Option<f64>,
    /// Least 10-s mean of the rate, deg/h.
    pub drift_min_dph: f64,
    /// Largest 10-s mean of the rate, deg/h.
    pub drift_max_dph: f64,
    /// Allan deviation at 1 s, deg/h.
    pub adev_1s_dph: f64,
    /// Least Allan deviation over the octave cluster times, deg/h.
    pub adev_min_dph: f64,
    /// Where it is, s.
    pub adev_min_tau_s: f64,
}

/// The family: every run and what they share.
#[derive(Debug, Clone, Serialize)]
pub struct Calibration {
    /// Per run.
    pub runs: Vec<RunStats>,
    /// Median white-noise density, deg/sqrt(h).
    pub noise_median_deg_rth: f64,
    /// Least, deg/sqrt(h).
    pub noise_min_deg_rth: f64,
    /// Largest, deg/sqrt(h).
    pub noise_max_deg_rth: f64,
    /// Largest |10-s mean| over the runs, deg/h.
    pub drift_abs_max_dph: f64,
    /// Median rate, Hz.
    pub rate_hz: f64,
}

/// Measures one run.
pub fn measure_run(s: &Series) -> Result<RunStats> {
    let n = s.rate_dps.len();
    let rate_hz = 1.0 / s.sample_period_s();
    if n < 16 {
        bail!(
            "{}: {n} samples, too short to calibrate on (at least 16)",
            s.name
        );
    }
    // 10-s means (a record shorter than 20 s: halves of it).
    let per_mean = ((DRIFT_MEAN_S * rate_hz).round().max(1.0) as usize).min(n / 2);
    let x: Vec<f64> = s.rate_dps.iter().map(|&r| f64::from(r)).collect();
    let diffs = x.windows(2).map(|w| w[1] - w[0]);
    let (sum, sum2) = diffs.fold((0.0, 0.0), |(a, b), d| (a + d, b + d * d));
    let m = (n - 1) as f64;
    let var_diff = (sum2 - sum * sum / m) / (m - 1.0);
    let sample_var = var_diff / 2.0;
    let quantum_dps = quantum(&x);
    let q2 = quantum_dps.map_or(0.0, |q| q * q / 12.0);
    let white_var = (sample_var - q2).max(0.0);
    let noise_deg_rth = (white_var / rate_hz).sqrt() * 60.0;
    let means: Vec<f64> = x
        .chunks_exact(per_mean)
        .map(|c| c.iter().sum::<f64>() / c.len() as f64 * 3600.0)
        .collect();
    let drift_min_dph = means.iter().copied().fold(f64::INFINITY, f64::min);
    let drift_max_dph = means.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let (mut adev_min, mut adev_min_tau, mut adev_1s) = (f64::INFINITY, f64::NAN, f64::NAN);
    let mut tau = 1.0;
    loop {
        let per = (tau * rate_hz).round() as usize;
        if per == 0 || n / per < 9 {
            break;
        }
        let a = adev(&x, per) * 3600.0;
        if tau == 1.0 {
            adev_1s = a;
        }
        if a < adev_min {
            adev_min = a;
            adev_min_tau = tau;
        }
        tau *= 2.0;
    }
    Ok(RunStats {
        name: s.name.clone(),
        samples: n,
        rate_hz,
        sample_sigma_dps: sample_var.sqrt(),
        noise_deg_rth,
        quantum_dps,
        drift_min_dph,
        drift_max_dph,
        adev_1s_dph: adev_1s,
        adev_min_dph: adev_min,
        adev_min_tau_s: adev_min_tau,
    })
}

/// Non-overlapping Allan deviation of `x` at clusters of `per` samples.
fn adev(x: &[f64], per: usize) -> f64 {
    let means: Vec<f64> = x
        .chunks_exact(per)
        .map(|c| c.iter().sum::<f64>() / per as f64)
        .collect();
    let k = means.len();
    if k < 2 {
        return f64::NAN;
    }
    let s: f64 = means.windows(2).map(|w| (w[1] - w[0]).powi(2)).sum();
    (0.5 * s / (k - 1) as f64).sqrt()
}

/// The output's step: the least gap between distinct values, when 99 % of the values are
/// within 1 % of a step of a multiple of it.
fn quantum(x: &[f64]) -> Option<f64> {
    let mut v: Vec<f64> = x.iter().copied().filter(|r| r.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    v.dedup();
    let step = v
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .fold(f64::INFINITY, f64::min);
    if !step.is_finite() || v.len() < 3 {
        return None;
    }
    let on_grid = v
        .iter()
        .filter(|r| {
            let k = *r / step;
            (k - k.round()).abs() < 0.01
        })
        .count();
    (on_grid as f64 >= 0.99 * v.len() as f64).then_some(step)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Measures every run.
pub fn measure(records: &[Series]) -> Result<Calibration> {
    let mut runs = Vec::with_capacity(records.len());
    for s in records {
        runs.push(measure_run(s)?);
    }
    if runs.is_empty() {
        bail!("no calibration run");
    }
    let noise: Vec<f64> = runs.iter().map(|r| r.noise_deg_rth).collect();
    Ok(Calibration {
        noise_median_deg_rth: median(noise.clone()),
        noise_min_deg_rth: noise.iter().copied().fold(f64::INFINITY, f64::min),
        noise_max_deg_rth: noise.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        drift_abs_max_dph: runs
            .iter()
            .map(|r| r.drift_min_dph.abs().max(r.drift_max_dph.abs()))
            .fold(0.0, f64::max),
        rate_hz: median(runs.iter().map(|r| r.rate_hz).collect()),
        runs,
    })
}

/// Where the runs and the gyro file's sensor `file` disagree (warnings: the image carries the
/// runs' values, [`crate::gyro_fit`]). Refuses a family without measurable noise (every run
/// constant).
pub fn warnings(file: &SensorConfig, cal: &Calibration) -> Result<Vec<String>> {
    let mut warnings = Vec::new();
    let file_noise = f64::from(file.noise_density_dps_rthz) * 60.0;
    let med = cal.noise_median_deg_rth;
    if !(med > 0.0 && med.is_finite() && cal.noise_min_deg_rth > 0.0) {
        bail!(
            "the calibration runs show no white noise (median {med} deg/sqrt(h)): a constant or saturated output cannot calibrate the filter"
        );
    }
    if med > DISAGREE_FACTOR * file_noise || med * DISAGREE_FACTOR < file_noise {
        warnings.push(format!(
            "white noise measured {med:.4} deg/sqrt(h) (median of {} runs) is {:.2}x the gyro file's {file_noise:.4}: check the rate column's unit and scale (rad/s read as deg/s shows 57x below); the image carries the measured value",
            cal.runs.len(),
            med / file_noise
        ));
    }
    for r in &cal.runs {
        if (r.rate_hz - f64::from(file.sample_rate_hz)).abs()
            > f64::from(fog_core::image::RATE_TOLERANCE * file.sample_rate_hz)
        {
            warnings.push(format!(
                "{}: sample rate {:.3} Hz, the gyro file says {} Hz",
                r.name, r.rate_hz, file.sample_rate_hz
            ));
        }
        if let (Some(q), true) = (r.quantum_dps, file.quantum_dps > 0.0) {
            let ratio = q / f64::from(file.quantum_dps);
            if (ratio - ratio.round()).abs() > 0.01 || ratio.round() < 1.0 {
                warnings.push(format!(
                    "{}: output step {q:.3e} deg/s is not a multiple of the gyro file's quantum {:.3e}",
                    r.name, file.quantum_dps
                ));
            }
        }
    }
    let bound_dph = drift_bound_dph(cal, f64::from(file.drift_bound_dps));
    if cal.drift_abs_max_dph > f64::from(file.drift_bound_dps) * 3600.0 {
        warnings.push(format!(
            "drift reaches {:.1} deg/h in the runs, beyond the gyro file's bound {:.1} deg/h: the image's bound is {bound_dph:.1} deg/h ({DRIFT_MARGIN} x the runs')",
            cal.drift_abs_max_dph,
            f64::from(file.drift_bound_dps) * 3600.0
        ));
    }
    Ok(warnings)
}

/// The table printed by `identify`: each run, the family, and the file's values beside.
pub fn table(cal: &Calibration, file: &SensorConfig) -> String {
    let mut s = String::from(
        "calibration run                rate Hz  noise deg/rt(h)  quantum deg/s  drift 10-s min..max deg/h  ADEV 1 s deg/h  ADEV min deg/h @ tau s\n",
    );
    for r in &cal.runs {
        s += &format!(
            "{:<30} {:>7.2}  {:>15.4}  {:>13}  {:>11.1} .. {:>11.1}  {:>14.3}  {:>8.3} @ {:.0}\n",
            short(&r.name),
            r.rate_hz,
            r.noise_deg_rth,
            r.quantum_dps.map_or("-".into(), |q| format!("{q:.3e}")),
            r.drift_min_dph,
            r.drift_max_dph,
            r.adev_1s_dph,
            r.adev_min_dph,
            r.adev_min_tau_s
        );
    }
    s += &format!(
        "family ({} runs)               {:>7.2}  {:.4} (median; {:.4} .. {:.4})  |drift| up to {:.1} deg/h\n",
        cal.runs.len(),
        cal.rate_hz,
        cal.noise_median_deg_rth,
        cal.noise_min_deg_rth,
        cal.noise_max_deg_rth,
        cal.drift_abs_max_dph
    );
    s += &format!(
        "gyro file                      {:>7.2}  {:.4}  quantum {:.3e}  drift bound {:.1} deg/h",
        file.sample_rate_hz,
        f64::from(file.noise_density_dps_rthz) * 60.0,
        file.quantum_dps,
        f64::from(file.drift_bound_dps) * 3600.0
    );
    s
}

fn short(name: &str) -> String {
    let base = std::path::Path::new(name)
        .file_name()
        .map_or(name.to_string(), |f| f.to_string_lossy().into_owned());
    if base.len() > 30 {
        format!("...{}", &base[base.len() - 27..])
    } else {
        base
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series(rate_hz: f64, n: usize, f: impl Fn(usize) -> f32) -> Series {
        Series {
            name: "run".into(),
            t_s: (0..n).map(|k| k as f64 / rate_hz).collect(),
            rate_dps: (0..n).map(f).collect(),
            drift_dps: None,
            temp_c: None,
            ..Default::default()
        }
    }

    /// Deterministic unit normal deviates (the simulator's generator and distribution).
    fn normals(seed: u64, n: usize) -> Vec<f64> {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        (0..n)
            .map(|_| rng.sample(rand_distr::StandardNormal))
            .collect()
    }

    #[test]
    fn measures_noise_quantum_drift_and_rate() {
        let (hz, n) = (50.0f64, 50 * 600);
        let q = 60.0 / 32768.0;
        // 0.2 deg/sqrt(h) at 50 Hz, drift 40 deg/h rising to 55.
        let sigma = 0.2 / 60.0 * hz.sqrt();
        let z = normals(5, n);
        let s = series(hz, n, |k| {
            let drift = (40.0 + 15.0 * k as f64 / n as f64) / 3600.0;
            (((drift + sigma * z[k]) / q).round() * q) as f32
        });
        let r = measure_run(&s).expect("test");
        assert!((r.rate_hz - 50.0).abs() < 1e-9);
        assert!(
            (r.noise_deg_rth / 0.2 - 1.0).abs() < 0.03,
            "{}",
            r.noise_deg_rth
        );
        let got_q = r.quantum_dps.expect("quantized");
        assert!((got_q / q - 1.0).abs() < 1e-4, "{got_q}");
        // The 10-s means carry white noise of sigma / sqrt(500) (3.8 deg/h): the range is
        // the drift's widened by about 2.5 of those at each end.
        let tol = 3.5 * sigma / (500.0f64).sqrt() * 3600.0;
        assert!((r.drift_min_dph - 40.0).abs() < tol, "{}", r.drift_min_dph);
        assert!((r.drift_max_dph - 55.0).abs() < tol, "{}", r.drift_max_dph);
        assert!(r.adev_min_dph < r.adev_1s_dph);
    }

    #[test]
    fn folds_the_family_into_the_sensor_and_warns_on_a_wrong_unit() {
        let file = SensorConfig::ECORE_2000;
        let mk = |noise: f64, drift_dph: f64, seed: u64| {
            let z = normals(seed, 100 * 300);
            let sigma = noise / 60.0 * 10.0;
            measure_run(&series(100.0, 100 * 300, |k| {
                (drift_dph / 3600.0 + sigma * z[k]) as f32
            }))
            .expect("test")
        };
        let runs = vec![mk(0.05, 10.0, 1), mk(0.1, -70.0, 2), mk(0.2, 20.0, 3)];
        let cal = Calibration {
            noise_median_deg_rth: median(runs.iter().map(|r| r.noise_deg_rth).collect()),
            noise_min_deg_rth: runs.iter().map(|r| r.noise_deg_rth).fold(9.0, f64::min),
            noise_max_deg_rth: runs.iter().map(|r| r.noise_deg_rth).fold(0.0, f64::max),
            drift_abs_max_dph: 70.0,
            rate_hz: 100.0,
            runs,
        };
        let w = warnings(&file, &cal).expect("test");
        assert!((cal.noise_median_deg_rth / 0.1 - 1.0).abs() < 0.05);
        assert!(w.iter().any(|l| l.contains("105.0 deg/h")), "{w:?}");
        assert!(w.iter().any(|l| l.contains("drift reaches 70.0")), "{w:?}");
        assert!(!w.iter().any(|l| l.contains("white noise")), "{w:?}");
        // The same runs read in rad/s as deg/s: noise 57x below the file's.
        let mut rad = cal.clone();
        rad.noise_median_deg_rth /= 57.3;
        rad.noise_min_deg_rth /= 57.3;
        rad.noise_max_deg_rth /= 57.3;
        let w = warnings(&file, &rad).expect("test");
        assert!(w.iter().any(|l| l.contains("rad/s")), "{w:?}");
    }
}

//! The fitted model's two least certain numbers, tuned on vehicle records with truth
//! (`identify --tune-on`), as the baselines get their q from the same vehicles.
//!
//! The calibration runs fit the model ([`crate::gyro_fit`]) but measure two things poorly:
//! the unit-to-unit spread of the temperature links (a run's own link is confounded with its
//! warm-up, so the runs' scatter overstates it) and the Gauss-Markov sigmas at the drift's
//! long times (the runs' Allan taus end at an eighth of their length), nor the terms'
//! correlation time. They are scaled here on a grid ([`MARKOV_TAUS_S`] x [`LINK_SCALES`] x
//! [`MARKOV_SCALES`], every triple), by the least mean heading RMS
//! over the vehicles with the filter's own stillness test; the pick is what the image
//! carries. Nothing is chosen on line.

use crate::nav::{self, NavRecord};
use anyhow::Result;
use fog_core::gyro_model::{MarkovTerm, MAX_MARKOV};
use fog_core::image::Image;
use serde::Serialize;

/// Scales of the links' prior spread tried (1: as fitted).
pub const LINK_SCALES: [f32; 4] = [0.1, 0.3, 0.6, 1.0];
/// Scales of the Gauss-Markov sigmas tried (1: as fitted).
pub const MARKOV_SCALES: [f32; 4] = [1.0, 2.0, 3.0, 5.0];
/// Correlation times of the Gauss-Markov terms tried, s: `None` as fitted, else every
/// term's variance in one term of this correlation time. The runs' Allan taus end at an
/// eighth of their length, after their deterministic part took the slowest wander out:
/// they cannot tell a 30-s term from flicker that lasts through a drive, and a correction
/// learned at a stop that decays in 30 s of driving is lost when the drift is flicker
/// (docs/drift-filter.md, the Gauss-Markov terms' correlation time).
pub const MARKOV_TAUS_S: [Option<f32>; 2] = [None, Some(3000.0)];

/// One grid point and its score.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Candidate {
    /// Scale of the links' spread.
    pub link_scale: f32,
    /// Scale of the Gauss-Markov sigmas.
    pub markov_scale: f32,
    /// Correlation time of the Gauss-Markov terms, s (`None`: as fitted).
    pub markov_tau_s: Option<f32>,
    /// Mean heading RMS over the vehicles, deg.
    pub heading_rms_deg: f64,
}

/// What the tuning picked.
#[derive(Debug, Clone, Serialize)]
pub struct Tuning {
    /// The pick (least mean heading RMS).
    pub picked: Candidate,
    /// Every grid point, in grid order.
    pub grid: Vec<Candidate>,
    /// Vehicles scored.
    pub vehicles: usize,
    /// The pick at an end of a grid (the grid may not bracket the optimum).
    pub at_grid_end: bool,
}

/// `image` with the links' spread times `link_scale` and the Gauss-Markov sigmas times
/// `markov_scale`.
pub fn scaled(image: &Image, link_scale: f32, markov_scale: f32) -> Image {
    let mut im = *image;
    im.model.temp_dps_per_c.sigma *= link_scale;
    im.model.temp_rate_dps_per_c_per_s.sigma *= link_scale;
    for t in &mut im.model.markov {
        t.sigma_dps *= markov_scale;
    }
    im
}

/// `image` with every Gauss-Markov term's variance in one term of correlation time `tau_s`
/// (the total variance kept; `None`: unchanged).
pub fn retimed(image: &Image, tau_s: Option<f32>) -> Image {
    let mut im = *image;
    if let Some(tau_s) = tau_s {
        let var: f32 = im
            .model
            .markov
            .iter()
            .map(|t| t.sigma_dps * t.sigma_dps)
            .sum();
        if var > 0.0 {
            im.model.markov = [MarkovTerm::default(); MAX_MARKOV];
            im.model.markov[0] = MarkovTerm {
                sigma_dps: var.sqrt(),
                tau_s,
            };
        }
    }
    im
}

/// Mean heading RMS, deg, of `image` over `val` (the filter's own test).
pub fn mean_heading_rms(image: &Image, val: &[NavRecord]) -> Result<f64> {
    anyhow::ensure!(!val.is_empty(), "no vehicle record to score on");
    let mut sum = 0.0;
    for v in val {
        let (drift, _) = run_image(image, v)?;
        sum += nav::score_drift(v, &drift).heading_rms_deg;
    }
    Ok(sum / val.len() as f64)
}

/// Tunes the two scales and the Gauss-Markov correlation time of `image` on `val` (module
/// docs); returns the tuned image.
pub fn tune(image: &Image, val: &[NavRecord]) -> Result<(Image, Tuning)> {
    let mut grid = Vec::new();
    for &markov_tau_s in &MARKOV_TAUS_S {
        let timed = retimed(image, markov_tau_s);
        for &link_scale in &LINK_SCALES {
            for &markov_scale in &MARKOV_SCALES {
                let h = mean_heading_rms(&scaled(&timed, link_scale, markov_scale), val)?;
                grid.push(Candidate {
                    link_scale,
                    markov_scale,
                    markov_tau_s,
                    heading_rms_deg: h,
                });
            }
        }
    }
    let picked = *grid
        .iter()
        .min_by(|a, b| a.heading_rms_deg.total_cmp(&b.heading_rms_deg))
        .ok_or_else(|| anyhow::anyhow!("empty tuning grid"))?;
    // The grids' open ends: a smaller links' spread, larger Gauss-Markov sigmas.
    let at_grid_end = picked.link_scale == LINK_SCALES[0]
        || picked.markov_scale == MARKOV_SCALES[MARKOV_SCALES.len() - 1];
    Ok((
        scaled(
            &retimed(image, picked.markov_tau_s),
            picked.link_scale,
            picked.markov_scale,
        ),
        Tuning {
            picked,
            grid,
            vehicles: val.len(),
            at_grid_end,
        },
    ))
}

/// One line on the pick.
pub fn describe(t: &Tuning) -> String {
    format!(
        "tuned on {} vehicle records: links' spread x{}, Gauss-Markov sigmas x{}{} (mean heading RMS {:.4} deg{})",
        t.vehicles,
        t.picked.link_scale,
        t.picked.markov_scale,
        t.picked
            .markov_tau_s
            .map_or(String::new(), |tau| format!(" in one term of {tau} s")),
        t.picked.heading_rms_deg,
        if t.at_grid_end {
            "; at the grid's end: the grid may not bracket the optimum"
        } else {
            ""
        }
    )
}

/// `image`'s filter over `rec` from power-on, its own test: drift estimate, deg/s, and
/// still flag per sample (a refused sample: drift 0, not still).
pub fn run_image(image: &Image, rec: &NavRecord) -> Result<(Vec<f64>, Vec<bool>)> {
    let mut f = image
        .filter()
        .map_err(|e| anyhow::anyhow!("image: {}", super::filter_error_words(&e)))?;
    anyhow::ensure!(
        rec.rate_dps.len() == rec.len() && rec.temp_c.as_ref().is_none_or(|t| t.len() == rec.len()),
        "record columns of different lengths"
    );
    let out = super::run_rows(
        &mut f,
        rec.rate_dps.iter().enumerate().map(|(k, &rate)| {
            let temp = rec
                .temp_c
                .as_ref()
                .and_then(|t| t.get(k))
                .map_or(f32::NAN, |&t| t as f32);
            (rate as f32, temp, None)
        }),
    );
    Ok((
        out.iter().map(|o| f64::from(o.drift_dps)).collect(),
        out.iter().map(|o| o.still).collect(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scaled_and_retimed_change_what_they_say_and_nothing_else() {
        let mut im = crate::motion::untrained(&fog_core::sensor::SensorConfig::ECORE_2000);
        im.model.temp_dps_per_c.sigma = 1e-4;
        im.model.temp_rate_dps_per_c_per_s.sigma = 2e-2;
        im.model.markov[0] = MarkovTerm {
            sigma_dps: 3e-4,
            tau_s: 30.0,
        };
        im.model.markov[1] = MarkovTerm {
            sigma_dps: 4e-4,
            tau_s: 300.0,
        };
        let s = scaled(&im, 0.5, 3.0);
        assert_eq!(s.model.temp_dps_per_c.sigma, 0.5e-4);
        assert_eq!(s.model.temp_rate_dps_per_c_per_s.sigma, 1e-2);
        assert_eq!(
            s.model.markov[0].sigma_dps,
            3.0 * im.model.markov[0].sigma_dps
        );
        let r = retimed(&im, Some(3000.0));
        // Variance 3e-4^2 + 4e-4^2 = (5e-4)^2 in one 3000-s term.
        assert_eq!(r.model.markov[0].tau_s, 3000.0);
        assert!((r.model.markov[0].sigma_dps - 5e-4).abs() < 1e-9);
        assert!(r.model.markov[1..].iter().all(|t| t.sigma_dps == 0.0));
        assert_eq!(retimed(&im, None), im);
        let mut back = s;
        back.model.temp_dps_per_c = im.model.temp_dps_per_c;
        back.model.temp_rate_dps_per_c_per_s = im.model.temp_rate_dps_per_c_per_s;
        back.model.markov = im.model.markov;
        assert_eq!(back, im);
    }
}

//! The identifier's level noise and second state, tuned on validation vehicle records.
//!
//! The gated Kalman baseline gets its q from the validation vehicles; the identifier gets
//! the same chance for both of its level's parameters: the random walk `q` and the second
//! state of the bank arrangements (their bias instability `B` and longest correlation time).
//! The dual-thermal's second state, the prior of the unit's temperature coefficient, is not
//! tuned here: the calibration runs measure it (`super::thermal_prior`), and a scan over
//! it on a handful of vehicles picked values that cost on others (docs/unit-fit.md). Coordinate
//! descent from the image's defaults: `q` at the default second state, the second state at
//! that `q`, `q` again. Score: the mean heading RMS over the validation vehicles with the
//! identifier's own detector.

use crate::nav::{self, NavRecord};
use anyhow::Result;
use fog_core::image::Image;
use fog_core::preset::{Arrangement, SecondState};
use serde::Serialize;

/// The identifier's level-noise grid, (deg/h)^2/h: (low, high, points per decade), the
/// range the arrangements were compared over (docs/unit-fit.md).
pub const LEVEL_Q_GRID_DPH2_PER_H: (f64, f64, usize) = (0.25, 16384.0, 4);
/// The bank's bias instability grid, deg/h (a factor 8 below to 2 above the E-Core class's
/// 1.5 deg/h specification, ASSUMED), each with the longest correlation times in
/// [`BANK_TAU_MAX_GRID_S`].
pub const BANK_B_GRID_DPH: [f32; 5] = [0.1875, 0.375, 0.75, 1.5, 3.0];
/// The bank's longest correlation time grid, s (10^4 s is the bank's limit, not a grid
/// end).
pub const BANK_TAU_MAX_GRID_S: [f32; 2] = [1_000.0, 10_000.0];

/// What the tuning picked, and its score.
#[derive(Debug, Clone, Copy)]
pub struct TunedLevel {
    /// Level random walk, (deg/h)^2/h.
    pub q_dph2_per_h: f64,
    /// Second state (thermal prior, deg/s per deg C, or the bank's `B`, deg/s, and
    /// `tau_max`, s).
    pub second: SecondState,
    /// Mean heading RMS over the validation vehicles, deg.
    pub heading_rms_deg: f64,
    /// `q` at an end of its grid (the grid does not bracket the optimum).
    pub q_at_grid_end: bool,
    /// The second state at an end of its sigma (or `B`) range, or (bank) at the short end of
    /// its tau range.
    pub second_at_grid_end: bool,
}

/// `image` with level noise `q_dph2_per_h` and second state `second`.
pub fn with_level(image: &Image, q_dph2_per_h: f64, second: SecondState) -> Image {
    let mut im = image.clone();
    im.config.level_q_dps2_per_s = (q_dph2_per_h / 3600f64.powi(3)) as f32;
    im.second_state = second;
    im
}

/// Mean heading RMS, deg, of `image` over `val` (its own detector).
pub fn mean_heading_rms(image: &Image, val: &[NavRecord]) -> Result<f64> {
    anyhow::ensure!(!val.is_empty(), "no vehicle record to score on");
    let mut sum = 0.0;
    for v in val {
        let (drift, _) = run_image(image, v)?;
        sum += nav::score_drift(v, &drift).heading_rms_deg;
    }
    Ok(sum / val.len() as f64)
}

/// The second-state grid of `image`'s arrangement (empty for the dual-thermal: its prior
/// is measured, module docs).
pub fn second_grid(image: &Image) -> Vec<SecondState> {
    let (sigmas_dph, taus_s): (&[f32], &[f32]) = if image.arrangement.is_bank() {
        (&BANK_B_GRID_DPH, &BANK_TAU_MAX_GRID_S)
    } else {
        (&[], &[])
    };
    sigmas_dph
        .iter()
        .flat_map(|&s| {
            taus_s.iter().map(move |&tau_s| SecondState {
                sigma: s / 3600.0,
                tau_s,
            })
        })
        .collect()
}

/// Tunes `image`'s level on `val` (see the module docs). `val` must not be empty.
pub fn tune(image: &Image, val: &[NavRecord]) -> Result<TunedLevel> {
    anyhow::ensure!(!val.is_empty(), "no validation vehicle record to tune on");
    let (lo, hi, per) = LEVEL_Q_GRID_DPH2_PER_H;
    let q_grid = nav::log_grid(lo, hi, per);
    let seconds = second_grid(image);
    let score = |q: f64, g: SecondState| mean_heading_rms(&with_level(image, q, g), val);
    let pick_q = |g: SecondState| -> Result<(f64, f64)> {
        let mut best = (f64::INFINITY, q_grid.first().copied().unwrap_or(0.0));
        for &q in &q_grid {
            let s = score(q, g)?;
            if s < best.0 {
                best = (s, q);
            }
        }
        anyhow::ensure!(
            best.0.is_finite(),
            "no level noise gives a finite heading error on these vehicles"
        );
        Ok(best)
    };
    let start = image.second_state;
    let (mut best, mut q) = pick_q(start)?;
    let mut second = start;
    for &g in &seconds {
        let s = score(q, g)?;
        if s < best {
            (best, second) = (s, g);
        }
    }
    // q again only where the second state moved (else the same scan, the same answer).
    if second != start {
        (best, q) = pick_q(second)?;
    }
    let sigma_dph = second.sigma * 3600.0;
    // 10^4 s is the bank's limit, not a grid end; the 10^3 s end is one.
    let second_at_grid_end = image.arrangement.is_bank()
        && (at_grid_end(sigma_dph, &BANK_B_GRID_DPH)
            || BANK_TAU_MAX_GRID_S.first() == Some(&second.tau_s));
    Ok(TunedLevel {
        q_dph2_per_h: q,
        second,
        heading_rms_deg: best,
        q_at_grid_end: at_grid_end(q, &q_grid),
        second_at_grid_end,
    })
}

/// `v` is the first or last point of `grid` (within 1e-9 relative) and the grid has more
/// than one point.
fn at_grid_end<T: Copy + Into<f64>>(v: T, grid: &[T]) -> bool {
    let v: f64 = v.into();
    grid.len() > 1
        && [grid.first(), grid.last()]
            .into_iter()
            .flatten()
            .any(|&e| (v / e.into() - 1.0).abs() < 1e-9)
}

/// One candidate's tuning, as `identify --json` (`tuning.candidates`) writes it.
#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    /// The arrangement, as `--level-update` names it.
    pub level_update: String,
    /// Level random walk, (deg/h)^2/h.
    pub level_q_dph2_per_h: f64,
    /// The thermal prior, deg/h per deg C, or the bank's B, deg/h.
    pub second_sigma_per_h: f32,
    /// The bank's longest tau, s (0 for the thermal prior).
    pub second_tau_s: f32,
    /// Mean heading RMS over the vehicles, deg.
    pub mean_heading_rms_deg: f64,
    /// q at an end of its grid.
    pub q_at_grid_end: bool,
    /// The second state at an end of its grid.
    pub second_at_grid_end: bool,
    /// One line for people ([`describe`]).
    pub text: String,
}

/// What [`pick_arrangement`] did.
#[derive(Debug, Clone, Serialize)]
pub struct Tuning {
    /// Vehicle records tuned on.
    pub records: usize,
    /// The kept arrangement, as `--level-update` names it.
    pub picked: String,
    /// Its index among the candidates.
    pub picked_index: usize,
    /// Every candidate, in the order given.
    pub candidates: Vec<Candidate>,
}

impl Tuning {
    /// One line per candidate (`on 32 validation vehicles: identifier dual: level q ...`),
    /// the kept one marked `(kept)`.
    pub fn lines(&self) -> Vec<String> {
        self.candidates
            .iter()
            .enumerate()
            .map(|(i, c)| {
                format!(
                    "on {} validation vehicles: identifier {}: {}{}",
                    self.records,
                    c.level_update,
                    c.text,
                    if i == self.picked_index {
                        " (kept)"
                    } else {
                        ""
                    }
                )
            })
            .collect()
    }

    /// A tuned parameter sits at an end of its grid (the grid does not bracket the optimum).
    pub fn any_at_grid_end(&self) -> bool {
        self.candidates
            .iter()
            .any(|c| c.q_at_grid_end || c.second_at_grid_end)
    }
}

/// One candidate image per arrangement, each tuned on `val` ([`tune`]); the tuned image
/// with the least mean heading RMS (ties to the first) and what was done. `candidates`
/// must not be empty.
pub fn pick_arrangement(candidates: &[Image], val: &[NavRecord]) -> Result<(Image, Tuning)> {
    let mut tuned = Vec::with_capacity(candidates.len());
    for im in candidates {
        tuned.push(tune(im, val)?);
    }
    let best = tuned
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.heading_rms_deg.total_cmp(&b.1.heading_rms_deg))
        .map(|(i, _)| i)
        .ok_or_else(|| anyhow::anyhow!("no arrangement to tune"))?;
    let name = |im: &Image| crate::motion::LevelUpdateArg::of(im.arrangement).cli_name();
    let t = tuned[best];
    let tuning = Tuning {
        records: val.len(),
        picked: name(&candidates[best]),
        picked_index: best,
        candidates: candidates
            .iter()
            .zip(&tuned)
            .map(|(im, t)| Candidate {
                level_update: name(im),
                level_q_dph2_per_h: t.q_dph2_per_h,
                second_sigma_per_h: t.second.sigma * 3600.0,
                second_tau_s: t.second.tau_s,
                mean_heading_rms_deg: t.heading_rms_deg,
                q_at_grid_end: t.q_at_grid_end,
                second_at_grid_end: t.second_at_grid_end,
                text: describe(im.arrangement, t),
            })
            .collect(),
    };
    Ok((
        with_level(&candidates[best], t.q_dph2_per_h, t.second),
        tuning,
    ))
}

/// What a tuning picked, one line (`level q 47.8 (deg/h)^2/h, temperature coefficient
/// prior 1.000 deg/h per deg C (AT AN END OF ITS GRID); mean heading RMS 0.1425 deg`).
pub fn describe(arrangement: Arrangement, t: &TunedLevel) -> String {
    let end = |at: bool| if at { " (AT AN END OF ITS GRID)" } else { "" };
    let second = if arrangement.is_bank() {
        format!(
            "bank B {:.4} deg/h, tau_max {} s",
            t.second.sigma * 3600.0,
            t.second.tau_s
        )
    } else {
        format!(
            "temperature coefficient prior {:.3} deg/h per deg C",
            t.second.sigma * 3600.0
        )
    };
    format!(
        "level q {:.3} (deg/h)^2/h{}, {second}{}; mean heading RMS {:.4} deg",
        t.q_dph2_per_h,
        end(t.q_at_grid_end),
        end(t.second_at_grid_end),
        t.heading_rms_deg
    )
}

/// `image`'s estimator over `rec` from power-on, its own detector: drift estimate, deg/s,
/// and still flag per sample (a refused sample: drift 0, not still).
pub fn run_image(image: &Image, rec: &NavRecord) -> Result<(Vec<f64>, Vec<bool>)> {
    let mut est = image
        .estimator()
        .map_err(|e| anyhow::anyhow!("identifier: {e}"))?;
    let (mut drift, mut still) = (Vec::with_capacity(rec.len()), Vec::with_capacity(rec.len()));
    anyhow::ensure!(
        rec.rate_dps.len() == rec.len() && rec.temp_c.as_ref().is_none_or(|t| t.len() == rec.len()),
        "record columns of different lengths"
    );
    for (k, &rate) in rec.rate_dps.iter().enumerate() {
        let temp = rec
            .temp_c
            .as_ref()
            .and_then(|t| t.get(k))
            .map_or(f32::NAN, |&t| t as f32);
        let o = est.push(rate as f32, temp, None);
        drift.push(o.map_or(0.0, |o| f64::from(o.drift_dps)));
        still.push(o.is_ok_and(|o| o.still));
    }
    Ok((drift, still))
}

#[cfg(test)]
mod tests {
    use super::*;
    fn image(arrangement: Arrangement, gm: SecondState) -> Image {
        let o = crate::motion::TrainOptions::new(fog_core::still::SensorConfig::ECORE_2000)
            .with_arrangement(arrangement);
        let mut im = crate::motion::untrained(&o).expect("untrained image");
        im.second_state = gm;
        im
    }

    #[test]
    fn each_arrangement_tunes_its_own_second_state() {
        let bank = second_grid(&image(
            Arrangement::BankGuarded,
            crate::motion::DEFAULT_BANK,
        ));
        assert_eq!(
            bank.len(),
            BANK_B_GRID_DPH.len() * BANK_TAU_MAX_GRID_S.len()
        );
        assert!(bank
            .iter()
            .any(|g| (g.sigma * 3600.0 - 1.5).abs() < 1e-4 && g.tau_s == 10_000.0));
        // The dual-thermal's prior is measured on the calibration runs, not tuned.
        assert!(second_grid(&image(Arrangement::DualThermal, SecondState::THERMAL)).is_empty());
    }

    #[test]
    fn with_level_sets_both_parameters_and_nothing_else() {
        let im = image(Arrangement::DualThermal, SecondState::THERMAL);
        let g = SecondState {
            sigma: 4.0 / 3600.0,
            tau_s: 0.0,
        };
        let t = with_level(&im, 3600.0, g);
        assert!((t.config.level_q_dps2_per_s * 3600.0 * 3600.0 - 1.0).abs() < 1e-6);
        assert_eq!(t.second_state, g);
        assert_eq!(t.model, im.model);
        assert_eq!(t.arrangement, im.arrangement);
    }

    /// Two 240-s vehicle records of the demo's family: units `unit`, `unit + 1`, seeds
    /// `seed`, `seed + 1`.
    fn vehicles(unit: u64, seed: u64) -> Vec<NavRecord> {
        (0..2)
            .map(|i| {
                let m = crate::demo::family_model(unit + i, true).expect("model");
                NavRecord::from_samples(&crate::demo::samples(&m, seed + i, 240.0).expect("sim"))
            })
            .collect()
    }

    #[test]
    fn the_pick_is_the_least_along_q_and_no_worse_than_the_defaults() {
        let val = vehicles(800, 201);
        let im = image(Arrangement::BankGuarded, crate::motion::DEFAULT_BANK);
        let t = tune(&im, &val).expect("tune");
        let score =
            |q: f64, g: SecondState| mean_heading_rms(&with_level(&im, q, g), &val).expect("score");
        assert_eq!(t.heading_rms_deg, score(t.q_dph2_per_h, t.second));
        let (lo, hi, per) = LEVEL_Q_GRID_DPH2_PER_H;
        for q in nav::log_grid(lo, hi, per) {
            assert!(
                score(q, t.second) >= t.heading_rms_deg,
                "q {q} beats the pick"
            );
            assert!(
                score(q, im.second_state) >= t.heading_rms_deg,
                "default state, q {q} beats the pick"
            );
        }
        assert!(second_grid(&im).contains(&t.second) || t.second == im.second_state);
        assert!(tune(&im, &[]).is_err());
    }

    #[test]
    fn the_arrangement_with_the_least_tuned_score_is_kept() {
        let val = vehicles(810, 301);
        let dual = image(Arrangement::DualThermal, SecondState::THERMAL);
        let bank = image(Arrangement::BankGuarded, crate::motion::DEFAULT_BANK);
        let (picked, t) = pick_arrangement(&[dual.clone(), bank.clone()], &val).expect("pick");
        let c = &t.candidates;
        assert_eq!(c.len(), 2);
        let least = usize::from(c[1].mean_heading_rms_deg < c[0].mean_heading_rms_deg);
        assert_eq!(t.picked_index, least);
        assert_eq!(t.picked, ["dual-thermal", "bank-guarded"][least]);
        assert_eq!(
            picked.arrangement,
            [dual.arrangement, bank.arrangement][least]
        );
        assert!((picked.second_state.sigma * 3600.0 - c[least].second_sigma_per_h).abs() < 1e-6);
        assert_eq!(picked.second_state.tau_s, c[least].second_tau_s);
        assert_eq!(
            mean_heading_rms(&picked, &val).expect("score"),
            c[least].mean_heading_rms_deg
        );
        let lines = t.lines();
        assert_eq!(lines.len(), 2);
        assert!(lines[least].ends_with(" (kept)") && !lines[1 - least].ends_with(" (kept)"));
        assert!(pick_arrangement(&[], &val).is_err());
    }
}

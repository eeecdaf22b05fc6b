//! The unit's own level wander at rest: the per-sample level's random-walk density chosen on
//! line from the unit's released still windows.
//!
//! Units of one family wander at different speeds (bias instability 0.5 to 3 deg/h, random
//! walk, warm-up), and the level noise that serves a vehicle in motion (tuned for holding the
//! level through a drive, `identify --tune-on`) is not the one that follows the drift best at
//! rest. [`RestQ`] runs [`REST_Q_GRID`] scalar random-walk Kalman filters side by side on
//! the released window means (still, confirmed by the next window: no rolled-back sample
//! reaches them), one per density of the grid `4^i (deg/h)^2/h`, `i = 0..7` (1 to 16,384),
//! and scores each by its prequential squared error: the squared difference between a
//! window mean and the filter's prediction of it before it saw it. The density with the
//! least score is the unit's ([`RestQ::q_dps2_per_s`]); the per-sample level uses it at
//! still samples ([`crate::motion::MotionEstimator`]). The squared prediction error is
//! the error against the true drift plus the window's white noise, the same for every
//! filter in expectation, so the least score is the least error against the drift (what
//! static `e_truth` measures).
//!
//! ASSUMED: the grid (the measured families' best densities are 64 to 16,384; its top keeps
//! the level's time constant near 2 s or more at the E-Core's noise, so that a slow turn is
//! not followed within a window); [`REST_Q_MIN_WINDOWS`] released windows before the
//! choice replaces the image's density. A window mean beyond twice the drift bound is not
//! scored (no unit's level is there). Measured: `cargo run --release -p fog-lab --bin unit_family` (static
//! rows, docs/unit-fit.md). Cost per released window: [`REST_Q_GRID`] divisions; state
//! `3 * REST_Q_GRID + 3` words.

/// Densities in the grid.
pub const REST_Q_GRID: usize = 8;

/// Released windows scored before the choice is used (ASSUMED: 5, five seconds at the
/// default 1-s window; before it, the image's density).
pub const REST_Q_MIN_WINDOWS: u32 = 5;

/// `(deg/h)^2/h` in `deg^2/s^3`.
const DPH2_PER_H: f32 = 1.0 / (3600.0 * 3600.0 * 3600.0);

/// The grid's densities, deg^2/s^3: `4^i (deg/h)^2/h`.
pub const REST_Q_DPS2_PER_S: [f32; REST_Q_GRID] = {
    let mut q = [0.0; REST_Q_GRID];
    let mut i = 0;
    let mut v = 1.0;
    while i < REST_Q_GRID {
        q[i] = v * DPH2_PER_H;
        v *= 4.0;
        i += 1;
    }
    q
};

/// The filters and their scores (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct RestQ {
    /// Each filter's level, deg/s.
    level_dps: [f32; REST_Q_GRID],
    /// Each filter's level variance, deg^2/s^2.
    var_dps2: [f32; REST_Q_GRID],
    /// Each filter's prequential squared error, deg^2/s^2, less the least of them.
    score: [f32; REST_Q_GRID],
    /// Time since the last released window, s.
    pending_s: f32,
    /// Released windows scored (saturating).
    windows: u32,
    /// The prior variance of every filter's level at power-on: the drift bound squared.
    prior_var_dps2: f32,
}

impl RestQ {
    /// At power-on: every level 0 with variance `drift_bound_dps^2`.
    pub fn new(drift_bound_dps: f32) -> Self {
        let prior = drift_bound_dps * drift_bound_dps;
        Self::at_power_on(if prior.is_finite() && prior > 0.0 {
            prior
        } else {
            1.0
        })
    }

    /// Back to power-on.
    pub fn restart(&mut self) {
        *self = Self::at_power_on(self.prior_var_dps2);
    }

    fn at_power_on(prior_var_dps2: f32) -> Self {
        Self {
            level_dps: [0.0; REST_Q_GRID],
            var_dps2: [prior_var_dps2; REST_Q_GRID],
            score: [0.0; REST_Q_GRID],
            pending_s: 0.0,
            windows: 0,
            prior_var_dps2,
        }
    }

    /// `dt_s` of time passed (one detector window, still or not).
    pub fn elapse(&mut self, dt_s: f32) {
        if dt_s.is_finite() && dt_s > 0.0 {
            self.pending_s += dt_s;
        }
    }

    /// A released window mean `z_dps` (the level's observation: rate minus the model and
    /// the second state) with its white-noise variance `r_dps2`. Ignored: a non-finite
    /// mean or one beyond twice the drift bound, a non-finite or non-positive variance. Not inlined: its frame stays apart from the
    /// caller's (16 B less stack high-water in the firmware's HIL run).
    #[inline(never)]
    pub fn update(&mut self, z_dps: f32, r_dps2: f32) {
        let plausible = z_dps.is_finite() && z_dps * z_dps <= 4.0 * self.prior_var_dps2;
        if !plausible || !r_dps2.is_finite() || r_dps2 <= 0.0 {
            return;
        }
        let scored = self.windows > 0;
        let mut least = f32::INFINITY;
        let filters = self
            .level_dps
            .iter_mut()
            .zip(self.var_dps2.iter_mut())
            .zip(self.score.iter_mut())
            .zip(REST_Q_DPS2_PER_S.iter());
        for (((level, var), score), q) in filters {
            let p = *var + q * self.pending_s;
            let y = z_dps - *level;
            if scored {
                *score += y * y;
            }
            let g = p / (p + r_dps2);
            *level += g * y;
            *var = p - g * p;
            least = least.min(*score);
        }
        // Scores relative to the least: they stay bounded (and their differences precise)
        // over any run.
        if least.is_finite() {
            for s in &mut self.score {
                *s -= least;
            }
        } else {
            self.score = [0.0; REST_Q_GRID];
        }
        self.pending_s = 0.0;
        self.windows = self.windows.saturating_add(1);
    }

    /// The unit's density, deg^2/s^3: the least score's, once [`REST_Q_MIN_WINDOWS`]
    /// windows are scored (ties: the smaller density); `None` before.
    pub fn q_dps2_per_s(&self) -> Option<f32> {
        if self.windows <= REST_Q_MIN_WINDOWS {
            return None;
        }
        let mut best = 0;
        for i in 1..REST_Q_GRID {
            if self.score[i] < self.score[best] {
                best = i;
            }
        }
        Some(REST_Q_DPS2_PER_S[best])
    }

    /// Released windows scored so far (saturating).
    pub fn windows(&self) -> u32 {
        self.windows
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::test_noise::Noise;

    const DPH: f32 = 1.0 / 3600.0;

    /// Window means of a random walk of density `q` plus white noise of variance `r`.
    fn choose(q_dph2_per_h: f32, r_dps2: f32, windows: usize, seed: u64) -> f32 {
        let mut z = Noise(seed);
        let mut sel = RestQ::new(30.0 * DPH);
        let step = libm::sqrtf(q_dph2_per_h * DPH2_PER_H);
        let mut drift = 10.0 * DPH;
        for _ in 0..windows {
            drift += step * z.normal12();
            sel.elapse(1.0);
            sel.update(drift + libm::sqrtf(r_dps2) * z.normal12(), r_dps2);
        }
        sel.q_dps2_per_s().expect("enough windows") / DPH2_PER_H
    }

    #[test]
    fn grid_is_powers_of_four_in_dph2_per_h() {
        for (i, q) in REST_Q_DPS2_PER_S.iter().enumerate() {
            let want = libm::powf(4.0, i as f32);
            assert!((q / DPH2_PER_H / want - 1.0).abs() < 1e-5, "{i}");
        }
    }

    #[test]
    fn finds_the_random_walk_it_is_given() {
        // 1-s window means at a white noise of 4 deg/h (the E-Core at 100 Hz over 1 s).
        let r = (4.0 * DPH) * (4.0 * DPH);
        for (truth, seed) in [(64.0_f32, 1), (1024.0, 2), (16384.0, 3)] {
            let got = choose(truth, r, 3600, seed);
            let ratio = got / truth;
            assert!((0.25..=4.0).contains(&ratio), "truth {truth} chose {got}");
        }
    }

    #[test]
    fn nothing_before_enough_windows_and_bad_input_is_ignored() {
        let mut sel = RestQ::new(30.0 * DPH);
        for _ in 0..REST_Q_MIN_WINDOWS {
            sel.elapse(1.0);
            sel.update(1e-3, 1e-6);
        }
        assert_eq!(sel.q_dps2_per_s(), None);
        let before = sel.clone();
        sel.update(f32::NAN, 1e-6);
        sel.update(1e-3, 0.0);
        sel.update(1e-3, f32::INFINITY);
        sel.update(1.0, 1e-6); // 3600 deg/h: beyond twice the 30-deg/h bound
        sel.update(f32::MAX, 1e-6);
        sel.elapse(f32::NAN);
        sel.elapse(-1.0);
        assert_eq!(sel, before);
        sel.elapse(1.0);
        sel.update(1e-3, 1e-6);
        assert!(sel.q_dps2_per_s().is_some());
        sel.restart();
        assert_eq!(sel, RestQ::new(30.0 * DPH));
    }
}

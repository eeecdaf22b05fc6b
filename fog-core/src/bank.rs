//! Level with the sensor's Allan noise model: a stillness-gated Kalman filter whose drift
//! is a random walk (rate random walk) plus a bank of first-order Gauss-Markov states, one
//! per decade of correlation time from 1 s, that together approximate flicker (bias
//! instability `B`).
//!
//! Why a bank: flicker has no single correlation time. A continuum of Gauss-Markov states
//! with weight `w` per unit of `ln tau` has the two-sided PSD `w / (2 f)`; flicker's
//! `B^2 / (2 pi f)` needs `w = B^2 / pi`, so one state per decade gets the stationary
//! variance `B^2 ln(10) / pi` (0.733 `B^2`). At rest every scale is observed together; in
//! motion each decays toward 0 at its own rate, so the estimate keeps the slow scales and
//! forgets the fast ones, which is what a flicker forecast over a drive should do.
//!
//! All arithmetic is f32 with the states in deg/h (values near 1, not 1e-4); the full
//! covariance of at most [`BANK_STATES`] states is kept. Tested against an f64 reference
//! (`cargo test -p fog-core --lib bank`).

// Matrix code: `p[i][j]` with the same `i`, `j` in several arrays reads as the algebra.
#![allow(clippy::needless_range_loop)]

/// Most Gauss-Markov states (correlation times 1, 10, ..., 10^4 s).
pub const BANK_GM_MAX: usize = 5;
/// Most states: the random walk and [`BANK_GM_MAX`] Gauss-Markov states.
pub const BANK_STATES: usize = BANK_GM_MAX + 1;

const DPH_PER_DPS: f32 = 3600.0;

/// The bank's noise model, from the sensor's specification (or tuned).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BankConfig {
    /// Random-walk variance growth of the slow state, (deg/s)^2 per s (>= 0, finite).
    pub q_rw_dps2_per_s: f32,
    /// Bias instability `B`, deg/s (flicker PSD `B^2 / (2 pi f)`, two-sided; > 0, finite).
    pub b_dps: f32,
    /// Longest correlation time of the bank, s: states at 1, 10, ... s up to it (1 to
    /// 10^4 s; finite).
    pub tau_max_s: f32,
}

impl BankConfig {
    /// Number of Gauss-Markov states: one per decade from 1 s to `tau_max_s`
    /// (0 when the configuration is invalid).
    pub fn gm_states(&self) -> usize {
        if !self.is_valid() {
            return 0;
        }
        let mut n = 0;
        let mut tau = 1.0f32;
        while n < BANK_GM_MAX && tau <= self.tau_max_s * 1.0001 {
            n += 1;
            tau *= 10.0;
        }
        n
    }

    /// Finite, `q >= 0`, `B > 0`, `1 <= tau_max_s <= 10^4` (within 0.01 %).
    pub fn is_valid(&self) -> bool {
        self.q_rw_dps2_per_s.is_finite()
            && self.q_rw_dps2_per_s >= 0.0
            && self.b_dps.is_finite()
            && self.b_dps > 0.0
            && self.tau_max_s.is_finite()
            && self.tau_max_s >= 1.0
            && self.tau_max_s <= 10_000.0 * 1.0001
    }
}

/// Entries of the packed upper triangle of the covariance.
const PACKED: usize = BANK_STATES * (BANK_STATES + 1) / 2;

/// Index of row `i`'s diagonal entry in the packed upper triangle (row-major, `j >= i`).
const fn row_start(i: usize) -> usize {
    i * BANK_STATES - i * (i.saturating_sub(1)) / 2
}

/// State and covariance (deg/h, (deg/h)^2; the covariance as its packed upper triangle):
/// what a checkpoint holds. Advanced by a [`BankParams`]; the preset's bank of released
/// windows is one of these beside a [`LevelBank`], under that bank's constants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BankState {
    x: [f32; BANK_STATES],
    p: [f32; PACKED],
}

const ZERO: BankState = BankState {
    x: [0.0; BANK_STATES],
    p: [0.0; PACKED],
};

/// The bank's constants, from its [`BankConfig`] and the sensor: set at construction,
/// never changed by a sample (the per-sample state is a [`BankState`]).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct BankParams {
    // Per-sample transition a_i, the products a_i a_j (packed), the process noise added to
    // each diagonal entry per sample ((deg/h)^2; q[0] the random walk's).
    a: [f32; BANK_STATES],
    aa: [f32; PACKED],
    q: [f32; BANK_STATES],
    // Stationary variance of each Gauss-Markov state ((deg/h)^2; 0 for the random walk and
    // the unused states).
    var: [f32; BANK_STATES],
    // Sample period, s; the random walk's variance at power-on and one sample's white
    // noise variance, (deg/h)^2.
    dt_s: f32,
    p0_dph2: f32,
    r_dph2: f32,
}

/// The filter: state `[b, g_1 .. g_M]` (deg/h), drift `b + sum g`. [`LevelBank::predict`]
/// every sample (still or not), [`LevelBank::update`] only with still samples;
/// [`LevelBank::checkpoint`] / [`LevelBank::rollback`] remove the samples of windows the
/// detector failed afterwards. The covariance is kept as its upper triangle (21 entries
/// for 6 states): per still sample about 21 multiplications to predict and 42
/// multiply-adds to update.
#[derive(Debug, Clone)]
pub struct LevelBank {
    params: BankParams,
    s: BankState,
    cp_now: BankState,
    cp_prev: BankState,
}

impl LevelBank {
    /// A filter at power-on: state 0, the random walk's variance `bound^2` (the whole
    /// drift bound, deg/s), each Gauss-Markov state at its stationary variance.
    /// `sample_var_dps2`: white noise per sample, `sample_rate_hz` > 0. `None` when `cfg`
    /// or the numbers are invalid. Always inlined: built in its caller's slot.
    #[inline(always)]
    pub fn new(
        cfg: BankConfig,
        bound_dps: f32,
        sample_var_dps2: f32,
        sample_rate_hz: f32,
    ) -> Option<Self> {
        let m = cfg.gm_states();
        let ok = |v: f32| v.is_finite() && v > 0.0;
        if m == 0 || !ok(bound_dps) || !ok(sample_var_dps2) || !ok(sample_rate_hz) {
            return None;
        }
        let n = m + 1;
        let dt_s = 1.0 / sample_rate_hz;
        let b_dph = cfg.b_dps * DPH_PER_DPS;
        // B^2 ln(10) / pi per decade.
        let var_gm = b_dph * b_dph * core::f32::consts::LN_10 / core::f32::consts::PI;
        let q_rw_dph2_per_sample = cfg.q_rw_dps2_per_s * DPH_PER_DPS * DPH_PER_DPS * dt_s;
        let mut a = [1.0f32; BANK_STATES];
        let mut q = [0.0f32; BANK_STATES];
        q[0] = q_rw_dph2_per_sample;
        // Constant loop bounds (no index checks); states from `n` on are unused: a = 1,
        // q = 0, stationary variance 0, so they stay 0.
        let mut var = [0.0f32; BANK_STATES];
        let mut tau = 1.0f32;
        for i in 1..BANK_STATES {
            if i < n {
                a[i] = crate::wnn::exp_anchor((-dt_s / tau).max(-87.0));
                q[i] = var_gm * (1.0 - a[i] * a[i]);
                var[i] = var_gm;
            }
            tau *= 10.0;
        }
        let mut aa = [0.0f32; PACKED];
        for i in 0..BANK_STATES {
            for j in i..BANK_STATES {
                aa[row_start(i) + j - i] = a[i] * a[j];
            }
        }
        let bound_dph = bound_dps * DPH_PER_DPS;
        let mut f = Self {
            params: BankParams {
                a,
                aa,
                q,
                var,
                dt_s,
                p0_dph2: bound_dph * bound_dph,
                r_dph2: sample_var_dps2 * DPH_PER_DPS * DPH_PER_DPS,
            },
            s: ZERO,
            cp_now: ZERO,
            cp_prev: ZERO,
        };
        f.restart();
        Some(f)
    }

    /// Back to power-on.
    pub fn restart(&mut self) {
        self.params.restart(&mut self.s);
        self.cp_now = self.s;
        self.cp_prev = self.s;
    }

    /// One sample's prediction.
    #[inline]
    pub fn predict(&mut self) {
        self.params.predict(&mut self.s);
    }

    /// Prediction over `k` samples at once (a window, or a rollback): `a^k` per state.
    pub fn predict_many(&mut self, k: u32) {
        self.params.predict_many(&mut self.s, k);
    }

    /// Kalman update with one still sample `z_dps` (= rate - model), white noise of the
    /// configured variance. A non-finite sample or result changes nothing.
    pub fn update(&mut self, z_dps: f32) {
        self.s.update_with(z_dps, self.params.r_dph2);
    }

    /// Kalman update with a window mean `z_dps` of white-noise variance `r_dps2`
    /// (ASSUMED: the states at the window's end; the 1-s state moves within a window, so
    /// its share is smoothed).
    pub fn update_mean(&mut self, z_dps: f32, r_dps2: f32) {
        self.s.update_mean(z_dps, r_dps2);
    }

    /// At a detector window start: the previous checkpoint becomes the current one and the
    /// current state the new current one.
    pub fn checkpoint(&mut self) {
        self.cp_prev = self.cp_now;
        self.cp_now = self.s;
    }

    /// A window failed: back to the checkpoint before the previous window, predicted over
    /// the `samples` since it; both checkpoints become that state.
    pub fn rollback(&mut self, samples: u32) {
        self.restore(self.cp_prev, samples);
    }

    /// A window failed: back to the checkpoint at its start, predicted over the `samples`
    /// since it; both checkpoints become that state (the windows before it stay).
    pub fn rollback_window(&mut self, samples: u32) {
        self.restore(self.cp_now, samples);
    }

    /// Back to `cp`, predicted over `samples`; both checkpoints become that state.
    fn restore(&mut self, cp: BankState, samples: u32) {
        self.s = cp;
        self.params.predict_many(&mut self.s, samples);
        self.cp_now = self.s;
        self.cp_prev = self.s;
    }

    /// The drift estimate, deg/s.
    pub fn estimate_dps(&self) -> f32 {
        self.s.estimate_dps()
    }

    /// The variance of the drift estimate, (deg/s)^2.
    pub fn estimate_var_dps2(&self) -> f32 {
        self.s.row_sums().1 / (DPH_PER_DPS * DPH_PER_DPS)
    }

    /// The constants (for a second state beside this bank).
    pub(crate) fn params(&self) -> &BankParams {
        &self.params
    }
}

impl BankParams {
    /// `s` at power-on: state 0, the random walk's variance `bound^2`, each Gauss-Markov
    /// state at its stationary variance.
    pub(crate) fn restart(&self, s: &mut BankState) {
        *s = ZERO;
        s.p[0] = self.p0_dph2;
        for i in 1..BANK_STATES {
            s.p[row_start(i)] = self.var[i];
        }
    }

    /// A state at power-on ([`BankParams::restart`]).
    pub(crate) fn power_on(&self) -> BankState {
        let mut s = ZERO;
        self.restart(&mut s);
        s
    }

    /// One sample's prediction of `s`.
    #[inline]
    fn predict(&self, s: &mut BankState) {
        // All BANK_STATES states, the unused ones at 0 (a = 1, q = 0): constant loop bounds
        // (unrolled, no index checks) and the same values as over the used states alone.
        for i in 1..BANK_STATES {
            s.x[i] *= self.a[i];
        }
        for k in 0..PACKED {
            s.p[k] *= self.aa[k];
        }
        for i in 0..BANK_STATES {
            s.p[row_start(i)] += self.q[i];
        }
    }

    /// Prediction of `s` over `k` samples at once (a window, or a rollback): `a^k` per
    /// state.
    pub(crate) fn predict_many(&self, s: &mut BankState, k: u32) {
        if k == 0 {
            return;
        }
        // Constant loop bounds (no index checks); the unused states stay 0 (their
        // stationary variance `var` is 0).
        let mut ak = [1.0f32; BANK_STATES];
        let mut tau = 1.0f32;
        for v in ak.iter_mut().skip(1) {
            *v = crate::wnn::exp_anchor((-(k as f32) * self.dt_s / tau).max(-87.0));
            tau *= 10.0;
        }
        for i in 1..BANK_STATES {
            s.x[i] *= ak[i];
        }
        for i in 0..BANK_STATES {
            let r = row_start(i);
            for j in i..BANK_STATES {
                s.p[r + j - i] *= ak[i] * ak[j];
            }
        }
        // q[0]: the random walk's growth per sample.
        s.p[0] += self.q[0] * k as f32;
        for i in 1..BANK_STATES {
            s.p[row_start(i)] += self.var[i] * (1.0 - ak[i] * ak[i]);
        }
    }
}

impl BankState {
    /// [`LevelBank::update_mean`] (no constant needed: the noise is the mean's).
    pub(crate) fn update_mean(&mut self, z_dps: f32, r_dps2: f32) {
        if r_dps2.is_finite() && r_dps2 > 0.0 {
            self.update_with(z_dps, r_dps2 * DPH_PER_DPS * DPH_PER_DPS);
        }
    }

    /// Kalman update with `z_dps` of white-noise variance `r_dph2`, (deg/h)^2.
    fn update_with(&mut self, z_dps: f32, r_dph2: f32) {
        let (h, total) = self.row_sums();
        let s = total + r_dph2;
        let innovation = z_dps * DPH_PER_DPS - self.estimate_dph();
        // Finite, positive s and a finite innovation: every gain is in [0, 1] and every
        // result finite, so the update is done in place.
        if !(s.is_finite() && s > 0.0 && innovation.is_finite()) {
            return;
        }
        let inv = 1.0 / s;
        for i in 0..BANK_STATES {
            let k = h[i] * inv;
            self.x[i] += k * innovation;
            let r = row_start(i);
            for j in i..BANK_STATES {
                self.p[r + j - i] -= k * h[j];
            }
            self.p[r] = self.p[r].max(0.0);
        }
    }

    /// `h = P 1` (row sums of the covariance) and `1' P 1`.
    fn row_sums(&self) -> ([f32; BANK_STATES], f32) {
        let mut h = [0.0f32; BANK_STATES];
        for i in 0..BANK_STATES {
            let r = row_start(i);
            h[i] += self.p[r];
            for j in i + 1..BANK_STATES {
                let v = self.p[r + j - i];
                h[i] += v;
                h[j] += v;
            }
        }
        let total = h.iter().sum();
        (h, total)
    }

    fn estimate_dph(&self) -> f32 {
        self.x.iter().sum()
    }

    /// The drift estimate, deg/s.
    pub(crate) fn estimate_dps(&self) -> f32 {
        self.estimate_dph() / DPH_PER_DPS
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_noise::Noise;

    /// f64 reference: the same filter with full f64 arithmetic, in deg/s.
    struct Reference {
        x: [f64; BANK_STATES],
        p: [[f64; BANK_STATES]; BANK_STATES],
        a: [f64; BANK_STATES],
        q: [f64; BANK_STATES],
        r: f64,
        n: usize,
    }

    impl Reference {
        fn new(cfg: BankConfig, bound: f64, r: f64, fs: f64) -> Self {
            let n = cfg.gm_states() + 1;
            let b = cfg.b_dps as f64;
            let var = b * b * core::f64::consts::LN_10 / core::f64::consts::PI;
            let mut s = Self {
                x: [0.0; BANK_STATES],
                p: [[0.0; BANK_STATES]; BANK_STATES],
                a: [1.0; BANK_STATES],
                q: [0.0; BANK_STATES],
                r,
                n,
            };
            s.p[0][0] = bound * bound;
            s.q[0] = cfg.q_rw_dps2_per_s as f64 / fs;
            let mut tau = 1.0;
            for i in 1..n {
                s.a[i] = libm::exp(-1.0 / fs / tau);
                s.q[i] = var * (1.0 - s.a[i] * s.a[i]);
                s.p[i][i] = var;
                tau *= 10.0;
            }
            s
        }
        fn predict(&mut self) {
            for i in 0..self.n {
                self.x[i] *= self.a[i];
                for j in 0..self.n {
                    self.p[i][j] *= self.a[i] * self.a[j];
                }
                self.p[i][i] += self.q[i];
            }
        }
        fn update(&mut self, z: f64) {
            let n = self.n;
            let h: [f64; BANK_STATES] = core::array::from_fn(|i| {
                if i < n {
                    self.p[i][..n].iter().sum()
                } else {
                    0.0
                }
            });
            let s: f64 = h[..n].iter().sum::<f64>() + self.r;
            let inn = z - self.x[..n].iter().sum::<f64>();
            for i in 0..n {
                self.x[i] += h[i] / s * inn;
                for j in 0..n {
                    self.p[i][j] -= h[i] * h[j] / s;
                }
            }
        }
        fn estimate(&self) -> f64 {
            self.x[..self.n].iter().sum()
        }
    }

    const CFG: BankConfig = BankConfig {
        q_rw_dps2_per_s: 1.9e-11,
        b_dps: 1.5 / 3600.0,
        tau_max_s: 10_000.0,
    };

    #[test]
    fn states_per_decade() {
        assert_eq!(CFG.gm_states(), 5);
        let c = BankConfig {
            tau_max_s: 1000.0,
            ..CFG
        };
        assert_eq!(c.gm_states(), 4);
        let c = BankConfig {
            tau_max_s: 1.0,
            ..CFG
        };
        assert_eq!(c.gm_states(), 1);
        for bad in [0.5, 2e4, f32::NAN] {
            let c = BankConfig {
                tau_max_s: bad,
                ..CFG
            };
            assert_eq!(c.gm_states(), 0);
            assert!(LevelBank::new(c, 0.01, 1e-4, 100.0).is_none());
        }
        let c = BankConfig { b_dps: 0.0, ..CFG };
        assert!(LevelBank::new(c, 0.01, 1e-4, 100.0).is_none());
    }

    /// One hour at 100 Hz of a wandering drift, still 3 of every 4 minutes: the f32 filter
    /// follows the f64 reference within 0.01 deg/h at every sample.
    #[test]
    fn matches_an_f64_reference() {
        let fs = 100.0;
        let r = 1.2e-4;
        let bound = 30.0 / 3600.0;
        let mut f = LevelBank::new(CFG, bound, r, fs).expect("valid");
        let mut g = Reference::new(CFG, bound as f64, r as f64, fs as f64);
        let mut z = Noise(7);
        let mut drift = 2.0 / 3600.0;
        let mut worst = 0.0f64;
        for k in 0..360_000u32 {
            drift += 1e-8 * z.normal() as f64;
            let still = (k / 6000) % 4 != 3;
            let y = drift + (r as f64).sqrt() * z.normal() as f64;
            f.predict();
            g.predict();
            if still {
                f.update(y as f32);
                g.update(y);
            }
            let e = (f.estimate_dps() as f64 - g.estimate()).abs() * 3600.0;
            worst = worst.max(e);
        }
        assert!(worst < 0.01, "worst {worst} deg/h");
        // And it tracked the drift.
        assert!((g.estimate() - drift).abs() * 3600.0 < 1.0);
    }

    /// A rotation in motion never reaches the estimate; the fast scales decay, the random
    /// walk holds.
    #[test]
    fn ignores_rotation_and_keeps_the_slow_part() {
        let mut f = LevelBank::new(CFG, 30.0 / 3600.0, 1.2e-4, 100.0).expect("valid");
        let mut z = Noise(3);
        for _ in 0..60_000 {
            f.predict();
            f.update(3.0 / 3600.0 + 0.011 * z.normal());
        }
        let before = f.estimate_dps();
        // Within the fast scales' noise (the 1-s and 10-s states follow the last samples).
        assert!((before * 3600.0 - 3.0).abs() < 1.5, "{}", before * 3600.0);
        for _ in 0..1000 {
            f.predict(); // 10 s of a 30 deg/s turn: no update
        }
        let after = f.estimate_dps();
        assert!(after.abs() <= before.abs() * 1.0001);
        assert!(after.abs() > 0.5 * before.abs());
    }

    /// Rollback restores the checkpoint before the previous window, predicted forward.
    #[test]
    fn rollback_removes_the_failed_windows() {
        let mut f = LevelBank::new(CFG, 30.0 / 3600.0, 1.2e-4, 100.0).expect("valid");
        let mut z = Noise(5);
        for _ in 0..10 {
            f.checkpoint();
            for _ in 0..100 {
                f.predict();
                f.update(1.0 / 3600.0 + 0.011 * z.normal());
            }
        }
        let mut clean = f.clone();
        f.checkpoint();
        for _ in 0..100 {
            f.predict();
            f.update(1.0 / 3600.0 + 0.011 * z.normal());
        }
        f.checkpoint();
        for _ in 0..100 {
            f.predict();
            f.update(0.5); // a drive's start taken for still
        }
        f.rollback(200);
        for _ in 0..200 {
            clean.predict();
        }
        assert!((f.estimate_dps() - clean.estimate_dps()).abs() < 1e-9);
        let v = (f.estimate_var_dps2() / clean.estimate_var_dps2() - 1.0).abs();
        assert!(v < 1e-3, "{v}");
    }
}

//! Causal input features for the network, computed sample by sample in fixed memory.

/// Turns the raw stream into the network's (unscaled) inputs.
pub trait FeatureMap<const N: usize> {
    /// Inputs for the current sample: `rate_dps` measured now, `t_s` since the start.
    fn next(&mut self, rate_dps: f32, t_s: f32) -> [f32; N];
    /// Inputs for the current sample when a temperature channel is measured too (`temp_c`,
    /// deg C; NaN when the sample has none). Maps that do not use temperature ignore it.
    #[inline]
    fn next_with_temp(&mut self, rate_dps: f32, t_s: f32, temp_c: f32) -> [f32; N] {
        let _ = temp_c;
        self.next(rate_dps, t_s)
    }
    /// Inputs to store for the training step of the current sample, when they differ from
    /// what [`FeatureMap::next`] returned for its output (e.g. [`MultiScaleLevels`] with an
    /// undelayed output); `None` (the default): the same.
    #[inline]
    fn train_inputs(&self) -> Option<[f32; N]> {
        None
    }
    /// Forgets the history.
    fn reset(&mut self);
}

/// The paper's inputs: `[X, T]` = `[rate_dps, t_s]`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RateTime;

impl FeatureMap<2> for RateTime {
    #[inline]
    fn next(&mut self, rate_dps: f32, t_s: f32) -> [f32; 2] {
        [rate_dps, t_s]
    }
    fn reset(&mut self) {}
}

/// Mean of the last `BINS` complete bins of `samples_per_bin` samples plus the current
/// partial bin: a causal moving average over `BINS` to `BINS + 1` bins in `BINS + 2` floats.
///
/// With 100 samples per bin at 100 Hz and `BINS = 10` it averages the last 10.00 to 10.99 s,
/// with no 1000-sample buffer. Before the first bin completes it averages what it has.
#[derive(Debug, Clone, PartialEq)]
pub struct BinnedMean<const BINS: usize> {
    samples_per_bin: u32,
    sums: [f32; BINS],
    /// Sum of `sums[..filled_bins]`, in that order, updated when a bin completes (the same
    /// value the per-sample sum would give, computed once per bin).
    complete_sum: f32,
    filled_bins: usize,
    next_bin: usize,
    partial_sum: f32,
    partial_n: u32,
}

impl<const BINS: usize> BinnedMean<BINS> {
    /// A mean over `BINS` bins of `samples_per_bin` samples (at least 1).
    pub fn new(samples_per_bin: u32) -> Self {
        Self {
            samples_per_bin: samples_per_bin.max(1),
            sums: [0.0; BINS],
            complete_sum: 0.0,
            filled_bins: 0,
            next_bin: 0,
            partial_sum: 0.0,
            partial_n: 0,
        }
    }

    /// Adds a sample; returns the current mean and whether a bin just completed.
    pub fn push(&mut self, x: f32) -> (f32, bool) {
        self.partial_sum += x;
        self.partial_n += 1;
        let mut completed = false;
        if self.partial_n >= self.samples_per_bin {
            if let Some(slot) = self.sums.get_mut(self.next_bin) {
                *slot = self.partial_sum;
            }
            self.next_bin = if self.next_bin + 1 >= BINS {
                0
            } else {
                self.next_bin + 1
            };
            self.filled_bins = (self.filled_bins + 1).min(BINS);
            self.complete_sum = self.sums[..self.filled_bins].iter().sum::<f32>();
            self.partial_sum = 0.0;
            self.partial_n = 0;
            completed = true;
        }
        (self.mean(), completed)
    }

    /// Current mean (0 before any sample).
    pub fn mean(&self) -> f32 {
        let n = self.filled_bins as u32 * self.samples_per_bin + self.partial_n;
        if n == 0 {
            return 0.0;
        }
        (self.complete_sum + self.partial_sum) / n as f32
    }

    /// Forgets everything.
    pub fn reset(&mut self) {
        *self = Self::new(self.samples_per_bin);
    }
}

/// Inputs `[level, trend, t_s]`: `level` = mean rate over the last 10 s (a [`BinnedMean`] of
/// 1-s bins), `trend` = `level` minus the mean of the levels seen at the last 50 bin ends.
///
/// With [`LevelTrendTime::with_kalman`] the level is instead the causal estimate (the
/// prediction before the sample's update) of a random-walk Kalman filter (its steady state
/// is an exponential average): the same filter
/// as the [`crate::baseline::RandomWalkKalman`] baseline, so that a network initialised as
/// the identity on its level starts exactly as that baseline.
///
/// Why: the denoised target arrives one block (5.12 s) late, so the network needs an input
/// that follows the drift *now*; the raw rate carries the full white noise (the paper's `X`
/// input makes the network pass it through), the 10-s level carries a tenth of it. Memory:
/// 64 floats.
///
/// With [`LevelTrendTime::with_trend_every`] the trend is computed only every `m` samples
/// and held in between (the level itself still changes every sample), so the network's
/// Gaussians along the trend are evaluated once per `m` samples
/// ([`crate::wnn::HiddenCache`]); the effect on the identification error is measured in
/// `docs/identify.md`.
#[derive(Debug, Clone, PartialEq)]
pub struct LevelTrendTime {
    level: BinnedMean<10>,
    kalman: Option<crate::baseline::RandomWalkKalman>,
    levels: BinnedMean<50>,
    per_bin: u32,
    in_bin: u32,
    /// Samples between two trend computations (1: every sample).
    trend_every: u32,
    /// Samples since the last trend computation.
    trend_age: u32,
    /// The trend of the last computation.
    trend: f32,
}

impl LevelTrendTime {
    /// Features for a stream with `samples_per_s` samples per second (rounded, at least 1).
    pub fn new(samples_per_s: f32) -> Self {
        let per_bin = if samples_per_s.is_finite() && samples_per_s >= 1.0 {
            libm::roundf(samples_per_s) as u32
        } else {
            1
        };
        Self {
            level: BinnedMean::new(per_bin),
            kalman: None,
            levels: BinnedMean::new(1),
            per_bin,
            in_bin: 0,
            trend_every: 1,
            trend_age: 0,
            trend: 0.0,
        }
    }

    /// The trend computed at samples `m - 1, 2m - 1, ...` (the same value as every sample
    /// would give there) and held for the `m - 1` samples after each (0 before the first);
    /// `m` at least 1.
    pub fn with_trend_every(mut self, m: u32) -> Self {
        self.trend_every = m.max(1);
        self
    }

    /// Level from a random-walk Kalman filter with process-to-measurement noise ratio
    /// `q_over_r` per sample (time constant about `1/sqrt(q_over_r)` samples) instead of the
    /// 10-s mean.
    pub fn with_kalman(samples_per_s: f32, q_over_r: f32) -> Self {
        let mut s = Self::new(samples_per_s);
        s.kalman = Some(crate::baseline::RandomWalkKalman::new(q_over_r, 1.0));
        s
    }
}

impl FeatureMap<3> for LevelTrendTime {
    fn next(&mut self, rate_dps: f32, t_s: f32) -> [f32; 3] {
        let (boxcar, boxcar_bin_done) = self.level.push(rate_dps);
        let (level, bin_done) = match self.kalman.as_mut() {
            None => (boxcar, boxcar_bin_done),
            Some(k) => {
                self.in_bin += 1;
                let done = self.in_bin >= self.per_bin;
                if done {
                    self.in_bin = 0;
                }
                (k.push(rate_dps), done)
            }
        };
        if bin_done {
            self.levels.push(level);
        }
        self.trend_age += 1;
        if self.trend_age >= self.trend_every {
            self.trend_age = 0;
            self.trend = if self.levels.filled_bins == 0 {
                0.0
            } else {
                level - self.levels.mean()
            };
        }
        [level, self.trend, t_s]
    }

    fn reset(&mut self) {
        self.level.reset();
        self.levels.reset();
        self.in_bin = 0;
        self.trend_age = 0;
        self.trend = 0.0;
        if let Some(k) = self.kalman.as_mut() {
            *k = crate::baseline::RandomWalkKalman::new(k.q(), k.r());
        }
    }
}

/// Bins of the temperature used by [`TimeTemp`] for its rate estimate: 2 x 30 one-second
/// bins.
pub(crate) const TEMP_RATE_BINS: usize = 60;

/// Inputs `[t_s, temp_c, dtemp_c_per_s]`: time since switch-on, the measured temperature,
/// and its rate of change, all from known inputs (none from the gyro rate): the inputs of a
/// model of the *repeatable* drift (warm-up as a function of time since switch-on,
/// temperature sensitivity, Shupe effect), which can then be predicted at zero lag instead
/// of tracked.
///
/// `dtemp_c_per_s` is causal: the difference between the mean temperature of the last 30
/// one-second bins and of the 30 before, over 30 s (a slope estimate about 30 s late, which
/// suppresses quantization steps of the temperature sensor: 1/16 C steps give rate errors
/// below 0.002 C/s). Before 60 bins exist it uses the halves of what it has (0 with fewer
/// than 2 bins). A sample without temperature (NaN, or [`FeatureMap::next`]) repeats the
/// last temperature seen (0 before any). Memory: 60 + 4 floats.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeTemp {
    per_bin: u32,
    bin_sum: f32,
    bin_n: u32,
    bins: [f32; TEMP_RATE_BINS],
    filled: usize,
    next_bin: usize,
    last_temp_c: f32,
    rate_c_per_s: f32,
}

impl TimeTemp {
    /// Features for a stream with `samples_per_s` samples per second (rounded, at least 1).
    pub fn new(samples_per_s: f32) -> Self {
        let per_bin = if samples_per_s.is_finite() && samples_per_s >= 1.0 {
            libm::roundf(samples_per_s) as u32
        } else {
            1
        };
        Self {
            per_bin,
            bin_sum: 0.0,
            bin_n: 0,
            bins: [0.0; TEMP_RATE_BINS],
            filled: 0,
            next_bin: 0,
            last_temp_c: 0.0,
            rate_c_per_s: 0.0,
        }
    }

    /// Bin `i` counted back from the newest (0 = newest); only for `i < filled`.
    fn back(&self, i: usize) -> f32 {
        let idx = (self.next_bin + TEMP_RATE_BINS - 1 - i) % TEMP_RATE_BINS;
        self.bins.get(idx).copied().unwrap_or(0.0)
    }

    fn update_rate(&mut self) {
        let half = self.filled / 2;
        if half == 0 {
            self.rate_c_per_s = 0.0;
            return;
        }
        let (mut new, mut old) = (0.0f32, 0.0f32);
        for i in 0..half {
            new += self.back(i);
            old += self.back(half + i);
        }
        // Bins are one second long (per_bin samples at samples_per_s).
        self.rate_c_per_s = (new - old) / (half * half) as f32;
    }
}

impl FeatureMap<3> for TimeTemp {
    fn next(&mut self, rate_dps: f32, t_s: f32) -> [f32; 3] {
        self.next_with_temp(rate_dps, t_s, f32::NAN)
    }

    fn next_with_temp(&mut self, _rate_dps: f32, t_s: f32, temp_c: f32) -> [f32; 3] {
        if temp_c.is_finite() {
            self.last_temp_c = temp_c;
        }
        self.bin_sum += self.last_temp_c;
        self.bin_n += 1;
        if self.bin_n >= self.per_bin {
            if let Some(slot) = self.bins.get_mut(self.next_bin) {
                *slot = self.bin_sum / self.bin_n as f32;
            }
            self.next_bin = (self.next_bin + 1) % TEMP_RATE_BINS;
            self.filled = (self.filled + 1).min(TEMP_RATE_BINS);
            self.bin_sum = 0.0;
            self.bin_n = 0;
            self.update_rate();
        }
        [t_s, self.last_temp_c, self.rate_c_per_s]
    }

    fn reset(&mut self) {
        *self = Self::new(self.per_bin as f32);
    }
}

/// Memories of the [`MultiScaleLevels`] levels, s, shortest first.
pub const BANK_MEMORIES_S: [f32; 6] = [3.0, 10.0, 30.0, 100.0, 300.0, 1000.0];

/// Delay of the rate entering the [`MultiScaleLevels`] levels, samples: at least the half support
/// of the denoiser's level-3 approximation (db4: (8 - 1)(2^3 - 1) + 1 = 50 samples), so that
/// no sample's noise is both in a training input and in its target (see [`MultiScaleLevels`]).
pub const BANK_DELAY: usize = 64;

/// Number of inputs of [`MultiScaleLevels`].
pub const BANK_INPUTS: usize = BANK_MEMORIES_S.len() + 3;

/// Index of `T` among the [`MultiScaleLevels`] inputs (then `temp_c`, `dtemp_c_per_s`).
pub const BANK_T: usize = BANK_MEMORIES_S.len();

/// A bank of causal levels of the rate at several time scales, plus the known inputs:
/// `[K_1000, K_3 - K_10, K_10 - K_30, K_30 - K_100, K_100 - K_300, K_300 - K_1000, T,
/// temp_c, dtemp_c_per_s]`, where `K_m` is the causal estimate (before the sample's update)
/// of a random-walk Kalman filter with memory `m` seconds (q/r = (dt/m)^2 per sample): it
/// starts as the growing mean of the record and settles into an exponential average of
/// memory `m`.
///
/// Why: any linear causal estimator of the drift from the rate is a filter; a weighted sum
/// of these levels spans exponential filters from 3 s to 1000 s, so a linear output layer
/// trained by least squares finds the best mixture (the single tuned Kalman filter is one
/// of them: weights 1 on `K_1000` and on every difference from its memory up). The
/// differences (not the levels themselves) are the inputs because the levels are nearly
/// collinear (all carry the turn-on bias), which a per-weight trainer (DRLS) handles badly;
/// the differences are nearly uncorrelated. `T`, `temp_c`, `dtemp_c_per_s` are those of
/// [`TimeTemp`] (the part of the drift that known inputs predict, at zero lag).
///
/// The levels see the rate [`BANK_DELAY`] samples late. The training target `d(k)` is the
/// denoised rate, which keeps the low-frequency part of the noise of the samples around
/// `k`; a level that contains those same samples is correlated with the target's noise,
/// and least squares then learns to reproduce that noise (measured: with no delay the
/// learned mixture was far worse than the single level it started from). With the delay,
/// inputs and target share no sample; the cost is that the levels are 64 samples (0.3 to
/// 1.3 s) older than the sample whose drift they estimate, which for drift on time scales
/// of tens of seconds is negligible, and no advantage over the zero-latency baselines.
/// Memory: 6 filters (5 floats each) + 64 floats + [`TimeTemp`].
#[derive(Debug, Clone, PartialEq)]
pub struct MultiScaleLevels {
    levels: [crate::baseline::RandomWalkKalman; BANK_MEMORIES_S.len()],
    known: TimeTemp,
    delay: [f32; BANK_DELAY],
    seen: usize,
    /// With [`MultiScaleLevels::undelayed_output`]: levels on the current samples (for the
    /// output) and the inputs of the delayed levels (for training).
    now: Option<[crate::baseline::RandomWalkKalman; BANK_MEMORIES_S.len()]>,
    train: [f32; BANK_INPUTS],
}

impl MultiScaleLevels {
    /// Features for a stream with `samples_per_s` samples per second.
    pub fn new(samples_per_s: f32) -> Self {
        let dt = if samples_per_s.is_finite() && samples_per_s > 0.0 {
            1.0 / samples_per_s
        } else {
            1.0
        };
        Self {
            levels: core::array::from_fn(|i| {
                let r = dt / BANK_MEMORIES_S[i];
                crate::baseline::RandomWalkKalman::new(r * r, 1.0)
            }),
            known: TimeTemp::new(samples_per_s),
            delay: [0.0; BANK_DELAY],
            seen: 0,
            now: None,
            train: [0.0; BANK_INPUTS],
        }
    }

    /// Output from levels on the current samples (no delay), training inputs from the
    /// delayed ones: the weights are learned on inputs that share no noise with their
    /// targets (a predictor 64 samples ahead), and applied to the freshest levels (for
    /// drift on time scales of seconds and more, the two predictors are the same). Costs
    /// six more filters.
    pub fn undelayed_output(mut self) -> Self {
        self.now = Some(self.levels);
        self
    }

    fn assemble(k: &[f32; BANK_MEMORIES_S.len()], known: &[f32; 3]) -> [f32; BANK_INPUTS] {
        let mut out = [0.0f32; BANK_INPUTS];
        let last = BANK_MEMORIES_S.len() - 1;
        out[0] = k[last];
        for i in 0..last {
            out[1 + i] = k[i] - k[i + 1];
        }
        out[BANK_T..].copy_from_slice(known);
        out
    }
}

impl FeatureMap<BANK_INPUTS> for MultiScaleLevels {
    fn next(&mut self, rate_dps: f32, t_s: f32) -> [f32; BANK_INPUTS] {
        self.next_with_temp(rate_dps, t_s, f32::NAN)
    }

    fn next_with_temp(&mut self, rate_dps: f32, t_s: f32, temp_c: f32) -> [f32; BANK_INPUTS] {
        let slot = self.seen % BANK_DELAY;
        let old = self.delay.get(slot).copied().unwrap_or(0.0);
        if let Some(v) = self.delay.get_mut(slot) {
            *v = rate_dps;
        }
        let delayed = self.seen >= BANK_DELAY;
        self.seen = self.seen.saturating_add(1);
        let mut k = [0.0f32; BANK_MEMORIES_S.len()];
        for (ki, f) in k.iter_mut().zip(self.levels.iter_mut()) {
            // Before the delay line is full the levels wait (0 until their first sample).
            *ki = if delayed {
                f.push(old)
            } else {
                f.push(f32::NAN)
            };
        }
        let known = self.known.next_with_temp(rate_dps, t_s, temp_c);
        let delayed_inputs = Self::assemble(&k, &known);
        match self.now.as_mut() {
            None => delayed_inputs,
            Some(now) => {
                self.train = delayed_inputs;
                let mut kn = [0.0f32; BANK_MEMORIES_S.len()];
                for (ki, f) in kn.iter_mut().zip(now.iter_mut()) {
                    *ki = f.push(rate_dps);
                }
                Self::assemble(&kn, &known)
            }
        }
    }

    fn train_inputs(&self) -> Option<[f32; BANK_INPUTS]> {
        self.now.is_some().then_some(self.train)
    }

    fn reset(&mut self) {
        for f in self.levels.iter_mut() {
            *f = crate::baseline::RandomWalkKalman::new(f.q(), f.r());
        }
        self.known.reset();
        self.delay = [0.0; BANK_DELAY];
        self.seen = 0;
        if let Some(now) = self.now.as_mut() {
            for f in now.iter_mut() {
                *f = crate::baseline::RandomWalkKalman::new(f.q(), f.r());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binned_mean_is_a_sliding_mean_of_bins() {
        let mut m = BinnedMean::<3>::new(2);
        let mut last = 0.0;
        for k in 0..20 {
            last = m.push(k as f32).0;
        }
        // After 20 samples: bins hold (14+15), (16+17), (18+19); no partial.
        assert_eq!(last, (14..20).sum::<i32>() as f32 / 6.0);
        assert_eq!(
            m.push(100.0).0,
            ((14..20).sum::<i32>() as f32 + 100.0) / 7.0
        );
    }

    #[test]
    fn time_temp_rate_of_a_ramp() {
        // 0.01 C/s ramp at 10 Hz: after 100 s the rate estimate is the ramp's slope.
        let mut f = TimeTemp::new(10.0);
        let mut out = [0.0; 3];
        for k in 0..1000 {
            let t = k as f32 * 0.1;
            out = f.next_with_temp(0.0, t, 20.0 + 0.01 * t);
        }
        assert!((out[2] - 0.01).abs() < 1e-4, "{out:?}");
        assert!((out[1] - (20.0 + 0.01 * 99.9)).abs() < 1e-4);
        // No temperature: the last one is held, so the rate decays to 0.
        for k in 1000..2000 {
            out = f.next(0.0, k as f32 * 0.1);
        }
        assert!(out[2].abs() < 1e-6, "{out:?}");
        assert!((out[1] - (20.0 + 0.01 * 99.9)).abs() < 1e-4);
    }

    #[test]
    fn level_and_trend() {
        let mut f = LevelTrendTime::new(10.0);
        let mut out = [0.0; 3];
        for k in 0..1000 {
            out = f.next(2.0, k as f32 * 0.1);
        }
        assert_eq!(out[0], 2.0);
        assert_eq!(out[1], 0.0);
        assert!((out[2] - 99.9).abs() < 1e-3);
    }

    /// `with_trend_every(m)`: at samples m-1, 2m-1, ... the held trend equals the
    /// per-sample trend (same bits); in between it keeps that value; 0 before. `m` = 1 is
    /// the per-sample trend; 7 does not divide the 10-sample bins, 10 does.
    #[test]
    fn trend_held_every_m_samples() {
        for m in [1u32, 7, 10] {
            let mut live = LevelTrendTime::new(10.0);
            let mut held = LevelTrendTime::new(10.0).with_trend_every(m);
            let mut last = 0.0f32;
            for k in 0..2_000u32 {
                let x = 0.01 * (k as f32 * 0.013).sin() + 1e-4 * (k % 7) as f32;
                let a = live.next(x, k as f32 * 0.1);
                let b = held.next(x, k as f32 * 0.1);
                assert_eq!(a[0].to_bits(), b[0].to_bits());
                assert_eq!(a[2].to_bits(), b[2].to_bits());
                if (k + 1) % m == 0 {
                    assert_eq!(a[1].to_bits(), b[1].to_bits(), "m {m}, sample {k}");
                    last = b[1];
                } else {
                    assert_eq!(b[1].to_bits(), last.to_bits(), "m {m}, sample {k}");
                }
            }
            assert_ne!(last, 0.0);
            held.reset();
            assert_eq!(held.next(1.0, 0.0)[1], 0.0);
        }
    }
}

//! Causal input features for the network, computed sample by sample in fixed memory.

/// Turns the raw stream into the network's (unscaled) inputs.
pub trait FeatureMap<const N: usize> {
    /// Inputs for the current sample: `rate_dps` measured now, `t_s` since the start.
    fn next(&mut self, rate_dps: f32, t_s: f32) -> [f32; N];
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
        // `take`, not `[..filled_bins]`: no range check (filled_bins <= BINS always).
        let total: f32 = self.sums.iter().take(self.filled_bins).sum::<f32>() + self.partial_sum;
        total / n as f32
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
#[derive(Debug, Clone, PartialEq)]
pub struct LevelTrendTime {
    level: BinnedMean<10>,
    kalman: Option<crate::baseline::RandomWalkKalman>,
    levels: BinnedMean<50>,
    per_bin: u32,
    in_bin: u32,
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
        }
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
        let trend = if self.levels.filled_bins == 0 {
            0.0
        } else {
            level - self.levels.mean()
        };
        [level, trend, t_s]
    }

    fn reset(&mut self) {
        self.level.reset();
        self.levels.reset();
        self.in_bin = 0;
        if let Some(k) = self.kalman.as_mut() {
            *k = crate::baseline::RandomWalkKalman::new(k.q(), k.r());
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
}

//! What the motion replay counts while a record streams through it: the summary's figures,
//! in constant memory.

use crate::report::motion::Angle;
use fog_core::drift_filter::DriftOutput;

/// Bins per decade of [`DiffMedian`]: 100, so the median is read within 1.2 %.
const BINS_PER_DECADE: f64 = 100.0;
/// Smallest |difference| binned, log10 (smaller nonzero ones share the first bin).
const LOG10_LO: f64 = -12.0;
/// Decades binned: 1e-12 .. 1e8 deg/s (larger ones share the last bin).
const DECADES: usize = 20;

/// The median |first difference| of a stream of rates, from a log-spaced histogram (100
/// bins per decade: the bin's geometric centre is within 1.2 % of the exact median; exact
/// when it is 0) in 16 kB whatever the record's length. Non-finite differences are left out.
#[derive(Debug, Clone)]
pub struct DiffMedian {
    prev: Option<f64>,
    zeros: u64,
    n: u64,
    bins: Vec<u64>,
}

impl Default for DiffMedian {
    fn default() -> Self {
        Self {
            prev: None,
            zeros: 0,
            n: 0,
            bins: vec![0; DECADES * BINS_PER_DECADE as usize],
        }
    }
}

impl DiffMedian {
    /// One rate, deg/s.
    pub fn push(&mut self, rate_dps: f64) {
        if let Some(p) = self.prev.replace(rate_dps) {
            let d = (rate_dps - p).abs();
            if !d.is_finite() {
                return;
            }
            self.n += 1;
            if d == 0.0 {
                self.zeros += 1;
                return;
            }
            let i = ((d.log10() - LOG10_LO) * BINS_PER_DECADE).floor();
            let last = self.bins.len() - 1;
            let i = if i <= 0.0 { 0 } else { (i as usize).min(last) };
            self.bins[i] += 1;
        }
    }

    /// Differences counted.
    pub fn len(&self) -> u64 {
        self.n
    }

    /// Whether no difference was counted.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// The median (the value at sorted index `n / 2`), deg/s; `None` without a difference.
    pub fn median(&self) -> Option<f64> {
        if self.n == 0 {
            return None;
        }
        let mid = self.n / 2;
        if mid < self.zeros {
            return Some(0.0);
        }
        let mut seen = self.zeros;
        for (i, &c) in self.bins.iter().enumerate() {
            seen += c;
            if mid < seen {
                return Some(10f64.powf(LOG10_LO + (i as f64 + 0.5) / BINS_PER_DECADE));
            }
        }
        None
    }

    /// The record's one-sample white noise over `sensor`'s: the median |first difference|
    /// (robust to the few large steps of a turn's onset) over `0.6745 sqrt(2)`, against the
    /// sensor's noise plus quantization. `None` when the median is 0 (a coarse quantum or a
    /// stuck output: not measurable this way) or there are fewer than 15 differences.
    pub fn noise_ratio(&self, sample_var_dps2: f32) -> Option<f64> {
        if self.n < 15 {
            return None;
        }
        let sigma = self.median()? / (0.674_49 * std::f64::consts::SQRT_2);
        let image = f64::from(sample_var_dps2).sqrt();
        (sigma > 0.0 && image > 0.0).then(|| sigma / image)
    }
}

/// The summary's counts over the rows of a motion replay.
#[derive(Debug, Clone, Default)]
pub struct Tally {
    /// Full scale, deg/s.
    full_scale_dps: f32,
    /// Rows.
    pub rows: usize,
    /// Rows at or beyond the full scale.
    pub at_full_scale: usize,
    /// Largest |rate|, deg/s.
    pub max_abs_rate_dps: f32,
    /// Rows flagged still.
    pub still_rows: usize,
    /// Largest |drift estimate|, deg/s.
    pub max_abs_drift_dps: f64,
    /// Raw angle (integral of the rate).
    pub raw: Angle,
    /// Compensated angle.
    pub compensated: Angle,
    /// The rate's |first differences|.
    pub noise: DiffMedian,
}

impl Tally {
    /// Counts for a sensor of full scale `full_scale_dps`.
    pub fn new(full_scale_dps: f32) -> Self {
        Self {
            full_scale_dps,
            ..Self::default()
        }
    }

    /// One row: time, the rate the estimator read and its output.
    pub fn push(&mut self, t_s: f64, rate_dps: f32, m: &DriftOutput) {
        self.rows += 1;
        self.at_full_scale += usize::from(rate_dps.abs() >= self.full_scale_dps);
        self.max_abs_rate_dps = self.max_abs_rate_dps.max(rate_dps.abs());
        self.still_rows += usize::from(m.still);
        self.max_abs_drift_dps = self.max_abs_drift_dps.max(f64::from(m.drift_dps).abs());
        self.raw.push(t_s, f64::from(rate_dps));
        self.compensated.push(t_s, f64::from(m.compensated_dps));
        self.noise.push(f64::from(rate_dps));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The histogram's median against the exact median of the same differences.
    #[test]
    fn median_within_the_bin_width_of_the_exact_one() {
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let mut rates = Vec::new();
        for _ in 0..20_001 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            rates.push((x >> 11) as f64 / (1u64 << 53) as f64 * 0.01 - 0.005);
        }
        let mut h = DiffMedian::default();
        for &r in &rates {
            h.push(r);
        }
        let mut d: Vec<f64> = rates.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
        let mid = d.len() / 2;
        let exact = *d.select_nth_unstable_by(mid, f64::total_cmp).1;
        let got = h.median().expect("median");
        assert!((got / exact - 1.0).abs() < 0.012, "{got} vs {exact}");
        assert_eq!(h.len(), 20_000);
    }

    #[test]
    fn quantized_stream_with_most_differences_zero_has_median_zero() {
        let mut h = DiffMedian::default();
        for k in 0..100 {
            h.push(if k % 10 == 0 { 1.0 } else { 0.0 });
        }
        assert_eq!(h.median(), Some(0.0));
        assert_eq!(
            h.noise_ratio(fog_core::sensor::SensorConfig::ECORE_2000.sample_var_dps2()),
            None
        );
        assert_eq!(DiffMedian::default().median(), None);
    }
}

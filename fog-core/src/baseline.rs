//! Causal drift estimators the identifier is compared with: cheap, and hard to beat.

use crate::kalman::{DiagonalModel, Kalman};

/// Scalar Kalman filter for a random-walk bias observed in white noise:
/// `b(k) = b(k-1) + w`, `var w = q`; `z(k) = b(k) + v`, `var v = r` (both deg^2/s^2).
///
/// Only `q / r` matters for the estimate; the steady-state gain is about `sqrt(q/r)` for
/// small `q/r`, an exponential average with a memory of `sqrt(r/q)` samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RandomWalkKalman {
    model: DiagonalModel<1>,
    r: f32,
    kf: Kalman<1>,
    started: bool,
}

impl RandomWalkKalman {
    /// A filter; `q` and `r` must be > 0 (otherwise 1e-6 and 1 are used).
    pub fn new(q: f32, r: f32) -> Self {
        let ok = |v: f32, d: f32| if v > 0.0 && v.is_finite() { v } else { d };
        Self {
            model: DiagonalModel {
                phi: [1.0],
                q: [ok(q, 1e-6)],
            },
            r: ok(r, 1.0),
            kf: Kalman::new([0.0], [0.0]),
            started: false,
        }
    }

    /// Process noise variance per sample.
    pub fn q(&self) -> f32 {
        self.model.q[0]
    }

    /// Measurement noise variance.
    pub fn r(&self) -> f32 {
        self.r
    }

    /// Estimate of the bias *before* this measurement (the causal prediction), then updates.
    pub fn push(&mut self, z: f32) -> f32 {
        let prediction = self.kf.x()[0];
        if !z.is_finite() {
            return prediction;
        }
        if !self.started {
            // First measurement: the estimate starts there with the measurement's variance.
            self.started = true;
            self.kf = Kalman::new([z], [self.r]);
            return z;
        }
        self.kf.predict(&self.model);
        self.kf.update(&[1.0], z, self.r);
        prediction
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kalman_tracks_a_constant() {
        let mut f = RandomWalkKalman::new(1e-4, 1.0);
        let mut y = 0.0;
        for k in 0..5000 {
            y = f.push(if k % 2 == 0 { 3.0 } else { 1.0 });
        }
        assert!((y - 2.0).abs() < 0.05, "{y}");
    }
}

//! Normalised least mean squares: `w += mu e h / (eps + h . h)`.

use super::{bound_weights, finite_inputs, Trainer};
use crate::wnn::dot;

/// Fixed NLMS configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NlmsConfig {
    /// Step size, `0 < mu < 2` for stability (1 = a-posteriori error 0).
    pub mu: f32,
    /// Regulariser of the normalisation, > 0 (same unit as `h . h`).
    pub eps: f32,
    /// Bound of every `|w|`.
    pub w_max: f32,
}

/// NLMS trainer (stateless but for its configuration).
#[derive(Debug, Clone, PartialEq)]
pub struct Nlms {
    cfg: NlmsConfig,
}

impl Nlms {
    /// A trainer; `None` unless `0 < mu < 2`, `eps > 0` and `w_max > 0`.
    pub fn new(cfg: NlmsConfig) -> Option<Self> {
        (cfg.mu > 0.0 && cfg.mu < 2.0 && cfg.eps > 0.0 && cfg.w_max > 0.0).then_some(Self { cfg })
    }
}

impl<const L: usize> Trainer<L> for Nlms {
    fn step(&mut self, w: &mut [f32; L], h: &[f32; L], d: f32) -> f32 {
        if !finite_inputs(h, d) {
            return f32::NAN;
        }
        let e = d - dot(w, h);
        let g = self.cfg.mu * e / (self.cfg.eps + dot(h, h));
        for (wa, ha) in w.iter_mut().zip(h) {
            *wa += g * ha;
        }
        bound_weights(w, self.cfg.w_max);
        e
    }

    fn reset(&mut self) {}
}

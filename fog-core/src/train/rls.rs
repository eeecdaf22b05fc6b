//! Exponentially weighted recursive least squares with the full `L x L` inverse
//! correlation matrix `P`: the O(L^2) baseline DRLS is compared with.
//!
//! ```text
//! k = P h / (lambda + h' P h);   e = d - w . h;   w += k e;   P = (P - k h' P) / lambda
//! ```
//! Guards: `P` is kept symmetric (only one triangle is computed), and when its trace
//! exceeds `trace_max` (a long silent stretch inflates it by `1/lambda` per sample) it is
//! scaled back to that trace.

use super::{bound_weights, finite_inputs, Trainer};
use crate::wnn::dot;

/// Fixed RLS configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RlsConfig {
    /// Forgetting factor, `0 < lambda <= 1`.
    pub lambda: f32,
    /// `P(0) = delta I`, > 0.
    pub delta: f32,
    /// Largest trace of `P` allowed (the guard).
    pub trace_max: f32,
    /// Bound of every `|w|`.
    pub w_max: f32,
}

/// RLS trainer state: `P`, `L^2` floats.
#[derive(Debug, Clone, PartialEq)]
pub struct Rls<const L: usize> {
    cfg: RlsConfig,
    p: [[f32; L]; L],
}

impl<const L: usize> Rls<L> {
    /// A trainer; `None` for an invalid configuration.
    pub fn new(cfg: RlsConfig) -> Option<Self> {
        let ok = cfg.lambda > 0.0
            && cfg.lambda <= 1.0
            && cfg.delta > 0.0
            && cfg.delta.is_finite()
            && cfg.trace_max > 0.0
            && cfg.w_max > 0.0;
        ok.then(|| {
            let mut s = Self {
                cfg,
                p: [[0.0; L]; L],
            };
            s.reset_p();
            s
        })
    }

    fn reset_p(&mut self) {
        for (i, row) in self.p.iter_mut().enumerate() {
            *row = [0.0; L];
            row[i] = self.cfg.delta;
        }
    }

    /// Trace of `P`.
    pub fn trace(&self) -> f32 {
        (0..L).map(|i| self.p[i][i]).sum()
    }
}

impl<const L: usize> Trainer<L> for Rls<L> {
    fn step(&mut self, w: &mut [f32; L], h: &[f32; L], d: f32) -> f32 {
        if !finite_inputs(h, d) {
            return f32::NAN;
        }
        let ph: [f32; L] = core::array::from_fn(|i| dot(&self.p[i], h));
        let denom = self.cfg.lambda + dot(h, &ph);
        let e = d - dot(w, h);
        if !(denom > 0.0 && denom.is_finite()) {
            // P lost positive definiteness (rounding): start it again.
            self.reset_p();
            return e;
        }
        let inv_denom = 1.0 / denom;
        for (wa, pa) in w.iter_mut().zip(&ph) {
            *wa += pa * inv_denom * e;
        }
        let inv_lambda = 1.0 / self.cfg.lambda;
        for i in 0..L {
            for j in i..L {
                let v = (self.p[i][j] - ph[i] * ph[j] * inv_denom) * inv_lambda;
                self.p[i][j] = v;
                self.p[j][i] = v;
            }
        }
        let tr = self.trace();
        if tr.is_nan() || tr > self.cfg.trace_max {
            if tr.is_finite() && tr > 0.0 {
                let s = self.cfg.trace_max / tr;
                for row in self.p.iter_mut() {
                    for v in row.iter_mut() {
                        *v *= s;
                    }
                }
            } else {
                self.reset_p();
            }
        }
        bound_weights(w, self.cfg.w_max);
        e
    }

    fn reset(&mut self) {
        self.reset_p();
    }
}

//! DRLS: per-weight recursive least squares with forgetting, no matrix (paper eqs. 6-15).
//!
//! ```text
//! e(k)    = d(k) - sum_l w_l(k-1) h_l(k)
//! U_a(k)  = (U_a(k-1)/lambda) / (1 + (U_a(k-1)/lambda) h_a(k)^2)
//! w_a(k)  = w_a(k-1) + U_a(k) h_a(k) e
//! ```
//!
//! What the paper leaves open, decided here (see [`DrlsConfig`]):
//! - **Mode.** [`DrlsMode::Parallel`] updates every weight with the same a-priori error, as
//!   eq. (15) is written. Each weight then corrects the whole error on its own, so with
//!   overlapping neurons the corrections add up (`sum_a U_a h_a^2` can exceed 2) and the
//!   recursion diverges. [`DrlsMode::Sequential`] refreshes the error after each weight
//!   (`e -= dw_a h_a`), which is what eqs. (6)-(7) say when `rho` is taken with the
//!   weights already updated: a Gauss-Seidel sweep, stable for any overlap.
//! - **`U_a(0)`** = [`DrlsConfig::u0`] (the inverse of an initial "energy" `S_a(0)`).
//! - **Guard.** With `h_a = 0` the recursion gives `U_a(k) = U_a(k-1)/lambda`: with
//!   lambda = 0.63 a silent neuron's `U_a` overflows f32 after about 190 samples (from 1),
//!   then `inf/inf` gives NaN. The guard caps `U_a <= u_max` (equivalently `S_a >= 1/u_max`:
//!   the forgotten energy never drops below a floor), and caps `|w_a| <= w_max`. With
//!   `u_max = INFINITY` and `w_max = INFINITY` the trainer is eq. (15) exactly.

use super::{bound_weights, Trainer};

/// How the error is shared among the weights within one sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DrlsMode {
    /// Eq. (15) as written: all weights updated with the same a-priori error.
    Parallel,
    /// The error refreshed after each weight's update (Gauss-Seidel).
    Sequential,
}

/// Fixed DRLS configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DrlsConfig {
    /// Forgetting factor, `0 < lambda <= 1` (paper: 0.63). Memory ~ `1/(1 - lambda)` samples.
    pub lambda: f32,
    /// `U_a(0)` for every weight, > 0.
    pub u0: f32,
    /// Upper bound of every `U_a` (the guard); `f32::INFINITY` = unguarded.
    pub u_max: f32,
    /// Bound of every `|w_a|`, output unit; `f32::INFINITY` = unbounded.
    pub w_max: f32,
    /// Error sharing.
    pub mode: DrlsMode,
}

impl DrlsConfig {
    /// Eq. (15) exactly as the paper writes it: lambda = 0.63, parallel, no guard, `U(0)=1`.
    pub const PAPER: Self = Self {
        lambda: 0.63,
        u0: 1.0,
        u_max: f32::INFINITY,
        w_max: f32::INFINITY,
        mode: DrlsMode::Parallel,
    };

    /// The paper's lambda with the sequential update and the guard (`U_a <= U_a(0)`,
    /// `|w| <= 1e4`).
    pub const PAPER_GUARDED: Self = Self {
        lambda: 0.63,
        u0: 1.0,
        u_max: 1.0,
        w_max: 1.0e4,
        mode: DrlsMode::Sequential,
    };

    /// True when the configuration is usable (`0 < lambda <= 1`, `u0 > 0`, bounds > 0).
    pub fn is_valid(&self) -> bool {
        self.lambda > 0.0
            && self.lambda <= 1.0
            && self.u0 > 0.0
            && self.u0.is_finite()
            && self.u_max > 0.0
            && self.w_max > 0.0
    }
}

/// DRLS trainer state for `L` weights of one output.
#[derive(Debug, Clone, PartialEq)]
pub struct Drls<const L: usize> {
    cfg: DrlsConfig,
    inv_lambda: [f32; L],
    u0: [f32; L],
    u: [f32; L],
    /// Steps at which a weight hit `w_max` (diagnostic).
    pub weight_saturations: u32,
}

impl<const L: usize> Drls<L> {
    /// A trainer; `None` for an invalid configuration.
    pub fn new(cfg: DrlsConfig) -> Option<Self> {
        if !cfg.is_valid() {
            return None;
        }
        let u0 = cfg.u0.min(cfg.u_max);
        Some(Self {
            cfg,
            inv_lambda: [1.0 / cfg.lambda; L],
            u0: [u0; L],
            u: [u0; L],
            weight_saturations: 0,
        })
    }

    /// Gives neuron `a` its own forgetting factor and `U_a(0)` (e.g. a bias neuron that must
    /// follow the turn-on bias faster than the others). Ignored for an invalid `a`, lambda
    /// outside `(0, 1]` or `u0 <= 0`; `u0` is capped at `u_max`.
    pub fn set_neuron(&mut self, a: usize, lambda: f32, u0: f32) {
        if a < L && lambda > 0.0 && lambda <= 1.0 && u0 > 0.0 {
            self.inv_lambda[a] = 1.0 / lambda;
            self.u0[a] = u0.min(self.cfg.u_max);
            self.u[a] = self.u0[a];
        }
    }

    /// The configuration.
    pub fn config(&self) -> &DrlsConfig {
        &self.cfg
    }

    /// Current `U_a` of every weight.
    pub fn u(&self) -> &[f32; L] {
        &self.u
    }
}

impl<const L: usize> Drls<L> {
    /// The per-weight sweep with the a-priori error `e0`, in two passes. Pass 1: every
    /// `U_a` (independent of the error: no dependency chain, so a host vectorises its
    /// divisions). Pass 2: the weights, `SEQ` refreshing the error after each one
    /// (Gauss-Seidel), which is the only serial chain. The operations on each weight are
    /// the same, in the same order, as in a single pass. Returns the sum of the new
    /// weights' squares (in any order: it is only compared with a bound).
    #[inline(always)]
    pub(crate) fn sweep_two_pass<const SEQ: bool>(
        &mut self,
        w: &mut [f32; L],
        h: &[f32; L],
        e0: f32,
    ) -> f32 {
        let u_max = self.cfg.u_max;
        for ((ua, il), &ha) in self.u.iter_mut().zip(&self.inv_lambda).zip(h) {
            let up = *ua * il;
            let un = up / (1.0 + up * ha * ha);
            *ua = if un > u_max { u_max } else { un };
        }
        let mut e = e0;
        let (mut sq0, mut sq1) = (0.0f32, 0.0f32);
        let mut a = 0;
        while a + 1 < L {
            let dw = self.u[a] * h[a] * e;
            if SEQ {
                e -= dw * h[a];
            }
            let w0 = w[a] + dw;
            w[a] = w0;
            sq0 += w0 * w0;
            let dw = self.u[a + 1] * h[a + 1] * e;
            if SEQ {
                e -= dw * h[a + 1];
            }
            let w1 = w[a + 1] + dw;
            w[a + 1] = w1;
            sq1 += w1 * w1;
            a += 2;
        }
        if a < L {
            let dw = self.u[a] * h[a] * e;
            let w0 = w[a] + dw;
            w[a] = w0;
            sq0 += w0 * w0;
        }
        sq0 + sq1
    }

    /// The same sweep in one pass: the same operations on each weight in the same order as
    /// [`Self::sweep_two_pass`], so the same bits (test `sweeps_agree`), with fewer
    /// instructions on a core without SIMD (no second load of `U_a` and `h_a`).
    #[inline(always)]
    pub(crate) fn sweep_fused<const SEQ: bool>(
        &mut self,
        w: &mut [f32; L],
        h: &[f32; L],
        e0: f32,
    ) -> f32 {
        let u_max = self.cfg.u_max;
        let (u, il) = (&mut self.u, &self.inv_lambda);
        // One weight: the same operations as the two passes, in the same order.
        let mut one = |a: usize, e: &mut f32, sq: &mut f32| {
            if a >= L {
                return;
            }
            let ha = h[a];
            let up = u[a] * il[a];
            let un = up / (1.0 + up * ha * ha);
            let un = if un > u_max { u_max } else { un };
            u[a] = un;
            let dw = un * ha * *e;
            if SEQ {
                *e -= dw * ha;
            }
            let wn = w[a] + dw;
            w[a] = wn;
            *sq += wn * wn;
        };
        let mut e = e0;
        let (mut sq0, mut sq1) = (0.0f32, 0.0f32);
        let mut a = 0;
        while a + 1 < L {
            one(a, &mut e, &mut sq0);
            one(a + 1, &mut e, &mut sq1);
            a += 2;
        }
        one(a, &mut e, &mut sq0);
        sq0 + sq1
    }

    /// The sweep: one pass on 32-bit ARM (the firmware's Cortex-M4F, where it is the
    /// fewest instructions), two passes elsewhere (a host vectorises the `U_a` pass);
    /// bit-identical either way.
    #[inline(always)]
    fn sweep<const SEQ: bool>(&mut self, w: &mut [f32; L], h: &[f32; L], e0: f32) -> f32 {
        if cfg!(target_arch = "arm") {
            self.sweep_fused::<SEQ>(w, h, e0)
        } else {
            self.sweep_two_pass::<SEQ>(w, h, e0)
        }
    }
}

impl<const L: usize> Trainer<L> for Drls<L> {
    fn step(&mut self, w: &mut [f32; L], h: &[f32; L], d: f32) -> f32 {
        // One pass for the a-priori output (left to right, as `wnn::dot`) and a finiteness
        // probe: `h * 0` is NaN exactly when `h` is infinite or NaN, and a sum of signed
        // zeros stays 0.
        let mut y = 0.0f32;
        let (mut probe0, mut probe1) = (0.0f32, 0.0f32);
        let mut cw = w.chunks_exact(4);
        let mut ch = h.chunks_exact(4);
        for (x, g) in (&mut cw).zip(&mut ch) {
            y += x[0] * g[0];
            y += x[1] * g[1];
            y += x[2] * g[2];
            y += x[3] * g[3];
            probe0 += g[0] * 0.0;
            probe1 += g[1] * 0.0;
            probe0 += g[2] * 0.0;
            probe1 += g[3] * 0.0;
        }
        for (x, g) in cw.remainder().iter().zip(ch.remainder()) {
            y += x * g;
            probe0 += g * 0.0;
        }
        if !d.is_finite() || probe0 + probe1 != 0.0 {
            return f32::NAN;
        }
        let e0 = d - y;
        let sq = match self.cfg.mode {
            DrlsMode::Sequential => self.sweep::<true>(w, h, e0),
            DrlsMode::Parallel => self.sweep::<false>(w, h, e0),
        };
        // The guard on the weights: no weight can exceed `w_max` (or be NaN) unless the sum
        // of squares does (or is NaN), so the per-weight pass runs only then. `w_max^2` is
        // held below infinity so that an infinite weight is caught too.
        let w_max = self.cfg.w_max;
        if w_max.is_finite() {
            let w_max2 = w_max * w_max;
            let w_max2 = if w_max2 > f32::MAX { f32::MAX } else { w_max2 };
            #[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN must take this branch
            let suspect = !(sq <= w_max2);
            if suspect && bound_weights(w, w_max) > 0 {
                self.weight_saturations = self.weight_saturations.saturating_add(1);
            }
        }
        e0
    }

    fn reset(&mut self) {
        self.u = self.u0;
        self.weight_saturations = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The one-pass and two-pass sweeps give the same bits (the HIL test relies on it: the
    /// firmware runs one, the host the other).
    #[test]
    fn sweeps_agree() {
        let mut state = 5u32;
        let mut next = move || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as f32 / (1u32 << 24) as f32
        };
        for cfg in [DrlsConfig::PAPER, DrlsConfig::PAPER_GUARDED] {
            let mut a = Drls::<31>::new(cfg).expect("valid");
            a.set_neuron(0, 0.9, 0.5);
            let mut b = a.clone();
            let (mut wa, mut wb) = ([0.0f32; 31], [0.0f32; 31]);
            for _ in 0..500 {
                let h: [f32; 31] = core::array::from_fn(|_| 2.0 * next() - 1.0);
                let e0 = next() - 0.5;
                let (sa, sb) = match cfg.mode {
                    DrlsMode::Sequential => (
                        a.sweep_fused::<true>(&mut wa, &h, e0),
                        b.sweep_two_pass::<true>(&mut wb, &h, e0),
                    ),
                    DrlsMode::Parallel => (
                        a.sweep_fused::<false>(&mut wa, &h, e0),
                        b.sweep_two_pass::<false>(&mut wb, &h, e0),
                    ),
                };
                assert_eq!(sa.to_bits(), sb.to_bits());
                assert_eq!(wa.map(f32::to_bits), wb.map(f32::to_bits));
                assert_eq!(a.u().map(f32::to_bits), b.u().map(f32::to_bits));
            }
        }
    }
}

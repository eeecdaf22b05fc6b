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
//!   `u_max = INFINITY` and `w_max = INFINITY` the trainer is eq. (15) exactly. The `U`
//!   bound is checked once per window of steps in which a growth bound proves it cannot
//!   bind (the same bits as checking it at every weight; see `guard_may_bind`).
//! - **Form.** [`DrlsForm::Gain`] keeps `U_a` (eq. 15 as above); [`DrlsForm::Energy`] keeps
//!   `S_a = 1/U_a` as eqs. (10)-(11) write it (`S_a(k) = lambda S_a(k-1) + h_a^2`,
//!   `w_a += (h_a / S_a) e`): the same recursion, fewer operations per weight.

use super::{bound_weights, Trainer};
use crate::wnn::dot;

/// How the error is shared among the weights within one sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DrlsMode {
    /// Eq. (15) as written: all weights updated with the same a-priori error.
    Parallel,
    /// The error refreshed after each weight's update (Gauss-Seidel).
    Sequential,
}

/// Which of the paper's two equivalent forms carries each weight's gain from step to step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DrlsForm {
    /// Eq. (15): `U_a` is kept, `U_a(k) = (U_a(k-1)/lambda) / (1 + (U_a(k-1)/lambda) h_a^2)`,
    /// `w_a += U_a h_a e`.
    Gain,
    /// Eqs. (10)-(11): the energy `S_a = 1/U_a` is kept, `S_a(k) = lambda S_a(k-1) + h_a^2`,
    /// `w_a += (h_a / S_a) e`; the guard reads `S_a >= 1/u_max`. The same recursion as
    /// [`DrlsForm::Gain`] in exact arithmetic; in f32 it rounds differently (about 1e-7
    /// relative per step) and takes 3 instructions fewer per weight on a Cortex-M4F (no
    /// `U/lambda`, no `1 + ...`).
    Energy,
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
    /// Form of the gain recursion.
    pub form: DrlsForm,
}

impl DrlsConfig {
    /// Eq. (15) exactly as the paper writes it: lambda = 0.63, parallel, no guard, `U(0)=1`.
    pub const PAPER: Self = Self {
        lambda: 0.63,
        u0: 1.0,
        u_max: f32::INFINITY,
        w_max: f32::INFINITY,
        mode: DrlsMode::Parallel,
        form: DrlsForm::Gain,
    };

    /// The paper's lambda with the sequential update and the guard (`U_a <= U_a(0)`,
    /// `|w| <= 1e4`).
    pub const PAPER_GUARDED: Self = Self {
        lambda: 0.63,
        u0: 1.0,
        u_max: 1.0,
        w_max: 1.0e4,
        mode: DrlsMode::Sequential,
        form: DrlsForm::Gain,
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

/// Steps for which [`Drls`] proves at once that the guard `U_a <= u_max` cannot bind (a
/// power of two: the growth bound is computed by squaring).
const GUARD_WINDOW: u32 = 128;

/// `GUARD_WINDOW = 2^GUARD_WINDOW_LOG2`.
const GUARD_WINDOW_LOG2: u32 = 7;

/// An upper bound of how much `U_a` can grow in [`GUARD_WINDOW`] steps, as computed in
/// f32: each step gives `U_a(k) = fl(fl(U_a(k-1) inv_lambda) / fl(1 + ...))` with a
/// denominator `>= 1`, so at most `U_a(k-1) inv_lambda (1 + 2^-24)^2`. The bound is that
/// factor to the power of the window, times 1.001 (which also covers the rounding of the
/// product `U_a * bound` in the check), rounded up into f32; infinite when it overflows.
fn guard_growth(inv_lambda: f32) -> f32 {
    // (1 + 2^-24)^2 < 1 + 2^-22 = 1 + 2 f32::EPSILON.
    let mut g = f64::from(inv_lambda) * (1.0 + 2.0 * f64::from(f32::EPSILON));
    for _ in 0..GUARD_WINDOW_LOG2 {
        g *= g;
    }
    let g = g * 1.001;
    if g.is_finite() && g < f64::from(f32::MAX) {
        // Round up: the nearest f32 may be below `g`.
        (g * (1.0 + 1.0e-6)) as f32
    } else {
        f32::INFINITY
    }
}

/// DRLS trainer state for `L` weights of one output.
#[derive(Debug, Clone, PartialEq)]
pub struct Drls<const L: usize> {
    cfg: DrlsConfig,
    /// Per weight: `1/lambda` ([`DrlsForm::Gain`]) or `lambda` ([`DrlsForm::Energy`]).
    factor: [f32; L],
    /// Per weight: `U_a` ([`DrlsForm::Gain`]) or `S_a = 1/U_a` ([`DrlsForm::Energy`]).
    state: [f32; L],
    /// `state` at the start (and after [`Trainer::reset`]).
    init: [f32; L],
    /// [`guard_growth`] of each `1/lambda`.
    growth: [f32; L],
    /// Steps left before the guard is checked again; 0: check at the next step.
    guard_steps_left: u32,
    /// The guard was proven not to bind for the current window.
    guard_idle: bool,
    /// Steps at which a weight hit `w_max` (diagnostic).
    pub weight_saturations: u32,
}

impl<const L: usize> Drls<L> {
    /// A trainer; `None` for an invalid configuration.
    pub fn new(cfg: DrlsConfig) -> Option<Self> {
        if !cfg.is_valid() {
            return None;
        }
        let (factor, init) = Self::neuron_state(&cfg, cfg.lambda, cfg.u0);
        Some(Self {
            cfg,
            factor: [factor; L],
            state: [init; L],
            init: [init; L],
            growth: [guard_growth(1.0 / cfg.lambda); L],
            guard_steps_left: 0,
            guard_idle: false,
            weight_saturations: 0,
        })
    }

    /// `(factor, initial state)` of a neuron with forgetting factor `lambda` and `U(0)` =
    /// `u0` (capped at `u_max`).
    fn neuron_state(cfg: &DrlsConfig, lambda: f32, u0: f32) -> (f32, f32) {
        let u0 = u0.min(cfg.u_max);
        match cfg.form {
            DrlsForm::Gain => (1.0 / lambda, u0),
            DrlsForm::Energy => (lambda, 1.0 / u0),
        }
    }

    /// Gives neuron `a` its own forgetting factor and `U_a(0)` (e.g. a bias neuron that must
    /// follow the turn-on bias faster than the others). Ignored for an invalid `a`, lambda
    /// outside `(0, 1]` or `u0 <= 0`; `u0` is capped at `u_max`.
    pub fn set_neuron(&mut self, a: usize, lambda: f32, u0: f32) {
        if a < L && lambda > 0.0 && lambda <= 1.0 && u0 > 0.0 {
            let (factor, init) = Self::neuron_state(&self.cfg, lambda, u0);
            self.factor[a] = factor;
            self.init[a] = init;
            self.state[a] = init;
            self.growth[a] = guard_growth(1.0 / lambda);
            self.guard_steps_left = 0;
        }
    }

    /// The configuration.
    pub fn config(&self) -> &DrlsConfig {
        &self.cfg
    }

    /// Current `U_a` of every weight (`1/S_a` in [`DrlsForm::Energy`]).
    pub fn u(&self) -> [f32; L] {
        match self.cfg.form {
            DrlsForm::Gain => self.state,
            DrlsForm::Energy => self.state.map(|s| 1.0 / s),
        }
    }

    /// The per-weight state as kept: `U_a` ([`DrlsForm::Gain`]) or `S_a`
    /// ([`DrlsForm::Energy`]); with [`Drls::set_state`], what an identifier image stores.
    pub fn state(&self) -> &[f32; L] {
        &self.state
    }

    /// Restores a state saved by [`Drls::state`] (same configuration). Refused (false,
    /// nothing changed) when a value is not finite and > 0.
    pub fn set_state(&mut self, state: &[f32; L]) -> bool {
        if !state.iter().all(|v| v.is_finite() && *v > 0.0) {
            return false;
        }
        self.state = *state;
        self.guard_steps_left = 0;
        true
    }
}

/// One weight's new gain state: [`DrlsForm::Gain`] `(U/lambda)/(1 + (U/lambda) h^2)` capped
/// at `bound` = `u_max`, or [`DrlsForm::Energy`] `lambda S + h^2` held at or above `bound` =
/// `1/u_max`; `CLAMP = false` leaves the bound out (see [`Drls::guard_may_bind`]).
#[inline(always)]
fn next_state<const ENERGY: bool, const CLAMP: bool>(
    state: f32,
    factor: f32,
    h: f32,
    bound: f32,
) -> f32 {
    if ENERGY {
        let sn = factor * state + h * h;
        if CLAMP && sn < bound {
            bound
        } else {
            sn
        }
    } else {
        let up = state * factor;
        let un = up / (1.0 + up * h * h);
        if CLAMP && un > bound {
            bound
        } else {
            un
        }
    }
}

/// One weight's change for the error `e`: `U h e` ([`DrlsForm::Gain`]) or `(h / S) e`
/// ([`DrlsForm::Energy`]; the division does not involve `e`, so a host computes it ahead,
/// outside the chain of errors).
#[inline(always)]
fn weight_step<const ENERGY: bool>(state: f32, h: f32, e: f32) -> f32 {
    if ENERGY {
        h / state * e
    } else {
        state * h * e
    }
}

impl<const L: usize> Drls<L> {
    /// The guard's bound on the state: `u_max` ([`DrlsForm::Gain`]) or `1/u_max`
    /// ([`DrlsForm::Energy`]).
    #[inline(always)]
    fn state_bound(&self) -> f32 {
        match self.cfg.form {
            DrlsForm::Gain => self.cfg.u_max,
            DrlsForm::Energy => 1.0 / self.cfg.u_max,
        }
    }

    /// The per-weight sweep with the a-priori error `e0`, in two passes. Pass 1: every
    /// state (independent of the error: no dependency chain, so a host vectorises it).
    /// Pass 2: the weights, `SEQ` refreshing the error after each one (Gauss-Seidel), which
    /// is the only serial chain. The operations on each weight are the same, in the same
    /// order, as in a single pass. Returns the sum of the new weights' squares (in any
    /// order: it is only compared with a bound).
    #[inline(always)]
    pub(crate) fn sweep_two_pass<const SEQ: bool, const ENERGY: bool, const CLAMP: bool>(
        &mut self,
        w: &mut [f32; L],
        h: &[f32; L],
        e0: f32,
    ) -> f32 {
        let bound = self.state_bound();
        for ((st, f), &ha) in self.state.iter_mut().zip(&self.factor).zip(h) {
            *st = next_state::<ENERGY, CLAMP>(*st, *f, ha, bound);
        }
        let mut e = e0;
        let (mut sq0, mut sq1) = (0.0f32, 0.0f32);
        let mut a = 0;
        while a + 1 < L {
            let dw = weight_step::<ENERGY>(self.state[a], h[a], e);
            if SEQ {
                e -= dw * h[a];
            }
            let w0 = w[a] + dw;
            w[a] = w0;
            sq0 += w0 * w0;
            let dw = weight_step::<ENERGY>(self.state[a + 1], h[a + 1], e);
            if SEQ {
                e -= dw * h[a + 1];
            }
            let w1 = w[a + 1] + dw;
            w[a + 1] = w1;
            sq1 += w1 * w1;
            a += 2;
        }
        if a < L {
            let dw = weight_step::<ENERGY>(self.state[a], h[a], e);
            let w0 = w[a] + dw;
            w[a] = w0;
            sq0 += w0 * w0;
        }
        sq0 + sq1
    }

    /// The same sweep in one pass: the same operations on each weight in the same order as
    /// [`Self::sweep_two_pass`], so the same bits (test `sweeps_agree`), with fewer
    /// instructions on a core without SIMD (no second load of the state and `h_a`).
    #[inline(always)]
    pub(crate) fn sweep_fused<const SEQ: bool, const ENERGY: bool, const CLAMP: bool>(
        &mut self,
        w: &mut [f32; L],
        h: &[f32; L],
        e0: f32,
    ) -> f32 {
        let bound = self.state_bound();
        let (st, fa) = (&mut self.state, &self.factor);
        // One weight: the same operations as the two passes, in the same order.
        let mut one = |a: usize, e: &mut f32, sq: &mut f32| {
            if a >= L {
                return;
            }
            let ha = h[a];
            let sn = next_state::<ENERGY, CLAMP>(st[a], fa[a], ha, bound);
            st[a] = sn;
            let dw = weight_step::<ENERGY>(sn, ha, *e);
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
    /// fewest instructions), two passes elsewhere (a host vectorises the state pass);
    /// bit-identical either way.
    #[inline(always)]
    fn sweep<const SEQ: bool, const ENERGY: bool, const CLAMP: bool>(
        &mut self,
        w: &mut [f32; L],
        h: &[f32; L],
        e0: f32,
    ) -> f32 {
        if cfg!(target_arch = "arm") {
            self.sweep_fused::<SEQ, ENERGY, CLAMP>(w, h, e0)
        } else {
            self.sweep_two_pass::<SEQ, ENERGY, CLAMP>(w, h, e0)
        }
    }

    /// [`Self::sweep`] for the configured form, with or without the guard's comparison.
    #[inline(always)]
    fn sweep_form<const SEQ: bool>(&mut self, w: &mut [f32; L], h: &[f32; L], e0: f32) -> f32 {
        match (self.cfg.form, self.guard_may_bind()) {
            (DrlsForm::Gain, true) => self.sweep::<SEQ, false, true>(w, h, e0),
            (DrlsForm::Gain, false) => self.sweep::<SEQ, false, false>(w, h, e0),
            (DrlsForm::Energy, true) => self.sweep::<SEQ, true, true>(w, h, e0),
            (DrlsForm::Energy, false) => self.sweep::<SEQ, true, false>(w, h, e0),
        }
    }

    /// Whether the guard (`U_a <= u_max`, i.e. `S_a >= 1/u_max`) can bind during the
    /// current window of [`GUARD_WINDOW`] steps: checked once per window. `U_a` grows by at
    /// most its growth bound ([`guard_growth`]) in a window (`S_a` shrinks by at most as
    /// much), so when every state is that far inside the bound, no state can cross it
    /// within the window, and the sweep leaves the comparison out with the same bits. An
    /// infinite `u_max` never binds. [`Drls::set_neuron`] and [`Trainer::reset`] start a
    /// new window.
    #[inline(always)]
    fn guard_may_bind(&mut self) -> bool {
        if self.guard_steps_left == 0 {
            let u_max = self.cfg.u_max;
            let bound = self.state_bound();
            let mut states = self.state.iter().zip(&self.growth);
            self.guard_idle = u_max == f32::INFINITY
                || match self.cfg.form {
                    DrlsForm::Gain => states.all(|(&u, &g)| u * g <= bound),
                    DrlsForm::Energy => states.all(|(&s, &g)| bound * g <= s),
                };
            self.guard_steps_left = GUARD_WINDOW;
        }
        self.guard_steps_left -= 1;
        !self.guard_idle
    }
}

impl<const L: usize> Trainer<L> for Drls<L> {
    fn step(&mut self, w: &mut [f32; L], h: &[f32; L], d: f32) -> f32 {
        // The a-priori output, left to right as `wnn::dot`. It is finite only if every `h`
        // is (a non-finite `h_a` makes `w_a h_a` NaN or infinite, and a sum never returns
        // from NaN or infinity to a finite value), so `h` is probed only when it is not.
        let y = dot(w, h);
        if !d.is_finite() || (!y.is_finite() && !h.iter().all(|v| v.is_finite())) {
            return f32::NAN;
        }
        let e0 = d - y;
        let sq = match self.cfg.mode {
            DrlsMode::Sequential => self.sweep_form::<true>(w, h, e0),
            DrlsMode::Parallel => self.sweep_form::<false>(w, h, e0),
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
        self.state = self.init;
        self.guard_steps_left = 0;
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
        for form in [DrlsForm::Gain, DrlsForm::Energy] {
            for cfg in [DrlsConfig::PAPER, DrlsConfig::PAPER_GUARDED] {
                let cfg = DrlsConfig { form, ..cfg };
                let mut a = Drls::<31>::new(cfg).expect("valid");
                a.set_neuron(0, 0.9, 0.5);
                let mut b = a.clone();
                let (mut wa, mut wb) = ([0.0f32; 31], [0.0f32; 31]);
                for _ in 0..500 {
                    let h: [f32; 31] = core::array::from_fn(|_| 2.0 * next() - 1.0);
                    let e0 = next() - 0.5;
                    let (sa, sb) = match (cfg.mode, form) {
                        (DrlsMode::Sequential, DrlsForm::Gain) => (
                            a.sweep_fused::<true, false, true>(&mut wa, &h, e0),
                            b.sweep_two_pass::<true, false, true>(&mut wb, &h, e0),
                        ),
                        (DrlsMode::Parallel, DrlsForm::Gain) => (
                            a.sweep_fused::<false, false, true>(&mut wa, &h, e0),
                            b.sweep_two_pass::<false, false, true>(&mut wb, &h, e0),
                        ),
                        (DrlsMode::Sequential, DrlsForm::Energy) => (
                            a.sweep_fused::<true, true, true>(&mut wa, &h, e0),
                            b.sweep_two_pass::<true, true, true>(&mut wb, &h, e0),
                        ),
                        (DrlsMode::Parallel, DrlsForm::Energy) => (
                            a.sweep_fused::<false, true, true>(&mut wa, &h, e0),
                            b.sweep_two_pass::<false, true, true>(&mut wb, &h, e0),
                        ),
                    };
                    assert_eq!(sa.to_bits(), sb.to_bits());
                    assert_eq!(wa.map(f32::to_bits), wb.map(f32::to_bits));
                    assert_eq!(a.u().map(f32::to_bits), b.u().map(f32::to_bits));
                }
            }
        }
    }

    /// The energy form (eqs. 10-11) follows the gain form (eq. 15): the same recursion in
    /// exact arithmetic, so over 20,000 steps at lambda 0.99 the weights stay within 1e-4 of
    /// the gain form's largest weight and every `U` within 1e-4 relative.
    #[test]
    fn energy_form_follows_gain_form() {
        let mut state = 3u32;
        let mut next = move || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as f32 / (1u32 << 24) as f32
        };
        let cfg = DrlsConfig {
            lambda: 0.99,
            u0: 1.0e-2,
            u_max: 1.0,
            w_max: 1.0e4,
            mode: DrlsMode::Sequential,
            form: DrlsForm::Gain,
        };
        let mut g = Drls::<8>::new(cfg).expect("valid");
        let mut e = Drls::<8>::new(DrlsConfig {
            form: DrlsForm::Energy,
            ..cfg
        })
        .expect("valid");
        let (mut wg, mut we) = ([0.0f32; 8], [0.0f32; 8]);
        let (mut worst_w, mut worst_u) = (0.0f32, 0.0f32);
        for k in 0..20_000 {
            let h: [f32; 8] = core::array::from_fn(|a| (a as f32 * 0.7 + k as f32 * 0.01).sin());
            let d = 0.3 * h[1] - 0.2 * h[5] + 0.05 * (next() - 0.5);
            let (eg, ee) = (g.step(&mut wg, &h, d), e.step(&mut we, &h, d));
            assert!(eg.is_finite() && ee.is_finite());
            let scale = wg.iter().fold(0.0f32, |m, v| m.max(v.abs()));
            for a in 0..8 {
                worst_w = worst_w.max((wg[a] - we[a]).abs() / scale);
                worst_u = worst_u.max((g.u()[a] - e.u()[a]).abs() / g.u()[a]);
            }
        }
        assert!(worst_w < 1e-4, "weights {worst_w:e}");
        assert!(worst_u < 1e-4, "U {worst_u:e}");
    }

    /// Eq. (15) (or eqs. 10-11 for [`DrlsForm::Energy`]) with the guard applied at every
    /// step, weight by weight, as the module docs write it: the reference for the trainer,
    /// which checks the guard once per window. `lam[a]` is neuron `a`'s lambda, `st[a]` its
    /// `U` (gain) or `S` (energy).
    fn reference_step<const L: usize>(
        cfg: &DrlsConfig,
        lam: &[f32; L],
        st: &mut [f32; L],
        w: &mut [f32; L],
        h: &[f32; L],
        d: f32,
    ) -> f32 {
        if !d.is_finite() || !h.iter().all(|v| v.is_finite()) {
            return f32::NAN;
        }
        let mut y = 0.0f32;
        for a in 0..L {
            y += w[a] * h[a];
        }
        let e0 = d - y;
        let mut e = e0;
        for a in 0..L {
            let dw = match cfg.form {
                DrlsForm::Gain => {
                    let up = st[a] * (1.0 / lam[a]);
                    let un = up / (1.0 + up * h[a] * h[a]);
                    st[a] = if un > cfg.u_max { cfg.u_max } else { un };
                    st[a] * h[a] * e
                }
                DrlsForm::Energy => {
                    let s_min = 1.0 / cfg.u_max;
                    let sn = lam[a] * st[a] + h[a] * h[a];
                    st[a] = if sn < s_min { s_min } else { sn };
                    h[a] / st[a] * e
                }
            };
            if cfg.mode == DrlsMode::Sequential {
                e -= dw * h[a];
            }
            w[a] += dw;
        }
        if cfg.w_max.is_finite() {
            super::bound_weights(w, cfg.w_max);
        }
        e0
    }

    /// The trainer equals the every-step guard bit for bit, in both forms, for forgetting
    /// factors where the guard never binds (0.99999), binds now and then (silent neurons at
    /// 0.99, a neuron restarted at `U = u_max`) and binds often (0.63), and with no guard.
    #[test]
    fn guard_window_changes_no_bit() {
        let mut state = 11u32;
        let mut next = move || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as f32 / (1u32 << 24) as f32
        };
        let mut bound_hits = 0u32;
        for form in [DrlsForm::Gain, DrlsForm::Energy] {
            for (lambda, u0, u_max) in [
                (0.99999f32, 1.0e-4f32, 1.0f32),
                (0.99, 1.0e-2, 1.0),
                (0.63, 1.0, 1.0),
                (0.99, 1.0, f32::INFINITY),
            ] {
                for mode in [DrlsMode::Sequential, DrlsMode::Parallel] {
                    let cfg = DrlsConfig {
                        lambda,
                        u0,
                        u_max,
                        w_max: 1.0e4,
                        mode,
                        form,
                    };
                    let mut t = Drls::<13>::new(cfg).expect("valid");
                    let mut lam = [lambda; 13];
                    let init = |u: f32| match form {
                        DrlsForm::Gain => u,
                        DrlsForm::Energy => 1.0 / u,
                    };
                    let mut st = [init(u0.min(u_max)); 13];
                    let (mut wt, mut wr) = ([0.0f32; 13], [0.0f32; 13]);
                    for k in 0..20_000 {
                        if k == 7_000 {
                            // A neuron restarted at the bound, with its own forgetting factor.
                            t.set_neuron(3, 0.995, u_max.min(1.0));
                            lam[3] = 0.995;
                            st[3] = init(u_max.min(1.0));
                        }
                        // Neurons 0..6 are silent for stretches of different lengths and
                        // phases: their U grows towards the bound, reaching it at every
                        // point of a window.
                        let h: [f32; 13] = core::array::from_fn(|a| {
                            let silent = a < 6 && ((k + 397 * a) / (700 + 130 * a)) % 2 == 1;
                            if silent {
                                0.0
                            } else {
                                2.0 * next() - 1.0
                            }
                        });
                        let d = next() - 0.5;
                        let et = t.step(&mut wt, &h, d);
                        let er = reference_step(&cfg, &lam, &mut st, &mut wr, &h, d);
                        let u_ref = match form {
                            DrlsForm::Gain => st,
                            DrlsForm::Energy => st.map(|s| 1.0 / s),
                        };
                        let at = (form, lambda, mode, k);
                        assert_eq!(et.to_bits(), er.to_bits(), "{at:?}");
                        assert_eq!(wt.map(f32::to_bits), wr.map(f32::to_bits), "{at:?}");
                        assert_eq!(t.u().map(f32::to_bits), u_ref.map(f32::to_bits), "{at:?}");
                        bound_hits += u_ref.iter().filter(|&&v| v == u_max).count() as u32;
                    }
                }
            }
        }
        // The bound did bind in these runs (the comparison was not vacuous).
        assert!(bound_hits > 10_000, "{bound_hits}");
    }
}

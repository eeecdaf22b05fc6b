//! Trainers of the network's output weights: DRLS (paper section 4.2) and two baselines.
//!
//! Every trainer trains the weights of **one output** from the hidden values `h` and the
//! desired output `d`, and returns the a-priori error `e = d - w . h` (before its update).
//! An `m`-output network uses one trainer per output.
//!
//! | trainer | per-sample cost (L neurons) | state |
//! |---|---|---|
//! | [`Drls`] parallel (eq. 15 as written) | 1 dot + L x (1 div, ~5 mul/add) | `L` floats |
//! | [`Drls`] sequential | the same + L mul/add | `L` floats |
//! | [`Rls`] (exponentially weighted, full P) | ~3 L^2 mul/add | `L^2` floats |
//! | [`Nlms`] | 2 dots + L mul/add, 1 div | none |

mod drls;
mod nlms;
mod rls;

pub use drls::{Drls, DrlsConfig, DrlsForm, DrlsMode};
pub use nlms::{Nlms, NlmsConfig};
pub use rls::{Rls, RlsConfig};

/// One trainer of one output's weights.
pub trait Trainer<const L: usize> {
    /// One step: updates `w` from hidden values `h` and desired output `d`; returns the
    /// a-priori error `d - w . h`.
    ///
    /// A non-finite `d` or `h` leaves `w` and the trainer unchanged and returns NaN: the
    /// caller counts it as a rejected sample.
    fn step(&mut self, w: &mut [f32; L], h: &[f32; L], d: f32) -> f32;

    /// Back to the initial state (the weights are the caller's).
    fn reset(&mut self);
}

/// True when `d` and every `h` are finite.
#[inline]
fn finite_inputs<const L: usize>(h: &[f32; L], d: f32) -> bool {
    d.is_finite() && h.iter().all(|v| v.is_finite())
}

/// Limits every weight to `[-w_max, w_max]` and maps NaN to 0; returns how many were hit.
#[inline]
fn bound_weights<const L: usize>(w: &mut [f32; L], w_max: f32) -> u32 {
    let mut hits = 0;
    for v in w.iter_mut() {
        if v.is_nan() || libm::fabsf(*v) > w_max {
            *v = if v.is_nan() {
                0.0
            } else {
                libm::copysignf(w_max, *v)
            };
            hits += 1;
        }
    }
    hits
}

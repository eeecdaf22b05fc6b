//! Wavelet neural network (paper section 3, eqs. 4-5): `n` inputs, `L` wavelet neurons,
//! `m` linear outputs.
//!
//! ```text
//! h_l = phi( sum_j a_lj * x_j - b_l )          (5)
//! y_i = sum_l w_il * h_l                        (4)
//! ```
//!
//! `a` (dilations, also the input weights) and `b` (translations) are fixed by a
//! [`WnnShape`]; only the output weights `w` are trained (see [`crate::train`]). Inputs are
//! expected already scaled (see [`InputScaling`]): the shape's `a` and `b` are in scaled
//! units.

/// The hidden unit's function.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Activation {
    /// `exp(-t^2 / 2)`: the paper's hidden unit (its scaling function `phi`).
    Gaussian,
    /// `(1 - t^2) exp(-t^2 / 2)`: the paper's mother wavelet `psi`.
    MexicanHat,
}

/// Below `-T_CUTOFF^2/2` the exponential underflows to subnormal numbers, which are slow on
/// some FPUs and useless here: beyond |t| = 13 the unit outputs exactly 0.
pub const T_CUTOFF: f32 = 13.0;

impl Activation {
    /// Value of the unit at `t` (any finite or infinite `t`; NaN gives 0).
    ///
    /// Accuracy: `libm::expf` (within 1 ulp), so a few ulp overall.
    #[inline]
    pub fn eval(self, t: f32) -> f32 {
        let t2 = t * t;
        if t2.is_nan() || t2 >= T_CUTOFF * T_CUTOFF {
            return 0.0;
        }
        let g = libm::expf(-0.5 * t2);
        match self {
            Self::Gaussian => g,
            Self::MexicanHat => (1.0 - t2) * g,
        }
    }
}

/// Affine scaling of the raw inputs into the network's units: `x_scaled = (x - offset) * gain`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InputScaling<const N: usize> {
    /// Subtracted from each raw input, raw unit.
    pub offset: [f32; N],
    /// Multiplies each input after the offset, 1/raw unit.
    pub gain: [f32; N],
}

impl<const N: usize> InputScaling<N> {
    /// No scaling.
    pub const IDENTITY: Self = Self {
        offset: [0.0; N],
        gain: [1.0; N],
    };

    /// Maps `[lo, hi]` of each input onto `[-1, 1]`; an input with `hi <= lo` (or non-finite
    /// bounds) keeps gain 1 around `lo`.
    pub fn from_ranges(lo: [f32; N], hi: [f32; N]) -> Self {
        let mut s = Self::IDENTITY;
        for j in 0..N {
            let span = hi[j] - lo[j];
            if span > 0.0 && span.is_finite() && lo[j].is_finite() {
                s.offset[j] = 0.5 * (lo[j] + hi[j]);
                s.gain[j] = 2.0 / span;
            } else if lo[j].is_finite() {
                s.offset[j] = lo[j];
            }
        }
        s
    }

    /// Scales one input vector.
    #[inline]
    pub fn apply(&self, x: &[f32; N]) -> [f32; N] {
        core::array::from_fn(|j| (x[j] - self.offset[j]) * self.gain[j])
    }
}

/// The fixed part of the network: dilations, translations, activation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WnnShape<const N: usize, const L: usize> {
    /// `a[l][j]`: dilation of neuron `l` along input `j` (scaled units^-1).
    pub a: [[f32; N]; L],
    /// `b[l]`: translation of neuron `l`.
    pub b: [f32; L],
    /// Hidden unit.
    pub activation: Activation,
}

impl<const N: usize, const L: usize> WnnShape<N, L> {
    /// Hidden layer outputs `h` for scaled inputs `x` (eq. 5).
    #[inline]
    pub fn hidden(&self, x: &[f32; N], h: &mut [f32; L]) {
        for ((hl, al), bl) in h.iter_mut().zip(&self.a).zip(&self.b) {
            let mut t = -*bl;
            for (aj, xj) in al.iter().zip(x) {
                t += aj * xj;
            }
            *hl = self.activation.eval(t);
        }
    }
}

/// Output weights of an `m`-output network (eq. 4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutputWeights<const L: usize, const M: usize> {
    /// `w[i][l]`: weight from neuron `l` to output `i`, output unit.
    pub w: [[f32; L]; M],
}

impl<const L: usize, const M: usize> OutputWeights<L, M> {
    /// All weights zero.
    pub const ZERO: Self = Self { w: [[0.0; L]; M] };

    /// Outputs `y` for hidden values `h` (eq. 4).
    #[inline]
    pub fn output(&self, h: &[f32; L]) -> [f32; M] {
        core::array::from_fn(|i| dot(&self.w[i], h))
    }
}

/// `sum_l a_l b_l`, left to right.
#[inline]
pub fn dot<const L: usize>(a: &[f32; L], b: &[f32; L]) -> f32 {
    let mut acc = 0.0f32;
    for (x, y) in a.iter().zip(b) {
        acc += x * y;
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn activations() {
        assert_eq!(Activation::Gaussian.eval(0.0), 1.0);
        assert_eq!(Activation::MexicanHat.eval(1.0), 0.0);
        assert!((Activation::Gaussian.eval(2.0) - libm::expf(-2.0)).abs() < 1e-7);
        assert!((Activation::MexicanHat.eval(2.0) + 3.0 * libm::expf(-2.0)).abs() < 1e-6);
        for t in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 1e30, 13.0] {
            assert_eq!(Activation::Gaussian.eval(t), 0.0);
            assert_eq!(Activation::MexicanHat.eval(t), 0.0);
        }
    }

    #[test]
    fn network_forward() {
        let shape = WnnShape::<2, 3> {
            a: [[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]],
            b: [0.0, 1.0, 0.5],
            activation: Activation::Gaussian,
        };
        let mut h = [0.0; 3];
        shape.hidden(&[0.0, 1.0], &mut h);
        assert_eq!(h[0], 1.0);
        assert_eq!(h[1], 1.0);
        assert!((h[2] - libm::expf(-0.125)).abs() < 1e-7);
        let w = OutputWeights::<3, 1> {
            w: [[1.0, 2.0, 0.0]],
        };
        assert_eq!(w.output(&h), [3.0]);
        let s = InputScaling::from_ranges([0.0, 10.0], [2.0, 10.0]);
        assert_eq!(s.apply(&[2.0, 11.0]), [1.0, 1.0]);
    }
}

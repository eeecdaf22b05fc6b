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

/// What a hidden neuron computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Neuron {
    /// `phi(a . x - b)`: the paper's wavelet neuron (eq. 5).
    Wavelet,
    /// Constant 1: an output bias (not in the paper; in its reference [8], Zhang 1995).
    Bias,
    /// The scaled input `x[j]` itself: a linear direct link (also from reference [8]).
    Linear(u8),
}

/// The fixed part of the network: neuron kinds, dilations, translations, activation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WnnShape<const N: usize, const L: usize> {
    /// `a[l][j]`: dilation of neuron `l` along input `j` (scaled units^-1).
    pub a: [[f32; N]; L],
    /// `b[l]`: translation of neuron `l`.
    pub b: [f32; L],
    /// Hidden unit of the wavelet neurons.
    pub activation: Activation,
    /// Kind of each neuron; all [`Neuron::Wavelet`] in the paper.
    pub kind: [Neuron; L],
}

/// Why a network shape could not be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ShapeError {
    /// The groups ask for more or fewer neurons than `L`.
    NeuronCount,
    /// A group names an input index `>= N`.
    NoSuchInput,
}

impl core::fmt::Display for ShapeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::NeuronCount => "neuron groups do not add up to the network's L",
            Self::NoSuchInput => "a neuron group names an input the network does not have",
        })
    }
}

impl core::error::Error for ShapeError {}

/// A group of neurons in a [`WnnShape::from_groups`] layout.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Group {
    /// One bias neuron.
    Bias,
    /// One linear link to input `j`.
    Linear(usize),
    /// `count` wavelet neurons along input `j` alone, translations evenly spaced over the
    /// scaled range [-1, 1] and dilation `a = (count - 1) / 2 * overlap`: with `overlap = 1`
    /// neighbours sit one standard deviation apart (for the Gaussian), so the group covers
    /// the range without gaps and without redundant overlap.
    Along {
        /// Input index.
        input: usize,
        /// Neurons in the group.
        count: usize,
        /// Dilation factor (1 = neighbours one sigma apart).
        overlap: f32,
    },
}

impl<const N: usize, const L: usize> WnnShape<N, L> {
    /// A layout made of groups (in order). Translations: a group of `K` neurons on input `j`
    /// puts neuron `i` at `c_i = -1 + 2 i / (K - 1)` (0 for `K = 1`) and uses
    /// `h = phi(a x_j - a c_i)`.
    pub fn from_groups(groups: &[Group], activation: Activation) -> Result<Self, ShapeError> {
        let mut s = Self {
            a: [[0.0; N]; L],
            b: [0.0; L],
            activation,
            kind: [Neuron::Wavelet; L],
        };
        let mut l = 0usize;
        for g in groups {
            match *g {
                Group::Bias => {
                    *s.kind.get_mut(l).ok_or(ShapeError::NeuronCount)? = Neuron::Bias;
                    l += 1;
                }
                Group::Linear(j) => {
                    let j8 = u8::try_from(j).map_err(|_| ShapeError::NoSuchInput)?;
                    if j >= N {
                        return Err(ShapeError::NoSuchInput);
                    }
                    *s.kind.get_mut(l).ok_or(ShapeError::NeuronCount)? = Neuron::Linear(j8);
                    l += 1;
                }
                Group::Along {
                    input,
                    count,
                    overlap,
                } => {
                    if input >= N {
                        return Err(ShapeError::NoSuchInput);
                    }
                    let a = if count > 1 {
                        0.5 * (count - 1) as f32 * overlap
                    } else {
                        overlap
                    };
                    for i in 0..count {
                        let c = if count > 1 {
                            -1.0 + 2.0 * i as f32 / (count - 1) as f32
                        } else {
                            0.0
                        };
                        let row = s.a.get_mut(l).ok_or(ShapeError::NeuronCount)?;
                        row[input] = a;
                        s.b[l] = a * c;
                        l += 1;
                    }
                }
            }
        }
        if l != L {
            return Err(ShapeError::NeuronCount);
        }
        Ok(s)
    }

    /// Hidden layer outputs `h` for scaled inputs `x` (eq. 5).
    #[inline]
    pub fn hidden(&self, x: &[f32; N], h: &mut [f32; L]) {
        for (((hl, kind), al), bl) in h.iter_mut().zip(&self.kind).zip(&self.a).zip(&self.b) {
            *hl = match *kind {
                Neuron::Wavelet => {
                    let mut t = -*bl;
                    for (aj, xj) in al.iter().zip(x) {
                        t += aj * xj;
                    }
                    self.activation.eval(t)
                }
                Neuron::Bias => 1.0,
                Neuron::Linear(j) => x.get(usize::from(j)).copied().unwrap_or(0.0),
            };
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
            kind: [Neuron::Wavelet; 3],
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
        let g = WnnShape::<2, 5>::from_groups(
            &[
                Group::Bias,
                Group::Linear(1),
                Group::Along {
                    input: 0,
                    count: 3,
                    overlap: 1.0,
                },
            ],
            Activation::Gaussian,
        )
        .expect("valid");
        let mut h5 = [0.0; 5];
        g.hidden(&[1.0, -0.5], &mut h5);
        assert_eq!(&h5[..2], &[1.0, -0.5]);
        // Centres at -1, 0, 1 with a = 1: x = 1 sits on the last one.
        assert_eq!(h5[4], 1.0);
        assert!((h5[3] - libm::expf(-0.5)).abs() < 1e-7);
        assert_eq!(
            WnnShape::<2, 4>::from_groups(&[Group::Bias], Activation::Gaussian),
            Err(ShapeError::NeuronCount)
        );
        assert_eq!(
            WnnShape::<2, 1>::from_groups(&[Group::Linear(2)], Activation::Gaussian),
            Err(ShapeError::NoSuchInput)
        );
        let s = InputScaling::from_ranges([0.0, 10.0], [2.0, 10.0]);
        assert_eq!(s.apply(&[2.0, 11.0]), [1.0, 1.0]);
    }
}

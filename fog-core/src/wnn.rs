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

/// `e^x` for `x` in `[-87, 88]` (the caller guarantees it; outside, the result is wrong but
/// finite or infinite, never a panic): `2^k e^r` with `k = round(x / ln 2)`, `|r| <= ln2/2`,
/// and a degree-7 Taylor polynomial for `e^r` (truncation below 5e-9 relative); rounding
/// makes it within 2 ulp of `e^x` (checked over the domain against f64 in the test
/// `exp_recurrence_accuracy`). About 20 instructions on a Cortex-M4F, against about 55
/// for `libm::expf`, and the same f32 operations on every target (no fused multiply-add).
///
/// Public for the firmware's side-by-side measurement against `micromath` and `libm`
/// (`scripts/fw-budget.sh`); the network uses it internally.
#[inline(always)]
pub fn exp_anchor(x: f32) -> f32 {
    const LOG2E: f32 = core::f32::consts::LOG2_E;
    // Adding 1.5 * 2^23 rounds to an integer (|x log2 e| < 2^22).
    const ROUND: f32 = 12_582_912.0;
    const LN2_HI: f32 = 0.693_145_75; // 0x3f317200: k * LN2_HI is exact for |k| < 256
    const LN2_LO: f32 = 1.428_606_8e-6;
    let z = x * LOG2E + ROUND;
    let kf = z - ROUND;
    let k = (z.to_bits() as i32).wrapping_sub(ROUND.to_bits() as i32);
    let r = (x - kf * LN2_HI) - kf * LN2_LO;
    let p = 1.0
        + r * (1.0
            + r * (0.5
                + r * (1.0 / 6.0
                    + r * (1.0 / 24.0
                        + r * (1.0 / 120.0 + r * (1.0 / 720.0 + r * (1.0 / 5040.0)))))));
    f32::from_bits((p.to_bits() as i32).wrapping_add(k.wrapping_shl(23)) as u32)
}

/// Fills `h` (walking away from the anchor) with `g r`, `g r (r q)`, ... : two values per
/// iteration.
#[inline(always)]
fn walk<'a>(mut h: impl Iterator<Item = &'a mut f32>, g: f32, r: f32, q: f32) {
    let (mut g, mut r) = (g, r);
    while let Some(a) = h.next() {
        g *= r;
        r *= q;
        *a = g;
        let Some(b) = h.next() else { break };
        g *= r;
        r *= q;
        *b = g;
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
    /// Constant 1: an output bias (not in the paper; in its reference \[8\], Zhang 1995).
    Bias,
    /// The scaled input `x[j]` itself: a linear direct link (also from reference \[8\]).
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
    /// How [`WnnShape::hidden`] evaluates the wavelet neurons: [`Evaluation::Direct`] (eq. 5
    /// neuron by neuron, the reference) or [`Evaluation::Recurrence`] (see
    /// [`WnnShape::with_recurrence`]).
    pub evaluation: Evaluation,
}

/// Most runs of evenly spaced neurons a shape evaluates by recurrence; further runs are
/// evaluated directly.
pub const MAX_RUNS: usize = 2;

/// Largest spacing of neighbouring centres, in units of `t` (standard deviations of the
/// Gaussian), for which a run is evaluated by recurrence. Beyond it `exp(-step^2)` and the
/// ratios leave f32's normal range; such neurons barely overlap and are evaluated directly.
pub const MAX_RECURRENCE_STEP: f32 = 4.0;

/// A run of neurons `start..start + count` that look along one input with the same dilation
/// `a` and translations `b_start + i * step`: `t_i = a x - b_i = t_0 - i * step`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Run {
    /// First neuron.
    pub start: u8,
    /// Neurons in the run (at least 2).
    pub count: u8,
    /// The input they look along.
    pub input: u8,
    /// Common dilation.
    pub a: f32,
    /// Spacing of `t` between neighbours (`b_{i+1} - b_i`), > 0.
    pub step: f32,
    /// `1 / step`.
    pub inv_step: f32,
    /// `exp(-step^2)`: ratio of two successive neighbour ratios.
    pub q: f32,
    /// `0.5 * step * step`.
    pub half_step2: f32,
}

/// How the hidden layer is evaluated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Evaluation {
    /// Every neuron by eq. (5): one `expf` per wavelet neuron. The reference.
    Direct,
    /// Runs of evenly spaced single-input neurons by a recurrence (2 `expf` and 1 division
    /// per run, then 2 multiplications per neuron; see [`WnnShape::with_recurrence`]); the
    /// other neurons directly. Only `runs[..n]` are used.
    Recurrence {
        /// The runs, sorted by `start`, not overlapping.
        runs: [Run; MAX_RUNS],
        /// Runs in use.
        n: u8,
        /// The neurons outside the runs when they are all biases and links (at most
        /// [`MAX_LISTED`]): `(neuron, source)`, source [`LISTED_BIAS`] for a bias, else the
        /// input of the link. `None`: some are not (they are then evaluated neuron by
        /// neuron, as [`Evaluation::Direct`] does).
        listed: Option<[(u8, u8); MAX_LISTED]>,
        /// Entries of `listed` in use.
        n_listed: u8,
    },
}

/// Most neurons outside the runs that [`Evaluation::Recurrence`] keeps in its list.
pub const MAX_LISTED: usize = 8;

/// `source` of a bias neuron in [`Evaluation::Recurrence`]'s list.
pub const LISTED_BIAS: u8 = u8::MAX;

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
            evaluation: Evaluation::Direct,
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

    /// Hidden layer outputs `h` for scaled inputs `x` (eq. 5), evaluated as
    /// [`WnnShape::evaluation`] says.
    #[inline]
    pub fn hidden(&self, x: &[f32; N], h: &mut [f32; L]) {
        self.hidden_memo(x, h, &mut [None; MAX_RUNS]);
    }

    /// [`WnnShape::hidden`], except that a run of [`Evaluation::Recurrence`] whose input has
    /// the bits `memo` holds for it is not evaluated: `h` is taken to hold its values for
    /// that input already. `memo` is updated to what `h` holds on return.
    #[inline]
    fn hidden_memo(&self, x: &[f32; N], h: &mut [f32; L], memo: &mut [Option<u32>; MAX_RUNS]) {
        match &self.evaluation {
            Evaluation::Direct => self.hidden_direct(x, h, 0, L),
            Evaluation::Recurrence {
                runs,
                n,
                listed: Some(listed),
                n_listed,
            } => {
                // Biases and links from the list, then the runs: no per-neuron dispatch.
                for &(l, src) in listed.iter().take(usize::from(*n_listed)) {
                    if let Some(v) = h.get_mut(usize::from(l)) {
                        *v = if src == LISTED_BIAS {
                            1.0
                        } else {
                            x.get(usize::from(src)).copied().unwrap_or(0.0)
                        };
                    }
                }
                for (run, seen) in runs.iter().zip(memo.iter_mut()).take(usize::from(*n)) {
                    self.hidden_run_memo(run, seen, x, h);
                }
            }
            Evaluation::Recurrence { runs, n, .. } => {
                let mut next = 0usize;
                for (run, seen) in runs.iter().zip(memo.iter_mut()).take(usize::from(*n)) {
                    let start = usize::from(run.start);
                    self.hidden_each(x, h, next, start);
                    self.hidden_run_memo(run, seen, x, h);
                    next = start + usize::from(run.count);
                }
                self.hidden_each(x, h, next, L);
            }
        }
    }

    #[allow(clippy::needless_range_loop)] // five arrays indexed by neuron
    /// Neurons `from..to` one by one, for the few outside the runs (bias, link): the same
    /// values as [`Self::hidden_direct`], without its loop set-up.
    #[inline(always)]
    fn hidden_each(&self, x: &[f32; N], h: &mut [f32; L], from: usize, to: usize) {
        for l in from..to.min(L) {
            h[l] = match self.kind[l] {
                Neuron::Bias => 1.0,
                Neuron::Linear(j) => x.get(usize::from(j)).copied().unwrap_or(0.0),
                Neuron::Wavelet => {
                    let mut t = -self.b[l];
                    for (aj, xj) in self.a[l].iter().zip(x) {
                        t += aj * xj;
                    }
                    self.activation.eval(t)
                }
            };
        }
    }

    /// Neurons `from..to` by eq. (5), one by one.
    #[inline]
    fn hidden_direct(&self, x: &[f32; N], h: &mut [f32; L], from: usize, to: usize) {
        let (Some(hs), Some(kinds), Some(as_), Some(bs)) = (
            h.get_mut(from..to),
            self.kind.get(from..to),
            self.a.get(from..to),
            self.b.get(from..to),
        ) else {
            return;
        };
        for (((hl, kind), al), bl) in hs.iter_mut().zip(kinds).zip(as_).zip(bs) {
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

    /// [`Self::hidden_run`] unless `seen` holds the bits of the run's input (its values in
    /// `h` are then those already); `seen` then holds them.
    #[inline(always)]
    fn hidden_run_memo(&self, run: &Run, seen: &mut Option<u32>, x: &[f32; N], h: &mut [f32; L]) {
        let bits = x.get(usize::from(run.input)).map(|v| v.to_bits());
        if *seen != bits || bits.is_none() {
            self.hidden_run(run, x, h);
            *seen = bits;
        }
    }

    /// One run by the recurrence (see [`WnnShape::with_recurrence`]).
    #[inline]
    fn hidden_run(&self, run: &Run, x: &[f32; N], h: &mut [f32; L]) {
        let start = usize::from(run.start);
        let count = usize::from(run.count);
        let (Some(hr), Some(br)) = (
            h.get_mut(start..start + count),
            self.b.get(start..start + count),
        ) else {
            return;
        };
        // An empty run has no neuron to evaluate (and no `br[0]`): nothing to do.
        let Some(&b_first) = br.first() else {
            return;
        };
        let xj = x.get(usize::from(run.input)).copied().unwrap_or(0.0);
        let p = run.a * xj;
        // The neuron nearest the input (NaN and below the run: 0; above: the last).
        let v = (p - b_first) * run.inv_step + 0.5;
        let near = if v > 0.0 {
            (v as usize).min(count - 1)
        } else {
            0
        };
        // Its t exactly as eq. (5) computes it, so the anchor is the direct value.
        // `near <= count - 1 = br.len() - 1`: `get` always finds it (no panic path).
        let tn = p - br.get(near).copied().unwrap_or(b_first);
        let t2 = tn * tn;
        #[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN must take this branch
        let beyond = !(t2 < T_CUTOFF * T_CUTOFF);
        if beyond {
            // The nearest neuron is beyond the cut-off (or x is NaN): so is every other.
            hr.fill(0.0);
            return;
        }
        // Arguments: -t2/2 in (-84.5, 0]; step tn - step^2/2 in [-60, 60] (|tn| < 13, step
        // <= 4): inside exp_anchor's domain.
        let g = exp_anchor(-0.5 * t2);
        // g_{i+1} / g_i = exp(step t_i - step^2/2); each step further multiplies it by q.
        let up = exp_anchor(run.step * tn - run.half_step2);
        let down = run.q / up;
        // Neurons with |t| < T_CUTOFF on each side (floor; a neuron exactly on the border
        // gets exp(-84.5) instead of 0): `near + 1 .. hi` above, `lo .. near` below.
        let reach_up = ((tn + T_CUTOFF) * run.inv_step) as usize;
        let reach_down = ((T_CUTOFF - tn) * run.inv_step) as usize;
        let hi = (near + 1).saturating_add(reach_up).min(count);
        let lo = near.saturating_sub(reach_down);
        // `get_mut`: every range lies in `0..count = 0..hr.len()` (near <= count - 1), so
        // these always succeed; they keep the panic path out of the firmware.
        if let Some(a) = hr.get_mut(near) {
            *a = g;
        }
        if let Some(live) = hr.get_mut(near + 1..hi) {
            walk(live.iter_mut(), g, up, run.q);
        }
        if let Some(live) = hr.get_mut(lo..near) {
            walk(live.iter_mut().rev(), g, down, run.q);
        }
        if hi < count {
            if let Some(dead) = hr.get_mut(hi..) {
                dead.fill(0.0);
            }
        }
        if lo > 0 {
            if let Some(dead) = hr.get_mut(..lo) {
                dead.fill(0.0);
            }
        }
        if self.activation == Activation::MexicanHat {
            // (1 - t^2) g with t exactly as eq. (5) computes it (no cancellation error near
            // the zero crossings |t| = 1).
            for (hl, bl) in hr.iter_mut().zip(br) {
                let t = p - bl;
                *hl *= 1.0 - t * t;
            }
        }
    }

    /// This shape with [`Evaluation::Recurrence`]: finds the runs (at most [`MAX_RUNS`], in
    /// order) of at least 2 consecutive wavelet neurons that look along one input with the
    /// same dilation and evenly spaced translations (within 1e-5 of the spacing, spacing in
    /// `(0, MAX_RECURRENCE_STEP]`), as [`WnnShape::from_groups`]'s `Along` groups are.
    ///
    /// # The recurrence
    /// In a run, `t_i = t_0 - i s` (`s` = spacing), so for the Gaussian
    /// `g_{i+1} / g_i = exp(s t_i - s^2/2) = r_i` and `r_{i+1} = r_i exp(-s^2)`. The run starts
    /// at the neuron nearest the input (`|t_n| <= s/2` inside the range), evaluated exactly
    /// as eq. (5) does, and walks both ways, where every value and every ratio only
    /// decreases: nothing overflows, and values underflow only past the cut-off
    /// ([`T_CUTOFF`]), where they are set to 0 as eq. (5) does. Cost per run: 2 `expf`, 1
    /// division; per neuron: 2 multiplications (plus 4 operations for the Mexican hat,
    /// `(1 - t^2) g` with `t = a x - b_i` as eq. (5) has it). Only the run's own input matters (a direct neuron would also turn a
    /// NaN in another input, times its zero dilation, into 0).
    ///
    /// # Accuracy
    /// The value `m` neurons from the anchor carries about `m^2/2` roundings of the ratios
    /// on top of `expf`'s: measured against [`Evaluation::Direct`] over the level-trend and
    /// paper layouts against eq. (5) in f64 (`cargo test -p fog-core --lib wnn --
    /// --nocapture`, test `recurrence_matches_direct`, inputs over [-4, 4]): largest
    /// absolute error 3.9e-7 (direct: 2.5e-7), largest relative error 1.5e-5 to 1.8e-5
    /// (direct: 1.5e-5 to 2.0e-5; at the tails both are dominated by the f32 rounding of
    /// `t` itself, `t^2 2^-24`); Mexican hat: absolute 6.1e-7, as direct. The
    /// translations of `from_groups` are `a c_i` rounded to f32, so "evenly spaced" itself
    /// holds only to an ulp of `b`; that difference is inside the figures above.
    pub fn with_recurrence(mut self) -> Self {
        let mut runs = [Run {
            start: 0,
            count: 0,
            input: 0,
            a: 0.0,
            step: 0.0,
            inv_step: 0.0,
            q: 0.0,
            half_step2: 0.0,
        }; MAX_RUNS];
        let mut n = 0usize;
        let mut l = 0usize;
        while l < L && n < MAX_RUNS {
            let len = self.run_at(l);
            if len >= 2 {
                if let Some(run) = self.make_run(l, len) {
                    runs[n] = run;
                    n += 1;
                }
                l += len;
            } else {
                l += 1;
            }
        }
        // The neurons outside the runs, listed when they are all biases and links.
        let mut listed = [(0u8, 0u8); MAX_LISTED];
        let mut n_listed = 0usize;
        let mut all_listed = true;
        for l in 0..L {
            let in_run = runs[..n].iter().any(|r| {
                (usize::from(r.start)..usize::from(r.start) + usize::from(r.count)).contains(&l)
            });
            if in_run {
                continue;
            }
            let source = match self.kind[l] {
                Neuron::Bias => Some(LISTED_BIAS),
                Neuron::Linear(j) if j != LISTED_BIAS => Some(j),
                _ => None,
            };
            match (source, listed.get_mut(n_listed), u8::try_from(l)) {
                (Some(src), Some(slot), Ok(l8)) => {
                    *slot = (l8, src);
                    n_listed += 1;
                }
                _ => all_listed = false,
            }
        }
        self.evaluation = Evaluation::Recurrence {
            runs,
            n: n as u8,
            listed: all_listed.then_some(listed),
            n_listed: n_listed as u8,
        };
        self
    }

    /// The single input of wavelet neuron `l` and its dilation, if it looks along one input.
    fn single_input(&self, l: usize) -> Option<(usize, f32)> {
        if self.kind.get(l) != Some(&Neuron::Wavelet) {
            return None;
        }
        let row = self.a.get(l)?;
        let mut found = None;
        for (j, &aj) in row.iter().enumerate() {
            if aj != 0.0 {
                if found.is_some() || !aj.is_finite() {
                    return None;
                }
                found = Some((j, aj));
            }
        }
        found
    }

    /// Length of the longest evenly spaced run starting at neuron `l` (0 or 1 if none).
    fn run_at(&self, l: usize) -> usize {
        let Some((j, a)) = self.single_input(l) else {
            return 0;
        };
        let (Some(&b0), Some(&b1)) = (self.b.get(l), self.b.get(l + 1)) else {
            return 1;
        };
        let step = b1 - b0;
        if !(step > 0.0 && step <= MAX_RECURRENCE_STEP) {
            return 1;
        }
        let mut len = 1;
        while l + len < L && len < usize::from(u8::MAX) {
            let i = l + len;
            if self.single_input(i) != Some((j, a)) {
                break;
            }
            let expect = b0 + len as f32 * step;
            if libm::fabsf(self.b[i] - expect) > 1e-5 * step {
                break;
            }
            len += 1;
        }
        len
    }

    fn make_run(&self, l: usize, len: usize) -> Option<Run> {
        let (j, a) = self.single_input(l)?;
        let first = *self.b.get(l)?;
        let last = *self.b.get(l + len - 1)?;
        let step = (last - first) / (len - 1) as f32;
        Some(Run {
            start: u8::try_from(l).ok()?,
            count: u8::try_from(len).ok()?,
            input: u8::try_from(j).ok()?,
            a,
            step,
            inv_step: 1.0 / step,
            q: libm::expf(-step * step),
            half_step2: 0.5 * step * step,
        })
    }
}

/// Hidden values kept from one evaluation to the next, for one [`WnnShape`].
///
/// A run of [`Evaluation::Recurrence`] is a function of its one input alone, so when that
/// input has exactly the same bits as at this buffer's previous evaluation, its values are
/// kept instead of evaluated again: the results are the same bits as
/// [`WnnShape::hidden`]'s. It pays where an input changes rarely, such as the time input
/// held for a denoising block ([`crate::identify::Identifier::with_block_time`]): the
/// level-trend network's 14 Gaussians along `T` are then evaluated once per block instead
/// of once per sample. The neurons outside the runs (bias, links, direct neurons) are
/// evaluated every time.
///
/// A buffer must be used with one shape only: it does not know which shape filled it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HiddenCache<const L: usize> {
    h: [f32; L],
    /// Bits of each run's input at the last evaluation; `None`: not evaluated yet.
    memo: [Option<u32>; MAX_RUNS],
}

impl<const L: usize> Default for HiddenCache<L> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const L: usize> HiddenCache<L> {
    /// An empty buffer (the first evaluation computes every neuron).
    pub const fn new() -> Self {
        Self {
            h: [0.0; L],
            memo: [None; MAX_RUNS],
        }
    }

    /// The hidden values of `shape` for the scaled inputs `x`: the same bits as
    /// [`WnnShape::hidden`].
    #[inline]
    pub fn eval<const N: usize>(&mut self, shape: &WnnShape<N, L>, x: &[f32; N]) -> &[f32; L] {
        shape.hidden_memo(x, &mut self.h, &mut self.memo);
        &self.h
    }

    /// The values of the last evaluation (all 0 before the first).
    pub fn values(&self) -> &[f32; L] {
        &self.h
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

/// `sum_l a_l b_l`, left to right (four terms per iteration, one accumulator: the same
/// sum, term by term, as a plain loop).
#[inline]
pub fn dot<const L: usize>(a: &[f32; L], b: &[f32; L]) -> f32 {
    let mut acc = 0.0f32;
    let mut ca = a.chunks_exact(4);
    let mut cb = b.chunks_exact(4);
    for (x, y) in (&mut ca).zip(&mut cb) {
        acc += x[0] * y[0];
        acc += x[1] * y[1];
        acc += x[2] * y[2];
        acc += x[3] * y[3];
    }
    for (x, y) in ca.remainder().iter().zip(cb.remainder()) {
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
            evaluation: Evaluation::Direct,
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

    /// [`HiddenCache`] gives the bits of [`WnnShape::hidden`] on every call, whichever
    /// inputs repeat: each input of the level-trend and paper layouts is held for a random
    /// number of calls (1 to 6) and sometimes NaN or infinite, and the cache is also fed
    /// the two alternating input streams the identifier gives its two buffers.
    #[test]
    fn hidden_cache_matches_hidden() {
        fn check<const N: usize, const L: usize>(shape: WnnShape<N, L>) {
            for shape in [shape, shape.with_recurrence()] {
                let mut state = 7u32;
                let mut next = move || {
                    state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                    state >> 8
                };
                let mut cache = HiddenCache::<L>::new();
                let mut x = [0.0f32; N];
                let mut hold = [0u32; N];
                let mut evaluated = 0;
                for i in 0..5_000 {
                    for j in 0..N {
                        if hold[j] == 0 {
                            hold[j] = 1 + next() % 6;
                            x[j] = match next() % 50 {
                                0 => f32::NAN,
                                1 => f32::INFINITY,
                                _ => 8.0 * (next() as f32 / (1u32 << 24) as f32) - 4.0,
                            };
                        }
                        hold[j] -= 1;
                    }
                    let mut want = [0.0f32; L];
                    shape.hidden(&x, &mut want);
                    let got = cache.eval(&shape, &x);
                    assert_eq!(got.map(f32::to_bits), want.map(f32::to_bits), "call {i}");
                    evaluated += 1;
                }
                assert_eq!(evaluated, 5_000);
            }
        }
        check(crate::identify::presets::level_trend_shape::<30>().expect("shape"));
        check(crate::identify::presets::paper_shape::<30>(Activation::Gaussian).expect("shape"));
        check(crate::identify::presets::paper_shape::<30>(Activation::MexicanHat).expect("shape"));
    }

    /// Inputs over [-4, 4] (the scaled range is [-1, 1]) from a fixed LCG.
    fn recurrence_inputs<const N: usize>(state: &mut u32) -> [f32; N] {
        let mut x = [0.0f32; N];
        for v in x.iter_mut() {
            *state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            *v = 8.0 * ((*state >> 8) as f32 / (1u32 << 24) as f32) - 4.0;
        }
        x
    }

    /// Eq. (5) in f64 for wavelet neuron `l` (from the same f32 a, b, x), 0 past the cutoff.
    fn wavelet_f64<const N: usize, const L: usize>(
        shape: &WnnShape<N, L>,
        x: &[f32; N],
        l: usize,
    ) -> f64 {
        let mut t = -f64::from(shape.b[l]);
        for (a, v) in shape.a[l].iter().zip(x) {
            t += f64::from(*a) * f64::from(*v);
        }
        if t.abs() >= f64::from(T_CUTOFF) {
            return 0.0;
        }
        let g = (-0.5 * t * t).exp();
        match shape.activation {
            Activation::Gaussian => g,
            Activation::MexicanHat => (1.0 - t * t) * g,
        }
    }

    /// Largest errors of the recurrence and of the direct evaluation against f64.
    #[derive(Default)]
    struct RecurrenceErrors {
        rel_f: f64,
        abs_f: f64,
        rel_d: f64,
        abs_d: f64,
    }

    /// Recurrence vs direct evaluation of `shape` (which must have two runs): bit-equal on
    /// the neurons that are not wavelets, within f32 rounding of eq. (5) in f64 on the
    /// wavelets, and 0 both ways on the neurons along a NaN or infinite input.
    fn check_recurrence<const N: usize, const L: usize>(shape: WnnShape<N, L>, name: &str) {
        extern crate std;
        let fast = shape.with_recurrence();
        let Evaluation::Recurrence { n, .. } = fast.evaluation else {
            panic!("no recurrence");
        };
        assert_eq!(n, 2, "{name}: runs found");
        let mut state = 99u32;
        let mut err = RecurrenceErrors::default();
        for i in 0..20_000 {
            let mut x = recurrence_inputs::<N>(&mut state);
            let (mut hd, mut hf) = ([0.0f32; L], [0.0f32; L]);
            if i % 1000 == 7 {
                // Non-finite input: the neurons along it give 0 both ways.
                x[N - 1] = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY][i / 1000 % 3];
                fast.hidden(&x, &mut hf);
                shape.hidden(&x, &mut hd);
                for l in 0..L {
                    if shape.a[l][N - 1] != 0.0 {
                        assert_eq!((hd[l], hf[l]), (0.0, 0.0), "{name}");
                    }
                }
                continue;
            }
            shape.hidden(&x, &mut hd);
            fast.hidden(&x, &mut hf);
            for l in 0..L {
                if shape.kind[l] != Neuron::Wavelet {
                    assert_eq!(hd[l].to_bits(), hf[l].to_bits());
                    continue;
                }
                let e = wavelet_f64(&shape, &x, l);
                let (d, f) = (f64::from(hd[l]), f64::from(hf[l]));
                assert!(f.is_finite(), "{name}: {x:?}");
                err.abs_f = err.abs_f.max((f - e).abs());
                err.abs_d = err.abs_d.max((d - e).abs());
                if e.abs() > 1e-30 {
                    err.rel_f = err.rel_f.max((f - e).abs() / e.abs());
                    err.rel_d = err.rel_d.max((d - e).abs() / e.abs());
                }
            }
        }
        let RecurrenceErrors {
            rel_f,
            abs_f,
            rel_d,
            abs_d,
        } = err;
        std::println!(
            "{name}: vs f64: recurrence max relative {rel_f:.2e} absolute {abs_f:.2e}; direct max relative {rel_d:.2e} absolute {abs_d:.2e}"
        );
        // Relative errors are dominated by the f32 rounding of t itself (t^2 * 2^-24 at
        // the tails, and the Mexican hat's zero crossings), which both evaluations share.
        assert!(abs_f < 1e-6, "{name}: {abs_f}");
        assert!(
            rel_f < 1.1 * rel_d + 1e-6,
            "{name}: {rel_f} vs direct {rel_d}"
        );
    }

    /// Recurrence vs direct evaluation, the level-trend layout (bias, link, 14 + 14
    /// Gaussians); inputs over [-4, 4] plus NaN and infinities (see [`check_recurrence`]).
    #[test]
    fn recurrence_matches_direct_level_trend() {
        let lt = WnnShape::<3, 30>::from_groups(
            &[
                Group::Bias,
                Group::Linear(0),
                Group::Along {
                    input: 1,
                    count: 14,
                    overlap: 1.0,
                },
                Group::Along {
                    input: 2,
                    count: 14,
                    overlap: 1.0,
                },
            ],
            Activation::Gaussian,
        )
        .expect("valid");
        check_recurrence(lt, "level-trend 14+14 Gaussian");
    }

    /// Recurrence vs direct evaluation, the paper's layout (15 + 15, Gaussian and Mexican
    /// hat).
    #[test]
    fn recurrence_matches_direct_paper() {
        for act in [Activation::Gaussian, Activation::MexicanHat] {
            let p = WnnShape::<2, 30>::from_groups(
                &[
                    Group::Along {
                        input: 0,
                        count: 15,
                        overlap: 1.0,
                    },
                    Group::Along {
                        input: 1,
                        count: 15,
                        overlap: 1.0,
                    },
                ],
                act,
            )
            .expect("valid");
            check_recurrence(
                p,
                if act == Activation::Gaussian {
                    "paper 15+15 Gaussian"
                } else {
                    "paper 15+15 Mexican hat"
                },
            );
        }
    }

    /// Recurrence vs direct evaluation, wider overlap (neighbours half a sigma apart) and
    /// sparser (2.5 and 3.75 sigma).
    #[test]
    fn recurrence_matches_direct_other_overlaps() {
        for overlap in [0.5f32, 2.5] {
            let s = WnnShape::<1, 10>::from_groups(
                &[
                    Group::Along {
                        input: 0,
                        count: 5,
                        overlap,
                    },
                    Group::Along {
                        input: 0,
                        count: 5,
                        overlap: overlap * 1.5,
                    },
                ],
                Activation::MexicanHat,
            )
            .expect("valid");
            check_recurrence(s, "1 input, 5+5 neurons, other overlaps");
        }
    }

    /// A wavelet neuron outside the runs (the warm-up neuron): no list, neuron by neuron,
    /// and the recurrence still matches the direct evaluation.
    #[test]
    fn recurrence_matches_direct_wavelet_outside_runs() {
        let tt = crate::identify::presets::time_temp_shape::<30>().expect("valid");
        assert!(matches!(
            tt.with_recurrence().evaluation,
            Evaluation::Recurrence { listed: None, .. }
        ));
        check_recurrence(tt, "time-temp: warm-up neuron outside the runs");
    }

    /// Biases and links only outside the runs: the level-trend preset lists them.
    #[test]
    fn recurrence_lists_biases_and_links() {
        let lt = crate::identify::presets::level_trend_shape::<30>().expect("valid");
        assert!(matches!(
            lt.evaluation,
            Evaluation::Recurrence {
                listed: Some(_),
                n_listed: 2,
                ..
            }
        ));
    }

    /// `exp_anchor` against f64 over its whole domain [-87, 88].
    #[test]
    fn exp_recurrence_accuracy() {
        let mut worst_ulp = 0.0f64;
        let n = 2_000_000;
        for i in 0..=n {
            let x = -87.0f32 + 175.0 * i as f32 / n as f32;
            let got = f64::from(exp_anchor(x));
            let want = f64::from(x).exp();
            let ulp = f64::from(f32::EPSILON)
                * f64::from(2.0f32.powi((want as f32).log2().floor() as i32));
            worst_ulp = worst_ulp.max((got - want).abs() / ulp);
        }
        extern crate std;
        std::println!("exp_anchor: worst error {worst_ulp:.2} ulp over [-87, 88]");
        assert!(worst_ulp <= 2.0, "{worst_ulp}");
    }
}

//! One small Kalman filter: `N` states, f32 (or f64 on the host: [`Scalar`]), no heap,
//! scalar observations.
//!
//! The model is apart from the filter that runs it (as `adskalman`): a [`DiagonalModel`]
//! holds the transition and the process noise of one step,
//!
//! ```text
//! x(k+1) = F x(k) + w,   F = diag(phi),   var w = diag(q)
//! z(k)   = h(k) x(k) + v,                 var v = r
//! ```
//!
//! and [`Kalman`] holds the state `x` and its covariance `P` and runs the model's steps.
//! The observation row `h` and its noise `r` are given per update: they change with time and
//! temperature in the drift filter. Every model in the project has a diagonal transition
//! (random walks, Gauss-Markov terms, constants), so the predict step is `O(N^2)`; an update
//! is `O(N^2)` too (scalar observation).
//!
//! Accuracy: tested against an f64 reference on random models, the state and covariance
//! agree to 1e-5 of their scale after 200 steps (`cargo test -p fog-core --lib kalman`).
//! `P` stays symmetric by construction (only its upper triangle is computed, then mirrored)
//! and its diagonal is clamped at 0 after each update (f32 cancellation).

/// The number type a filter runs in: `f32` (the firmware) or `f64` (the host's baselines).
pub trait Scalar:
    Copy
    + PartialOrd
    + core::ops::Add<Output = Self>
    + core::ops::Sub<Output = Self>
    + core::ops::Mul<Output = Self>
    + core::ops::Div<Output = Self>
    + core::ops::AddAssign
    + core::ops::SubAssign
    + core::ops::MulAssign
{
    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;
    /// Neither infinite nor NaN.
    fn finite(self) -> bool;
    /// From f64 (rounded to the type).
    fn from_f64(v: f64) -> Self;
    /// To f64 (exact).
    fn to_f64(self) -> f64;
}

impl Scalar for f32 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    fn finite(self) -> bool {
        self.is_finite()
    }
    fn from_f64(v: f64) -> Self {
        v as f32
    }
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
}

impl Scalar for f64 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    fn finite(self) -> bool {
        self.is_finite()
    }
    fn from_f64(v: f64) -> Self {
        v
    }
    fn to_f64(self) -> f64 {
        self
    }
}

/// One step of a model with a diagonal transition and diagonal process noise.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DiagonalModel<const N: usize, T: Scalar = f32> {
    /// Transition: `x_i <- phi_i x_i` (1 for a random walk or a constant, `e^(-dt/tau)`
    /// for a Gauss-Markov term).
    pub phi: [T; N],
    /// Process noise variance added to `P_ii` per step, in the state's unit squared.
    pub q: [T; N],
}

impl<const N: usize, T: Scalar> DiagonalModel<N, T> {
    /// The model of `steps` steps of `self` at once: `phi^steps`, and the noise the steps
    /// add up to (`q * sum phi^(2j)`, `j < steps`; `q * steps` where `phi` is 1).
    pub fn repeated(&self, steps: u32) -> Self {
        let mut out = *self;
        for ((phi_out, q_out), (&phi, &q)) in out
            .phi
            .iter_mut()
            .zip(out.q.iter_mut())
            .zip(self.phi.iter().zip(self.q.iter()))
        {
            // In f64: phi near 1 raised to thousands loses f32 digits.
            let phi64 = phi.to_f64();
            let phin = libm::pow(phi64, steps as f64);
            *phi_out = T::from_f64(phin);
            let gain = if (1.0 - phi64 * phi64).abs() < 1e-12 {
                steps as f64
            } else {
                (1.0 - phin * phin) / (1.0 - phi64 * phi64)
            };
            *q_out = T::from_f64(q.to_f64() * gain);
        }
        out
    }
}

/// The innovation of a scalar observation: `e = z - h x`, its variance `s = h P h' + r`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Innovation<T: Scalar = f32> {
    /// `z - h x`, the observation's unit.
    pub e: T,
    /// `h P h' + r`, the observation's unit squared (> 0 whenever `r > 0`).
    pub s: T,
}

impl<T: Scalar> Innovation<T> {
    /// The normalized innovation squared `e^2 / s` (chi-square with one degree of freedom
    /// when the model is right); `None` when `s` is not > 0.
    pub fn nis(&self) -> Option<T> {
        (self.s > T::ZERO).then(|| self.e * self.e / self.s)
    }
}

/// State `x` and covariance `P` of an `N`-state Kalman filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kalman<const N: usize, T: Scalar = f32> {
    x: [T; N],
    p: [[T; N]; N],
}

impl<const N: usize, T: Scalar> Kalman<N, T> {
    /// A filter at its prior: mean `x0`, covariance `diag(p0)`.
    pub fn new(x0: [T; N], p0: [T; N]) -> Self {
        let mut p = [[T::ZERO; N]; N];
        for (i, row) in p.iter_mut().enumerate() {
            if let (Some(v), Some(d)) = (row.get_mut(i), p0.get(i)) {
                *v = *d;
            }
        }
        Self { x: x0, p }
    }

    /// A filter at its prior: mean `x0`, covariance `p0` (made symmetric: the mean of it
    /// and its transpose).
    pub fn with_covariance(x0: [T; N], p0: [[T; N]; N]) -> Self {
        let mut p = p0;
        for i in 0..N {
            for j in (i + 1)..N {
                let (Some(a), Some(b)) = (
                    p0.get(i).and_then(|r| r.get(j)),
                    p0.get(j).and_then(|r| r.get(i)),
                ) else {
                    continue;
                };
                let v = (*a + *b) * T::from_f64(0.5);
                if let Some(x) = p.get_mut(i).and_then(|r| r.get_mut(j)) {
                    *x = v;
                }
                if let Some(x) = p.get_mut(j).and_then(|r| r.get_mut(i)) {
                    *x = v;
                }
            }
        }
        Self { x: x0, p }
    }

    /// The state.
    pub fn x(&self) -> &[T; N] {
        &self.x
    }

    /// The covariance.
    pub fn p(&self) -> &[[T; N]; N] {
        &self.p
    }

    /// `h x`.
    pub fn observe(&self, h: &[T; N]) -> T {
        dot(h, &self.x)
    }

    /// `h P h'`: the variance of `h x`.
    pub fn observe_var(&self, h: &[T; N]) -> T {
        let mut s = T::ZERO;
        for (row, &hi) in self.p.iter().zip(h.iter()) {
            s += hi * dot(row, h);
        }
        s
    }

    /// Predict one step of `model`: `x <- F x`, `P <- F P F' + Q`.
    pub fn predict(&mut self, model: &DiagonalModel<N, T>) {
        for (x, &phi) in self.x.iter_mut().zip(model.phi.iter()) {
            *x *= phi;
        }
        for (i, (row, &phi_i)) in self.p.iter_mut().zip(model.phi.iter()).enumerate() {
            for (j, (v, &phi_j)) in row.iter_mut().zip(model.phi.iter()).enumerate() {
                *v *= phi_i * phi_j;
                if i == j {
                    if let Some(&q) = model.q.get(i) {
                        *v += q;
                    }
                }
            }
        }
    }

    /// The innovation of observing `z = h x + v`, `var v = r`, without updating.
    pub fn innovation(&self, h: &[T; N], z: T, r: T) -> Innovation<T> {
        Innovation {
            e: z - self.observe(h),
            s: self.observe_var(h) + r,
        }
    }

    /// Update with the observation `z = h x + v`, `var v = r`; returns the innovation it
    /// used. Nothing changes (and `None` is returned) when `z` or `r` is not finite or the
    /// innovation variance is not > 0.
    pub fn update(&mut self, h: &[T; N], z: T, r: T) -> Option<Innovation<T>> {
        let inn = self.innovation(h, z, r);
        if !(z.finite() && r.finite() && inn.s > T::ZERO && inn.s.finite()) {
            return None;
        }
        // u = P h'; K = u / s; x += K e; P -= u u' / s (upper triangle, mirrored).
        let mut u = [T::ZERO; N];
        for (ui, row) in u.iter_mut().zip(self.p.iter()) {
            *ui = dot(row, h);
        }
        let inv_s = T::ONE / inn.s;
        for (x, &ui) in self.x.iter_mut().zip(u.iter()) {
            *x += ui * inv_s * inn.e;
        }
        for i in 0..N {
            for j in i..N {
                let (Some(&ui), Some(&uj)) = (u.get(i), u.get(j)) else {
                    continue;
                };
                let Some(v) = self.p.get_mut(i).and_then(|r| r.get_mut(j)) else {
                    continue;
                };
                *v -= ui * uj * inv_s;
                if i == j && *v < T::ZERO {
                    *v = T::ZERO;
                }
                let v = *v;
                if let Some(m) = self.p.get_mut(j).and_then(|r| r.get_mut(i)) {
                    *m = v;
                }
            }
        }
        Some(inn)
    }
}

fn dot<const N: usize, T: Scalar>(a: &[T; N], b: &[T; N]) -> T {
    let mut s = T::ZERO;
    for (&x, &y) in a.iter().zip(b.iter()) {
        s += x * y;
    }
    s
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)] // the reference is written as the textbook's sums
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The textbook filter in f64 with full matrices: the reference.
    struct Reference<const N: usize> {
        x: [f64; N],
        p: [[f64; N]; N],
    }

    impl<const N: usize> Reference<N> {
        fn predict(&mut self, phi: &[f32; N], q: &[f32; N]) {
            let mut f = [[0.0f64; N]; N];
            for i in 0..N {
                f[i][i] = phi[i] as f64;
            }
            let mut x = [0.0; N];
            for i in 0..N {
                for j in 0..N {
                    x[i] += f[i][j] * self.x[j];
                }
            }
            self.x = x;
            let mut fp = [[0.0; N]; N];
            for i in 0..N {
                for j in 0..N {
                    for k in 0..N {
                        fp[i][j] += f[i][k] * self.p[k][j];
                    }
                }
            }
            let mut p = [[0.0; N]; N];
            for i in 0..N {
                for j in 0..N {
                    for k in 0..N {
                        p[i][j] += fp[i][k] * f[j][k];
                    }
                }
                p[i][i] += q[i] as f64;
            }
            self.p = p;
        }

        fn update(&mut self, h: &[f32; N], z: f32, r: f32) {
            let h: [f64; N] = core::array::from_fn(|i| h[i] as f64);
            let mut ph = [0.0; N];
            for i in 0..N {
                for j in 0..N {
                    ph[i] += self.p[i][j] * h[j];
                }
            }
            let s: f64 = (0..N).map(|i| h[i] * ph[i]).sum::<f64>() + r as f64;
            let k: [f64; N] = core::array::from_fn(|i| ph[i] / s);
            let e = z as f64 - (0..N).map(|i| h[i] * self.x[i]).sum::<f64>();
            for i in 0..N {
                self.x[i] += k[i] * e;
            }
            // Joseph form: (I - K h) P (I - K h)' + K r K'.
            let mut a = [[0.0; N]; N];
            for i in 0..N {
                for j in 0..N {
                    a[i][j] = if i == j { 1.0 } else { 0.0 } - k[i] * h[j];
                }
            }
            let mut ap = [[0.0; N]; N];
            for i in 0..N {
                for j in 0..N {
                    for m in 0..N {
                        ap[i][j] += a[i][m] * self.p[m][j];
                    }
                }
            }
            let mut p = [[0.0; N]; N];
            for i in 0..N {
                for j in 0..N {
                    for m in 0..N {
                        p[i][j] += ap[i][m] * a[j][m];
                    }
                    p[i][j] += k[i] * r as f64 * k[j];
                }
            }
            self.p = p;
        }
    }

    const N: usize = 5;

    fn model() -> impl Strategy<Value = ([f32; N], [f32; N], [f32; N])> {
        (
            prop::array::uniform5(0.9f32..1.0),
            prop::array::uniform5(1e-4f32..1e-2),
            prop::array::uniform5(0.1f32..2.0),
        )
    }

    proptest! {
        /// 200 predict/update steps on a random model: f32 against the f64 reference.
        #[test]
        fn matches_the_f64_reference(
            (phi, q, p0) in model(),
            seed in 0u64..1000,
            r in 0.01f32..1.0,
        ) {
            let mut f = Kalman::<N>::new([0.0; N], p0);
            let mut reference = Reference::<N> {
                x: [0.0; N],
                p: core::array::from_fn(|i| core::array::from_fn(|j| if i == j { p0[i] as f64 } else { 0.0 })),
            };
            let m = DiagonalModel { phi, q };
            let mut state = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
            let mut next = || {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                ((state >> 33) as f64 / (1u64 << 31) as f64 - 0.5) as f32
            };
            for _ in 0..200 {
                f.predict(&m);
                reference.predict(&phi, &q);
                let h: [f32; N] = core::array::from_fn(|_| 1.0 + next());
                let z = 2.0 * next();
                f.update(&h, z, r);
                reference.update(&h, z, r);
            }
            let scale_p = (0..N).map(|i| reference.p[i][i]).fold(0.0f64, f64::max);
            for i in 0..N {
                let sx = reference.p[i][i].sqrt().max(1e-3);
                prop_assert!((f.x()[i] as f64 - reference.x[i]).abs() <= 1e-4 * sx.max(reference.x[i].abs()) + 1e-5,
                    "x[{i}] {} vs {}", f.x()[i], reference.x[i]);
                for j in 0..N {
                    prop_assert!((f.p()[i][j] as f64 - reference.p[i][j]).abs() <= 1e-5 * scale_p,
                        "P[{i}][{j}] {} vs {}", f.p()[i][j], reference.p[i][j]);
                }
            }
        }
    }

    #[test]
    fn repeated_steps_equal_the_steps() {
        let m = DiagonalModel::<3, f32> {
            phi: [1.0, 0.99, 0.5],
            q: [1e-3, 2e-3, 0.1],
        };
        let mut a = Kalman::new([1.0, 2.0, 3.0], [1.0, 0.5, 0.2]);
        let mut b = a;
        for _ in 0..50 {
            a.predict(&m);
        }
        b.predict(&m.repeated(50));
        for i in 0..3 {
            assert!((a.x()[i] - b.x()[i]).abs() < 1e-5, "{i}");
            assert!((a.p()[i][i] - b.p()[i][i]).abs() < 1e-4, "{i}");
        }
    }

    #[test]
    fn a_bad_observation_changes_nothing() {
        let mut f = Kalman::<2, f32>::new([1.0, 0.0], [1.0, 1.0]);
        let before = f;
        assert!(f.update(&[1.0, 1.0], f32::NAN, 1.0).is_none());
        assert!(f.update(&[1.0, 1.0], 1.0, f32::INFINITY).is_none());
        assert!(f.update(&[0.0, 0.0], 1.0, 0.0).is_none());
        assert_eq!(f, before);
    }

    #[test]
    fn a_scalar_random_walk_is_the_textbook_one() {
        // q = 0.01, r = 1: steady-state P+ solves P = (P + q) r / (P + q + r).
        let m = DiagonalModel::<1, f32> {
            phi: [1.0],
            q: [0.01],
        };
        let mut f = Kalman::new([0.0], [10.0]);
        for _ in 0..2000 {
            f.predict(&m);
            f.update(&[1.0], 0.0, 1.0);
        }
        let p = f64::from(f.p()[0][0]);
        let steady = {
            let q = 0.01f64;
            (-q + (q * q + 4.0 * q).sqrt()) / 2.0
        };
        assert!((p - steady).abs() < 1e-5, "{p} vs {steady}");
        // The same in f64 (the host's baselines): to 1e-12.
        let m64 = DiagonalModel::<1, f64> {
            phi: [1.0],
            q: [0.01],
        };
        let mut g = Kalman::new([0.0], [10.0]);
        for _ in 0..2000 {
            g.predict(&m64);
            g.update(&[1.0], 0.0, 1.0);
        }
        assert!((g.p()[0][0] - steady).abs() < 1e-12, "{}", g.p()[0][0]);
    }
}

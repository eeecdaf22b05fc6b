//! The warm-up of a unit whose time constant is not known as a Kalman filter can carry it:
//! a few exponentials at fixed time constants with a joint prior.
//!
//! A unit's warm-up is `a e^(-t/tau)` with `a` (mean `m`, spread `s`) and `tau` log-uniform
//! on `[tau_min, tau_max]`, independent ([`crate::gyro_model::GyroModel`]). It is written
//! as `sum_j c_j e^(-t/tau_j)` on [`TERMS`] basis time constants spread geometrically over
//! the range (one term when the range is narrower than [`ONE_TERM_RATIO`]). The basis
//! coefficients of one exponential, `c(tau)`, are its least-squares projection on the basis
//! over `t` in `[0, inf)`: `c(tau) = G^-1 g(tau)` with `G_ij = tau_i tau_j / (tau_i +
//! tau_j)` and `g_j(tau) = tau tau_j / (tau + tau_j)` (the integrals of the products). The
//! prior of the coefficients is then
//!
//! ```text
//! E[c]   = m E_tau[c(tau)]
//! Cov[c] = (m^2 + s^2) E_tau[c c'] - m^2 E_tau[c] E_tau[c]'
//! ```
//!
//! with `E_tau` a midpoint rule of [`QUADRATURE`] points in `ln tau`. So a slope seen in the
//! first minutes is not read as one amplitude at one time constant: the filter's posterior
//! weighs every time constant of the range, and its prediction through a long drive is the
//! average over them. Accuracy: an exponential of the range is reproduced by its
//! projection within 5 % of its amplitude at every `t` for a range ratio of 9, 9 % for 15
//! and 26 % for 100 (the worst at `t` near 0; unit test `one_exponential_is_reproduced`). Computed once when a
//! filter is built, in f32 (the MCU's FPU: a few thousand instructions at boot).

/// Number of basis terms.
pub const TERMS: usize = 3;
/// Below this ratio `tau_max / tau_min` one term at the geometric mean carries the warm-up.
pub const ONE_TERM_RATIO: f32 = 1.5;
/// Points of the quadrature over `ln tau`.
pub const QUADRATURE: usize = 32;

/// The basis and the prior of its coefficients.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WarmupBasis {
    /// Time constants, s; 0: the term is absent (its coefficient stays 0).
    pub tau_s: [f32; TERMS],
    /// Prior mean of the coefficients, deg/s.
    pub mean_dps: [f32; TERMS],
    /// Prior covariance of the coefficients, (deg/s)^2.
    pub cov_dps2: [[f32; TERMS]; TERMS],
}

impl WarmupBasis {
    /// The basis of a warm-up of amplitude mean `m_dps`, spread `s_dps`, time constant
    /// log-uniform on `[tau_min_s, tau_max_s]` (0 < min <= max, finite: else `None`).
    pub fn new(m_dps: f32, s_dps: f32, tau_min_s: f32, tau_max_s: f32) -> Option<Self> {
        if !(tau_min_s > 0.0 && tau_min_s <= tau_max_s && tau_max_s.is_finite()) {
            return None;
        }
        let second = m_dps * m_dps + s_dps * s_dps;
        if tau_max_s / tau_min_s < ONE_TERM_RATIO {
            let mut out = Self {
                tau_s: [0.0; TERMS],
                mean_dps: [0.0; TERMS],
                cov_dps2: [[0.0; TERMS]; TERMS],
            };
            out.tau_s[0] = libm::sqrtf(tau_min_s * tau_max_s);
            out.mean_dps[0] = m_dps;
            out.cov_dps2[0][0] = s_dps * s_dps;
            return Some(out);
        }
        let (l0, l1) = (libm::logf(tau_min_s), libm::logf(tau_max_s));
        let mut tau_s = [0.0; TERMS];
        for (j, t) in tau_s.iter_mut().enumerate() {
            *t = libm::expf(l0 + (l1 - l0) * j as f32 / (TERMS - 1) as f32);
        }
        let mut g = [[0.0; TERMS]; TERMS];
        for (i, row) in g.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = tau_s[i] * tau_s[j] / (tau_s[i] + tau_s[j]);
            }
        }
        let g_inv = invert(g)?;
        let mut ec = [0.0; TERMS];
        let mut ecc = [[0.0; TERMS]; TERMS];
        for k in 0..QUADRATURE {
            let tau = libm::expf(l0 + (l1 - l0) * (k as f32 + 0.5) / QUADRATURE as f32);
            let c = project(&g_inv, &tau_s, tau);
            for i in 0..TERMS {
                ec[i] += c[i] / QUADRATURE as f32;
                for j in 0..TERMS {
                    ecc[i][j] += c[i] * c[j] / QUADRATURE as f32;
                }
            }
        }
        let mut mean_dps = [0.0; TERMS];
        let mut cov_dps2 = [[0.0; TERMS]; TERMS];
        for i in 0..TERMS {
            mean_dps[i] = m_dps * ec[i];
            for j in 0..TERMS {
                cov_dps2[i][j] = second * ecc[i][j] - m_dps * m_dps * ec[i] * ec[j];
            }
        }
        Some(Self {
            tau_s,
            mean_dps,
            cov_dps2,
        })
    }
}

/// `c(tau) = G^-1 g(tau)`.
fn project(g_inv: &[[f32; TERMS]; TERMS], tau_s: &[f32; TERMS], tau: f32) -> [f32; TERMS] {
    let mut g = [0.0; TERMS];
    for (v, &tj) in g.iter_mut().zip(tau_s) {
        *v = tau * tj / (tau + tj);
    }
    let mut c = [0.0; TERMS];
    for (ci, row) in c.iter_mut().zip(g_inv) {
        *ci = row.iter().zip(&g).map(|(a, b)| a * b).sum();
    }
    c
}

/// Inverse of a symmetric positive definite `TERMS x TERMS` matrix by Gauss-Jordan
/// elimination with partial pivoting; `None` when singular.
fn invert(mut a: [[f32; TERMS]; TERMS]) -> Option<[[f32; TERMS]; TERMS]> {
    let mut inv = [[0.0; TERMS]; TERMS];
    for (i, row) in inv.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    for c in 0..TERMS {
        let mut p = c;
        for r in c + 1..TERMS {
            if libm::fabsf(a[r][c]) > libm::fabsf(a[p][c]) {
                p = r;
            }
        }
        let pivot = libm::fabsf(a[p][c]);
        if pivot.is_nan() || pivot <= 1e-30 {
            return None;
        }
        a.swap(c, p);
        inv.swap(c, p);
        let d = a[c][c];
        for q in 0..TERMS {
            a[c][q] /= d;
            inv[c][q] /= d;
        }
        for r in 0..TERMS {
            if r != c {
                let f = a[r][c];
                for q in 0..TERMS {
                    a[r][q] -= f * a[c][q];
                    inv[r][q] -= f * inv[c][q];
                }
            }
        }
    }
    Some(inv)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[allow(clippy::needless_range_loop)] // the Gram matrix reads clearest with indices
    fn one_exponential_is_reproduced() {
        for (lo, hi, tol) in [
            (150.0, 1300.0, 0.05),
            (100.0, 1500.0, 0.09),
            (30.0, 3000.0, 0.26),
        ] {
            let b = WarmupBasis::new(1.0, 0.0, lo, hi).expect("basis");
            let mut g = [[0.0; TERMS]; TERMS];
            for i in 0..TERMS {
                for j in 0..TERMS {
                    g[i][j] = b.tau_s[i] * b.tau_s[j] / (b.tau_s[i] + b.tau_s[j]);
                }
            }
            let g_inv = invert(g).expect("invert");
            for k in 0..=20 {
                let tau = lo * libm::powf(hi / lo, k as f32 / 20.0);
                let c = project(&g_inv, &b.tau_s, tau);
                for t in (0..=6000).step_by(50) {
                    let t = t as f32;
                    let want = libm::expf(-t / tau);
                    let got: f32 = (0..TERMS).map(|j| c[j] * libm::expf(-t / b.tau_s[j])).sum();
                    assert!(
                        (got - want).abs() < tol,
                        "range {lo}..{hi} tau {tau} t {t}: {got} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_prior_is_that_of_the_warm_up_it_stands_for() {
        // The prior's value at t = 0 (sum of coefficients) has the amplitude's mean and
        // about its variance; its covariance is symmetric with a non-negative diagonal.
        let (m, s) = (10.0, 20.0);
        let b = WarmupBasis::new(m, s, 100.0, 1500.0).expect("basis");
        let mean0: f32 = b.mean_dps.iter().sum();
        let var0: f32 = b.cov_dps2.iter().flatten().sum();
        assert!((mean0 / m - 1.0).abs() < 0.03, "{mean0}");
        assert!((var0 / (s * s) - 1.0).abs() < 0.06, "{var0}");
        for i in 0..TERMS {
            assert!(b.cov_dps2[i][i] >= 0.0);
            for j in 0..TERMS {
                assert!(
                    (b.cov_dps2[i][j] - b.cov_dps2[j][i]).abs()
                        < 1e-6 * b.cov_dps2[i][i].abs().max(b.cov_dps2[j][j].abs())
                );
            }
        }
    }

    #[test]
    fn a_narrow_range_is_one_term() {
        let b = WarmupBasis::new(2.0, 3.0, 400.0, 500.0).expect("basis");
        assert!((b.tau_s[0] - 447.2136).abs() < 1e-2);
        assert_eq!(&b.tau_s[1..], &[0.0, 0.0]);
        assert_eq!(b.mean_dps[0], 2.0);
        assert_eq!(b.cov_dps2[0][0], 9.0);
        assert!(WarmupBasis::new(1.0, 1.0, 0.0, 10.0).is_none());
        assert!(WarmupBasis::new(1.0, 1.0, 20.0, 10.0).is_none());
    }
}

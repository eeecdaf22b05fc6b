#!/usr/bin/env python3
"""Oracle detectability bound for the independent `host-sim gap` benchmark (issue 13).

Requires: python3 and numpy (`pip install numpy`); scripts/gap_indep_gen.py (imported).

Question: how many records of a set made by scripts/gap_indep_gen.py could ANY test name
right, if it knew everything the generator drew except the noise realisation? For every
record of DIR/manifest.jsonl this script computes the power of an ORACLE test that knows the
effect's exact shape and parameters and the true baseline noise model (N, B, K from the
manifest; the constant bias stays unknown), at a threshold that keeps `none` false alarms
<= 5 % over the whole vocabulary. That power bounds (or, where said, approximates a bound
on) the power of any real test, which has to estimate all of this from the record.

Method per effect (s = the generator's strength, D, sigma_w as in gap_indep_gen.py):
- Deterministic effects of known shape: rate_ramp, warmup, temperature, scale_factor (true
  error on the recorded true_rate_dps). The effect signal m is rebuilt exactly by re-running the
  generator's make_record() with the record's seed twice, with its strength and with
  strength 0 (the generator draws the same numbers either way), m = difference. Detection
  SNR of the matched filter (generalised least squares), d^2 = m^T C^-1 m, on 1-s block
  means, with the unknown constant bias projected out (and NO linear trend projected out:
  a real test must allow a constant bias, but a trend is what the ramp is; slow wander is
  the rate random walk, which is in C). C is exact for the generator's noise: white
  sigma_w^2 / L; random walk K^2 dt (min(i, j) + 1) averaged over the blocks; flicker from
  the exact circulant autocovariance of the generator's FFT shaping, irfft(gain^2) on 2n
  points, averaged over the blocks (no numeric integration, no approximation). The signal
  inside the 1-s blocks (what block means lose) is added as a white-noise-only term
  d_in^2 = sum (m - block mean)^2 / sigma_w^2 (an approximation; its share is printed).
  Temperature: the oracle's regressor is the true coefficients applied to the RECORDED
  1/16-degC channel (dT/dt by the generator's 30-s moving mean, shrunk at the ends instead
  of the raw series there), not the true temperature, whose sample-scale wander the channel
  cannot show; d is then the mismatched-filter SNR (regressor vs true drift), block means
  alone or with the within-block part, whichever is larger. The d with the true
  temperature is printed beside it.
- sinusoid (known frequency, phase, amplitude): the matched filter in stationary noise,
  d^2 = sum m^2 dt / S(f), S(f) the exact two-sided PSD of the generator's baseline at the
  line (white N^2, flicker B^2 / (2 pi f), discrete random walk K^2 dt^2 / (4 sin^2(pi f
  dt))). Exact for white noise (d = s), asymptotic (>= 90 cycles) otherwise.
- markov (known sigma, tau, and baseline): the Gaussian likelihood-ratio test of baseline
  vs baseline + Gauss-Markov in Whittle form on the first differences (differencing
  removes the bias and makes the walk white; the likelihood ratio does not change), T =
  sum_k (1 - S0/S1)(f_k) I_k / S0(f_k), I_k the periodogram; under either hypothesis T is a
  weighted sum of unit exponentials, whose tails come from the Lugannani-Rice saddlepoint
  approximation. By Neyman-Pearson this is the most powerful test of the two simple
  hypotheses (up to the Whittle approximation). Beside it the exact Gaussian LRT on 1-s
  block means (the generalised eigenvalues of the two block covariances, the constant bias
  as a diffuse component; a weighted chi-square, saddlepoint tails), which --mc checks;
  the power used is the larger of the two.
- spikes (known amplitude law 5-30 sigma_w and rate, unknown places): the max |z| test over
  all samples with white noise only (for coloured noise added, every sample's SNR is lower,
  so white-only is an upper bound per spike), threshold for n samples; a record with k
  spikes (k from the manifest) is detected with 1 - (1 - alpha) q^k, q = P(one spike below
  the threshold) over the amplitude law. Not the exact likelihood-ratio test of the sparse
  mixture, but with spikes of >= 5 sigma_w in >= 90,000 samples the two differ little; a
  record with 0 spikes (37 % at s = 1) is undetectable by any test.
- dropouts: the timestamp test (any gap > 1.5 dt): power 1 if at least one sample was
  dropped, no false alarm possible; a record with 0 dropped samples (72 % at s = 1) is
  undetectable by any test.
- quantization (known quantum q): the lattice test, the count of samples of the CSV (10
  significant digits) within the print tolerance of a multiple of q, against its Chernoff
  bound under the null (continuous values: hit probability 2 tol / q per sample).
- none: right unless some test fires: (1 - alpha)^9.
Also printed: the sinusoid's power with the frequency and phase UNKNOWN (periodogram
maximum over the n/2 Fourier bins, line on a bin, all else known: threshold ln((n/2) /
alpha), noncentral chi-square(2, d^2) with the line), the detectable count and score with
that power for the sinusoid records (context beside the headline), and with --diag the effect records of
oracle power < 0.05 that the diagnosis named an effect on.

Threshold: Bonferroni over the 9 effect tests, alpha = 0.05 / 9 per test (one-sided z
2.54), so an oracle running all of them flags a `none` record at most 5 % of the time. A
record counts as right with the probability that its own effect's test fires (upper bound:
the oracle is not charged for another test also firing). Expected right = sum over the
records. Per effect, s90 is the strength at which the class's mean power (the class's
records with everything but s kept) reaches 90 %.

--mc R checks the statistics by Monte-Carlo on one record of each of the deterministic,
sinusoid and markov classes (the one whose oracle power is nearest 50 %): R baseline-only
noise draws made with the generator's own code (white + gap_indep_gen.flicker + cumsum walk, + gauss_markov), the
oracle statistic applied without and with the effect (mean and sd of z vs N(0,1), N(d,1);
for markov the block LRT's mean, sd, false alarms and power vs the saddlepoint prediction).
Deterministic: numpy's default_rng, seeded per record from --mc-seed and the record seed.

Usage:
  scripts/gap_oracle_bound.py --dir RECORDS [--diag BENCH_OUT] [--json OUT.json]
      [--mc R] [--mc-seed 1] [--no-csv-check]
(--diag: a gap_indep_bench.py output folder, to print the diagnosis's verdicts beside.)
"""

import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gap_indep_gen as gen  # noqa: E402

N_TESTS = 9
ALPHA = 0.05 / N_TESTS
LINEAR = ["rate_ramp", "warmup", "temperature", "scale_factor", "sinusoid"]
BLOCK_S = 1.0


def phi(x):
    return 0.5 * math.erfc(-x / math.sqrt(2.0))


def phi_vec(x):
    x = np.asarray(x, float)
    return 0.5 * np.array([math.erfc(-v / math.sqrt(2.0)) for v in x.ravel()]).reshape(x.shape)


def norm_ppf(p):
    """Inverse standard normal CDF by bisection (p in (0, 1))."""
    lo, hi = -40.0, 40.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if phi(mid) < p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


Z_THR = norm_ppf(1.0 - ALPHA)


def noise_params(m):
    """Per-sample white sigma, flicker B and walk K in dps units, as the generator uses them."""
    dt = 1.0 / m["fs_hz"]
    n_dps = m["arw_deg_rth"] / 60.0
    return dt, n_dps / math.sqrt(dt), m["bi_deg_h"] * gen.DEG_H, m["rrw_deg_h_rh"] / 216000.0


def baseline_noise(rng, n, dt, sigma_w, b, k):
    """Baseline-only noise with the generator's own code (no bias: it is projected out)."""
    y = sigma_w * rng.standard_normal(n)
    y += gen.flicker(rng, n, dt, b)
    y += np.cumsum(rng.standard_normal(n)) * k * math.sqrt(dt)
    return y


# ---------------------------------------------------------------- block-mean GLS
def stationary_block(acov, nb, L):
    """Covariance of the block means (L samples) of a stationary series, acov[lag]."""
    n = len(acov)
    u = np.arange(-(L - 1), L)
    tri = (L - np.abs(u)) / float(L * L)
    lags = np.abs(np.arange(nb)[:, None] * L + u[None, :])
    cf = (acov[np.minimum(lags, n - 1)] * tri[None, :]).sum(axis=1)
    return cf[np.abs(np.arange(nb)[:, None] - np.arange(nb)[None, :])]


def block_cov(n, dt, L, sigma_w, b, k):
    """Exact covariance of the block means (L samples each) of the generator's baseline."""
    nb = n // L
    # White.
    c = np.eye(nb) * sigma_w**2 / L
    # Flicker: circulant autocovariance of irfft(rfft(w) * gain) on 2n points.
    m2 = 2 * n
    f = np.fft.rfftfreq(m2, dt)
    g2 = np.zeros_like(f)
    g2[1:] = b**2 / (math.pi * f[1:]) / (2.0 * dt)
    c += stationary_block(np.fft.irfft(g2, m2)[:n], nb, L)
    # Random walk x_i = K sqrt(dt) sum_{j<=i} w_j: cov K^2 dt (min(i, j) + 1).
    p = np.arange(L)
    mmin = np.minimum.outer(p, p).sum() / float(L * L)
    a = np.minimum.outer(np.arange(nb), np.arange(nb)) * float(L)
    rw = a + 1.0 + (L - 1) / 2.0
    rw[np.diag_indices(nb)] = np.arange(nb) * float(L) + 1.0 + mmin
    c += k**2 * dt * rw
    return c


class Gls:
    """Whitened GLS with the constant projected out, for one baseline."""

    def __init__(self, n, dt, sigma_w, b, k, block_s=BLOCK_S):
        self.L = max(1, int(round(block_s / dt)))
        self.nb = n // self.L
        self.n = n
        self.scale = sigma_w**2 / self.L
        chol = np.linalg.cholesky(block_cov(n, dt, self.L, sigma_w, b, k) / self.scale)
        self.linv = np.linalg.inv(chol)
        self.uw = self.white(np.ones(self.nb), scaled=True)

    def means(self, x):
        return x[: self.nb * self.L].reshape(self.nb, self.L).mean(axis=1)

    def white(self, xbar, scaled=False):
        w = self.linv @ xbar
        return w if scaled else w / math.sqrt(self.scale)

    def filt(self, m):
        """Whitened, bias-projected matched filter of signal m; its norm is d (block part)."""
        mw = self.white(self.means(m))
        return mw - self.uw * (self.uw @ mw) / (self.uw @ self.uw)

    def z(self, y, filt):
        yw = self.white(self.means(y))
        return float(filt @ yw) / float(np.linalg.norm(filt))


def temp_rate(temp, dt, win_s=30.0):
    """dT/dt of a recorded temperature channel: the generator's 30-s moving mean, with the
    window shrunk to the samples available at the ends, then np.gradient."""
    k = max(1, int(round(win_s / dt)))
    ker = np.ones(k)
    sm = np.convolve(temp, ker, mode="same") / np.convolve(np.ones(len(temp)), ker, mode="same")
    return np.gradient(sm, dt)


def within_dev(m, L):
    """Deviations of m from its block means (the part block means do not see)."""
    nb = len(m) // L
    mm = m[: nb * L].reshape(nb, L)
    return (mm - mm.mean(axis=1, keepdims=True)).ravel()


def within_d2(m, L, sigma_w):
    return float((within_dev(m, L) ** 2).sum()) / sigma_w**2


# ---------------------------------------------------------------- spectra
def psd0(f, dt, sigma_w, b, k):
    """Two-sided PSD of the generator's baseline (dps^2/Hz)."""
    return (sigma_w**2 * dt + b**2 / (2.0 * math.pi * f)
            + k**2 * dt**2 / (4.0 * np.sin(math.pi * f * dt) ** 2))


def psd_gm(f, dt, sigma, tc):
    a = math.exp(-dt / tc)
    return sigma**2 * (1.0 - a * a) * dt / (1.0 - 2.0 * a * np.cos(2.0 * math.pi * f * dt) + a * a)


def diff_freqs(n, dt):
    nd = n - 1
    return np.arange(1, (nd - 1) // 2 + 1) / (nd * dt)


def binned(c, nbins=400):
    """Weights c >= 0 grouped into log bins: (weight, multiplicity); sum of c_k E_k with
    E_k ~ Exp(1) becomes sum of w_j Gamma(m_j) (weights within 0.5 % of their bin)."""
    c = c[c > 0]
    lc = np.log(c)
    lo, hi = lc.min(), lc.max() + 1e-12
    nb = max(1, min(nbins * 10, int(math.ceil((hi - lo) / 0.01))))
    edges = np.linspace(lo, hi, nb + 1)
    j = np.clip(np.searchsorted(edges, lc, side="right") - 1, 0, nb - 1)
    cnt = np.bincount(j, minlength=nb).astype(float)
    s = np.bincount(j, weights=c, minlength=nb)
    keep = cnt > 0
    return s[keep] / cnt[keep], cnt[keep]


def _sp_at(w, mult, t, x, mean, var):
    """Lugannani-Rice tail P(sum > x) given the saddlepoint t of x."""
    kt = float(-(mult * np.log1p(-w * t)).sum())
    k2 = float((mult * w * w / (1.0 - w * t) ** 2).sum())
    r = math.copysign(math.sqrt(max(2.0 * (t * x - kt), 0.0)), t)
    u = t * math.sqrt(k2)
    if abs(r) < 1e-4 or abs(u) < 1e-4:
        return 1.0 - phi((x - mean) / math.sqrt(var))
    dens = math.exp(-0.5 * r * r) / math.sqrt(2.0 * math.pi)
    return min(1.0, max(0.0, 1.0 - phi(r) + dens * (1.0 / u - 1.0 / r)))


def sp_tail(w, mult, x):
    """P(sum_j w_j G_j > x), G_j ~ Gamma(mult_j, 1), w_j > 0, by the Lugannani-Rice
    saddlepoint approximation; the saddlepoint by safeguarded Newton."""
    mean = float((w * mult).sum())
    var = float((w * w * mult).sum())
    hi = (1.0 - 1e-13) / w.max()
    lo = -1.0 / w.max()
    while float((mult * w / (1.0 - w * lo)).sum()) > x:
        lo *= 4.0
    t = 0.0
    for _ in range(200):
        k1 = float((mult * w / (1.0 - w * t)).sum())
        if k1 > x:
            hi = t
        else:
            lo = t
        k2 = float((mult * w * w / (1.0 - w * t) ** 2).sum())
        tn = t - (k1 - x) / k2
        if not (lo < tn < hi):
            tn = 0.5 * (lo + hi)
        if abs(tn - t) <= 1e-12 * max(abs(t), 1.0 / w.max()):
            t = tn
            break
        t = tn
    return _sp_at(w, mult, t, x, mean, var)


def sp_quantile(w, mult, alpha):
    """x with P(sum > x) = alpha (bisection on the saddlepoint t in (0, 1 / max w))."""
    mean = float((w * mult).sum())
    var = float((w * w * mult).sum())
    lo, hi = 0.0, 1.0 / w.max()
    for _ in range(80):
        t = 0.5 * (lo + hi)
        x = float((mult * w / (1.0 - w * t)).sum())
        if _sp_at(w, mult, t, x, mean, var) > alpha:
            lo = t
        else:
            hi = t
    t = 0.5 * (lo + hi)
    return float((mult * w / (1.0 - w * t)).sum())


def markov_power(n, dt, sigma_w, b, k, sigma, tc, alpha=ALPHA):
    f = diff_freqs(n, dt)
    s0 = psd0(f, dt, sigma_w, b, k)
    g = psd_gm(f, dt, sigma, tc) / s0  # S1 / S0 - 1
    v = g / (1.0 + g)  # 1 - S0 / S1
    w0, m0 = binned(v)
    thr = sp_quantile(w0, m0, alpha)
    w1, m1 = binned(v * (1.0 + g))
    pw = sp_tail(w1, m1, thr)
    dz = float((v * g).sum()) / math.sqrt(float((v * v).sum()))  # mean shift in H0 sd
    return pw, dz, thr, g


def whittle_power(g, alpha=ALPHA):
    """Power of the Whittle LRT for the ratio g = S_gm / S0 on the Fourier grid."""
    v = g / (1.0 + g)
    w0, m0 = binned(v)
    w1, m1 = binned(v * (1.0 + g))
    return sp_tail(w1, m1, sp_quantile(w0, m0, alpha))


class MarkovBlockLrt:
    """Exact Gaussian likelihood-ratio test on 1-s block means, baseline C0 vs C0 + C_gm
    (sigma, tau known), the unknown constant bias as a diffuse component kappa 1 1^T in both
    (kappa 1e6 times the block variance: the constant direction gets no weight).
    T = ybar^T (C0^-1 - C1^-1) ybar = sum_j mu_j / (1 + mu_j) z_j^2, 1 + mu_j the generalised
    eigenvalues of (C1, C0): under H0 a chi-square weighted by mu / (1 + mu), under H1 by
    mu; tails by the saddlepoint approximation."""

    def __init__(self, n, dt, sigma_w, b, k, sigma, tc, block_s=BLOCK_S):
        self.L = max(1, int(round(block_s / dt)))
        nb = n // self.L
        self.n, self.nb = n, nb
        c0 = block_cov(n, dt, self.L, sigma_w, b, k)
        self.sc = float(np.mean(np.diag(c0)))
        c0 = c0 / self.sc + 1e6
        self.cg = stationary_block(sigma**2 * np.exp(-np.arange(n) * dt / tc), nb, self.L) / self.sc
        self.l0i = np.linalg.inv(np.linalg.cholesky(c0))
        mmat = self.l0i @ self.cg @ self.l0i.T
        self.mu = np.maximum(np.linalg.eigvalsh(0.5 * (mmat + mmat.T)), 0.0)
        self.l1i = None

    def power(self, scale2=1.0, alpha=ALPHA):
        """(power, threshold) with the GM variance multiplied by scale2."""
        mu = self.mu * scale2
        c = mu / (1.0 + mu)
        keep = c > 1e-12 * max(c.max(), 1e-300)
        thr = sp_quantile(2.0 * c[keep], np.full(keep.sum(), 0.5), alpha)
        pw = sp_tail(2.0 * mu[keep], np.full(keep.sum(), 0.5), thr)
        return pw, thr

    def stat(self, y):
        if self.l1i is None:
            c1 = np.linalg.inv(self.l0i) @ np.linalg.inv(self.l0i).T + self.cg
            self.l1i = np.linalg.inv(np.linalg.cholesky(c1))
        ybar = y[: self.nb * self.L].reshape(self.nb, self.L).mean(axis=1) / math.sqrt(self.sc)
        w0 = self.l0i @ ybar
        w1 = self.l1i @ ybar
        return float(w0 @ w0 - w1 @ w1)


# ---------------------------------------------------------------- per-record oracle
def read_csv(path):
    with open(path) as fh:
        names = fh.readline().strip().split(",")
    arr = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return {nm: arr[:, i] for i, nm in enumerate(names)}


def chernoff_thr(p, alpha):
    """Smallest x with the Chernoff bound of P(sum Bernoulli(p) >= x) <= alpha."""
    mu = float(p.sum())
    if mu <= 0:
        return 1.0
    lo, hi = mu, float(len(p)) + 1.0
    if hi <= lo:
        return hi
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        u = mid / mu
        if -mu * (u * math.log(u) - u + 1.0) > math.log(alpha):
            lo = mid
        else:
            hi = mid
    return hi


def spike_miss_prob(n):
    """(threshold t, q = P(one spike of amplitude U(5, 30) sigma_w stays below t))."""
    a1 = 1.0 - (1.0 - ALPHA) ** (1.0 / n)  # per-sample two-sided level
    t = norm_ppf(1.0 - a1 / 2.0)
    amps = 5.0 + 25.0 * (np.arange(2000) + 0.5) / 2000.0  # midpoint rule over U(5, 30)
    return t, float(np.mean(phi_vec(t - amps) - phi_vec(-t - amps)))


def oracle_record(m, folder, csv_check):
    cls = m["effect"]
    seed = m["seed"]
    dur = m["duration_s"]
    dt, sigma_w, b, k = noise_params(m)
    cols, keep, _, truth, fs = gen.make_record(seed, cls, dur, m.get("mode", "fitted"))
    n = len(cols["t_s"])
    out = {"name": m["name"], "effect": cls, "s": m["strength"], "fs": fs}
    if m["strength"] is not None and abs(truth["strength"] - m["strength"]) > 1e-9 * m["strength"]:
        sys.exit(f"{m['name']}: regenerated strength {truth['strength']} != manifest")
    csv = None
    path = os.path.join(folder, m["name"] + ".csv")
    if os.path.exists(path) and (csv_check or cls in ("quantization", "dropouts")):
        csv = read_csv(path)
        dev = np.abs(csv["rate_dps"] - cols["rate_dps"][keep])
        tol = 6e-10 * np.abs(cols["rate_dps"][keep]) + 1e-300
        out["csv_match"] = bool((dev <= tol).all()) and len(csv["rate_dps"]) == int(keep.sum())
        if not out["csv_match"]:
            sys.exit(f"{m['name']}: regenerated record differs from the CSV")
    if cls in LINEAR:
        cols0, _, _, _, _ = gen.make_record(seed, cls, dur, m.get("mode", "fitted"), strength=0.0)
        sig = cols["rate_dps"] - cols0["rate_dps"]
        if cls == "sinusoid":
            f0 = m["params"]["sine_freq_hz"]
            mc = sig - sig.mean()
            d2 = float((mc**2).sum()) * dt / float(psd0(np.array([f0]), dt, sigma_w, b, k)[0])
            out.update(d=math.sqrt(d2), d_within_share=0.0, sig=sig,
                       p_unknown_f=sine_unknown_f_power(math.sqrt(d2), n), n=n)
        else:
            gls = Gls(n, dt, sigma_w, b, k)
            filt = gls.filt(sig)
            d2b = float(filt @ filt)
            d2w = within_d2(sig, gls.L, sigma_w)
            out.update(d=math.sqrt(d2b + d2w), d_block=math.sqrt(d2b),
                       d_within_share=d2w / max(d2b + d2w, 1e-300), sig=sig, gls=gls)
            if cls == "temperature":
                # The oracle's regressor: the true coefficients on the RECORDED channel (1/16
                # degC; dT/dt by the generator's 30-s smoother, shrunk at the ends instead of
                # the raw series there), not the true temperature, whose sample-scale wander
                # (raw at the generator's ends) the channel cannot show. Mismatched-filter SNR.
                tr = cols["temp_c"]
                x2 = temp_rate(tr, dt)
                reg = (m["params"]["bias_deg_h_per_c"] * (tr - tr.mean())
                       + m["params"]["bias_deg_h_per_c_per_s"] * (x2 - x2.mean())) / 3600.0
                fr = gls.filt(reg)
                rin, sin_ = within_dev(reg, gls.L), within_dev(sig, gls.L)
                nb2, nw2 = float(fr @ fr), float(rin @ rin) / sigma_w**2
                cb, cw = float(fr @ filt), float(rin @ sin_) / sigma_w**2
                d_blk = cb / math.sqrt(nb2)
                d_all = (cb + cw) / math.sqrt(nb2 + nw2)
                out.update(d_true_temp=out["d"], d_block=d_blk, filt_sig=reg,
                           d=max(d_blk, d_all), d_within_share=0.0 if d_blk >= d_all else 1.0)
        out["p"] = phi(out["d"] - Z_THR)
        out["d_per_s"] = out["d"] / m["strength"]
    elif cls == "markov":
        sig, tc = m["params"]["gm_sigma_deg_h"] / 3600.0, m["params"]["gm_tau_s"]
        pw, dz, _, g = markov_power(n, dt, sigma_w, b, k, sig, tc)
        lrt = MarkovBlockLrt(n, dt, sigma_w, b, k, sig, tc)
        pb = lrt.power()[0]
        out.update(p=max(pw, pb), p_whittle=pw, p_block=pb, d=dz, lrt=lrt, g=g)
    elif cls == "spikes":
        t, q = spike_miss_prob(n)
        kk = m["params"]["spikes"]
        out.update(p=1.0 - (1.0 - ALPHA) * q**kk, spikes=kk, q_miss=q, t=t)
    elif cls == "dropouts":
        tt = csv["t_s"] if csv is not None else cols["t_s"][keep]
        gaps = int((np.diff(tt) > 1.5 * dt).sum())
        out.update(p=1.0 if gaps > 0 else 0.0, dropped=m["params"]["dropped"], gaps=gaps, n=n)
    elif cls == "quantization":
        q = m["params"]["quantum_dps"]
        v = csv["rate_dps"] if csv is not None else np.array([float("%.10g" % x) for x in cols["rate_dps"]])
        tol = 5e-10 * np.abs(v) * 1.001 + 1e-18
        hits = int((np.abs(v - q * np.round(v / q)) <= tol).sum())
        thr = chernoff_thr(np.minimum(2.0 * tol / q, 1.0), ALPHA)
        # Power at the bottom of the range (s 0.01): the same values, q(0.01) = 0.01 sigma_w.
        thr_lo = chernoff_thr(np.minimum(2.0 * tol / (0.01 * sigma_w), 1.0), ALPHA)
        out.update(p=1.0 if hits >= thr else 0.0, hits=hits, n_kept=len(v), thr=thr,
                   p_at_s_lo=1.0 if len(v) >= thr_lo else 0.0)
    elif cls == "none":
        out.update(p=(1.0 - ALPHA) ** N_TESTS)
    else:
        sys.exit(f"{m['name']}: class {cls} not handled")
    out["_m"] = m
    return out


def class_power(cls, recs, s):
    """Mean oracle power of the class's records at strength s (all else as drawn)."""
    ps = []
    for r in recs:
        m = r["_m"]
        if cls in LINEAR:
            ps.append(phi(s * r["d_per_s"] - Z_THR))
        elif cls == "markov":
            pw = whittle_power(r["g"] * (s / m["strength"]) ** 2)
            ps.append(max(pw, r["lrt"].power((s / m["strength"]) ** 2)[0]))
        elif cls == "spikes":
            ps.append(1.0 - (1.0 - ALPHA) * math.exp(-s * (1.0 - r["q_miss"])))
        elif cls == "dropouts":
            ps.append(1.0 - math.exp(-s / 3.0))
        elif cls == "quantization":
            ps.append(r["p_at_s_lo"] if s >= gen.S_RANGE[cls][0] else float("nan"))
    return float(np.mean(ps))


def rice_tail(a, b):
    """P(|a + Z| > b), Z standard complex normal with E|Re Z|^2 = 1 (Marcum Q_1(a, b)),
    by integrating the Rice density on a grid."""
    r = np.linspace(b, max(b, a) + 12.0, 6001)
    x = a * r
    li0 = np.where(x < 600.0, np.log(np.i0(np.minimum(x, 600.0))),
                   x - 0.5 * np.log(2.0 * math.pi * np.maximum(x, 1.0)))
    pdf = np.exp(np.log(np.maximum(r, 1e-300)) - 0.5 * (r * r + a * a) + li0)
    return float(min(1.0, ((pdf[1:] + pdf[:-1]) * 0.5 * np.diff(r)).sum()))


def sine_unknown_f_power(d, n):
    """Power of the periodogram-maximum test (frequency and phase unknown, everything else
    known, line on a Fourier bin) for a line of known-phase SNR d: n/2 bins, each
    |X|^2 / S ~ Exp(1) under H0; threshold ln((n/2) / alpha); with the line 2 |X|^2 / S is a
    noncentral chi-square(2, d^2)."""
    x = math.log((n / 2.0) / ALPHA)
    return rice_tail(d, math.sqrt(2.0 * x))


def s90_sine_unknown_f(recs):
    def mean_pw(s):
        return float(np.mean([sine_unknown_f_power(s * r["d_per_s"], r["n"]) for r in recs]))
    lo, hi = 0.01, 1e4
    for _ in range(50):
        mid = math.sqrt(lo * hi)
        if mean_pw(mid) < 0.9:
            lo = mid
        else:
            hi = mid
    return math.sqrt(lo * hi)


def s90(cls, recs):
    lo_r, hi_r = gen.S_RANGE[cls]
    if cls == "quantization":
        return ("<= %.3g" % lo_r) if class_power(cls, recs, lo_r) >= 0.9 else "n/a"
    lo, hi = lo_r / 1000.0, hi_r * 1000.0
    if class_power(cls, recs, hi) < 0.9:
        return "> %.3g" % hi
    for _ in range(25 if cls == "markov" else 60):
        mid = math.sqrt(lo * hi)
        if class_power(cls, recs, mid) < 0.9:
            lo = mid
        else:
            hi = mid
    return "%.3g" % math.sqrt(lo * hi)


# ---------------------------------------------------------------- Monte-Carlo checks
def mc_check(r, folder, draws, seed):
    m = r["_m"]
    r = oracle_record(m, folder, False)
    cls = r["effect"]
    dt, sigma_w, b, k = noise_params(m)
    n = int(round(m["duration_s"] * m["fs_hz"]))
    rng = np.random.default_rng([seed, m["seed"]])  # independent draws per checked record
    z0, z1 = [], []
    if cls == "markov":
        sig = m["params"]["gm_sigma_deg_h"] / 3600.0
        tc = m["params"]["gm_tau_s"]
        lrt = r["lrt"]
        pw, thr = lrt.power()
        for i in range(draws):
            y = baseline_noise(rng, n, dt, sigma_w, b, k)
            z0.append(lrt.stat(y))
            z1.append(lrt.stat(y + gen.gauss_markov(rng, n, dt, sig, tc)))
        z0, z1 = np.array(z0), np.array(z1)
        c = lrt.mu / (1.0 + lrt.mu)
        return (f"{r['name']}: block LRT T without effect mean {z0.mean():.4g} sd "
                f"{z0.std(ddof=1):.4g} (predicted {c.sum():.4g}, {math.sqrt(2.0 * (c * c).sum()):.4g}); "
                f"with effect mean {z1.mean():.4g} (predicted {lrt.mu.sum():.4g}); false alarms "
                f"{int((z0 > thr).sum())}/{draws} (predicted {ALPHA * draws:.2f}); power "
                f"{(z1 > thr).mean():.3f} (predicted {pw:.3f}; Whittle full rate {r['p_whittle']:.3f})")
    if cls == "sinusoid":
        f0 = m["params"]["sine_freq_hz"]
        mc = r["sig"] - r["sig"].mean()
        s_line = float(psd0(np.array([f0]), dt, sigma_w, b, k)[0])
        norm = r["d"]
        for i in range(draws):
            y = baseline_noise(rng, n, dt, sigma_w, b, k)
            zz = float(mc @ y) * dt / s_line / norm
            z0.append(zz)
            z1.append(zz + norm)  # the statistic is linear: with the effect, z + d exactly
    else:
        gls = r["gls"]
        filt = gls.filt(r.get("filt_sig", r["sig"]))
        for i in range(draws):
            y = baseline_noise(rng, n, dt, sigma_w, b, k)
            z0.append(gls.z(y, filt))
            z1.append(gls.z(y + r["sig"], filt))
    z0, z1 = np.array(z0), np.array(z1)
    dref = r["d_block"] if "d_block" in r else r["d"]
    return (f"{r['name']}: z without effect mean {z0.mean():+.3f} sd {z0.std(ddof=1):.3f}; "
            f"with effect mean {z1.mean():.3f} sd {z1.std(ddof=1):.3f} (d {dref:.3f}); "
            f"fired {(z1 > Z_THR).mean():.3f} (predicted {phi(dref - Z_THR):.3f}), "
            f"false {int((z0 > Z_THR).sum())}/{draws}")


# Issue 26 counts a record as detectable when the oracle names it with this power or more.
DETECTABLE_P = 0.9


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dir", required=True)
    ap.add_argument("--diag", default=None, help="gap_indep_bench.py output folder (optional)")
    ap.add_argument("--json", default=None)
    ap.add_argument("--mc", type=int, default=0, help="Monte-Carlo draws per checked record")
    ap.add_argument("--mc-seed", type=int, default=1)
    ap.add_argument("--no-csv-check", action="store_true",
                    help="skip comparing the regenerated record with the CSV (still read for "
                         "quantization and dropouts)")
    a = ap.parse_args()
    man = [json.loads(l) for l in open(os.path.join(a.dir, "manifest.jsonl")) if l.strip()]
    diag = {}
    diag_ci = {}
    diag_shrink = {}
    diag_s90 = {}
    if a.diag:
        for m in man:
            js = os.path.join(a.diag, m["name"] + ".json")
            if os.path.exists(js):
                dj = json.load(open(js))
                diag[m["name"]] = dj["effect"]
                diag_ci[m["name"]] = dj.get("params_ci95") or {}
                sh = [c.get("shrink") for c in dj.get("candidates", []) if c["effect"] == m["effect"]]
                diag_shrink[m["name"]] = sh[0] if sh and sh[0] is not None else None
        sj = os.path.join(a.diag, "summary.json")
        if os.path.exists(sj):
            for c, v in json.load(open(sj)).get("power", {}).items():
                diag_s90[c] = v.get("s90")
    print(f"alpha per test {ALPHA:.5f} (0.05 / {N_TESTS}), one-sided z {Z_THR:.3f}; "
          f"block {BLOCK_S:g} s", file=sys.stderr)
    recs = []
    for m in man:
        r = oracle_record(m, a.dir, not a.no_csv_check)
        for key in ("sig", "gls", "filt_sig"):  # large; --mc rebuilds its records
            r.pop(key, None)
        if "lrt" in r:
            r["lrt"].l0i = r["lrt"].cg = None
        recs.append(r)
        extra = ""
        if "d" in r:
            extra += f" d {r['d']:.3f}"
        if "d_true_temp" in r:
            extra += (f" (recorded channel, block means{' + within' if r['d_within_share'] else ''};"
                      f" with the true temperature {r['d_true_temp']:.3f})")
        elif r.get("d_within_share"):
            extra += f" (within-block share of d^2 {r['d_within_share']:.3f})"
        if "p_block" in r:
            extra += f" (Whittle {r['p_whittle']:.3f}, 1-s block LRT {r['p_block']:.3f})"
        for key in ("spikes", "dropped", "hits"):
            if key in r:
                extra += f" {key} {r[key]}"
        dg = f" diag {diag[m['name']]}" if m["name"] in diag else ""
        s = "-" if r["s"] is None else f"{r['s']:.4g}"
        print(f"{m['name']:<22} s {s:>8} P {r['p']:.3f}{extra}{dg}", flush=True)
    classes = sorted({r["effect"] for r in recs})
    rows = []
    print("\n| class | n | diagnosis right | oracle expected right | oracle % | oracle s90 | diagnosis s90 | range |")
    print("|---|---|---|---|---|---|---|---|")
    tot_o, tot_n, tot_d = 0.0, 0, 0
    eff_o, eff_n = 0.0, 0
    for c in classes:
        rr = [r for r in recs if r["effect"] == c]
        po = sum(r["p"] for r in rr)
        dr = sum(diag.get(r["name"]) == c for r in rr) if diag else None
        so = s90(c, rr) if c != "none" else "-"
        ds = diag_s90.get(c, "-") if c != "none" else "-"
        ds = "not reached" if ds is None else (f"{ds:.3g}" if isinstance(ds, float) else ds)
        rng_s = "-" if c == "none" else "%g-%g" % gen.S_RANGE[c]
        drs = "-" if dr is None else f"{dr}/{len(rr)}"
        print(f"| {c} | {len(rr)} | {drs} | {po:.2f}/{len(rr)} | {100 * po / len(rr):.1f} % | {so} | {ds} | {rng_s} |")
        rows.append({"class": c, "n": len(rr), "diag_right": dr, "oracle_right": po,
                     "oracle_s90": so, "diag_s90": ds})
        tot_o += po
        tot_n += len(rr)
        if c != "none":
            eff_o += po
            eff_n += len(rr)
            tot_d += dr or 0
    eff_n_div = max(eff_n, 1)
    print(f"\noracle expected right over the effect records: {eff_o:.2f} of {eff_n} "
          f"({100 * eff_o / eff_n_div:.1f} %); over all records {tot_o:.2f} of {tot_n} "
          f"({100 * tot_o / tot_n:.1f} %)" + (f"; diagnosis {tot_d} of {eff_n} effect records "
                                               f"({100 * tot_d / eff_n_div:.1f} %)" if diag else ""))
    if diag:
        weak = [r for r in recs if r["effect"] != "none" and r["p"] < 0.05 and r["name"] in diag]
        print(f"effect records the oracle detects with P < 0.05: {len(weak)}; the diagnosis named "
              f"an effect on {sum(diag[r['name']] != 'none' for r in weak)} of them (the right one on "
              f"{sum(diag[r['name']] == r['effect'] for r in weak)}): "
              + ", ".join(f"{r['name']} -> {diag[r['name']]}" for r in weak if diag[r['name']] != "none"))
    if diag:
        det = [r for r in recs if r["effect"] != "none" and r["p"] >= DETECTABLE_P and r["name"] in diag]
        ok = [r for r in det if diag[r["name"]] == r["effect"]]
        print(f"oracle-detectable effect records (oracle power >= {DETECTABLE_P:g}, from the truth "
              f"alone): {len(det)}; the diagnosis named the right effect on {len(ok)} "
              f"({100 * len(ok) / max(1, len(det)):.1f} %); misses: "
              + (", ".join(f"{r['name']} -> {diag[r['name']]}" for r in det if r not in ok) or "none"))
        # The same count where a sinusoid's frequency is not given to the oracle (no test that
        # searches for the line can beat the periodogram maximum): context, not the headline.
        det_f = [r for r in det if r["effect"] != "sinusoid" or r["p_unknown_f"] >= DETECTABLE_P]
        ok_f = [r for r in det_f if r in ok]
        print(f"  of them detectable with the sinusoid's frequency unknown (power >= {DETECTABLE_P:g}): "
              f"{len(det_f)}; right {len(ok_f)} ({100 * len(ok_f) / max(1, len(det_f)):.1f} %)")
        shr = sorted(diag_shrink[r["name"]] for r in det if diag_shrink.get(r["name"]) is not None)
        if shr:
            print(f"median held-out shrink of the true effect's candidate over the oracle-detectable "
                  f"records: {shr[len(shr) // 2] if len(shr) % 2 else 0.5 * (shr[len(shr) // 2 - 1] + shr[len(shr) // 2]):.3f} "
                  f"({len(shr)} records)")
        # 95 % intervals of the named effect's parameters against the generator's truth.
        truth_key = {"rate_ramp_dps_per_s": ("ramp_deg_h_per_h", 3600.0 * 3600.0),
                     "bias_dps_per_c": ("bias_deg_h_per_c", 3600.0),
                     "bias_dps_per_c_per_s": ("bias_deg_h_per_c_per_s", 3600.0),
                     "warmup_dps": ("warmup_deg_h", 3600.0),
                     "warmup_tau_s": ("warmup_tau_s", 1.0),
                     "gm_sigma_dps": ("gm_sigma_deg_h", 3600.0),
                     "gm_tau_s": ("gm_tau_s", 1.0),
                     "sine_amplitude_dps": ("sine_amplitude_dps", 1.0),
                     "sine_freq_hz": ("sine_freq_hz", 1.0)}
        man_by = {m["name"]: m for m in man}
        cov, tot, miss_cov = 0, 0, []
        for r in ok:
            ci = diag_ci.get(r["name"], {})
            if not ci:
                continue
            inside = True
            for k, (lo, hi) in ci.items():
                if k not in truth_key:
                    continue
                tk, sc = truth_key[k]
                tv = man_by[r["name"]]["params"].get(tk)
                # An unbounded side is written as null in the JSON.
                lo = -math.inf if lo is None else lo
                hi = math.inf if hi is None else hi
                if tv is not None and not (lo * sc <= tv <= hi * sc):
                    inside = False
            tot += 1
            cov += inside
            if not inside:
                miss_cov.append(r["name"])
        print(f"rightly named detectable records with 95 % intervals: {tot}; every true parameter "
              f"inside on {cov}" + (f" (outside: {', '.join(miss_cov)})" if miss_cov else ""))
        nn = [r for r in recs if r["effect"] == "none" and r["name"] in diag]
        if nn:
            fl = [r for r in nn if diag[r["name"]] != "none"]
            print(f"none records flagged: {len(fl)} of {len(nn)}"
                  + (": " + ", ".join(f"{r['name']} -> {diag[r['name']]}" for r in fl) if fl else ""))
    if "sinusoid" in classes:
        rr = [r for r in recs if r["effect"] == "sinusoid"]
        print(f"sinusoid with frequency and phase unknown (periodogram maximum over n/2 bins, "
              f"line on a bin, all else known): expected right {sum(r['p_unknown_f'] for r in rr):.2f}"
              f" of {len(rr)}, s90 {s90_sine_unknown_f(rr):.3g}")
    if a.mc:
        print(f"\nMonte-Carlo checks ({a.mc} draws each, seed {a.mc_seed}):")
        for c in [c for c in LINEAR + ["markov"] if c in classes]:
            # The record whose oracle power is nearest 50 % (the most informative check).
            r = min((r for r in recs if r["effect"] == c), key=lambda r: abs(r["p"] - 0.5))
            print("  " + mc_check(r, a.dir, a.mc, a.mc_seed), flush=True)
    if a.json:
        keep = [{k: v for k, v in r.items() if k not in ("sig", "gls", "lrt", "g", "filt_sig", "_m")} for r in recs]
        json.dump({"alpha": ALPHA, "z_thr": Z_THR, "records": keep, "classes": rows,
                   "oracle_right_effect": eff_o / eff_n}, open(a.json, "w"), indent=1)


if __name__ == "__main__":
    main()

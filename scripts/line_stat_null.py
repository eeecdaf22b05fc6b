#!/usr/bin/env python3
"""Null distribution of `host-sim gap`'s line (sinusoid) statistic, and the Gumbel scale its
test uses (`LINE_GUMBEL_SCALE` in host-sim/src/gap/evidence.rs).

Requires: python3, numpy.

The statistic (host-sim/src/gap/evidence.rs `line_stat`): the record on its time line,
mean removed, zero-padded to twice the next power of two, periodogram; each bin over the
median of its 256-bin chunk; s = ln of the largest ratio. For Gaussian noise whose
spectrum is flat over a chunk the ratios do not depend on the noise level or colour, so
white noise gives the null for any record of the same length.

The largest of M exponential bins is ln M + G (G a standard Gumbel variable), so s is close
to a Gumbel law in ln units with scale c / x, x = exp(mean s) * ln 2 the typical largest
bin over the chunk mean; c would be 1 with an exact median, more because the median of 256
bins is itself noisy. This script measures c (from the standard deviation: scale = sd *
sqrt(6) / pi) for several record lengths, then checks the test as host-sim runs it: the
Gumbel mean from the mean of 12 null draws (the diagnosis's 12 baseline simulations), p from
the Gumbel tail with c = LINE_GUMBEL_SCALE, and the share of null records whose z (normal
score of p) exceeds 2.5, the test's threshold (one-sided normal: 0.62 %).

Usage: python3 scripts/line_stat_null.py [--draws 300] [--seed 1]
"""
import argparse
import math
from statistics import NormalDist

import numpy as np

LINE_GUMBEL_SCALE = 1.2
CHUNK = 256
EULER_GAMMA = 0.5772156649015329


def line_stat(y):
    n = len(y)
    nfft = (1 << int(math.ceil(math.log2(n)))) * 2
    buf = np.zeros(nfft)
    buf[:n] = y - y.mean()
    p = np.abs(np.fft.rfft(buf)[: nfft // 2]) ** 2
    # host-sim takes the largest ratio above 4 cycles per block (about 70 bins of 45,000
    # samples); bin 0 alone is left out here, and the chunks start one bin later.
    p = p[1 : (len(p) // CHUNK) * CHUNK]
    full = (len(p) // CHUNK) * CHUNK
    ch = p[:full].reshape(-1, CHUNK)
    med = np.median(ch, axis=1, keepdims=True)
    return float(np.log((ch / med).max()))


def gumbel_z(s, null_mean, c):
    x = math.exp(null_mean) * math.log(2.0)
    beta = c / x
    mu = null_mean - EULER_GAMMA * beta
    p = -math.expm1(-math.exp(-(s - mu) / beta))
    p = min(max(p, 1e-300), 1.0 - 1e-16)
    return -NormalDist().inv_cdf(p)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--draws", type=int, default=300)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    print(f"{'samples':>8} {'mean s':>7} {'sd s':>6} {'c':>5} {'q99':>6} {'q995':>6}  z>2.5 (12-null location, c={LINE_GUMBEL_SCALE})")
    for n in (45_000, 90_000, 180_000, 360_000):
        s = np.array([line_stat(rng.standard_normal(n)) for _ in range(a.draws)])
        x = math.exp(s.mean()) * math.log(2.0)
        c = s.std(ddof=1) * math.sqrt(6.0) / math.pi * x
        hits = 0
        for i in range(a.draws):
            others = np.delete(s, i)
            loc = rng.choice(others, 12, replace=False).mean()
            hits += gumbel_z(s[i], loc, LINE_GUMBEL_SCALE) > 2.5
        q99, q995 = np.quantile(s, [0.99, 0.995])
        print(f"{n:>8} {s.mean():7.3f} {s.std(ddof=1):6.3f} {c:5.2f} {q99:6.3f} {q995:6.3f}  {hits}/{a.draws} = {100.0 * hits / a.draws:.2f} %")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Time PyWavelets' wavedec + soft universal threshold + waverec (db4, periodization,
3 levels) on the same 2^20-sample signal as fog-core's criterion benchmark.

Prints one line: `pywt_samples_per_s <value>` (best of 20 runs, like criterion's fastest
sample, and the median). The same threshold rule as fog-core: sigma = median(|cD1|)/0.6745
(numerical zeros ignored), mu = sigma*sqrt(2 ln N), applied to every detail level.
Data: float32 input (pywt computes in float32 for float32 input), as fog-core does.
"""
import math
import statistics
import time

import numpy as np
import pywt

N = 1 << 20


def signal(n):
    state = 1
    out = np.empty(n, dtype=np.float32)
    a, c = 1664525, 1013904223
    for i in range(n):
        state = (state * a + c) & 0xFFFFFFFF
        u = np.float32((state >> 8) / float(1 << 24)) - np.float32(0.5)
        out[i] = np.float32(0.05) * np.float32(math.sin(np.float32(i) * np.float32(1e-3))) + np.float32(0.02) * u
    return out


def denoise(x):
    coeffs = pywt.wavedec(x, "db4", mode="periodization", level=3)
    d1 = np.abs(coeffs[-1])
    d1 = d1[d1 > 1e-5 * np.abs(x).max() * math.sqrt(2)]
    sigma = np.median(d1) / 0.6745 if d1.size else 0.0
    mu = sigma * math.sqrt(2 * math.log(len(x)))
    coeffs[1:] = [pywt.threshold(c, mu, "soft") for c in coeffs[1:]]
    return pywt.waverec(coeffs, "db4", mode="periodization")


def main():
    x = signal(N)
    denoise(x)  # warm-up
    times = []
    for _ in range(20):
        t0 = time.perf_counter()
        denoise(x)
        times.append(time.perf_counter() - t0)
    print(f"pywt {pywt.__version__} numpy {np.__version__}: best {min(times)*1e3:.2f} ms, median {statistics.median(times)*1e3:.2f} ms per 2^20 samples")
    print(f"pywt_samples_per_s {N / min(times):.0f}")
    print(f"pywt_samples_per_s_median {N / statistics.median(times):.0f}")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Generate the PyWavelets reference vectors that fog-core's tests check against.

Writes fog-core/tests/data/db4_pywt.json. Tests need no Python: the numbers are committed.
Re-run after changing the definitions below (and say why in the commit):

    pip install numpy PyWavelets
    python3 scripts/gen_db4_vectors.py

Definitions mirrored from fog-core (keep in sync):
- coefficients: pywt.wavedec(x, 'db4', mode='periodization', level=L), concatenated
  [cA_L, cD_L, ..., cD_1];
- sigma ('finest'): median(|cD_1| above tol_1) / 0.6745, tol_j = 1e-5 * max|x| * sqrt(2)^j;
  0 when nothing is above tol. 'per_level': the same on each level's details with tol_j;
- threshold mu = sigma * sqrt(2 ln U), U = len(x); approximation coefficients untouched;
- soft / hard shrinkage as pywt.threshold(d, mu, 'soft' | 'hard').
Signals are rounded to f32 first, so the Rust input is exactly the Python input.
"""
import json
import math
import os
import sys

import numpy as np
import pywt

ZERO_REL = 1e-5
OUT = os.path.join(os.path.dirname(__file__), "..", "fog-core", "tests", "data", "db4_pywt.json")


def signals(n, rng):
    t = np.arange(n) / 100.0  # 100 Hz, seconds
    out = {
        "constant": np.full(n, 0.25),
        "step": np.where(np.arange(n) < n * 3 // 7, -0.5, 1.25) + 0.01 * rng.standard_normal(n),
        "ramp": 0.002 * np.arange(n) - 0.3,
        "noise": rng.standard_normal(n),
        # E-Core-like: bias + slow drift + white noise, quantized to 60/32768 deg/s.
        "gyro": np.round((0.05 + 0.003 * np.sin(2 * np.pi * t / 60.0) + 0.015 * rng.standard_normal(n)) / (60 / 32768)) * (60 / 32768),
        "sine_noise": np.sin(2 * np.pi * np.arange(n) / 37.0) + 0.2 * rng.standard_normal(n),
    }
    return {k: v.astype(np.float32).astype(np.float64) for k, v in out.items()}


def mad_sigma(d, tol):
    a = np.abs(d)
    a = a[a > tol]
    return 0.0 if a.size == 0 else float(np.median(a) / 0.6745)


def denoise(x, level, rule, per_level):
    n = len(x)
    coeffs = pywt.wavedec(x, "db4", mode="periodization", level=level)
    peak = float(np.max(np.abs(x)))
    finest = mad_sigma(coeffs[-1], ZERO_REL * peak * math.sqrt(2))
    out = [coeffs[0]]
    sigmas = []
    for j in range(level, 0, -1):  # coeffs[1] is cD_level ... coeffs[-1] is cD_1
        d = coeffs[level - j + 1]
        s = mad_sigma(d, ZERO_REL * peak * math.sqrt(2) ** j) if (per_level and j > 1) else finest
        sigmas.append((j, s))
        out.append(pywt.threshold(d, s * math.sqrt(2 * math.log(n)), rule))
    y = pywt.waverec(out, "db4", mode="periodization")
    return y, sorted(sigmas)


def f(v):
    return [float(f"{x:.10g}") for x in v]


def main():
    rng = np.random.default_rng(20071105)
    plan = {64: [1, 2, 3], 256: [1, 2, 3, 4, 5], 1024: [1, 3, 5], 4096: [3, 5]}
    cases = []
    for n, levels in plan.items():
        for name, x in signals(n, rng).items():
            if n == 4096 and name not in ("noise", "gyro"):
                continue
            case = {"name": f"{name}_{n}", "signal": f(x), "levels": []}
            for level in levels:
                entry = {"level": level, "coeffs": f(np.concatenate(pywt.wavedec(x, "db4", mode="periodization", level=level)))}
                if level == 3 or n <= 256:
                    soft, sig = denoise(x, level, "soft", False)
                    hard, _ = denoise(x, level, "hard", False)
                    per, sig_pl = denoise(x, level, "soft", True)
                    entry.update({
                        "sigma_finest": sig[0][1],
                        "soft": f(soft), "hard": f(hard),
                        "per_level_soft": f(per), "per_level_sigma": [s for _, s in sig_pl],
                    })
                case["levels"].append(entry)
            cases.append(case)
    doc = {
        "generator": "scripts/gen_db4_vectors.py",
        "pywt": pywt.__version__, "numpy": np.__version__, "seed": 20071105,
        "zero_rel": ZERO_REL, "cases": cases,
    }
    with open(OUT, "w") as fh:
        json.dump(doc, fh, separators=(",", ":"))
    print(f"wrote {len(cases)} cases to {os.path.normpath(OUT)} ({os.path.getsize(OUT)} bytes)", file=sys.stderr)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Reference vectors for host-sim's overlapping Allan deviation.

Writes host-sim/tests/data/allan_vectors.json: a few rate series (white, random walk,
flicker) at 100 Hz and `allantools.oadev(data, rate=100, data_type="freq", taus=...)` for
each. host-sim/tests/allan_vectors.rs asserts agreement within 1e-9 relative.

    pip install allantools numpy
    python3 scripts/gen_allan_vectors.py

Deterministic: numpy seeds are fixed. The committed JSON was made with allantools 2024.6.
"""
import json
import os

import allantools
import numpy as np

RATE_HZ = 100.0
N = 4000


def series():
    rng = np.random.default_rng(20240601)
    white = 1e-3 * rng.standard_normal(N)
    walk = 1e-4 * np.cumsum(rng.standard_normal(N)) + 0.5
    np.random.seed(7)  # allantools.noise uses numpy's global generator
    flicker = 2e-3 * np.asarray(allantools.noise.pink(N)) - 0.01
    return {"white": white, "random_walk": walk, "flicker": flicker}


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    out = os.path.join(here, "..", "host-sim", "tests", "data", "allan_vectors.json")
    ms = sorted(set([2**k for k in range(12)] + [3, 5, 7, 10, 33, 100, 333, 1000, 1999, 2000]))
    ms = [m for m in ms if 2 * m <= N]
    taus = np.array(ms, dtype=float) / RATE_HZ
    cases = []
    for name, data in series().items():
        data = np.asarray(data, dtype=float)
        t, dev, _err, ns = allantools.oadev(data, rate=RATE_HZ, data_type="freq", taus=taus)
        m_used = [int(round(x * RATE_HZ)) for x in t]
        cases.append({
            "name": name,
            "rate_hz": RATE_HZ,
            "data": [float(x) for x in data],
            "m": m_used,
            "tau_s": [float(x) for x in t],
            "oadev": [float(x) for x in dev],
            "n": [int(x) for x in ns],
        })
    doc = {
        "generator": "scripts/gen_allan_vectors.py",
        "allantools_version": allantools.__version__,
        "numpy_version": np.__version__,
        "call": "allantools.oadev(data, rate=rate_hz, data_type='freq', taus=m/rate_hz)",
        "cases": cases,
    }
    with open(out, "w") as f:
        json.dump(doc, f, indent=None, separators=(",", ":"))
        f.write("\n")
    print(f"wrote {out}: {len(cases)} cases, {len(ms)} taus each")


if __name__ == "__main__":
    main()

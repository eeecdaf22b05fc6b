#!/usr/bin/env python3
"""How low can a random-walk Kalman filter bring static e_truth on a unit family?

Requires: python3 and numpy. Reads DIR/static-test/*.csv of a family made by
scripts/gen_unit_family.py (columns t_s, rate_dps, drift_dps).

For every static test record and every level density q of a grid (2^i (deg/h)^2/h, i = 0..14,
1 to 16,384) runs the scalar random-walk Kalman filter on every sample (r = var(diff)/2 of
the record, level 0 with the variance of a 30-deg/h bound at power-on, as `unit_family`'s
"RW-KF all still") and prints e_truth = RMS(estimate - drift) / RMS(drift) per record and
q, then the pooled e_truth (sqrt(sum (e D)^2 / sum D^2), D the record's drift RMS) at the
best common q and with each record's own best q (an oracle no causal filter has: it knows
the truth). The second is a floor for the whole class of random-walk filters, whatever rule
picks their q (the product's static e_truth is `fog-lab drift_filter_eval`'s, docs/drift-filter.md).

    python3 scripts/rw_kf_q_bound.py --family DIR
"""
import argparse
import glob
import os

import numpy as np

DPH = 1.0 / 3600.0
GRID_DPH2_PER_H = np.array([2.0 ** i for i in range(15)])


def e_truth_per_q(path):
    d = np.genfromtxt(path, delimiter=",", names=True)
    y, drift = d["rate_dps"], d["drift_dps"]
    dt = d["t_s"][1] - d["t_s"][0]
    r = np.var(np.diff(y)) / 2.0
    q = GRID_DPH2_PER_H * DPH ** 3 * dt  # (deg/s)^2 per sample
    x = np.zeros_like(q)
    p = np.full_like(q, (30.0 * DPH) ** 2)
    sq = np.zeros_like(q)
    for yk, dk in zip(y, drift):
        p = p + q
        k = p / (p + r)
        x = x + k * (yk - x)
        p = (1.0 - k) * p
        sq += (x - dk) ** 2
    rms_drift = np.sqrt(np.mean(drift ** 2))
    return rms_drift, np.sqrt(sq / len(y)) / rms_drift


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--family", required=True, help="a family folder of gen_unit_family.py")
    a = ap.parse_args()
    files = sorted(glob.glob(os.path.join(a.family, "static-test", "*.csv")))
    if not files:
        raise SystemExit(f"{a.family}/static-test: no .csv records")
    rows = [(os.path.basename(f),) + e_truth_per_q(f) for f in files]
    d = np.array([r[1] for r in rows])
    e = np.array([r[2] for r in rows])

    def pooled(v):
        return float(np.sqrt(np.sum((v * d) ** 2) / np.sum(d ** 2)))

    print("q (deg/h)^2/h: " + " ".join(f"{q:g}" for q in GRID_DPH2_PER_H))
    for name, dr, ev in rows:
        print(f"{name:<16} drift {dr / DPH:6.2f} deg/h  e_truth " + " ".join(f"{v:.3f}" for v in ev)
              + f"  best q {GRID_DPH2_PER_H[int(np.argmin(ev))]:g}")
    per_q = [pooled(e[:, j]) for j in range(len(GRID_DPH2_PER_H))]
    j = int(np.argmin(per_q))
    print(f"pooled e_truth: best common q {GRID_DPH2_PER_H[j]:g} -> {per_q[j]:.4f}; "
          f"each record's own best q (oracle) -> {pooled(e.min(axis=1)):.4f}")


if __name__ == "__main__":
    main()

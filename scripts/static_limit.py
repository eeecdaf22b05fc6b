#!/usr/bin/env python3
"""The causal limit of e_truth on a unit family's static records (issue 42's static goal).

On each static-test record of a family made by scripts/gen_unit_family.py, an f64 Kalman
filter run per sample that knows everything the generator knows except the random paths:

  - the deterministic drift exactly (both warm-ups, k1 (T - Tref) + k2 (T - Tref)^2 and the
    Shupe term, with the temperature recomputed by the generator's own `thermal`), taken out
    of the rate before filtering;
  - the turn-on as a level with the unit's own centre and power-on spread as its prior, the
    rate random walk (the unit's own) as that level's process noise;
  - the flicker (two-sided PSD B^2 / (2 pi f) from f = fs / m, the generator's FFT length m,
    to Nyquist) as a bank of first-order Gauss-Markov terms, two per decade, each of variance
    B^2 ln(ratio) / pi (the bank's PSD within a few % of B^2 / (2 pi f) inside the band; the
    largest error printed);
  - the white noise (the unit's sigma) and the quantum (q^2 / 12) as the observation noise.

Its estimate of the drift at each sample uses that sample and the ones before it (filtered),
so its e_truth = RMS(estimate - drift) / RMS(drift) (`fog_lab::static_rw::e_truth`) is close
to the least any causal estimator reaches on these records: the minimum mean square error of
a linear estimator, were the flicker the bank. ASSUMED: (1) the bank stands for the flicker
(its PSD is off by up to 8.5 % inside [4 f_lo, fs / 8] and by up to 32 % at the band's edges,
its variance 9 % high); a filter's error is flat near its true model, and measured so: a
bank fitted by least squares with corners a decade past each edge, and its variances x0.8
and x1.25, moved the mean e_truth by at most 0.2 % (f20: 0.10926 as here, 0.10923, 0.10948,
0.10940; f100's first two records: 0.19988, 0.19986, 0.20013, 0.20020); (2) the quantum as
white noise: the best linear estimator, where a non-linear one could use the lattice
(the static-test units here have white noise of 1.4 quanta or more).

    python3 scripts/static_limit.py --family F/f100 [F/f20 ...] [--json OUT.json]

Prints per record and per family the limit's e_truth; compare with `drift_filter_eval`'s
`static e_truth` rows (the filter, its window-rate limit and the random-walk filter with q
from the calibration runs).
"""

import argparse
import glob
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gen_nav_records as g  # noqa: E402

DPH = g.DPH


def deterministic_dps(t, meta):
    """The generator's deterministic drift (no turn-on), deg/s, as gen_unit_family.record."""
    u, c, fam = meta["sensor"], meta["conditions"], meta["family"]
    duration_s = meta["duration_s"]
    tc = np.arange(0.0, duration_s + 2.0, 1.0)
    temp_c = g.thermal(tc, c["ambient_start_c"], c["self_heating_c"],
                       c["ambient_ramp_c_per_h"] / 3600.0, c["thermal_tau_s"])
    temp, dtemp = np.interp(t, tc, temp_c), np.interp(t, tc, np.gradient(temp_c, tc))
    dt_ref = temp - fam["t_ref_c"]
    return DPH * (u["warmup1_dph"] * np.exp(-t / u["warmup1_tau_s"])
                  + u["warmup2_dph"] * np.exp(-t / u["warmup2_tau_s"])
                  + u["k1_dph_per_c"] * dt_ref + u["k2_dph_per_c2"] * dt_ref ** 2
                  + u["shupe_dph_per_c_per_min"] * 60.0 * dtemp)


def flicker_bank(b_dps, fs, n, per_decade=2):
    """Gauss-Markov terms (tau_s, variance) whose summed PSD follows B^2 / (2 pi f) between
    the generator's lowest frequency fs / m and Nyquist; and the bank's largest relative
    PSD error inside [4 f_lo, fs / 8]."""
    m = 1 << int(math.ceil(math.log2(2 * n)))
    f_lo, f_hi = fs / m, fs / 2.0
    k = int(math.ceil(per_decade * math.log10(f_hi / f_lo))) + 1
    corners = np.logspace(math.log10(f_lo), math.log10(f_hi), k)
    ratio = corners[1] / corners[0]
    var = b_dps ** 2 * math.log(ratio) / math.pi
    taus = 1.0 / (2.0 * math.pi * corners)
    f = np.logspace(math.log10(4 * f_lo), math.log10(fs / 8.0), 200)
    bank = sum(2.0 * var * T / (1.0 + (2.0 * math.pi * f * T) ** 2) for T in taus)
    err = np.max(np.abs(bank / (b_dps ** 2 / (2.0 * math.pi * f)) - 1.0))
    return [(T, var) for T in taus], err


def limit_estimate(y, fs, level_mean, level_var, q_level, bank, r):
    """Per-sample filtered drift estimate of level + bank from y = drift + white."""
    dt = 1.0 / fs
    phi = np.array([1.0] + [math.exp(-dt / T) for T, _ in bank])
    qd = np.array([q_level] + [v * (1.0 - math.exp(-2.0 * dt / T)) for T, v in bank])
    x = np.zeros(len(phi))
    x[0] = level_mean
    p = np.diag([level_var] + [v for _, v in bank])
    phi2 = np.outer(phi, phi)
    est = np.empty(len(y))
    for i, yi in enumerate(y):
        if i > 0:
            x *= phi
            p *= phi2
            p[np.diag_indices_from(p)] += qd
        ph = p.sum(axis=1)
        s = ph.sum() + r
        kg = ph / s
        x += kg * (yi - x.sum())
        p -= np.outer(kg, ph)
        est[i] = x.sum()
    return est


def e_truth(est, drift):
    return math.sqrt(np.mean((est - drift) ** 2)) / math.sqrt(np.mean(drift ** 2))


def run_record(path):
    meta = json.load(open(path + ".json"))
    data = np.loadtxt(path, delimiter=",", skiprows=1, usecols=(0, 1, 3))
    t, rate, drift = data[:, 0], data[:, 1], data[:, 2]
    u, fam = meta["sensor"], meta["family"]
    fs = fam["rate_hz"]
    det = deterministic_dps(t, meta)
    bank, err = flicker_bank(u["bias_instability_dph"] * DPH, fs, len(t))
    q_level = (u["rrw_dph_rth"] * DPH / 60.0) ** 2 / fs
    r = u["sigma_dps"] ** 2 + fam["quantum_dps"] ** 2 / 12.0
    est = det + limit_estimate(rate - det, fs, u["turn_on_centre_dph"] * DPH,
                               (u["turn_on_sigma_dph"] * DPH) ** 2, q_level, bank, r)
    # The deterministic part recomputed: how far it is from the truth's (the random paths'
    # sum, whose mean should be the turn-on; printed as a check).
    rest = drift - det
    return e_truth(est, drift), err, float(np.mean(rest)) / DPH, meta["conditions"]["turn_on_dph"]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--family", nargs="+", required=True)
    ap.add_argument("--json")
    o = ap.parse_args()
    out = {}
    for fam in o.family:
        recs = sorted(glob.glob(os.path.join(fam, "static-test", "static-[0-9][0-9].csv")))
        if not recs:
            sys.exit(f"{fam}: no static-test/static-NN.csv")
        rows = []
        for p in recs:
            e, err, rest_dph, turn_on = run_record(p)
            rows.append(e)
            print(f"{p}: limit e_truth {e:.4f} (flicker bank PSD error <= {100 * err:.1f} %; "
                  f"drift less the deterministic part: mean {rest_dph:+.2f} dph, turn-on {turn_on:+.2f})",
                  flush=True)
        out[fam] = {"records": [os.path.basename(p) for p in recs], "e_truth": rows,
                    "mean": float(np.mean(rows))}
        print(f"== {fam}: causal limit e_truth mean {np.mean(rows):.4f} ({len(rows)} records)", flush=True)
    if o.json:
        with open(o.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()

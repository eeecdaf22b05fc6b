#!/usr/bin/env python3
"""Twins of the real-noise benchmark: what `host-sim gap` does on each real record against
what it does on Gaussian records of the model it named for that record.

Requires: python3 and numpy; scripts/gap_real_bench.py (its records, injections and scores)
and scripts/gap_indep_gen.py (its noise generators: independent of the simulator in
host-sim) are imported; a finished `gap_real_bench.py --out REAL` run (its clean records'
JSON name each record's model, its summary.json scores the real records).

Question: where `gap` misses an effect injected into a real record, is the cause the real
noise (what the vocabulary cannot state: the sensor's colour above its white band, a
non-Gaussian value distribution, the record's own transients) or the record itself (its
length, its own wander at the size the benchmark injects)? A twin answers it: a record with
the same sample times, the same mean, the same output quantum (the record's own), and the noise of the model
`gap` named on the clean real record, as a Gaussian process, with the benchmark's injection
(the same sizes in units of the twin's own 100-s Allan deviation, the same dithered
re-rounding). Where the twin is right and the real record wrong, the real noise costs the
decision (the sim-to-real gap); where both miss, the record's length and noise level hide
the effect even under the model `gap` assumes.

The twin's model, from REAL/<record>-none.json: the round-1 baseline (white N, flicker B,
random walk K, a Gauss-Markov term if any), then each named round as `gap` applies it
(`white_noise`, `bias_instability`, `rate_random_walk`: added in quadrature; `markov`: its
refitted N, B, K when it states all three, and the round's sigma and T; `quantization`:
the twin is rounded to the record's own quantum; a name in the last round `--rounds`
allows is not applied, as `gap` does not apply it).
ASSUMED and stated: the round-1 baseline stands for the baseline `gap` fits again after a
quantum (not in the JSON; the refitted N a later `markov` states equals round 1's on the
records looked at); `markov`'s parameters are its round's (`gap` applies its candidate's,
the same on ADIS16405 run 4 y, the one clean record that names it). The twin leaves out
the baseline's colour (the white term's spectral
shape) and its non-Gaussian marginal map (white and Gaussian here), and any other named
effect of the clean record (none on the benchmark's 21 record-axes at main e869241; a name
the twin does not reproduce is listed in the output as `not_reproduced`).
Noise per sample, dt the record's mean sample period: white N / sqrt(dt) N(0, 1); flicker by
FFT shaping (gap_indep_gen.flicker: one-sided PSD B^2 / (pi f), Allan floor 0.664 B, the
convention of `gap`'s B); random walk, cumulated K sqrt(dt) N(0, 1); Gauss-Markov, the exact
AR(1) (gap_indep_gen.gauss_markov); sum plus the real record's mean, rounded to the
record's quantum.

Scores (gap_real_bench.score on the twins: right = the injected effect named and every
other name one the same seed's clean twin also gets), and per effect and pooled, paired per
(record, effect) with the real benchmark's row: both right, real only, twin only, neither;
the mean paired difference twin - real with its 95 % interval (normal approximation over
the pairs, 1.96 standard errors: a little narrow for 21 pairs, and the "all" row takes a
record's five effects as independent; with --seeds > 1 a record's twin score is its share
of right seeds, and the counts call a twin right when at least half its draws are). A twin
`gap` fails on or refuses is left out of the pairs and listed, as a failed real row is.

  python3 scripts/gap_twin_bench.py --real REAL --out DIR [--bin target/release/host-sim]
      [--seeds 1] [--first-seed 0] [--jobs 2] [--records adis1x,...] [--effects rate_ramp,...] [--rescore]

Writes DIR/<record>~<seed>-<effect>.csv, .json, .log and DIR/twins.json; never writes into
REAL. Prints the twins' scores and the paired table.
"""
import argparse
import concurrent.futures as cf
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gap_indep_gen as gen  # noqa: E402
import gap_real_bench as bench  # noqa: E402


def twin_model(clean_json, rounds_cap):
    """(noise dict N, B, K, gm_sigma, gm_tau; names not reproduced) of the model `gap`
    named on a clean real record. A name in round `rounds_cap` (the last `--rounds`
    allows) is left out, as `gap` does not apply it."""
    js = json.load(open(clean_json))
    nz = js["baseline"]["noise"]
    m = {
        "n": nz["arw_dps_per_rthz"],
        "b": nz["bias_instability_dps"],
        "k": nz["rrw_dps_per_s_rthz"],
        "gm_sigma": nz["gm_sigma_dps"],
        "gm_tau": nz["gm_tau_s"],
    }
    skipped = []
    for r in bench.named_effects(js):
        e, p = r["effect"], r.get("params") or {}
        if r.get("round", 0) >= rounds_cap:
            skipped.append(f"{e} (round {r.get('round')}: the cap, not applied by gap)")
        elif e == "quantization":
            pass  # the twin is rounded to the record's own quantum
        elif e == "white_noise":
            m["n"] = math.hypot(m["n"], p.get("added_arw_dps_per_rthz", 0.0))
        elif e == "bias_instability":
            m["b"] = math.hypot(m["b"], p.get("added_bias_instability_dps", 0.0))
        elif e == "rate_random_walk":
            m["k"] = math.hypot(m["k"], p.get("added_rrw_dps_per_s_rthz", 0.0))
        elif e == "markov":
            refit = ("refit_arw_dps_per_rthz", "refit_bias_instability_dps", "refit_rrw_dps_per_s_rthz")
            if all(k in p for k in refit):  # as gap's take_refit_noise: all three or none
                for key, k in zip(("n", "b", "k"), refit):
                    m[key] = p[k]
            m["gm_sigma"], m["gm_tau"] = p["gm_sigma_dps"], max(p["gm_tau_s"], 1e-6)
        else:
            skipped.append(e)
    return m, skipped


def twin_noise(m, t, mean, q, seed):
    """One twin's clean rate, deg/s, on the lattice of q."""
    rng = np.random.default_rng(seed)
    n = len(t)
    dt = (t[-1] - t[0]) / (n - 1)
    x = m["n"] / math.sqrt(dt) * rng.standard_normal(n)
    if m["b"] > 0.0:
        x += gen.flicker(rng, n, dt, m["b"])
    if m["k"] > 0.0:
        x += np.cumsum(m["k"] * math.sqrt(dt) * rng.standard_normal(n))
    if m["gm_sigma"] > 0.0:
        x += gen.gauss_markov(rng, n, dt, m["gm_sigma"], m["gm_tau"])
    x += mean
    return [float(v) for v in (np.round(x / q) * q if q > 0.0 else x)]


def interval(d):
    """Mean of the paired differences d and its 95 % interval (normal approximation)."""
    if not d:
        return None
    mu = sum(d) / len(d)
    if len(d) < 2:
        return [mu, None, None]
    sd = math.sqrt(sum((x - mu) ** 2 for x in d) / (len(d) - 1))
    h = 1.96 * sd / math.sqrt(len(d))
    return [mu, mu - h, mu + h]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--real", required=True, help="a finished gap_real_bench.py --out directory (read only)")
    ap.add_argument("--out", required=True)
    ap.add_argument("--bin", default="target/release/host-sim")
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--first-seed", type=int, default=0, help="the twins' draws are first-seed .. first-seed + seeds - 1 (a later run adds draws to an earlier one's)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--records", default=None, help="comma list (default: every record of REAL's summary)")
    ap.add_argument("--effects", default=None, help="comma list (default: REAL's)")
    ap.add_argument("--rounds", type=int, default=None, help="default: REAL's")
    ap.add_argument("--rescore", action="store_true", help="score the JSON already in --out, run nothing")
    a = ap.parse_args()
    if os.path.abspath(a.out) == os.path.abspath(a.real):
        sys.exit(f"--out {a.out} is --real: the twins never write into the real benchmark's directory")
    real = json.load(open(os.path.join(a.real, "summary.json")))
    names = a.records.split(",") if a.records else real["records"]
    effects = a.effects.split(",") if a.effects else real["effects"]
    for e in effects:
        if e not in bench.EFFECTS:
            sys.exit(f"--effects: unknown effect {e} (known: {', '.join(bench.EFFECTS)})")
    a.rounds = a.rounds or real["rounds"]
    if a.first_seed < 0 or a.first_seed + a.seeds > 1000:
        sys.exit("--first-seed and --seeds: the draws must lie in 0..999 (a record's seeds are 1000 apart)")
    a.dither = real["dither"]
    if real.get("scale", 1.0) != 1.0:
        sys.exit(f"{a.real}: sizes x{real['scale']}; twins are made at x1 only")
    os.makedirs(a.out, exist_ok=True)
    jobs, truths, models = [], {}, {}
    order = bench.CORE + [n for n in bench.RECORDS if n not in bench.CORE]
    for name in names:
        if name not in bench.RECORDS:
            sys.exit(f"--records: unknown record {name}")
        m, skipped = twin_model(os.path.join(a.real, f"{name}-none.json"), a.rounds)
        t, rate, q = bench.read_record(name)
        dt = (t[-1] - t[0]) / (len(t) - 1)
        mean = sum(rate) / len(rate)
        temp = bench.temp_profile(t)
        models[name] = {"model": m, "quantum_dps": q, "not_reproduced": skipped}
        ri = order.index(name)
        for s in range(a.first_seed, a.first_seed + a.seeds):
            tw = f"{name}~{s}"
            seed = 52_000_000 + 1000 * ri + s
            clean = twin_noise(m, t, mean, q, seed)
            s100 = bench.adev(clean, dt, 100.0)
            base = os.path.join(a.out, f"{tw}-none")
            if not a.rescore:
                bench.write_csv(base + ".csv", t, clean, temp)
            jobs.append((tw, "none", base))
            for effect in effects:
                ei = bench.EFFECTS.index(effect) + 1
                add, truth = bench.inject(effect, t, clean, temp, s100, 1.0, seed + 100 * ei)
                out = bench.add_rounded(clean, add, q, a.dither, seed + 7919 + 100 * ei)
                base = os.path.join(a.out, f"{tw}-{effect}")
                if not a.rescore:
                    bench.write_csv(base + ".csv", t, out, temp)
                truths[(tw, effect)] = truth
                jobs.append((tw, effect, base))
        print(f"{name}: twin N {m['n']:.4g}, B {m['b']:.4g}, K {m['k']:.4g}, GM {m['gm_sigma']:.4g} deg/s T {m['gm_tau']:.4g} s, quantum {q:.5g}" + (f"; not reproduced: {skipped}" if skipped else ""), file=sys.stderr)

    def run(job):
        tw, effect, base = job
        if a.rescore:
            rc = 0 if os.path.exists(base + ".json") else 1
            return tw, effect, bench.outcome(base, rc, 0.0)
        rc, secs = bench.run_gap(a.bin, base + ".csv", base + ".json", base + ".log", a.rounds)
        return tw, effect, bench.outcome(base, rc, secs)

    clean, injected = {}, {}
    with cf.ThreadPoolExecutor(max_workers=a.jobs) as ex:
        for tw, effect, res in ex.map(run, jobs):
            (clean if effect == "none" else injected)[(tw, effect)] = res
            if not a.rescore:
                js = res[2]
                got = [r["effect"] for r in bench.named_effects(js)] if js else f"rc {res[0]}: {res[3]}"
                print(f"{tw}-{effect}: {got} ({res[1]:.0f} s)", file=sys.stderr, flush=True)
    twins = [f"{n}~{s}" for n in names for s in range(a.first_seed, a.first_seed + a.seeds)]
    summary = bench.score(twins, effects, 1.0, a, clean, injected, truths)
    bench.print_summary(summary)

    # Paired with the real benchmark, per (record, effect).
    real_right = {(r["record"], r["effect"]): r.get("right") for r in real["rows"] if r["effect"] != "none"}
    twin_right, failed_twins = {}, []
    for r in summary["rows"]:
        if r["effect"] == "none":
            continue
        rec = r["record"].split("~")[0]
        if "right" not in r:  # gap failed or refused the twin: left out, as a real row would be
            failed_twins.append(r["record"] + "-" + r["effect"])
            continue
        twin_right.setdefault((rec, r["effect"]), []).append(bool(r["right"]))
    pairs = []
    for (rec, e), tws in sorted(twin_right.items()):
        rr = real_right.get((rec, e))
        if rr is None:
            continue
        pairs.append({"record": rec, "effect": e, "real_right": bool(rr), "twin_right_share": sum(tws) / len(tws)})
    table = {}
    for e in effects + ["all"]:
        ps = [p for p in pairs if e in ("all", p["effect"])]
        if not ps:
            continue
        tw_ok = [p["twin_right_share"] >= 0.5 for p in ps]
        row = {
            "pairs": len(ps),
            "real_right": sum(p["real_right"] for p in ps),
            "twin_right": round(sum(p["twin_right_share"] for p in ps), 2),
            "both": sum(p["real_right"] and w for p, w in zip(ps, tw_ok)),
            "real_only": sum(p["real_right"] and not w for p, w in zip(ps, tw_ok)),
            "twin_only": sum(w and not p["real_right"] for p, w in zip(ps, tw_ok)),
            "neither": sum(not w and not p["real_right"] for p, w in zip(ps, tw_ok)),
            "twin_minus_real": interval([p["twin_right_share"] - p["real_right"] for p in ps]),
        }
        table[e] = row
    print("\npaired with the real records (twin: the model gap named on the clean real record, Gaussian):")
    print(f"{'effect':<12} {'pairs':>5} {'real':>5} {'twin':>6} {'both':>5} {'real only':>9} {'twin only':>9} {'neither':>7}  twin - real (95 %)")
    for e, r in table.items():
        d = r["twin_minus_real"]
        ci = f"{d[0]:+.3f} ({d[1]:+.3f} to {d[2]:+.3f})" if d and d[1] is not None else "-"
        print(f"{e:<12} {r['pairs']:>5} {r['real_right']:>5} {r['twin_right']:>6} {r['both']:>5} {r['real_only']:>9} {r['twin_only']:>9} {r['neither']:>7}  {ci}")
    if failed_twins:
        print(f"twins gap failed on or refused, left out of the pairs: {', '.join(failed_twins)}")
    for p in pairs:
        if p["real_right"] != (p["twin_right_share"] >= 0.5):
            print(f"  {p['record']} {p['effect']}: real {'right' if p['real_right'] else 'wrong'}, twin right {p['twin_right_share']:.2f}")
    summary.update({"real": os.path.abspath(a.real), "seeds": a.seeds, "first_seed": a.first_seed, "failed_twins": failed_twins, "models": models, "pairs": pairs, "paired": table})
    with open(os.path.join(a.out, "twins.json"), "w") as f:
        json.dump(summary, f, indent=1)


if __name__ == "__main__":
    main()

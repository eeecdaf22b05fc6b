#!/usr/bin/env python3
"""Real noise, known effect: `host-sim gap` on real static gyro records with one vocabulary
effect added, scored against the same record without it.

Records (from ../shared/data/real, never copied into the repository; each cut to at most
1800 s and written to --out), every static record long enough for the held-out split and
every axis (21 record-axes; `--records core` gives the six of the figures before issue 43's
benchmark grew: adis4x, adis4z, adis5x, adis5z, adis2y, mpu10x; injection seeds follow a
fixed order, so a record's injections are the same whatever --records and --effects hold):
  - ADIS16405 (University of Calgary via SMAC-Group/imudata, CC BY-NC-SA 4.0), 100 Hz, output
    counts of 0.05 deg/s: runs 1-6, x, y and z (1800 s from t = 200 s, past run 4's handling
    bump at 117-119 s);
  - MPU-6050 (sunsided, EUPL 1.2), ~100 Hz with host arrival times, counts of 1/131 deg/s:
    `unmoved-with-x-pointing-forward-10min`, x, y and z (655 s).
Too short for the held-out split (at least 12,288 samples, 123 s at 100 Hz): the KVH-1750
logs' static lead-in (1.9-2.7 s; the rest turns), the Xsens MTi's (52 s), the other MPU-6050
static records (102-132 s).
Every record (clean and injected) gets the same synthetic `temp_c` column (a warm-up of 8 C
with time constant 600 s and a 1.5 C swing of period 900 s), so that the temperature link has
a channel to be tied to; the sensors' own temperature is not used.

The effect is added as a sensor whose own noise is much larger than its quantum would record
it (the default, dithered): the record's sample r is already on the lattice, r = Q(v) = v + e
with e uniform and independent of the signal (v's noise spreads over many quanta: ADIS16405
sample standard deviation 0.35 deg/s = 7 quanta), so Q(v + x) = r + Q(x - e), which is r plus
x rounded stochastically (up with probability frac(x / q), seeded). With --no-dither (the
injection of the figures before issue 43's dithered default) the effect is rounded to the
lattice deterministically, r + q round(x / q): a slow effect then enters as a staircase (a
ramp of 30 s100 on ADIS run 4 x is six jumps of 0.05 deg/s, 308 s apart), which no sensor
whose noise dithers its quantum outputs. `--dither` is accepted and is the default.

Effects, each sized from the clean record's own 100-s Allan deviation s100 (as the issue that
asked for this benchmark sized them; --scale multiplies every size) and added to the rate
before it is rounded again to the record's output quantum:
  rate_ramp    a ramp whose change over the record is 30 s100;
  warmup       20 s100 exp(-t / 300 s);
  sinusoid     20 s100 sin(2 pi 0.37 Hz t + 0.4);
  temperature  20 s100 per standard deviation of temp_c, times (temp_c - mean);
  markov       a Gauss-Markov term of sigma 8 s100, T 30 s (seeded).

Scores, over the injected records (a name "of its own" is one the clean record also gets):
  - right: the injected effect is named, and every other name is one of the record's own;
  - same: right, and every one of the record's own effects is named too;
  - twice: records (clean or injected) with an effect named twice;
  - zero: named effects whose fitted size is zero;
  - inside: of the rightly named, those whose true parameters are all inside the stated 95 %
    intervals (where intervals are stated);
  - unexplained: what the last round says stays unexplained (clean records).

  python3 scripts/gap_real_bench.py --out DIR [--bin target/release/host-sim] [--jobs 2]
      [--rounds 4] [--scale 1.0 | --scales 0.125,0.25,0.5,1] [--records adis4x,adis4z,...]
      [--effects rate_ramp,...] [--no-dither]

Writes DIR/<record>-<effect>.csv, .json and .log, and DIR/summary.json (with "dither": true or
false); prints the scores, and per effect how many records are right.

The power curve on real noise (--scales): the same records and injections (the same seeds:
the points differ only by the size) at each scale, the clean records run once in DIR/, each
scale's injected ones and its summary.json in DIR/scale-S/; prints per effect the records
named right at each size and the size named right on 90 % of them (linear in log size
between the two scales that bracket 90 %; "<=" when the smallest size already reaches it),
and writes DIR/power.json (per effect and size: right, scored, refused as not static,
failed). The sizes are in the benchmark's unit (x1: the plain sizes above, multiples of the
record's own s100); for the ramp, the warm-up and the temperature link also in the unit D
of the simulated benchmark (scripts/gap_indep_gen.py: the noise's Allan deviation at a
sixth of the record; here the record's own), where the oracle's s90 (docs/gap.md, "Oracle
bound") is stated; the line's and the Gauss-Markov term's units differ and are not
converted. A record `gap` refuses (an effect beyond its static test) or that fails is
shown apart and not counted.
"""
import argparse
import concurrent.futures as cf
import gzip
import json
import math
import os
import random
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REAL = os.path.normpath(os.path.join(HERE, "..", "..", "shared", "data", "real"))

ADIS = os.path.join(REAL, "adis16405_calgary", "adis16405_run{}.csv.gz")
MPU = os.path.join(REAL, "mpu6050_sunsided", "unmoved-with-x-pointing-forward-10min.csv")
# name: (file, column, first sample, quantum deg/s). Every static record of ../shared/data/real
# long enough for the held-out split (the KVH logs' static lead-in is 1.9-2.7 s, the Xsens's
# 52 s, the other MPU-6050 static records 102-132 s: too short), every axis.
RECORDS = {
    f"adis{run}{ax}": (ADIS.format(run), f"g{ax}_dps", 20000, 0.05)
    for run in range(1, 7)
    for ax in "xyz"
}
RECORDS.update({f"mpu10{ax}": (MPU, f"g{ax}_dps", 0, 1.0 / 131.0) for ax in "xyz"})
# The six record-axes of the figures before the benchmark grew (issue 43).
CORE = ["adis4x", "adis4z", "adis5x", "adis5z", "adis2y", "mpu10x"]
MAX_S = 1800.0
EFFECTS = ["rate_ramp", "warmup", "sinusoid", "temperature", "markov"]
# The plain (x1) size in multiples of the record's s100, where the simulated benchmark sizes
# the same quantity in its unit D: a ramp's change over the record, a warm-up's amplitude,
# the RMS of the temperature-driven drift (scripts/gap_indep_gen.py).
PLAIN_S100 = {"rate_ramp": 30.0, "warmup": 20.0, "temperature": 20.0}
# The true parameters the report's keys hold, per effect.
TRUE_KEYS = {
    "rate_ramp": ["rate_ramp_dps_per_s"],
    "warmup": ["warmup_dps", "warmup_tau_s"],
    "sinusoid": ["sine_amplitude_dps", "sine_freq_hz"],
    "temperature": ["bias_dps_per_c"],
    "markov": ["gm_sigma_dps", "gm_tau_s"],
}
# Keys whose value is the named effect's size (all zero: nothing was fitted).
SIZE_KEYS = {
    "rate_ramp": ["rate_ramp_dps_per_s"],
    "warmup": ["warmup_dps"],
    "sinusoid": ["sine_amplitude_dps"],
    "temperature": ["bias_dps_per_c", "bias_dps_per_c_per_s"],
    "markov": ["gm_sigma_dps"],
    "spikes": ["spike_probability"],
    "quantization": ["quantum_dps"],
    "white_noise": ["added_arw_dps_per_rthz"],
    "bias_instability": ["added_bias_instability_dps"],
    "rate_random_walk": ["added_rrw_dps_per_s_rthz"],
    "dropouts": ["drop_probability"],
    "scale_factor": ["scale_factor_error_ppm"],
}


def read_record(name):
    path, col, first, q = RECORDS[name]
    opener = gzip.open if path.endswith(".gz") else open
    t, r = [], []
    with opener(path, "rt") as f:
        header = f.readline().strip().split(",")
        ti, ci = header.index("t_s"), header.index(col)
        for i, line in enumerate(f):
            if i < first:
                continue
            p = line.split(",")
            t.append(float(p[ti]))
            r.append(float(p[ci]))
            if t[-1] - t[0] >= MAX_S:
                t.pop()
                r.pop()
                break
    t0 = t[0]
    return [x - t0 for x in t], r, q


def adev(rate, dt, tau_s):
    """Overlapping Allan deviation at tau_s (m = tau / dt samples), deg/s."""
    m = max(1, int(round(tau_s / dt)))
    c = [0.0]
    for x in rate:
        c.append(c[-1] + x * dt)
    n = len(c) - 1
    s, k = 0.0, 0
    for i in range(0, n - 2 * m + 1):
        d = c[i + 2 * m] - 2 * c[i + m] + c[i]
        s += d * d
        k += 1
    tau = m * dt
    return math.sqrt(s / (2 * tau * tau * k)) if k else float("nan")


def temp_profile(t):
    return [25.0 + 8.0 * (1.0 - math.exp(-x / 600.0)) + 1.5 * math.sin(2 * math.pi * x / 900.0) for x in t]


def inject(effect, t, rate, temp, s100, scale, seed):
    """The effect's added rate per sample, deg/s, and its true parameters."""
    n, total = len(t), t[-1] if t else 1.0
    if effect == "none":
        return [0.0] * n, {}
    if effect == "rate_ramp":
        k = scale * 30.0 * s100 / total
        return [k * x for x in t], {"rate_ramp_dps_per_s": k}
    if effect == "warmup":
        a, tau = scale * 20.0 * s100, 300.0
        return [a * math.exp(-x / tau) for x in t], {"warmup_dps": a, "warmup_tau_s": tau}
    if effect == "sinusoid":
        a, f = scale * 20.0 * s100, 0.37
        return [a * math.sin(2 * math.pi * f * x + 0.4) for x in t], {
            "sine_amplitude_dps": a,
            "sine_freq_hz": f,
        }
    if effect == "temperature":
        m = sum(temp) / n
        sd = math.sqrt(sum((x - m) ** 2 for x in temp) / n)
        k = scale * 20.0 * s100 / sd
        return [k * (x - m) for x in temp], {"bias_dps_per_c": k}
    if effect == "markov":
        sigma, tc = scale * 8.0 * s100, 30.0
        rng = random.Random(seed)
        out, x = [], rng.gauss(0.0, sigma)
        for i in range(n):
            dt = t[i] - t[i - 1] if i else 0.0
            phi = math.exp(-dt / tc)
            x = phi * x + sigma * math.sqrt(max(0.0, 1.0 - phi * phi)) * rng.gauss(0.0, 1.0)
            out.append(x)
        return out, {"gm_sigma_dps": sigma, "gm_tau_s": tc}
    raise ValueError(effect)


def add_rounded(rate, add, q, dither, seed):
    """The record `rate` (on the lattice of q) with the effect `add` added and rounded to q
    again: stochastically (up with probability frac(x / q), `random.Random(seed)`) when
    `dither`, else to the nearest count (module doc)."""
    if dither:
        rng = random.Random(seed)
        return [(round(r / q) + math.floor(x / q + rng.random())) * q for r, x in zip(rate, add)]
    return [round((r + x) / q) * q for r, x in zip(rate, add)]


def write_csv(path, t, rate, temp):
    with open(path, "w") as f:
        f.write("t_s,rate_dps,temp_c\n")
        for a, b, c in zip(t, rate, temp):
            f.write(f"{a:.6f},{b:.10g},{c:.5f}\n")


def run_gap(binary, csv, js, log, rounds):
    t0 = time.time()
    with open(log, "w") as lf:
        p = subprocess.run(
            [binary, "gap", "--input", csv, "--json", js, "--rounds", str(rounds)],
            stdout=lf,
            stderr=subprocess.STDOUT,
        )
    return p.returncode, time.time() - t0


def failure(log):
    """The first line of `gap`'s error in `log` (empty when there is none or no log)."""
    try:
        with open(log) as f:
            for line in f:
                if line.lower().startswith("error:"):
                    return line.strip()
    except OSError:
        pass
    return ""


# How `gap` says it refuses a record that is not static (an effect beyond its static test).
NOT_STATIC = "not a static record"


def outcome(base, rc, secs):
    """One run's result, (rc, seconds, report or None, gap's error line): the report
    BASE.json when rc is 0 and it exists, else the error its log BASE.log names."""
    js = json.load(open(base + ".json")) if rc == 0 and os.path.exists(base + ".json") else None
    return rc, secs, js, "" if js else failure(base + ".log")


def named_effects(js):
    rounds = js.get("rounds") or []
    return [r for r in rounds if r.get("effect") not in (None, "none")]


def zero_size(r):
    keys = SIZE_KEYS.get(r["effect"], [])
    p = r.get("params") or {}
    vals = [p.get(k) for k in keys if p.get(k) is not None]
    return bool(vals) and all(v == 0.0 for v in vals)


def inside(r, truth):
    ci = r.get("params_ci95") or {}
    checked, ok = 0, True
    for k, v in truth.items():
        if k in ci and ci[k] is not None:
            lo, hi = ci[k]
            lo = -math.inf if lo is None else lo
            hi = math.inf if hi is None else hi
            checked += 1
            ok &= lo <= v <= hi
    return (ok if checked else None), checked


def score(names, effects, scale, a, clean, injected, truths):
    """Scores of one scale's injected records against the clean ones: the summary dict."""
    results = dict(clean)
    results.update(injected)
    rows, right, total, twice, zero, named_right, in_ci, same_own = [], 0, 0, 0, 0, 0, 0, 0
    own = {}
    for n in names:
        rc, _, js, _ = results[(n, "none")]
        own[n] = set(r["effect"] for r in named_effects(js)) if js else set()
    unexplained = {}
    for (n, e), (rc, secs, js, why) in sorted(results.items()):
        if js is None:
            rows.append({"record": n, "effect": e, "error": f"rc {rc}" + (f": {why}" if why else ""),
                         "refused_not_static": NOT_STATIC in why})
            continue
        named = named_effects(js)
        names_ = [r["effect"] for r in named]
        dup = len(names_) != len(set(names_))
        zeros = [r["effect"] for r in named if zero_size(r)]
        twice += dup
        zero += len(zeros)
        row = {"record": n, "effect": e, "named": names_, "twice": dup, "zero_size": zeros, "seconds": round(secs, 1)}
        if e == "none":
            unexplained[n] = js.get("unexplained")
        else:
            total += 1
            others_ok = all(x == e or x in own[n] for x in names_)
            ok = e in names_ and others_ok
            right += ok
            row["right"] = ok
            same = ok and set(x for x in names_ if x != e) == own[n]
            same_own += same
            row["own_effects_the_same"] = same
            if e in names_:
                r = next(r for r in named if r["effect"] == e)
                inn, k = inside(r, truths[(n, e)])
                row["true_inside_ci95"] = inn
                if ok and inn is not None:
                    named_right += 1
                    in_ci += bool(inn)
        rows.append(row)
    return {
        "records": names,
        "effects": effects,
        "scale": scale,
        "rounds": a.rounds,
        "dither": a.dither,
        "injected_right": [right, total],
        "injected_right_and_own_effects_the_same": [same_own, total],
        "records_with_an_effect_named_twice": [twice, len(results)],
        "named_with_zero_size": zero,
        "true_inside_ci95_of_rightly_named": [in_ci, named_right],
        "own_effects": {k: sorted(v) for k, v in own.items()},
        "unexplained_clean": unexplained,
        "rows": rows,
    }


def print_summary(summary):
    s = summary
    print(f"injection: {'dithered (stochastic rounding)' if s['dither'] else 'rounded to the nearest count (--no-dither)'}, sizes x{s['scale']:g}")
    print(f"injected effect named, others the record's own: {s['injected_right'][0]}/{s['injected_right'][1]}")
    print(f"... and every one of the record's own effects named too: {s['injected_right_and_own_effects_the_same'][0]}/{s['injected_right_and_own_effects_the_same'][1]}")
    print(f"records with an effect named twice: {s['records_with_an_effect_named_twice'][0]}/{s['records_with_an_effect_named_twice'][1]}")
    print(f"named effects with zero fitted size: {s['named_with_zero_size']}")
    print(f"true parameters inside the 95 % intervals: {s['true_inside_ci95_of_rightly_named'][0]}/{s['true_inside_ci95_of_rightly_named'][1]} rightly named (with intervals)")
    for e in s["effects"]:
        rs = [r for r in s["rows"] if r["effect"] == e and "right" in r]
        print(f"  {e}: right {sum(r['right'] for r in rs)}/{len(rs)}, named at all {sum(e in r['named'] for r in rs)}/{len(rs)}")
    for n, v in s["own_effects"].items():
        print(f"  {n}: own effects {v}")


def s90(points):
    """The size (x the benchmark's plain size) named right on 90 % of the records: linear in
    log size between the two scales that bracket 0.9 (the first crossing from below), as
    (size, "="); (smallest scale, "<=") when the smallest already reaches it; (None, "") when
    no scale does. A point whose fraction is None (no record scored) is left out."""
    pts = sorted((sc, f) for sc, f in points if f is not None)
    if not pts or max(f for _, f in pts) < 0.9:
        return None, ""
    if pts[0][1] >= 0.9:
        return pts[0][0], "<="
    for (s0, f0), (s1, f1) in zip(pts, pts[1:]):
        if f0 < 0.9 <= f1:
            w = (0.9 - f0) / (f1 - f0)
            return math.exp(math.log(s0) + w * (math.log(s1) - math.log(s0))), "="
    return None, ""


def power_curve(names, effects, scales, summaries, plain_in_d, a):
    """Prints the power table (per effect and size: named right, refusals apart; the size
    named right on 90 %; sizes in D) and returns what DIR/power.json holds."""
    power = {"records": names, "effects": effects, "rounds": a.rounds, "dither": a.dither, "scales": scales,
             "plain_in_d": plain_in_d, "effect": {}}
    print("\n== power on real noise: injected effect named right (no foreign name), per size")
    print("(in D: the size in the simulated benchmark's unit, the record's own Allan deviation at a")
    print(" sixth of its length; x1's median over the records, and the 90 % size so converted)")
    print("| effect | " + " | ".join(f"x{sc:g}" for sc in scales) + " | size named right on 90 % | x1 in D | 90 % size in D |")
    print("|---|" + "---|" * len(scales) + "---|---|---|")
    for e in effects:
        pts, cells, counts = [], [], {}
        for sc in scales:
            rows = [r for r in summaries[sc]["rows"] if r["effect"] == e]
            rs = [r for r in rows if "right" in r]
            # A record gap refuses as not static (the effect beyond its static test) is
            # shown apart, as is any other failure; neither is counted.
            refused = sum(1 for r in rows if r.get("refused_not_static"))
            failed = sum(1 for r in rows if "error" in r and not r.get("refused_not_static"))
            k = sum(r["right"] for r in rs)
            pts.append((sc, k / len(rs) if rs else None))
            note = ", ".join(x for x in (f"{refused} refused as not static" if refused else "",
                                         f"{failed} failed" if failed else "") if x)
            cells.append(f"{k}/{len(rs)}" + (f" ({note})" if note else ""))
            counts[f"{sc:g}"] = {"right": k, "scored": len(rs), "refused_not_static": refused, "failed": failed}
        x90, rel = s90(pts)
        in_d = sorted(plain_in_d[n][e] for n in names if plain_in_d[n][e] is not None) if e in PLAIN_S100 else []
        med = statistics.median(in_d) if in_d else None
        power["effect"][e] = {
            "counts": counts,
            "s90_scale": x90,
            "s90_relation": rel,
            "plain_in_d_median": med,
            "s90_in_d": None if x90 is None or med is None else x90 * med,
        }
        d1 = "-" if med is None else f"{med:.3g} ({in_d[0]:.3g}-{in_d[-1]:.3g})"
        d90 = "-" if med is None or x90 is None else f"{'<= ' if rel == '<=' else ''}{x90 * med:.3g}"
        s90_text = "not reached" if x90 is None else f"{'<= ' if rel == '<=' else ''}x{x90:.3g}"
        print(f"| {e} | " + " | ".join(cells) + f" | {s90_text} | {d1} | {d90} |")
    return power


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True)
    ap.add_argument("--bin", default=os.path.join(HERE, "..", "target", "release", "host-sim"))
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=4)
    size = ap.add_mutually_exclusive_group()
    size.add_argument("--scale", type=float, default=1.0)
    size.add_argument(
        "--scales",
        help="comma list of size scales (e.g. 0.125,0.25,0.5,1): the power curve; each scale's "
        "injected records in OUT/scale-S/, the clean ones once in OUT/, OUT/power.json",
    )
    ap.add_argument("--records", default=",".join(RECORDS),
                    help="comma list, or 'core' for the six record-axes of the earlier figures")
    ap.add_argument("--effects", default=",".join(EFFECTS))
    ap.add_argument("--seed", type=int, default=38001)
    ap.add_argument("--rescore", action="store_true", help="score the JSON already in --out, run nothing")
    ap.add_argument(
        "--dither",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="round the added effect stochastically, as a sensor whose noise dithers its quantum records it (the default); --no-dither rounds it to the nearest count (a slow effect enters as a staircase)",
    )
    a = ap.parse_args()
    if not os.path.isdir(REAL):
        print(f"SKIPPED: {REAL} is absent (real records are not in a user's clone)", file=sys.stderr)
        return 0
    curve = a.scales is not None
    if curve:
        try:
            scales = [float(x) for x in a.scales.split(",") if x.strip()]
        except ValueError:
            sys.exit(f"--scales {a.scales!r}: not a comma list of numbers")
        if not scales or any(not (x > 0.0 and math.isfinite(x)) for x in scales):
            sys.exit(f"--scales {a.scales!r}: sizes must be positive and finite, at least one")
        if len(set(f"{x:g}" for x in scales)) != len(scales):
            sys.exit(f"--scales {a.scales!r}: two sizes share a folder name (scale-S, S printed as %g)")
    else:
        scales = [a.scale]
    os.makedirs(a.out, exist_ok=True)
    names = CORE if a.records == "core" else [x for x in a.records.split(",") if x]
    effects = [x for x in a.effects.split(",") if x]
    for x in names:
        if x not in RECORDS:
            sys.exit(f"unknown record {x}; known: {', '.join(RECORDS)}")
    for x in effects:
        if x not in EFFECTS:
            sys.exit(f"unknown effect {x}; known: {', '.join(EFFECTS)}")
    prev = os.path.join(a.out, "power.json" if curve else "summary.json")
    if a.rescore and os.path.exists(prev):
        was = json.load(open(prev)).get("dither", False)
        if was != a.dither:
            sys.exit(f"{prev}: its records were injected {'with' if was else 'without'} dither; rescore with {'--dither' if was else '--no-dither'}")
    outdir = {sc: os.path.join(a.out, f"scale-{sc:g}") if curve else a.out for sc in scales}
    for d in outdir.values():
        os.makedirs(d, exist_ok=True)
    clean_jobs, jobs, truths = [], {sc: [] for sc in scales}, {sc: {} for sc in scales}
    plain_in_d = {}
    # Seeds by a fixed order (the six earlier record-axes first, the effects as in EFFECTS),
    # whatever --records and --effects hold; the same at every scale, so a curve's points
    # differ only by the size.
    order = CORE + [n for n in RECORDS if n not in CORE]
    for name in names:
        ri = order.index(name)
        t, rate, q = read_record(name)
        dt = (t[-1] - t[0]) / (len(t) - 1)
        s100 = adev(rate, dt, 100.0)
        # The simulated benchmark's unit D (scripts/gap_indep_gen.py: the noise's Allan
        # deviation at a sixth of the record), here the record's own.
        if curve:
            d_blk = adev(rate, dt, t[-1] / 6.0)
            plain_in_d[name] = {e: PLAIN_S100[e] * s100 / d_blk if d_blk > 0.0 else None for e in PLAIN_S100}
        temp = temp_profile(t)
        base = os.path.join(a.out, f"{name}-none")
        if not a.rescore:  # --rescore reads what an earlier run wrote, never rewrites it
            write_csv(base + ".csv", t, rate, temp)
        clean_jobs.append((name, "none", base))
        for sc in scales:
            for effect in effects:
                ei = EFFECTS.index(effect) + 1
                add, truth = inject(effect, t, rate, temp, s100, sc, a.seed + 100 * ri + ei)
                out = add_rounded(rate, add, q, a.dither, a.seed + 7919 + 100 * ri + ei)
                base = os.path.join(outdir[sc], f"{name}-{effect}")
                if not a.rescore:
                    write_csv(base + ".csv", t, out, temp)
                truths[sc][(name, effect)] = truth
                jobs[sc].append((name, effect, base))
        print(f"{name}: {len(t)} samples, {t[-1]:.0f} s, quantum {q:.5g} deg/s, s100 {s100 * 3600:.2f} deg/h", file=sys.stderr)

    def run_all(js_):
        got_ = {}
        if a.rescore:
            for n, e, b in js_:
                got_[b] = outcome(b, 0 if os.path.exists(b + ".json") else 1, 0.0)
            return got_
        with cf.ThreadPoolExecutor(max_workers=a.jobs) as ex:
            futs = {
                ex.submit(run_gap, a.bin, b + ".csv", b + ".json", b + ".log", a.rounds): (n, e, b)
                for n, e, b in js_
            }
            for fut in cf.as_completed(futs):
                n, e, b = futs[fut]
                got_[b] = outcome(b, *fut.result())
                rc, secs, js, _ = got_[b]
                shown = [r["effect"] for r in named_effects(js)] if js else f"rc {rc}"
                print(f"{n}-{e}: {shown} ({secs:.0f} s)", file=sys.stderr)
        return got_

    # One pool for every record, keyed by file: the clean ones first (every scale scores
    # against them).
    got = run_all(clean_jobs + [j for sc in scales for j in jobs[sc]])
    clean = {(n, e): got[b] for n, e, b in clean_jobs}
    summaries = {}
    for sc in scales:
        injected = {(n, e): got[b] for n, e, b in jobs[sc]}
        summaries[sc] = score(names, effects, sc, a, clean, injected, truths[sc])
        json.dump(summaries[sc], open(os.path.join(outdir[sc], "summary.json"), "w"), indent=1)
        if curve:
            print(f"\n== sizes x{sc:g} ({outdir[sc]})")
        print_summary(summaries[sc])
    if curve:
        power = power_curve(names, effects, scales, summaries, plain_in_d, a)
        json.dump(power, open(os.path.join(a.out, "power.json"), "w"), indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Runs `host-sim gap` on records made by scripts/gap_indep_gen.py and scores it (issue 13).

Requires: python3 and numpy (`pip install numpy`); a built host-sim (`--bin`, default
target/release/host-sim).

For every record in DIR/manifest.jsonl (optionally only --classes), runs
  host-sim gap --input DIR/NAME.csv --json OUT/NAME.json --no-task [--gyro DIR/NAME.toml]
(`--gyro` in --mode sim), then prints and writes (OUT/summary.json, OUT/summary.md):
- the confusion table (truth x named), right-effect rate over the effect records, the rate
  at which `none` records are wrongly flagged, the median held-out shrink of the true
  effect's candidate (over the effect records; and, as a diagnostic, over those whose
  held-out gap is significant, gap_before > null_gap_95), CPU seconds per record;
- a detection-power curve per effect: P(named right | strength) from a logistic fit in
  ln(strength), the strength where it reaches 90 %, and an SVG plot (OUT/power.svg).

Usage:
  scripts/gap_indep_bench.py --dir RECORDS --out RESULTS [--jobs 1] [--mode fitted|sim]
      [--classes a,b] [--limit N] [--extra-args "..."]
"""

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np


def run_one(binary, d, out, name, mode, extra):
    js = os.path.join(out, name + ".json")
    if os.path.exists(js):
        return name, 0.0, None
    # The first decision alone (what this benchmark scores; gap's default runs rounds).
    cmd = [binary, "gap", "--input", os.path.join(d, name + ".csv"), "--json", js, "--no-task", "--rounds", "1"]
    if mode == "sim":
        cmd += ["--gyro", os.path.join(d, name + ".toml")]
    cmd += extra
    t0 = time.time()
    r = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.time() - t0
    if r.returncode != 0:
        return name, wall, r.stderr.strip()
    return name, wall, None


def logistic_fit(x, y):
    """P(y=1) = 1 / (1 + exp(-(a + b x))) by Newton; returns (a, b) or None."""
    x = np.asarray(x, float)
    y = np.asarray(y, float)
    if len(x) < 3 or y.min() == y.max():
        return None
    a, b = 0.0, 1.0
    lam = 0.5  # ridge on the slope: keeps (nearly) separable data finite
    for _ in range(100):
        p = 1 / (1 + np.exp(-np.clip(a + b * x, -50, 50)))
        w = p * (1 - p) + 1e-9
        g = np.array([np.sum(y - p), np.sum((y - p) * x) - lam * b])
        h = np.array([[np.sum(w), np.sum(w * x)], [np.sum(w * x), np.sum(w * x * x) + lam]])
        step = np.linalg.solve(h, g)
        a += step[0]
        b += step[1]
        if np.abs(step).max() < 1e-8:
            break
    return a, b


def s90(fit):
    if fit is None:
        return None
    a, b = fit
    if b <= 0:
        return None
    u = (math.log(9.0) - a) / b
    return math.exp(min(max(u, -50.0), 50.0))


def svg_power(curves, path):
    """One panel per effect: points (right = 1 / wrong = 0) and the logistic fit."""
    names = sorted(curves)
    cols = 4
    rows = max(1, math.ceil(len(names) / cols))
    w, h = 250, 170
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{cols * w}" height="{rows * h}" '
           'font-family="sans-serif" font-size="10">']
    for i, nm in enumerate(names):
        c = curves[nm]
        ox, oy = (i % cols) * w, (i // cols) * h
        x0, x1, y0, y1 = ox + 35, ox + w - 10, oy + h - 30, oy + 20
        lo, hi = c["range"]
        lx = lambda s: x0 + (math.log(s) - math.log(lo)) / (math.log(hi) - math.log(lo)) * (x1 - x0)
        ly = lambda p: y0 - p * (y0 - y1)
        out.append(f'<rect x="{x0}" y="{y1}" width="{x1 - x0}" height="{y0 - y1}" fill="none" stroke="#888"/>')
        out.append(f'<text x="{x0}" y="{oy + 14}" font-weight="bold">{nm}</text>')
        out.append(f'<line x1="{x0}" x2="{x1}" y1="{ly(0.9)}" y2="{ly(0.9)}" stroke="#c66" stroke-dasharray="3,3"/>')
        out.append(f'<text x="{ox + 2}" y="{ly(0.9) + 3}">0.9</text>')
        out.append(f'<text x="{ox + 2}" y="{ly(0.0) + 3}">0</text><text x="{ox + 2}" y="{ly(1.0) + 3}">1</text>')
        out.append(f'<text x="{x0}" y="{y0 + 12}">{lo:g}</text><text x="{x1 - 25}" y="{y0 + 12}">{hi:g}</text>')
        out.append(f'<text x="{(x0 + x1) / 2 - 30}" y="{y0 + 24}">strength s (log)</text>')
        for s, ok in c["points"]:
            s = min(max(s, lo), hi)
            out.append(f'<circle cx="{lx(s):.1f}" cy="{ly(1.0 if ok else 0.0):.1f}" r="2.5" '
                       f'fill="{"#2a2" if ok else "#d22"}" fill-opacity="0.6"/>')
        if c["fit"] is not None:
            a, b = c["fit"]
            pts = []
            for k in range(61):
                s = math.exp(math.log(lo) + (math.log(hi) - math.log(lo)) * k / 60)
                p = 1 / (1 + math.exp(-min(max(a + b * math.log(s), -50.0), 50.0)))
                pts.append(f"{lx(s):.1f},{ly(p):.1f}")
            out.append(f'<polyline points="{" ".join(pts)}" fill="none" stroke="#22c"/>')
        if c["s90"] is not None and lo <= c["s90"] <= hi:
            out.append(f'<line x1="{lx(c["s90"]):.1f}" x2="{lx(c["s90"]):.1f}" y1="{y0}" y2="{y1}" stroke="#c66"/>')
        lab = "s90 = " + (f'{c["s90"]:.3g}' if c["s90"] is not None else "n/a")
        out.append(f'<text x="{x1 - 80}" y="{oy + 14}">{lab}</text>')
    out.append("</svg>")
    with open(path, "w") as f:
        f.write("\n".join(out))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dir", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--bin", default="target/release/host-sim")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--mode", choices=["fitted", "sim"], default="fitted")
    ap.add_argument("--classes", default=None)
    ap.add_argument("--limit", type=int, default=0, help="records per class (0 = all)")
    ap.add_argument("--extra-args", default="")
    a = ap.parse_args()
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from gap_indep_gen import S_RANGE

    man = [json.loads(l) for l in open(os.path.join(a.dir, "manifest.jsonl")) if l.strip()]
    seen = {}
    recs = []
    for m in man:
        if m["name"] in seen:
            continue
        seen[m["name"]] = True
        if a.classes and m["effect"] not in a.classes.split(","):
            continue
        recs.append(m)
    if a.limit:
        per = {}
        recs = [m for m in recs if per.setdefault(m["effect"], []).append(1) or len(per[m["effect"]]) <= a.limit]
    os.makedirs(a.out, exist_ok=True)
    extra = a.extra_args.split()
    t0 = time.time()
    walls = {}
    errors = {}
    with ThreadPoolExecutor(max_workers=a.jobs) as ex:
        for name, wall, err in ex.map(lambda m: run_one(a.bin, a.dir, a.out, m["name"], a.mode, extra), recs):
            walls[name] = wall
            if err:
                errors[name] = err
                print(f"{name}: ERROR {err}", file=sys.stderr)
            else:
                print(f"{name}: done in {wall:.1f} s", file=sys.stderr)
    elapsed = time.time() - t0
    cpu = resource.getrusage(resource.RUSAGE_CHILDREN)
    rows = []
    for m in recs:
        js = os.path.join(a.out, m["name"] + ".json")
        if not os.path.exists(js):
            continue
        d = json.load(open(js))
        true_shrink = None
        for c in d.get("candidates", []):
            if c["effect"] == m["effect"] and c.get("shrink") is not None:
                true_shrink = c["shrink"]
        rows.append({"name": m["name"], "truth": m["effect"], "named": d["effect"],
                     "strength": m.get("strength"), "fs_hz": m["fs_hz"],
                     "has_temp": m["has_temp"], "has_motion": m["has_motion"],
                     "gap_before": d["gap_before"], "gap_after": d["gap_after"],
                     "null_gap_95": d.get("null_gap_95"),
                     "true_shrink": true_shrink, "decision": d.get("decision", "")})
    eff = [r for r in rows if r["truth"] != "none"]
    nones = [r for r in rows if r["truth"] == "none"]
    right = sum(r["named"] == r["truth"] for r in eff)
    none_false = sum(r["named"] != "none" for r in nones)
    shr = [r["true_shrink"] for r in eff if r["true_shrink"] is not None]
    # Diagnostic beside the goal's figure: the shrink over the effect records whose held-out
    # gap is significant (gap_before > null_gap_95); on the others the gap is within the
    # simulations' spread and its shrink is noise about 0.
    shr_sig = [r["true_shrink"] for r in eff if r["true_shrink"] is not None
               and r["null_gap_95"] is not None and r["gap_before"] > r["null_gap_95"]]
    classes = sorted({r["truth"] for r in rows})
    named_set = sorted({r["named"] for r in rows} | set(classes))
    curves = {}
    for c in classes:
        if c == "none":
            continue
        pts = [(r["strength"], r["named"] == c) for r in rows if r["truth"] == c]
        fit = logistic_fit([math.log(s) for s, _ in pts], [1.0 if ok else 0.0 for _, ok in pts])
        if fit is None and pts and all(ok for _, ok in pts):
            s9 = min(s for s, _ in pts)  # every record right: at most the weakest strength
        else:
            s9 = s90(fit)
        curves[c] = {"points": pts, "fit": fit, "s90": s9, "range": S_RANGE[c],
                     "right": sum(ok for _, ok in pts), "n": len(pts)}
    summary = {
        "records": len(rows), "errors": errors,
        "right_effect": right / max(1, len(eff)), "right_count": [right, len(eff)],
        "none_false": none_false / max(1, len(nones)), "none_false_count": [none_false, len(nones)],
        "median_true_shrink": float(np.median(shr)) if shr else None,
        "median_true_shrink_significant_gap": float(np.median(shr_sig)) if shr_sig else None,
        "significant_gap_count": len(shr_sig),
        "wall_s": elapsed, "cpu_s_children": cpu.ru_utime + cpu.ru_stime,
        "cpu_s_per_record": (cpu.ru_utime + cpu.ru_stime) / max(1, len(walls)),
        "max_wall_s": max(walls.values()) if walls else None,
        "power": {c: {k: v for k, v in cv.items() if k != "points"} for c, cv in curves.items()},
        "rows": rows,
    }
    json.dump(summary, open(os.path.join(a.out, "summary.json"), "w"), indent=1)
    ab = lambda s: s[:10]
    md = ["| truth \\ named | " + " | ".join(ab(n) for n in named_set) + " | right | median shrink |",
          "|---" * (len(named_set) + 3) + "|"]
    for c in classes:
        rr = [r for r in rows if r["truth"] == c]
        cells = [str(sum(r["named"] == n for r in rr)) or "." for n in named_set]
        cells = [x if x != "0" else "." for x in cells]
        ok = sum(r["named"] == c for r in rr)
        sh = [r["true_shrink"] for r in rr if r["true_shrink"] is not None]
        md.append(f"| {c} | " + " | ".join(cells) +
                  f" | {ok}/{len(rr)} | {np.median(sh) if sh else float('nan'):.2f} |")
    md.append("")
    md.append(f"right effect named: {100 * summary['right_effect']:.1f} % ({right} of {len(eff)}); "
              f"none wrongly flagged: {100 * summary['none_false']:.1f} % ({none_false} of {len(nones)}); "
              f"median held-out shrink of the true effect: {summary['median_true_shrink'] if shr else float('nan'):.2f} "
              f"(over the {len(shr_sig)} with gap_before > null_gap_95: "
              f"{float(np.median(shr_sig)) if shr_sig else float('nan'):.2f}); "
              f"CPU per record {summary['cpu_s_per_record']:.1f} s; wall {elapsed:.0f} s")
    md.append("")
    md.append("| effect | right | strength range | s90 (90 % named right) |")
    md.append("|---|---|---|---|")
    for c, cv in curves.items():
        s9 = f"{cv['s90']:.3g}" if cv["s90"] is not None else "not reached"
        md.append(f"| {c} | {cv['right']}/{cv['n']} | {cv['range'][0]:g}-{cv['range'][1]:g} | {s9} |")
    text = "\n".join(md)
    open(os.path.join(a.out, "summary.md"), "w").write(text + "\n")
    svg_power(curves, os.path.join(a.out, "power.svg"))
    print(text)


if __name__ == "__main__":
    main()

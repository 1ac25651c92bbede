#!/usr/bin/env python3
"""Largest stable time step in contact per method, speed and rod resolution.

    python3 hstar.py v30 v60 v120 v240

Each directory holds the stability.csv of one `weft stability` sweep (README.md). h* is the
largest step of the sweep at which the run, and the run at every smaller step, completed the
simulated second with no edge stretched beyond 50 % and touched the wall (contact_steps > 0).
"""
import csv
import os
import re
import sys

METHODS = ("rods_impulse", "rods_linear", "rods_adonis")


def hstar(rows, combo, speed, strain_limit=None):
    """h* (None: no step of the sweep qualifies); with strain_limit, the runs must also keep
    every edge within that strain (the production tolerance of 1 %, against the thesis' 50 %)."""
    cells = {float(r["dt"]): r for r in rows if r["combo"] == combo and r["value"] == speed}
    best = None
    for dt in sorted(cells):
        r = cells[dt]
        if r["outcome"] != "stable" or int(r["contact_steps"]) == 0:
            break
        if strain_limit is not None and float(r["max_strain"]) > strain_limit:
            break
        best = dt
    return best, cells


def ms(x):
    return "none" if x is None else f"{x * 1e3:g} ms"


def main(dirs):
    print("| vertices | edge [mm] | speed [rad/s] | impulse | linear compliance | ADONIS | ADONIS / impulse "
          "| ADONIS / linear | ADONIS's largest strain at h* | h* at 1 % strain: impulse / linear / ADONIS "
          "| failures below 20 ms (method, dt, outcome) |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---|")
    for d in dirs:
        rows = list(csv.DictReader(open(os.path.join(d, "stability.csv"))))
        v = int(re.search(r"v(\d+)", os.path.basename(d.rstrip("/"))).group(1))
        for speed in sorted({r["value"] for r in rows}, key=float):
            h = {m: hstar(rows, m, speed) for m in METHODS}
            a, i, l = h["rods_adonis"][0], h["rods_impulse"][0], h["rods_linear"][0]
            strain = float(h["rods_adonis"][1][a]["max_strain"]) * 100 if a else float("nan")
            fails = [f"{r['combo'][5:]} {float(r['dt']) * 1e3:g} ms {r['outcome']}" for r in rows
                     if r["value"] == speed and r["outcome"] not in ("stable", "excessive_strain") and float(r["dt"]) < 0.02]
            ratio = lambda x, y: "-" if x is None or y is None else f"{x / y:.0f}"
            tight = " / ".join(ms(hstar(rows, m, speed, 0.0101)[0]) for m in METHODS)
            print(f"| {v} | {200 / (v - 1):.2f} | {speed} | {ms(i)} | {ms(l)} | {ms(a)} | {ratio(a, i)} | {ratio(a, l)} "
                  f"| {strain:.1f} % | {tight} | {'; '.join(fails) or '-'} |")


if __name__ == "__main__":
    main(sys.argv[1:])

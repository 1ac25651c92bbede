#!/usr/bin/env python3
"""Tables of bench/peers_sweep.sh's runs: per run directory, example, size and solver the mean
iterations, setup, solve and total per solve, and the peer's total over SA+PPCG's of the same
run (the ratio the targets use); then the best setting of each peer per case.

Usage: bench/summarize_peers.py DIR [DIR ...]   (each holding run directories with bench_linear.csv)
"""
import csv
import os
import sys


def rows(top):
    for name in sorted(os.listdir(top)):
        path = os.path.join(top, name, "bench_linear.csv")
        if os.path.exists(path):
            with open(path) as f:
                for r in csv.DictReader(f):
                    r["run"] = name
                    yield r


def main():
    best = {}
    print("| run | example | vertices | solver | its | setup [s] | solve [s] | total [s] | / SA+PPCG |")
    print("|---|---|---:|---|---:|---:|---:|---:|---:|")
    for top in sys.argv[1:]:
        data = list(rows(top))
        sa = {(r["run"], r["example"], r["m"]): float(r["mean_total_s"]) for r in data if r["solver"] == "sa_ppcg"}
        for r in data:
            key = (r["run"], r["example"], r["m"])
            total = float(r["mean_total_s"])
            ratio = total / sa[key] if key in sa and r["solver"] != "sa_ppcg" else None
            fails = int(r["failures"])
            print(f"| {r['run']} | {r['example']} | {int(r['vertices']):,} | {r['solver']} | {float(r['mean_iterations']):.1f} | "
                  f"{float(r['mean_setup_s']):.3f} | {float(r['mean_solve_s']):.3f} | {total:.3f} | "
                  f"{'' if ratio is None else f'{ratio:.2f}x'}{' (failed)' if fails else ''} |")
            if ratio is not None and not fails:
                case = (r["example"], r["vertices"], r["solver"])
                if case not in best or ratio < best[case][0]:
                    best[case] = (ratio, r["run"])
    print()
    print("| example | vertices | peer | best run | its total / SA+PPCG's |")
    print("|---|---:|---|---|---:|")
    for (example, vertices, solver), (ratio, run) in sorted(best.items()):
        print(f"| {example} | {int(vertices):,} | {solver} | {run} | {ratio:.2f}x |")


if __name__ == "__main__":
    main()

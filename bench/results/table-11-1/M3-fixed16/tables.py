#!/usr/bin/env python3
"""Tables of M3-fixed16.md from the bench_linear.jsonl files of this directory.

For each case: iterations, what the solver owns, (A + own) / (A + Diag-PCG's own) and the
mean setup / solve / total seconds per solve, for the default (fixed16 prolongators) and
single-precision prolongators side by side, measured in the same run.

    python3 tables.py pinned/bench_linear.jsonl others/bench_linear.jsonl pinned1M/bench_linear.jsonl
"""
import json
import sys

FIXED, SINGLE, DIAG = "sa_ppcg", "sa_ppcg:prolongator_storage=single", "diag_pcg"


def cases(path):
    rows = {}
    for line in open(path):
        d = json.loads(line)
        if d.get("record") != "solver":
            continue
        c = d["case"]
        rows.setdefault((c["example"], c["tessellation"], c["vertices"]), {})[d["solver"]] = d
    return rows


def main(paths):
    print("| example | tessellation | vertices | iterations (both) | own fixed16 / single [MB] "
          "| ratio fixed16 | ratio single | total fixed16 / single [s] | Diag-PCG / fixed16 |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    for path in paths:
        for (ex, tess, n), s in sorted(cases(path).items()):
            f, g, d = s[FIXED], s[SINGLE], s[DIAG]
            it = f["mean_iterations"] if f["mean_iterations"] == g["mean_iterations"] else \
                f"{f['mean_iterations']:g} / {g['mean_iterations']:g}"
            ref = d["memory_with_matrix_bytes"]
            print(f"| {ex} | {tess} | {n:,} | {it:g} | {f['memory_bytes'] / 1e6:.1f} / {g['memory_bytes'] / 1e6:.1f} "
                  f"| **{f['memory_with_matrix_bytes'] / ref:.3f}** | {g['memory_with_matrix_bytes'] / ref:.3f} "
                  f"| {f['mean_total_s']:.3g} / {g['mean_total_s']:.3g} | {d['mean_total_s'] / f['mean_total_s']:.2f} |")


if __name__ == "__main__":
    main(sys.argv[1:])

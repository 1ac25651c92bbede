#!/usr/bin/env python3
"""Combine the runs of bench/table_11_1.sh into one report (Markdown on stdout).

Every speedup is a ratio of two solvers measured in the same run (same systems, same
minutes of a shared machine); runs are kept apart and named in each cell's source column.
Usage: bench/summarize_table_11_1.py [results directory]
"""
import csv
import math
import sys
from collections import defaultdict
from pathlib import Path

EXAMPLES = ["pinned", "drooping", "re-entrant", "dropHorizontal", "dropVertical"]
M = [30, 40, 60, 80, 100, 150, 200, 300, 400, 600, 800, 1000]
# Thesis Table 11.1 (methods/multigrid §10.3), regular tessellation: (vs Diag-PCG, vs PARDISO) per m and example.
THESIS_REGULAR = {
    30: [(0.39, 0.76), (0.58, 0.72), (0.55, 0.72), (0.57, 0.61), (0.53, 0.61)],
    40: [(0.45, 1.06), (0.63, 0.99), (0.60, 0.95), (0.57, 0.75), (0.51, 0.80)],
    60: [(0.40, 1.31), (0.50, 1.18), (0.54, 1.17), (0.62, 0.96), (0.35, 0.94)],
    80: [(0.43, 1.51), (0.53, 1.35), (0.50, 1.31), (0.65, 1.14), (0.35, 1.04)],
    100: [(0.54, 1.78), (0.66, 1.57), (0.72, 1.53), (0.77, 1.37), (0.40, 1.06)],
    150: [(0.85, 2.23), (1.03, 1.89), (1.02, 1.86), (1.07, 1.69), (0.50, 1.14)],
    200: [(1.07, 2.29), (1.35, 2.03), (1.36, 2.01), (1.40, 1.89), (0.60, 1.18)],
    300: [(2.23, 2.27), (2.87, 2.07), (2.67, 1.95), (2.27, 1.92), (2.35, 1.11)],
    400: [(3.89, 2.14), (5.01, 1.95), (4.87, 1.92), (3.64, 1.84), (1.14, 0.77)],
    600: [(5.48, 2.21), (7.10, 2.01), (6.38, 1.76), (4.70, 1.85), (2.29, 1.32)],
    800: [(7.12, 2.26), (9.28, 2.10), (8.84, 1.96), (6.09, 1.89), (3.46, 1.53)],
    1000: [(9.20, 2.40), (11.64, 2.20), (10.89, 2.04), (7.53, 2.13), (3.01, 1.80)],
}
THESIS_IRREGULAR = {
    30: [(0.43, 0.87), (0.49, 0.80), (0.51, 0.80), (0.52, 0.64), (0.56, 0.71)],
    100: [(0.56, 2.06), (0.61, 1.87), (0.67, 1.93), (0.89, 1.74), (0.53, 1.42)],
    200: [(1.22, 2.61), (1.19, 2.21), (1.43, 2.32), (1.33, 2.23), (0.76, 1.56)],
    300: [(2.32, 2.54), (2.51, 2.21), (2.36, 2.33), (2.20, 2.19), (1.29, 1.39)],
    400: [(3.78, 2.45), (4.20, 2.18), (4.22, 2.16), (3.26, 2.10), (2.03, 1.39)],
    600: [(5.32, 2.49), (5.98, 2.22), (6.13, 2.21), (4.63, 2.13), (2.63, 1.57)],
    800: [(7.02, 2.56), (7.84, 2.24), (7.72, 2.19), (5.93, 2.21), (2.39, 1.68)],
    1000: [(8.97, 2.73), (9.82, 2.56), (9.59, 2.47), (5.74, 2.08), (2.81, 1.71)],
}


def load(root):
    runs = {}
    for f in sorted(root.glob("*/bench_linear.csv")):
        rows = defaultdict(dict)
        with f.open() as fh:
            for r in csv.DictReader(fh):
                rows[(r["example"], r["tessellation"], int(r["m"]), int(r["vertices"]))][r["solver"]] = r
        runs[f.parent.name] = rows
    return runs


def total(r):
    return float(r["mean_total_s"])


def fmt_ratio(x):
    return "-" if x is None else f"{x:.2f}"


def main():
    root = Path(sys.argv[1] if len(sys.argv) > 1 else Path(__file__).parent / "results" / "table-11-1")
    runs = load(root)
    cells = defaultdict(dict)  # (tess, m, example) -> {"diag": (ratio, run), "direct": ..., "petsc": ...}
    details = []
    for run, rows in runs.items():
        for (ex, tess, m, n), solvers in rows.items():
            sa = solvers.get("sa_ppcg")
            if not sa or int(sa["failures"]) > 0:
                continue
            for key, other in (("diag", "diag_pcg"), ("direct", "cholmod"), ("petsc", "petsc_gamg"),
                               ("diag_ppcg", "diag_ppcg"), ("sa_mpcg", "sa_mpcg")):
                o = solvers.get(other)
                if o and int(o["failures"]) == 0:
                    cells[(tess, m, ex)][key] = (total(o) / total(sa), run)
            for name, r in solvers.items():
                details.append((ex, tess, n, run, name, r))

    print(f"# Thesis Table 11.1, reproduced ({root})\n")
    print("T(other) / T(SA+PPCG), T = mean setup + solve seconds per solve; thesis values in parentheses "
          "(vs Diag-PCG / vs PARDISO). Direct = CHOLMOD supernodal (OpenBLAS).\n")
    for tess, thesis in (("regular", THESIS_REGULAR), ("irregular", THESIS_IRREGULAR)):
        print(f"## {tess}\n")
        print("| m | vertices | " + " | ".join(EXAMPLES) + " |")
        print("|---|---|" + "---|" * len(EXAMPLES))
        for m in M:
            if not any((tess, m, ex) in cells for ex in EXAMPLES):
                continue
            n = (m + 1) ** 2
            row = []
            for k, ex in enumerate(EXAMPLES):
                c = cells.get((tess, m, ex), {})
                ours = f"{fmt_ratio(c.get('diag', (None,))[0])} / {fmt_ratio(c.get('direct', (None,))[0])}"
                th = thesis.get(m)
                row.append(ours + (f" ({th[k][0]:.2f} / {th[k][1]:.2f})" if th else ""))
            print(f"| {m} | {n} | " + " | ".join(row) + " |")
        print()
    peers = [(k, v) for k, v in sorted(cells.items()) if "petsc" in v or "diag_ppcg" in v or "sa_mpcg" in v]
    if peers:
        print("## Peers and ablation: T(other) / T(SA+PPCG)\n")
        print("| example | tessellation | m | PETSc GAMG | Diag+PPCG | SA+MPCG (no prefiltering) | Diag-PCG |")
        print("|---|---|---|---|---|---|---|")
        for (tess, m, ex), c in peers:
            g = lambda key: fmt_ratio(c.get(key, (None,))[0])
            print(f"| {ex} | {tess} | {m} | {g('petsc')} | {g('diag_ppcg')} | {g('sa_mpcg')} | {g('diag')} |")
        print()
    print("## Per solver\n")
    print("| example | tessellation | vertices | run | solver | solves | its | rate | setup [s] | solve [s] | "
          "energy error | memory [MB] | levels | op. cx | SpMV % of triad |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for ex, tess, n, run, name, r in sorted(details, key=lambda d: (d[1], EXAMPLES.index(d[0]), d[2], d[3], d[4])):
        err = float(r["mean_energy_error"])
        print(f"| {ex} | {tess} | {n} | {run} | {name} | {r['solves']} | {float(r['mean_iterations']):.1f} | "
              f"{float(r['mean_rate']):.3f} | {float(r['mean_setup_s']):.3g} | {float(r['mean_solve_s']):.3g} | "
              f"{'-' if err < 0 else f'{err:.1e}'} | {int(r['memory_bytes']) / 1e6:.0f} | {r['levels']} | "
              f"{float(r['operator_complexity']):.2f} | {float(r['spmv_pct_stream']):.0f} |")


if __name__ == "__main__":
    main()

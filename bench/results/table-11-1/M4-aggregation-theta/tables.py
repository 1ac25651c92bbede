#!/usr/bin/env python3
"""Tables of M4-aggregation-theta.md from the bench_linear.jsonl files of this directory.

Per case, for every SA+PPCG variant of the run: iterations, mean setup and solve seconds per
solve, T(Diag-PCG) / T(variant), T(CHOLMOD) / T(variant) (T = setup + solve, same run) and
memory (A + own) / (A + Diag-PCG's own). Variants are named by their solver key; "flat" is
`sa_ppcg:prolongator_degree=2:cycle_gamma=2:cycle_gamma_levels=2:theta=0.25:filter_scale=1.92`,
which is the `sa_ppcg_flat` preset (aggregation at 0.25, smoothing filter at 0.48) under the
keys of the binary these runs used.

    python3 tables.py campA/bench_linear.jsonl campB/bench_linear.jsonl x1M/bench_linear.jsonl
"""
import importlib.util
import sys
from pathlib import Path

# The JSONL reader of M3-fixed16/tables.py: {(example, tessellation, vertices): {solver: record}}.
_spec = importlib.util.spec_from_file_location("m3_tables", Path(__file__).resolve().parent.parent / "M3-fixed16" / "tables.py")
_m3 = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_m3)
cases = _m3.cases

FLAT = "sa_ppcg:prolongator_degree=2:cycle_gamma=2:cycle_gamma_levels=2:theta=0.25:filter_scale=1.92"
OLD = "sa_ppcg:prolongator_degree=2:cycle_gamma=2:cycle_gamma_levels=2:theta=0.25"
NAMES = {"sa_ppcg": "default", FLAT: "flat", "sa_ppcg_flat": "flat", OLD: "degree 2 + W, theta 0.25"}


def main(paths):
    print("| example | tessellation | vertices | variant | iterations | setup [s] | solve [s] "
          "| Diag-PCG / it | CHOLMOD / it | memory vs Diag-PCG |")
    print("|---|---|---:|---|---:|---:|---:|---:|---:|---:|")
    for path in paths:
        rows = cases(path)
        for (ex, tess, n), by in sorted(rows.items(), key=lambda kv: (kv[0][1], kv[0][0], kv[0][2])):
            diag, chol = by.get("diag_pcg"), by.get("cholmod")
            for key, d in by.items():
                if not key.startswith("sa_ppcg"):
                    continue
                t = d["mean_total_s"]
                vs_diag = f"{diag['mean_total_s'] / t:.2f}" if diag else "-"
                vs_chol = f"{chol['mean_total_s'] / t:.2f}" if chol else "-"
                mem = f"{d['memory_with_matrix_bytes'] / diag['memory_with_matrix_bytes']:.3f}" if diag else "-"
                print(f"| {ex} | {tess} | {n:,} | {NAMES.get(key, key)} | {d['mean_iterations']:.1f} "
                      f"| {d['mean_setup_s']:.3g} | {d['mean_solve_s']:.3g} | {vs_diag} | {vs_chol} | {mem} |")


if __name__ == "__main__":
    main(sys.argv[1:])

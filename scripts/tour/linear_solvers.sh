#!/usr/bin/env bash
# Tour, linear solvers (docs/tour/linear-solvers.md): Diag-PCG (conjugate gradients with a
# 3x3 block-Jacobi preconditioner, Baraff-Witkin's modified PCG) against SA+PPCG (smoothed-
# aggregation multigrid preconditioning prefiltered PCG, thesis ch. 11) as the mesh grows.
#
#   scripts/tour/linear_solvers.sh [--quick] [OUT_DIR]   (default OUT_DIR: out/tour/linear-solvers)
#
# `weft bench linear` on the thesis' "pinned" example (a 1 m x 1 m cotton-like sheet pinned at
# two corners, regular tessellation, dt = 2 ms, one Baraff-Witkin step = one solve per step):
# both solvers solve the same system every step, to the thesis' tolerance (relative M^-1-norm
# residual 1e-5). Sizes m = 30 60 100 150 200 300 ((m+1)^2 = 961 ... 90601 vertices), 5 steps each;
# --quick: m = 20 40 (441, 1681 vertices), 2 steps. -> bench/bench_linear.{csv,jsonl,md},
# scaling.{png,svg} (iterations and time per solve against vertices; scripts/weft_plot.py
# scaling), summary.md and summary.json (scripts/tour/tour_summary.py).
# Environment: WEFT (default build/release/apps/weft), TOUR_QUICK=1 (same as --quick),
# THREADS (OpenMP threads, default 1: times on a shared 2-core machine are steadier with one).
set -euo pipefail
# shellcheck source=scripts/tour/common.sh
source "$(dirname "$0")/common.sh"
tour_init linear_solvers.sh linear-solvers 16 "$@"
mkdir -p "$OUT/bench"
THREADS=${THREADS:-1}
if [ "$QUICK" = 1 ]; then size_args=(--quick --sizes 20 40); else size_args=(--sizes 30 60 100 150 200 300 --steps 5); fi
tour_started "threads=$THREADS"
"$WEFT" bench linear --examples pinned --tessellations regular "${size_args[@]}" --solvers diag_pcg sa_ppcg \
  --threads "$THREADS" --out "$OUT/bench" > "$OUT/bench/report.md" 2> "$OUT/bench.log" || {
  rc=$?; cat "$OUT/bench.log" >&2; echo "linear_solvers.sh: weft bench linear exited with $rc" >&2; exit "$rc"; }
cat "$OUT/bench.log"
tour_finished
/usr/bin/python3 scripts/tour/tour_summary.py linear "$OUT"

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
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
QUICK=${TOUR_QUICK:-0}
OUT=""
for a in "$@"; do
  case "$a" in
    --quick) QUICK=1 ;;
    -h|--help) sed -n '2,16p' "$0"; exit 0 ;;
    -*) echo "linear_solvers.sh: unknown option $a (usage: linear_solvers.sh [--quick] [OUT_DIR])" >&2; exit 2 ;;
    *) OUT=$a ;;
  esac
done
OUT=${OUT:-$ROOT/out/tour/linear-solvers}
WEFT=${WEFT:-$ROOT/build/release/apps/weft}
case "$OUT" in /*) ;; *) OUT=$PWD/$OUT ;; esac   # paths as given, from the caller's directory
case "$WEFT" in /*) ;; *) WEFT=$PWD/$WEFT ;; esac
cd "$ROOT"
THREADS=${THREADS:-1}
[ -x "$WEFT" ] || { echo "linear_solvers.sh: no weft binary at $WEFT (build it with scripts/setup.sh, or set WEFT)" >&2; exit 2; }
if [ -d "$OUT" ] && [ -n "$(ls -A "$OUT")" ] && ! grep -qs "^started" "$OUT/info.txt"; then
  echo "linear_solvers.sh: $OUT is not empty and not an output of this script: give a new or empty directory" >&2; exit 2
fi
rm -rf "$OUT"  # an earlier output of this script (its info.txt says so)
mkdir -p "$OUT/bench"
if [ "$QUICK" = 1 ]; then size_args=(--quick --sizes 20 40); else size_args=(--sizes 30 60 100 150 200 300 --steps 5); fi
echo "started $(date -u +%FT%TZ); $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), $(nproc --all) CPUs; weft $WEFT; quick=$QUICK; threads=$THREADS" > "$OUT/info.txt"
"$WEFT" bench linear --examples pinned --tessellations regular "${size_args[@]}" --solvers diag_pcg sa_ppcg \
  --threads "$THREADS" --out "$OUT/bench" > "$OUT/bench/report.md" 2> "$OUT/bench.log" || {
  rc=$?; cat "$OUT/bench.log" >&2; echo "linear_solvers.sh: weft bench linear exited with $rc" >&2; exit "$rc"; }
cat "$OUT/bench.log"
echo "finished $(date -u +%FT%TZ)" >> "$OUT/info.txt"
/usr/bin/python3 scripts/tour/tour_summary.py linear "$OUT"

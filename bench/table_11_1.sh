#!/usr/bin/env bash
# Reproduce thesis Table 11.1 (spec 04 §10.3) with `weft bench linear`, in runs that fit a
# 24 GiB, 2-core machine in about 75 minutes. Every run compares its solvers on the same
# systems, so each speedup is a ratio measured within one run. SA+PPCG is in every run.
#   A  five examples, regular, 961 .. 361,201 vertices: CHOLMOD, Diag-PCG, SA+PPCG, PETSc GAMG
#   B  pinned, regular, 641,601 and 1,002,001 vertices, in two runs because CHOLMOD's factor
#      (~12 GB at 1M) and PETSc's copy do not fit in 24 GiB together with the assembly
#   C  five examples, irregular, 961 .. 90,601 vertices
#   D  the prefiltering ablation of thesis Fig. 11.8 on dropHorizontal (Diag-PCG, Diag+PPCG,
#      SA+MPCG, SA+PPCG), 961 .. 160,801 vertices
# Needs the back ends: cmake --preset backends && cmake --build --preset backends --target weft
# Usage: bench/table_11_1.sh [weft binary] [output directory]
set -euo pipefail
cd "$(dirname "$0")/.."
WEFT="${1:-build/backends/apps/weft}"
OUT="${2:-bench/results/table-11-1}"
mkdir -p "$OUT"
common=(bench linear --step-budget 5e5)
small=(30 40 60 80 100 150 200 300 400 600)
"$WEFT" "${common[@]}" --tessellations regular --sizes "${small[@]}" \
  --solvers cholmod diag_pcg sa_ppcg petsc_gamg --out "$OUT/A-regular" > "$OUT/A-regular.md"
"$WEFT" "${common[@]}" --examples pinned --tessellations regular --sizes 800 1000 \
  --solvers cholmod sa_ppcg --out "$OUT/B1-pinned-1M-direct" > "$OUT/B1-pinned-1M-direct.md"
"$WEFT" "${common[@]}" --examples pinned --tessellations regular --sizes 800 1000 \
  --solvers diag_pcg sa_ppcg petsc_gamg --out "$OUT/B2-pinned-1M-iterative" > "$OUT/B2-pinned-1M-iterative.md"
"$WEFT" "${common[@]}" --tessellations irregular --sizes 30 40 60 80 100 150 200 300 \
  --solvers cholmod diag_pcg sa_ppcg petsc_gamg --out "$OUT/C-irregular" > "$OUT/C-irregular.md"
"$WEFT" "${common[@]}" --examples dropHorizontal --tessellations regular --sizes 30 60 100 200 300 400 \
  --solvers diag_pcg diag_ppcg sa_mpcg sa_ppcg --out "$OUT/D-ablation" > "$OUT/D-ablation.md"

#!/usr/bin/env bash
# Tune the PETSc peers of `weft bench linear` (GAMG, hypre BoomerAMG, Trilinos ML) before they
# are compared with SA+PPCG: each run takes one setting of every peer through PETSC_OPTIONS
# (an option of one preconditioner is ignored by the others) and runs SA+PPCG beside them, so
# every ratio is measured within one run. Needs the back ends:
#   cmake --preset backends && cmake --build --preset backends --target weft
# Usage: bench/peers_sweep.sh [weft binary] [output directory] [m ...]   (default m: 300)
set -euo pipefail
cd "$(dirname "$0")/.."
WEFT="${1:-build/backends/apps/weft}"
OUT="${2:-bench/results/peers/sweep}"
shift 2 2>/dev/null || shift $#
SIZES=("${@:-300}")
mkdir -p "$OUT"
# name | BoomerAMG | GAMG | ML
SETTINGS=(
  "s0|||"
  "s1|-pc_hypre_boomeramg_strong_threshold 0.5|-pc_gamg_threshold 0.01|-pc_ml_Threshold 0.01"
  "s2|-pc_hypre_boomeramg_strong_threshold 0.7|-pc_gamg_threshold 0.05|-pc_ml_Threshold 0.05"
  "s3|-pc_hypre_boomeramg_coarsen_type HMIS -pc_hypre_boomeramg_interp_type ext+i|-pc_gamg_agg_nsmooths 0|-pc_ml_maxCoarseSize 500"
  "s4|-pc_hypre_boomeramg_coarsen_type PMIS -pc_hypre_boomeramg_interp_type ext+i -pc_hypre_boomeramg_agg_nl 1|-mg_levels_ksp_max_it 1|-mg_levels_ksp_max_it 1"
  "s5|-pc_hypre_boomeramg_nodal_coarsen 4|-mg_levels_ksp_max_it 4|-mg_levels_ksp_max_it 4"
  "s6|-pc_hypre_boomeramg_nodal_coarsen 4 -pc_hypre_boomeramg_vec_interp_variant 2|-pc_gamg_threshold 0.01 -mg_levels_ksp_max_it 1|-pc_ml_Threshold 0.01 -mg_levels_ksp_max_it 1"
  # Round 2: the best single changes of round 1 together (GAMG and ML share -mg_levels_ksp_max_it).
  "t1|-pc_hypre_boomeramg_coarsen_type PMIS -pc_hypre_boomeramg_interp_type ext+i -pc_hypre_boomeramg_agg_nl 1 -pc_hypre_boomeramg_strong_threshold 0.5|-pc_gamg_agg_nsmooths 0 -mg_levels_ksp_max_it 1|-mg_levels_ksp_max_it 1 -pc_ml_maxCoarseSize 500"
  "t2|-pc_hypre_boomeramg_coarsen_type PMIS -pc_hypre_boomeramg_interp_type ext+i -pc_hypre_boomeramg_agg_nl 1 -pc_hypre_boomeramg_P_max 4|-pc_gamg_agg_nsmooths 0 -pc_gamg_threshold 0.01 -mg_levels_ksp_max_it 1|-pc_ml_Threshold 0.01 -mg_levels_ksp_max_it 1 -pc_ml_maxCoarseSize 500"
  "t3|-pc_hypre_boomeramg_coarsen_type HMIS -pc_hypre_boomeramg_interp_type ext+i -pc_hypre_boomeramg_agg_nl 1 -pc_hypre_boomeramg_P_max 4|-pc_gamg_agg_nsmooths 0|-pc_ml_Threshold 0.01"
)
prefixed() {  # "-a 1 -b" -> "-weft_a 1 -weft_b"
  local out="" t
  for t in $1; do
    if [[ $t == -* ]]; then out+=" -weft_${t#-}"; else out+=" $t"; fi
  done
  echo "$out"
}
for entry in "${SETTINGS[@]}"; do
  IFS='|' read -r name boomer gamg ml <<< "$entry"
  dir="$OUT/$name"
  if [ -f "$dir/bench_linear.csv" ]; then echo "peers_sweep: $name done"; continue; fi
  echo "peers_sweep: $name: BoomerAMG '$boomer', GAMG '$gamg', ML '$ml'"
  PETSC_OPTIONS="$(prefixed "$boomer") $(prefixed "$gamg") $(prefixed "$ml")" \
    "$WEFT" bench linear --examples pinned dropHorizontal --tessellations regular --sizes "${SIZES[@]}" --steps 2 --threads 1 \
    --solvers sa_ppcg petsc_gamg petsc_boomeramg petsc_ml --out "$dir" > /dev/null
done

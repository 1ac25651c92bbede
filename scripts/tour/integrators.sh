#!/usr/bin/env bash
# Tour, integrators (docs/tour/integrators.md): backward Euler solved as root finding on the
# residual (cloth_root_direct) against minimisation of the incremental potential
# (cloth_ip_direct), on the folded hinge of thesis §6.5 (methods/integration-and-contact E2).
#
#   scripts/tour/integrators.sh [--quick] [OUT_DIR]      (default OUT_DIR: out/tour/integrators)
#
# 1. Newton iterations of the hinge's first step at dt = 1/240, 5/240, 10/240 s for three ways
#    of solving the same equation: incremental potential (backtracking on E_inc, the default),
#    root finding (backtracking on |f|^2/2) and pure Newton (full steps, exact Hessian), with a
#    generous iteration limit (10000; --quick: 2000). -> first_step.csv, histories.jsonl and
#    histories.{png,svg} (the residual of every first step, scripts/weft_plot.py histories).
# 2. `weft stability` on the hinge: dt x Young's modulus (1e6, 1e8, 1e11 Pa), both
#    combinations at the default limit of 100 Newton iterations per step -> hinge_map/.
# 3. (not with --quick) the same map on the hanging cloth at 11 x 11 vertices, 1 s -> cloth_map/.
# 4. The work-precision diagram: `weft ablate --sweep time.dt=...` of both combinations on the
#    hanging cloth at 11 x 11 vertices, 0.5 s (--quick: 7 x 7, 0.25 s), error against run time
#    -> work_precision/ (ablate.csv, pareto.{png,svg}).
# Then scripts/tour/tour_summary.py writes summary.md and summary.json.
# Environment: WEFT (default build/release/apps/weft), TOUR_QUICK=1 (same as --quick).
set -euo pipefail
set -f  # overrides hold brackets: no globbing
# shellcheck source=scripts/tour/common.sh
source "$(dirname "$0")/common.sh"
tour_init integrators.sh integrators 20 "$@"
mkdir -p "$OUT/runs"
export OMP_NUM_THREADS=1  # 4 and 121 vertices: threads only wait for each other, worst on a loaded machine
MAXIT=10000
[ "$QUICK" = 1 ] && MAXIT=2000
DTS="0.004166666666666667 0.020833333333333332 0.041666666666666664"  # 1/240, 5/240, 10/240 s
FRAME=0.041666666666666664                                             # one frame at 24 frames/s
tour_started

# 1. first steps. variant|combination and overrides
variants=(
  "incremental_potential|combo=cloth_ip_direct"
  "root_finding|combo=cloth_root_direct"
  "pure_newton|combo=cloth_ip_direct integrator.line_search=full_step integrator.hessian=exact"
)
: > "$OUT/runs.txt"
for v in "${variants[@]}"; do
  name=${v%%|*}; ov=${v#*|}
  for dt in $DTS; do
    dir="$OUT/runs/${name}_dt$dt"
    t0=$EPOCHREALTIME
    rc=0
    # shellcheck disable=SC2086
    "$WEFT" run scenes/hinge.json $ov time.dt=$dt time.duration=$FRAME time.frame_rate=24 \
      integrator.max_iterations=$MAXIT --out "$dir" -q > "$dir.log" 2>&1 || rc=$?
    echo "$name $dt $rc $dir $t0 $EPOCHREALTIME" >> "$OUT/runs.txt"
    echo "first step: $name dt=$dt exit $rc"
  done
done

# 2. and 3. stability maps (weft stability draws stability_map.{png,svg} itself)
# shellcheck disable=SC2086  # DTS is a list
"$WEFT" stability scenes/hinge.json --duration 0.25 --vary cloths.0.material.youngs_modulus=1e6,1e8,1e11 \
  --combos cloth_ip_direct cloth_root_direct --dt $DTS -o "$OUT/hinge_map" -q
if [ "$QUICK" != 1 ]; then
  # shellcheck disable=SC2086
  "$WEFT" stability scenes/hanging_cloth.json 'cloths.0.mesh.resolution=[11,11]' --duration 1 \
    --vary cloths.0.material.youngs_modulus=1e6,1e8,1e11 --combos cloth_ip_direct cloth_root_direct --dt $DTS \
    -o "$OUT/cloth_map" -q
fi
# 4. work-precision diagram: frame / 2, 4, 8, 16
WP_RES="[11,11]"; WP_T=0.5
[ "$QUICK" = 1 ] && WP_RES="[7,7]" && WP_T=0.25
"$WEFT" ablate scenes/hanging_cloth.json "cloths.0.mesh.resolution=$WP_RES" --combos cloth_ip_direct cloth_root_direct \
  --sweep time.dt=0.020833333333333332,0.010416666666666666,0.005208333333333333,0.0026041666666666665 \
  --duration "$WP_T" -o "$OUT/work_precision" -q > "$OUT/work_precision.log" 2>&1
tour_finished
/usr/bin/python3 scripts/tour/tour_summary.py integrators "$OUT"

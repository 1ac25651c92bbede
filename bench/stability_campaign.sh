#!/usr/bin/env bash
# The stability study of the integrator issue: every integrator (and the minimisation's
# globalisations) on the hinge, the hanging cloth, a stiff beam and a folded sheet, over
# dt up to one frame against Young's modulus, mass density or thickness. Writes one
# directory per grid under ${OUT:-out/stability}; summary.txt collects the maps.
set -euo pipefail
cd "$(dirname "$0")/.."
WEFT=${WEFT:-build/release/apps/weft}
OUT=${OUT:-out/stability}
mkdir -p "$OUT"
DTS="0.004166666666666667 0.020833333333333332 0.041666666666666664"
# name|overrides (positional, before the list options)|combination
variants=(
  "ip_adaptive||cloth_ip_direct"
  "ip_trust_region|integrator.globalization=trust_region integrator.trust_radius=1e-3|cloth_ip_direct"
  "ip_projected|integrator.hessian=projected|cloth_ip_direct"
  "ip_pure_newton|integrator.line_search=full_step integrator.hessian=exact|cloth_ip_direct"
  "root||cloth_root_direct"
  "lie||cloth_lie_direct"
)
grids=(
  "hinge_Y|scenes/hinge.json --duration 0.25 --vary cloths.0.material.youngs_modulus=1e6,1e8,1e11"
  "cloth_Y|scenes/hanging_cloth.json cloths.0.mesh.resolution=[11,11] --duration 1 --vary cloths.0.material.youngs_modulus=1e6,1e8,1e11"
  "cloth_density|scenes/hanging_cloth.json cloths.0.mesh.resolution=[11,11] --duration 1 --vary cloths.0.material.density=0.01,0.15,1.0"
  "beam_thickness|scenes/beam_16mm.json --duration 0.5 --vary cloths.0.material.thickness=0.001,0.004,0.016"
  "folded_Y|scenes/folded_sheet.json --duration 0.5 --vary cloths.0.material.youngs_modulus=1e6,1e8,1e11"
)
: > "$OUT/summary.txt"
for g in "${grids[@]}"; do
  gname=${g%%|*}; gargs=${g#*|}
  for v in "${variants[@]}"; do
    vname=${v%%|*}; rest=${v#*|}; vover=${rest%%|*}; vcombo=${rest#*|}
    if [ -n "${ONLY:-}" ] && [[ "$vname" != $ONLY ]]; then continue; fi
    # shellcheck disable=SC2086
    $WEFT stability $gargs $vover --combos "$vcombo" --dt $DTS -o "$OUT/${gname}_${vname}" -q > "$OUT/${gname}_${vname}.txt" 2>&1 || true
    { echo "== $gname / $vname"; cat "$OUT/${gname}_${vname}.txt"; } >> "$OUT/summary.txt"
  done
done
echo "maps in $OUT/summary.txt"

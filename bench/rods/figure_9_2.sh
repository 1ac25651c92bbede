#!/usr/bin/env bash
# Figure 9.2 of the thesis (methods/rod-contact §14.1, V-20): the whip-it stability sweep. `weft stability`
# on scenes/whip.json over the time step (5 us to 100 ms, 1-2-5 per decade: 14 steps) against
# the whipping speed (the handle's angular velocity about z, default 1, 3, 10, 20 rad/s) for
# the three response methods (impulses, linear compliance, ADONIS). A run succeeds when it
# completes the simulated time with no edge stretched beyond 50 % (and no failed step); each
# cell is classified stable / diverged / not converged / excessive strain.
#
# Scaled down, and why:
#   - DURATION (default 1 s, thesis 5 s): the 5 us column alone is 200,000 steps per second
#     simulated at about 2-3 ms per step on the shared 2-vCPU machine. Every speed meets the
#     wall within the first second (the handle starts 0.3 rad before it).
#   - EXTRA, overrides of the scene (default: START and gravity=[0,0,0]):
#     START turns the handle's start 0.3 rad (17 degrees) back from the wall: in
#     scenes/whip.json the rod starts along +x with its outer 4 cm inside the wall (x from
#     0.21 m, |y| < 2.5 mm), and at 1 rad/s it would meet the wall again only after a turn.
#     Gravity off: with gravity a 20 cm hair whirled at omega hangs at an angle
#     atan(omega^2 r / g) from the vertical, below the reach of the wall's edge at 1-3 rad/s
#     (omega^2 r < g): those columns would never touch the wall. Without gravity the whip
#     turns in the wall's plane. EXTRA="" runs the scene as it is.
#   - Two passes: "large" (100 us to 100 ms, minutes) and "small" (5 to 50 us, hours); the
#     summary counts a step as stable only if every smaller step that was run is stable, and
#     says which cells were not run yet. PASSES="large" runs the first only.
# Results: $OUT/runs/<pass>_<combo>/stability.csv (one row per run, written as it finishes),
# then bench/rods/figure_9_2.py merges them into $OUT/stability.csv, $OUT/stability_map.txt
# and $OUT/summary.md (largest stable step per method and speed, ADONIS/linear and
# ADONIS/impulse ratios, the thesis result alongside, the hardware). Re-run the .py alone to
# harvest a sweep still running.
#
#   bench/rods/figure_9_2.sh                       # everything, two runs at a time
#   PASSES=large bench/rods/figure_9_2.sh          # the 100 us - 100 ms part only
#   nohup bench/rods/figure_9_2.sh > bench/results/rods/figure_9_2/console.txt 2>&1 &
set -euo pipefail
set -f  # the overrides hold brackets: no globbing
cd "$(dirname "$0")/../.."
WEFT=${WEFT:-build/release/apps/weft}
OUT=${OUT:-bench/results/rods/figure_9_2}
DURATION=${DURATION:-1}
SPEEDS=${SPEEDS:-1,3,10,20}
COMBOS=${COMBOS:-rods_impulse rods_linear rods_adonis}
PASSES=${PASSES:-large small}
JOBS=${JOBS:-2}
START="rods.0.root=[0.0477668,-0.0147760,0] rods.0.direction=[0.9553365,-0.2955202,0]"  # (5 cm, 0, 0) and +x turned by -0.3 rad about z
EXTRA=${EXTRA-$START gravity=[0,0,0]}
export OMP_NUM_THREADS=1  # one rod: no parallelism inside a run; JOBS runs side by side
DTS_large="0.1 0.05 0.02 0.01 0.005 0.002 0.001 0.0005 0.0002 0.0001"
DTS_small="5e-05 2e-05 1e-05 5e-06"
mkdir -p "$OUT/runs"
{
  echo "started $(date -u +%FT%TZ) on $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), $(nproc --all) vCPUs (shared with 3 other workers)"
  echo "weft: $WEFT ($(git rev-parse --short HEAD 2>/dev/null || echo '?') + working tree)"
  echo "scene: scenes/whip.json $EXTRA; duration $DURATION s; speeds $SPEEDS rad/s; combos $COMBOS; passes $PASSES; $JOBS runs at a time"
} > "$OUT/sweep_info.txt"
jobs_list=()
for pass in $PASSES; do
  for c in $COMBOS; do jobs_list+=("$pass $c"); done
done
run_one() {
  set -f
  local pass=$1 combo=$2 dts_var="DTS_$1"
  local dir="$OUT/runs/${pass}_${combo}"
  local t0=$SECONDS
  # shellcheck disable=SC2086
  "$WEFT" stability scenes/whip.json $EXTRA --dt ${!dts_var} --vary "rods.0.motion.angular_velocity.2=$SPEEDS" \
    --combos "$combo" --duration "$DURATION" -o "$dir" > "$dir.log" 2>&1 || echo "weft stability exited with $?" >> "$dir.log"
  echo "$pass $combo done in $((SECONDS - t0)) s" >> "$OUT/sweep_info.txt"
}
export -f run_one
export WEFT OUT DURATION SPEEDS EXTRA DTS_large DTS_small
printf '%s\n' "${jobs_list[@]}" | xargs -P "$JOBS" -L 1 bash -c 'run_one "$0" "$1"'
echo "finished $(date -u +%FT%TZ)" >> "$OUT/sweep_info.txt"
python3 bench/rods/figure_9_2.py "$OUT"

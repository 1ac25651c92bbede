#!/usr/bin/env bash
# Tour, contact (docs/tour/contact.md): impulses, linear compliance and ADONIS on the whip of
# thesis §9.1 (Figure 9.2, methods/rod-contact V-20): a rotating handle whips a thin elastic rod against
# the edge of a wall, again and again.
#
#   scripts/tour/contact.sh [--quick] [OUT_DIR]          (default OUT_DIR: out/tour/contact)
#
# `weft stability` on scenes/whip.json, set up as bench/rods/figure_9_2.sh does (no gravity,
# the handle starting 0.3 rad before the wall), for rods_impulse, rods_linear and rods_adonis:
# time steps 100 ms ... 0.5 ms against the handle's speed 1, 3, 10 and 20 rad/s, 1 s simulated; a run
# is stable when it completes with no failed step and no edge stretched beyond 50 %.
# --quick: 20 rad/s only, steps 50 10 2 0.5 ms, 0.5 s simulated (the whip first meets the wall at about 0.35 s).
# -> stability.csv, stability_map.{txt,png,svg} (drawn by weft stability), summary.md and
# summary.json (scripts/tour/tour_summary.py): the largest stable step h* per method and speed
# (every smaller step of the sweep stable too), and h* counting only runs that touched the wall
# (the steps in contact come from stability.csv's contact_steps).
# Then the work-precision diagram of the three at 20 rad/s: `weft ablate --sweep time.dt=...`
# (10 to 0.5 ms; --quick: 10 to 2 ms), 0.5 s, all against ADONIS at 0.125 ms, error against
# run time -> work_precision/ (ablate.csv with the contacts per run, pareto.{png,svg}).
# Environment: WEFT (default build/release/apps/weft), TOUR_QUICK=1 (same as --quick).
set -euo pipefail
set -f  # the overrides hold brackets: no globbing
# shellcheck source=scripts/tour/common.sh
source "$(dirname "$0")/common.sh"
tour_init contact.sh contact 20 "$@"
# (5 cm, 0, 0) and +x turned by -0.3 rad about z: the rod starts outside the wall; no gravity
SETUP="rods.0.root=[0.0477668,-0.0147760,0] rods.0.direction=[0.9553365,-0.2955202,0] gravity=[0,0,0]"
if [ "$QUICK" = 1 ]; then
  SPEEDS=20; DTS="0.05 0.01 0.002 0.0005"; DURATION=0.5; WP_DTS=0.01,0.005,0.002
else
  SPEEDS=1,3,10,20; DTS="0.1 0.05 0.02 0.01 0.005 0.002 0.001 0.0005"; DURATION=1; WP_DTS=0.01,0.005,0.002,0.001,0.0005
fi
export OMP_NUM_THREADS=1  # one rod: nothing to share between threads
tour_started "speeds $SPEEDS rad/s; dt $DTS s; duration $DURATION s"
# shellcheck disable=SC2086
"$WEFT" stability scenes/whip.json $SETUP --dt $DTS --vary "rods.0.motion.angular_velocity.2=$SPEEDS" \
  --combos rods_impulse rods_linear rods_adonis --duration "$DURATION" -o "$OUT" -q
# shellcheck disable=SC2086
"$WEFT" ablate scenes/whip.json $SETUP rods.0.motion.angular_velocity.2=20 --combos rods_impulse rods_linear rods_adonis \
  --reference rods_adonis --sweep "time.dt=$WP_DTS" --duration 0.5 -o "$OUT/work_precision" -q > "$OUT/work_precision.log" 2>&1
tour_finished
# stability.csv's contact_steps tells a run that met the wall from one that never reached it
/usr/bin/python3 scripts/tour/tour_summary.py contact "$OUT"

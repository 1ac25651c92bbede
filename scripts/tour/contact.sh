#!/usr/bin/env bash
# Tour, contact (docs/tour/contact.md): impulses, linear compliance and ADONIS on the whip of
# thesis §9.1 (Figure 9.2, spec 03 V-20): a rotating handle whips a thin elastic rod against
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
# Environment: WEFT (default build/release/apps/weft), TOUR_QUICK=1 (same as --quick).
set -euo pipefail
set -f  # the overrides hold brackets: no globbing
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
QUICK=${TOUR_QUICK:-0}
OUT=""
for a in "$@"; do
  case "$a" in
    --quick) QUICK=1 ;;
    -h|--help) sed -n '2,17p' "$0"; exit 0 ;;
    -*) echo "contact.sh: unknown option $a (usage: contact.sh [--quick] [OUT_DIR])" >&2; exit 2 ;;
    *) OUT=$a ;;
  esac
done
OUT=${OUT:-$ROOT/out/tour/contact}
WEFT=${WEFT:-$ROOT/build/release/apps/weft}
case "$OUT" in /*) ;; *) OUT=$PWD/$OUT ;; esac   # paths as given, from the caller's directory
case "$WEFT" in /*) ;; *) WEFT=$PWD/$WEFT ;; esac
cd "$ROOT"
[ -x "$WEFT" ] || { echo "contact.sh: no weft binary at $WEFT (build it with scripts/setup.sh, or set WEFT)" >&2; exit 2; }
if [ -d "$OUT" ] && [ -n "$(ls -A "$OUT")" ] && ! grep -qs "^started" "$OUT/info.txt"; then
  echo "contact.sh: $OUT is not empty and not an output of this script: give a new or empty directory" >&2; exit 2
fi
rm -rf "$OUT"  # an earlier output of this script (its info.txt says so)
mkdir -p "$OUT"
# (5 cm, 0, 0) and +x turned by -0.3 rad about z: the rod starts outside the wall; no gravity
SETUP="rods.0.root=[0.0477668,-0.0147760,0] rods.0.direction=[0.9553365,-0.2955202,0] gravity=[0,0,0]"
if [ "$QUICK" = 1 ]; then
  SPEEDS=20; DTS="0.05 0.01 0.002 0.0005"; DURATION=0.5
else
  SPEEDS=1,3,10,20; DTS="0.1 0.05 0.02 0.01 0.005 0.002 0.001 0.0005"; DURATION=1
fi
export OMP_NUM_THREADS=1  # one rod: nothing to share between threads
echo "started $(date -u +%FT%TZ); $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), $(nproc --all) CPUs; weft $WEFT; quick=$QUICK; speeds $SPEEDS rad/s; dt $DTS s; duration $DURATION s" > "$OUT/info.txt"
# shellcheck disable=SC2086
"$WEFT" stability scenes/whip.json $SETUP --dt $DTS --vary "rods.0.motion.angular_velocity.2=$SPEEDS" \
  --combos rods_impulse rods_linear rods_adonis --duration "$DURATION" -o "$OUT" -q
echo "finished $(date -u +%FT%TZ)" >> "$OUT/info.txt"
# stability.csv's contact_steps tells a run that met the wall from one that never reached it
# (tour_summary.py re-runs the stable cells with `weft run` only for a CSV without that column)
# shellcheck disable=SC2086  # SETUP is a list of overrides
/usr/bin/python3 - "$OUT/setup.json" "$DURATION" $SETUP <<'PY'
import json, sys
json.dump({"scene": "scenes/whip.json", "duration": float(sys.argv[2]), "overrides": sys.argv[3:],
           "vary_key": "rods.0.motion.angular_velocity.2"}, open(sys.argv[1], "w"), indent=2)
PY
/usr/bin/python3 scripts/tour/tour_summary.py contact "$OUT" --weft "$WEFT"

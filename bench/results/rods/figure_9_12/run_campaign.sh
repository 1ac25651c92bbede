#!/bin/sh
# The Figure 9.12 campaign at 1000 rods, scaled to a 2-vCPU machine shared with other jobs:
# the first rotation (pi rad/s about x) moved to 0.10-0.25 s, 0.3 s simulated per run, so
# every run covers a rotation start and stop and 50 ms after it. Resumable: rerun with the
# same arguments plus --resume to skip the runs bench_hair.csv already holds. OMP_NUM_THREADS
# (default 2) sets the threads; WEFT the binary.
cd "$(dirname "$0")/../../../.."
exec env OMP_NUM_THREADS="${OMP_NUM_THREADS:-2}" "${WEFT:-build/h_hair/apps/weft}" bench hair scenes/hairball_1000.json \
  rods.0.motion.phases.0.start=0.1 rods.0.motion.phases.0.end=0.25 \
  obstacles.0.motion.phases.0.start=0.1 obstacles.0.motion.phases.0.end=0.25 \
  --duration 0.3 --out bench/results/rods/figure_9_12 "$@"

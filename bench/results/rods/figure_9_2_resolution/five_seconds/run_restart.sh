#!/bin/sh
. bench/results/rods/figure_9_2_resolution/five_seconds/common.sh
for V in 30 60 120; do common rods.0.vertices=$V --combos rods_adonis -o bench/results/rods/figure_9_2_resolution/five_seconds/v${V}_restart; done

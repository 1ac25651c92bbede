#!/bin/sh
# overlap_follow (the default since it landed): end-overlap contacts follow their edge pair.
# Linear compliance and ADONIS (exact re-linearisations with the projected restart, and
# projected re-linearisations) at 30, 60 and 120 vertices over 5 s.
. bench/results/rods/figure_9_2_resolution/five_seconds/common.sh
O=bench/results/rods/figure_9_2_resolution/five_seconds
for V in 30 60 120; do
  common rods.0.vertices=$V --combos rods_linear rods_adonis -o $O/v${V}_follow
  common rods.0.vertices=$V contact.relinearization=projected --combos rods_adonis -o $O/v${V}_follow_projected
done

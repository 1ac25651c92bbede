#!/bin/sh
. bench/results/rods/figure_9_2_resolution/five_seconds/common.sh
common rods.0.vertices=30 contact.relinearization=projected --combos rods_adonis -o bench/results/rods/figure_9_2_resolution/five_seconds/v30_projected
common rods.0.vertices=60 --combos rods_linear rods_adonis -o bench/results/rods/figure_9_2_resolution/five_seconds/v60
common rods.0.vertices=60 contact.relinearization=projected --combos rods_adonis -o bench/results/rods/figure_9_2_resolution/five_seconds/v60_projected

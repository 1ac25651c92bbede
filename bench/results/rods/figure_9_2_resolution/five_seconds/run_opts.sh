#!/bin/sh
for OPT in contact.limit_stretch=true contact.relinearization=projected; do
  N=$(echo $OPT | cut -d. -f2 | cut -d= -f1)
  OMP_NUM_THREADS=1 /tmp/weft_stab stability /work/main/scenes/whip.json "rods.0.root=[0.0477668,-0.0147760,0]" \
    "rods.0.direction=[0.9553365,-0.2955202,0]" "gravity=[0,0,0]" "obstacles.0.center=[0.17,0,0]" \
    rods.0.vertices=120 contact.redetections=20 integrator.max_iterations=200 $OPT \
    --dt 0.05 0.02 0.01 0.005 0.002 0.001 0.0005 0.0002 \
    --vary "rods.0.motion.angular_velocity.2=10,20" --combos rods_adonis \
    --duration 5 -o v120_$N   # v120_limit_stretch, v120_relinearization (renamed v120_projected)
done

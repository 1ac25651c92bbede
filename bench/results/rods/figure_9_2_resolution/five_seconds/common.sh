# Sourced by run_60.sh and run_restart.sh: the near-wall whip's 5 s sweep (run from the
# repository root; WEFT selects the binary).
W=${WEFT:-build/release/apps/weft}
common() { OMP_NUM_THREADS=1 $W stability scenes/whip.json "rods.0.root=[0.0477668,-0.0147760,0]" \
    "rods.0.direction=[0.9553365,-0.2955202,0]" "gravity=[0,0,0]" "obstacles.0.center=[0.17,0,0]" \
    contact.redetections=20 integrator.max_iterations=200 \
    --dt 0.05 0.02 0.01 0.005 0.002 0.001 0.0005 0.0002 \
    --vary "rods.0.motion.angular_velocity.2=10,20" --duration 5 -q --no-plots "$@"; }

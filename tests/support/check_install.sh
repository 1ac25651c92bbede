#!/usr/bin/env bash
# weft as a user's project sees it: install the build tree into a temporary prefix, build
# examples/custom_energy out of tree with find_package(weft) against that prefix, run it, and
# run the installed weft without the source tree (it finds its scripts and scenes in
# PREFIX/share/weft).
#   check_install.sh BUILD_DIR SOURCE_DIR WORK_DIR
set -euo pipefail
build=$1 src=$2 work=$3
rm -rf "$work"
mkdir -p "$work"
prefix="$work/prefix"
cmake --install "$build" --prefix "$prefix" >"$work/install.log"
for f in bin/weft share/weft/scripts/weft_plot.py share/weft/scripts/weft_render.py share/weft/scenes/hanging_cloth.json \
         include/weft/framework/simulator.hpp lib/cmake/weft/weftConfig.cmake lib/cmake/weft/weftTargets.cmake; do
  [ -e "$prefix/$f" ] || { echo "install: $f is missing from the prefix"; exit 1; }
done

launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
cmake -S "$src/examples/custom_energy" -B "$work/consumer" -G Ninja -DCMAKE_BUILD_TYPE=Release \
      -DCMAKE_PREFIX_PATH="$prefix" "${launcher[@]}" >"$work/configure.log" || { cat "$work/configure.log"; exit 1; }
cmake --build "$work/consumer" >"$work/build.log" || { cat "$work/build.log"; exit 1; }
"$work/consumer/custom_energy" | tail -n 1 | grep -q '^settled' || { echo "custom_energy did not settle"; exit 1; }

# The installed binary, from an unrelated directory, with no variable pointing at the source.
cd "$work"
env -u WEFT_SOURCE_DIR -u WEFT_DATA_DIR "$prefix/bin/weft" run "$prefix/share/weft/scenes/hanging_cloth.json" -q --out "$work/run" \
    time.duration=0.25 'cloths.0.mesh.resolution=[7,7]'
[ -f "$work/run/summary.json" ] || { echo "installed weft wrote no summary"; exit 1; }
env -u WEFT_SOURCE_DIR -u WEFT_DATA_DIR "$prefix/bin/weft" render --help >"$work/render_help.txt" \
  || { echo "installed weft render did not find its script"; cat "$work/render_help.txt"; exit 1; }
echo "install check: consumer built and settled; installed weft ran and found share/weft"

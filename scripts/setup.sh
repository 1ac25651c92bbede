#!/usr/bin/env bash
# Install what is missing (Debian 12 packages), configure once, build incrementally.
# Idempotent: a second run installs nothing and rebuilds nothing that did not change.
#   scripts/setup.sh [TARGET ...]   build only these targets (default: everything of the preset)
set -euo pipefail
cd "$(dirname "$0")/.."

# libopenblas0-pthread: the rods' banded solves call LAPACK (dgbtrf/dgbtrs), and reference
# LAPACK and OpenBLAS round differently. A hair ball or a whip is chaotic over hundreds of
# steps, so which one liblapack.so.3 points to decides which step a marginal run fails at:
# two default-suite tests passed on OpenBLAS and failed on reference LAPACK (2026-11-28).
# Installing it here gives every build (default, back ends, slow) the same LAPACK; with it,
# V-21's first 8 steps matched an AMD EPYC record bitwise on an Intel Xeon
# (bench/results/rods/lapack/).
PACKAGES=(cmake ninja-build g++ ccache pkg-config
          libeigen3-dev libboost-dev libfmt-dev doctest-dev
          nlohmann-json3-dev libtinyobjloader-dev libcli11-dev libspdlog-dev
          liblapack-dev libopenblas0-pthread python3-matplotlib python3-pil povray ffmpeg fonts-dejavu-core)
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}"
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

PRESET="${WEFT_PRESET:-release}"
if [ ! -f "build/$PRESET/build.ninja" ]; then
  cmake --preset "$PRESET"
fi
if (($#)); then
  cmake --build --preset "$PRESET" --target "$@"
else
  cmake --build --preset "$PRESET"
fi

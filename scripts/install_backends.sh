#!/usr/bin/env bash
# Install the Debian 12 packages of the optional linear-solver back ends, only what is missing:
#   -DWEFT_WITH_CHOLMOD=ON  libsuitesparse-dev (CHOLMOD; GPL-2+ Supernodal module) and
#                           libopenblas0-pthread: it switches the libblas.so.3 alternative that
#                           CHOLMOD and PETSc load from reference BLAS to OpenBLAS (the supernodal
#                           factorisation is BLAS-3 bound: ~2.7 GFlop/s on reference BLAS)
#   -DWEFT_WITH_PETSC=ON    libpetsc-real-dev, libopenmpi-dev, openmpi-bin (mpirun), pkg-config (~300 MB)
# Usage: scripts/install_backends.sh [cholmod] [petsc]   (no argument: both)
# Idempotent: a second run installs nothing.
set -euo pipefail

want=("$@")
((${#want[@]})) || want=(cholmod petsc)
PACKAGES=()
for w in "${want[@]}"; do
  case "$w" in
    cholmod) PACKAGES+=(libsuitesparse-dev libopenblas0-pthread) ;;
    petsc) PACKAGES+=(libpetsc-real-dev libopenmpi-dev openmpi-bin pkg-config) ;;
    *) echo "install_backends: unknown back end '$w' (cholmod, petsc)" >&2; exit 2 ;;
  esac
done

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "install_backends: installing ${missing[*]}"
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
else
  echo "install_backends: nothing to install"
fi

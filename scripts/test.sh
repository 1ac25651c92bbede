#!/usr/bin/env bash
# Quick start 2: install, build, and run the test suite (the fast default suite).
#   --slow      the long, labelled suite instead (.ci/run runs it after the other two)
#   --backends  install and enable the optional back ends (CHOLMOD, PETSc + MPI), build
#               them in build/backends and run their tests
set -euo pipefail
cd "$(dirname "$0")/.."
case "${1:-}" in
  --slow)
    ./scripts/setup.sh
    ctest --preset slow ;;
  --backends)
    ./scripts/install_backends.sh
    # Only what the back-end tests run: their suites and the weft command that links them.
    WEFT_PRESET=backends ./scripts/setup.sh weft test_linear_backends test_petsc_two_ranks
    ctest --preset backends ;;
  "")
    ./scripts/setup.sh
    ctest --preset release ;;
  *)
    echo "usage: $0 [--slow | --backends]" >&2
    exit 2 ;;
esac

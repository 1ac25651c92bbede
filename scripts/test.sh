#!/usr/bin/env bash
# Quick start 2: install, build, and run the test suite (the fast default suite; pass
# --slow to run the long, labelled suite instead, as CI does in a separate job).
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh
if [ "${1:-}" = "--slow" ]; then
  ctest --preset slow
else
  ctest --preset release
fi

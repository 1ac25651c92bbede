#!/usr/bin/env bash
# Quick start 1: install, build, and run the default demo (hanging cloth) into out/.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh
./build/release/apps/weft run scenes/hanging_cloth.json --out out "$@"
echo "demo: frames in out/ (open out/frames.pvd in ParaView), statistics in out/stats.jsonl, summary in out/summary.json"

#!/usr/bin/env bash
# Quick start 1: install, build the weft command (only it and its libraries), and run the
# default demo (hanging cloth) into out/. Extra arguments go to `weft run`, e.g. time.duration=1.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh weft
./build/release/apps/weft run scenes/hanging_cloth.json --out out "$@"
echo "demo: frames in out/ (open out/frames.pvd in ParaView), statistics in out/stats.jsonl, summary in out/summary.json"

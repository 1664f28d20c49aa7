#!/usr/bin/env bash
# msid on a fresh Debian bookworm machine (as root, or with sudo):
#   ./bootstrap.sh demo   install what is missing, build, run the main job on the built-in plant
#   ./bootstrap.sh test   install what is missing, build, run every test (ctest: unit, stats, integration)
set -euo pipefail
cd "$(dirname "$0")"
mode=${1:-}
case "$mode" in
  demo|test|build) ;;
  *) echo "usage: $0 demo|test|build" >&2; exit 2 ;;
esac

scripts/deps.sh
jobs=$(nproc 2>/dev/null || echo 2)
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release > build.log 2>&1 || { cat build.log; exit 1; }
cmake --build build -j "$jobs" >> build.log 2>&1 || { tail -50 build.log; exit 1; }

case "$mode" in
  demo) exec ./build/tools/msid demo --out build/demo ;;
  test) cd build && exec ctest --output-on-failure -j "$jobs" ;;
  build) echo "built: build/tools/msid" ;;
esac

#!/usr/bin/env bash
# msid on a fresh Debian bookworm machine (as root, or with sudo):
#   ./bootstrap.sh demo   install and build only what the demo needs (msid, msid-devsim), run `msid demo`:
#                         the simulator on Modbus TCP loopback, measure, fit, validate, plot into ./msid-demo/
#   ./bootstrap.sh test   install what is missing, build, run every test (ctest: unit, stats, integration)
set -euo pipefail
cd "$(dirname "$0")"
mode=${1:-}
case "$mode" in
  demo|test|build) ;;
  *) echo "usage: $0 demo|test|build" >&2; exit 2 ;;
esac

jobs=$(nproc 2>/dev/null || echo 2)
if [ "$mode" = demo ]; then
  # no tests (no cmocka), no cross builds: the two executables the demo runs
  scripts/deps.sh demo
  cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DMSID_BUILD_TESTS=OFF > build.log 2>&1 || { cat build.log; exit 1; }
  cmake --build build -j "$jobs" --target msid_cli msid_devsim >> build.log 2>&1 || { tail -50 build.log; exit 1; }
  exec ./build/tools/msid demo --out msid-demo
fi
scripts/deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release > build.log 2>&1 || { cat build.log; exit 1; }
cmake --build build -j "$jobs" >> build.log 2>&1 || { tail -50 build.log; exit 1; }

case "$mode" in
  test) cd build && exec ctest --output-on-failure -j "$jobs" ;;
  build) echo "built: build/tools/msid" ;;
esac

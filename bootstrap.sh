#!/usr/bin/env bash
# msid on a fresh Debian bookworm machine (as root, or with sudo):
#   ./bootstrap.sh demo   install and build only what the demo needs (msid without bench, fit --method
#                         cissim|multi; msid-devsim), run `msid demo`: the simulator on Modbus TCP loopback,
#                         measure, fit, validate, plot into ./msid-demo/
#   ./bootstrap.sh build  install what is missing, build every target (a demo build directory is switched back)
#   ./bootstrap.sh test   install what is missing, build, run every test (ctest: unit, stats, integration)
#   ./bootstrap.sh test-aarch64 | test-armhf
#                         cross-build for a 64-bit or 32-bit ARM Linux bench controller into build-aarch64/ or
#                         build-armhf/ and run the suites under qemu-user (scripts/cross_test.sh, docs/target.md)
set -euo pipefail
trap 'echo "bootstrap: failed (exit $?) at line $LINENO: $BASH_COMMAND" >&2' ERR
cd "$(dirname "$0")"
mode=${1:-}
case "$mode" in
  demo|test|build) ;;
  test-aarch64|test-armhf) exec scripts/cross_test.sh "${mode#test-}" all ;;
  *) echo "usage: $0 demo|test|build|test-aarch64|test-armhf" >&2; exit 2 ;;
esac

jobs=$(nproc 2>/dev/null || echo 2)
# Ninja (when present) compiles the objects of every target at once: the heavy fitting sources start
# first and the light ones fill the other cores (make waits for each library before the next target).
# An existing build directory keeps its generator.
gen=()
if [ ! -f build/CMakeCache.txt ] && command -v ninja >/dev/null; then gen=(-G Ninja); fi
if [ "$mode" = demo ]; then
  # no tests (no cmocka), no cross builds: the two executables the demo runs, and of msid only what the
  # demo runs (MSID_DEMO, cmake/msid_demo.cmake: no bench, no cissim or multi fits, C++ at MSID_DEMO_OPT)
  scripts/deps.sh demo
  cmake -S . -B build "${gen[@]}" -DCMAKE_BUILD_TYPE=Release -DMSID_BUILD_TESTS=OFF -DMSID_DEMO=ON \
    > build.log 2>&1 || { cat build.log; exit 1; }
  cmake --build build -j "$jobs" --target msid_cli msid_devsim >> build.log 2>&1 || { tail -50 build.log; exit 1; }
  exec ./build/tools/msid demo --out msid-demo
fi
scripts/deps.sh
# the full build: every target and command at -O3 (a build directory the demo configured is switched back:
# MSID_DEMO=OFF brings back the commands the demo build left out)
cmake -S . -B build "${gen[@]}" -DCMAKE_BUILD_TYPE=Release -DMSID_DEMO=OFF -DMSID_BUILD_TESTS=ON \
  > build.log 2>&1 || { cat build.log; exit 1; }
cmake --build build -j "$jobs" >> build.log 2>&1 || { tail -50 build.log; exit 1; }
echo "bootstrap: built in $SECONDS s with $jobs jobs (log: build.log)" >&2

case "$mode" in
  test) cd build && exec ctest --output-on-failure -j "$jobs" ;;
  build) echo "built: build/tools/msid" ;;
esac

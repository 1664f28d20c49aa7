#!/usr/bin/env bash
# msid for a Linux ARM bench controller, built on this PC and tested under qemu-user
# (docs/target.md "Linux bench controller"):
#   scripts/cross_test.sh aarch64|armhf [all|ci] [ctest arguments...]
# Installs what is missing (scripts/deps.sh cross-arm64|cross-armhf: cross compiler, qemu-user, the target's
# libraries), builds every target into build-<arch>/ with cmake/<triplet>.cmake, and runs ctest there: the
# unit, stats and integration tests run through the emulator (CMAKE_CROSSCOMPILING_EMULATOR; the pytest
# harnesses through MSID_EMULATOR, tests/common/msid_emulator.py).
#   all  every test that user-mode emulation can run (the default)
#   ci   the subset .ci/run runs: every library and both executables, in a few minutes
# Left out under emulation: the libFuzzer harnesses (a host clang build), the CAN VM (an x86-64 kernel),
# the soaks (they read the RSS of the process, here qemu's), the install tests (they build consumers with the
# host's compiler), `msid bench` (it re-executes /proc/self/exe, which needs binfmt_misc) and the demo
# build's check (a script that runs the binaries directly).
set -euo pipefail
trap 'echo "cross_test: failed (exit $?) at line $LINENO: $BASH_COMMAND" >&2' ERR
cd "$(dirname "$0")/.."
arch=${1:-}
subset=${2:-all}
case "$arch" in
  aarch64) deb=arm64; triplet=aarch64-linux-gnu; qemu=qemu-aarch64 ;;
  armhf) deb=armhf; triplet=arm-linux-gnueabihf; qemu=qemu-arm ;;
  *) echo "usage: $0 aarch64|armhf [all|ci] [ctest arguments...]" >&2; exit 2 ;;
esac
case "$subset" in
  all|ci) ;;
  *) echo "usage: $0 aarch64|armhf [all|ci] [ctest arguments...]" >&2; exit 2 ;;
esac
shift $(( $# < 2 ? $# : 2 ))
jobs=$(nproc 2>/dev/null || echo 2)

scripts/deps.sh "cross-$deb"
dir=build-$arch
gen=()
if [ ! -f "$dir/CMakeCache.txt" ] && command -v ninja >/dev/null; then gen=(-G Ninja); fi
# Modbus across architectures (tests/modbus/test_mb_cross_arch.py) when this machine's build is there
# (./bootstrap.sh build or test made it): x86-64 msid against the emulated msid-devsim and the reverse.
other=""
if [ -x build/tools/msid ] && [ -x build/firmware_sim/msid-devsim ]; then other=$PWD/build; fi
cmake -S . -B "$dir" "${gen[@]}" -DCMAKE_TOOLCHAIN_FILE="cmake/$triplet.cmake" -DCMAKE_BUILD_TYPE=Release \
  -DMSID_BUILD_TESTS=ON -DMSID_OTHER_BUILD_DIR="$other" > "$dir.log" 2>&1 || { cat "$dir.log"; exit 1; }
cmake --build "$dir" -j "$jobs" >> "$dir.log" 2>&1 || { tail -50 "$dir.log"; exit 1; }

exclude='^(fuzz_|vcan_|soak_|install_|demo_build_left_out$|pytest_test_bench$)'
sel=()
if [ "$subset" = ci ]; then
  # lib/ (every object's unit test), daq/ (codecs, stream, the Modbus client against msid-devsim), tools/
  # (fit, est, the msid command end to end) and the results that must not depend on the architecture
  sel=(-R '^(test_(status|dmath_rng|design|gen|linedft|linedft_f32|spread|meas|frf|plant|determinism|golden|can_decoder|mb_proto|stream|mb_est|mb_acq|fit_unit|csv_rows)|pytest_test_(determinism|frf_golden|e2e_dt|cross_arch|mb_cross_arch))$')
fi
cd "$dir"
# the prefix of cmake/linux-cross.cmake, for the pytest files registered without msid_add_pytests
export MSID_EMULATOR="$qemu -L /usr/$triplet"
exec ctest --output-on-failure -j "$jobs" -E "$exclude" "${sel[@]}" "$@"

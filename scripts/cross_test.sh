#!/usr/bin/env bash
# msid for a Linux ARM bench controller, built on this PC and tested under qemu-user
# (docs/target.md "Linux bench controller"):
#   scripts/cross_test.sh aarch64|armhf [all|ci] [ctest arguments...]
# Installs what is missing (scripts/deps.sh cross-arm64|cross-armhf: cross compiler, qemu-user, the target's
# libraries), builds every target into build-<arch>/ with cmake/<triplet>.cmake, and runs ctest there: the
# unit, stats and integration tests run through the emulator (CMAKE_CROSSCOMPILING_EMULATOR; the pytest
# harnesses through MSID_EMULATOR, tests/common/msid_emulator.py).
#   all  every test that user-mode emulation can run (the default), the Python extension's in the target's
#        Python (MSID_CROSS_PYTHON=0: deps.sh does not fetch that Python; without it msid._msid is left out)
#   ci   the subset .ci/run runs, in a few minutes: lib/, daq/ and msid-devsim (not the C++ tools) with their C tests
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

# all: the target's Python and NumPy too (into the private sysroot), so msid._msid is cross-built and its
# tests run in the target's interpreter (tools/python/CMakeLists.txt)
if [ "$subset" = all ]; then MSID_CROSS_PYTHON=${MSID_CROSS_PYTHON:-1} scripts/deps.sh "cross-$deb"; else scripts/deps.sh "cross-$deb"; fi
dir=${MSID_CROSS_DIR:-build-$arch}   # MSID_CROSS_DIR: another build directory
gen=()
if [ ! -f "$dir/CMakeCache.txt" ] && command -v ninja >/dev/null; then gen=(-G Ninja); fi
# Against this machine's build when it is there (./bootstrap.sh build or test made it): lib/'s outputs bit
# for bit (target_linux_bits) and, with the tools, x86-64 msid against the emulated msid-devsim and the
# reverse (tests/modbus/test_mb_cross_arch.py).
other=""
if [ -f build/CMakeCache.txt ]; then other=$PWD/build; fi
# ci: lib/, daq/ and msid-devsim with their C tests (the C++ tools take most of an hour to cross-build on 2 cores)
tools=ON
if [ "$subset" = ci ]; then tools=OFF; fi
cmake -S . -B "$dir" "${gen[@]}" -DCMAKE_TOOLCHAIN_FILE="cmake/$triplet.cmake" -DCMAKE_BUILD_TYPE=Release \
  -DMSID_BUILD_TESTS=ON -DMSID_BUILD_TOOLS=$tools -DMSID_OTHER_BUILD_DIR="$other" > "$dir.log" 2>&1 || { cat "$dir.log"; exit 1; }
cmake --build "$dir" -j "$jobs" >> "$dir.log" 2>&1 || { tail -50 "$dir.log"; exit 1; }

exclude='^(fuzz_|vcan_|soak_|install_|demo_build_left_out$|pytest_test_bench$)'
sel=()
if [ "$subset" = ci ]; then
  # lib/ (every object's unit test but the three long exhaustive ones), the scalar kernels, lib/'s outputs
  # against x86-64's bit for bit, daq/ (codecs, stream, CAN session, the Modbus client against msid-devsim)
  # and msid-devsim's CANopen node through daq's CANopen master (test_co_node), its tick backend (test_co_map),
  # the checks before a run (test_co_map_check) and an interface's bit rate read from the kernel (test_can_bitrate)
  sel=(-R '^(test_(status|design|gen|linedft|linedft_scalar|linedft_f32|spread|meas|frf|plant|determinism|golden|can_decoder|dbc|mb_proto|stream|can_session|mb_est|mb_acq|mbap|daq_noalloc|noalloc|co_node|co_map|co_map_check|can_bitrate)|target_linux_bits)$')
fi
cd "$dir"
# the prefix of cmake/linux-cross.cmake (why LD_LIBRARY_PATH: there), for the pytest files registered
# without msid_add_pytests
# (and the libraries scripts/deps.sh unpacked where apt could not install them, as the toolchain file adds)
ld=/usr/$triplet/lib
root=${MSID_CROSS_ROOT:-/opt/msid-cross/$triplet}
if [ -d "$root/usr/lib/$triplet" ]; then ld=$ld:$root/usr/lib/$triplet; fi
export MSID_EMULATOR="$qemu -L /usr/$triplet -E LD_LIBRARY_PATH=$ld"
exec ctest --output-on-failure -j "$jobs" -E "$exclude" "${sel[@]}" "$@"

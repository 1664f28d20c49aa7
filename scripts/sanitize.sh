#!/usr/bin/env bash
# The unit, statistics and integration suites under AddressSanitizer + UndefinedBehaviorSanitizer
# (LeakSanitizer included), in build-asan/. CI runs it after the README's test command (.ci/run).
#   scripts/sanitize.sh [extra ctest args]
# Not run here: the Modbus and vcan suites (they test links, not memory; the Modbus adapter's memory is
# fuzzed by tests/fuzz/fuzz_mb_acq; the host-timed ones, test_map, test_map_peer, test_measure and
# test_py_measure, would also lose ticks to ASan's slowdown), the real F-16 record's test (six minutes under
# ASan: its readers and estimators run under ASan on the smaller records of the CLI and unit tests), the speed benchmarks (pytest_test_bench: timing runs of the same code
# paths the other tests cover), the soak (it bounds RSS, which ASan shadow memory inflates: 137 MB) and the
# fuzz label (its own clang build with the same sanitizers), the label montecarlo: the Monte Carlo suites
# run the same estimators and `msid fit` / `msid validate` paths as the unit and CLI tests hundreds of times
# with other seeds (tests/CMakeLists.txt msid_montecarlo, tests/integration/CMakeLists.txt), 40 minutes
# under ASan for no path the others do not take; and the plotting package's tests (pytest_test_pkg_plot,
# pytest_test_pkg_files, pytest_test_plot_phase_bound: matplotlib and python-control in an uninstrumented
# interpreter, the msid calls among them taken by the CLI tests).
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc 2>/dev/null || echo 2)
# -O1 without -g: Eigen-heavy C++ under ASan at -O2 -g compiles several times slower, for no more findings;
# the Eigen-heavy libraries as unity sources of 4 files (MSID_UNITY_BUILD, cmake/msid_demo.cmake): their
# common instantiations compiled once per batch, the build's longest part
launcher=(); command -v ccache >/dev/null && launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=None -DCMAKE_C_FLAGS=-O1 -DCMAKE_CXX_FLAGS=-O1 -DMSID_SANITIZE=ON -DMSID_UNITY_BUILD=ON \
    "${launcher[@]}" > build-asan.log 2>&1 || {
  tail -30 build-asan.log; exit 1; }
cmake --build build-asan -j "$jobs" >> build-asan.log 2>&1 || { tail -50 build-asan.log; exit 1; }
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:strict_string_checks=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
cd build-asan
exec ctest --output-on-failure -j "$jobs" -L 'unit|stats|integration' -LE montecarlo \
    -E 'pytest_test_mb_|pytest_test_(map|map_peer|measure|py_measure|f16_record)$|pytest_test_bench|vcan|^fuzz_|^soak_|pytest_test_pkg_(plot|files)|pytest_test_plot_phase_bound' "$@"

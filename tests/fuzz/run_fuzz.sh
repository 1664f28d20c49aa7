#!/usr/bin/env bash
# Build the libFuzzer harnesses with clang (ASan + UBSan) in their own build directory and run them.
#   run_fuzz.sh build BUILD_DIR                    configure and build every harness
#   run_fuzz.sh run BUILD_DIR HARNESS SECONDS [libFuzzer options...]
# `run` fuzzes for SECONDS from the seed corpus tests/fuzz/corpus/HARNESS (copied: the repository's
# corpus is never changed) and fails on any crash, leak, timeout or sanitizer report; exit 77 (skipped)
# only if clang is missing (scripts/deps.sh installs it). Used by ctest (label fuzz) and docs/reliability.md.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
cmd=${1:?usage}; bdir=${2:?usage}
command -v clang >/dev/null && command -v clang++ >/dev/null || { echo "run_fuzz: clang not found: skipped"; exit 77; }
case "$cmd" in
build)
  cmake -S "$here" -B "$bdir" -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=None >/dev/null
  cmake --build "$bdir" -j "${MSID_FUZZ_JOBS:-2}" ;;
run)
  h=${3:?harness}; secs=${4:?seconds}; shift 4
  [ -x "$bdir/$h" ] || { echo "run_fuzz: $bdir/$h is not built" >&2; exit 1; }
  work=$(mktemp -d "${TMPDIR:-/tmp}/msid-fuzz-$h.XXXXXX")
  trap 'rm -rf "$work"' EXIT
  mkdir -p "$work/corpus"
  export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}
  export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
  "$bdir/$h" "$work/corpus" "$here/corpus/$h" -max_total_time="$secs" -seed="${MSID_FUZZ_SEED:-1}" -timeout=10 -rss_limit_mb=2048 \
      -artifact_prefix="$work/" -print_final_stats=1 "$@" 2>"$work/log" || {
    tail -60 "$work/log"; for a in "$work"/crash-* "$work"/leak-* "$work"/timeout-* "$work"/oom-*; do
      [ -e "$a" ] && { echo "run_fuzz: reproducer (base64) $a:"; base64 -w0 "$a"; echo; }; done; exit 1; }
  grep -E '^(#[0-9]+.*DONE|stat::number_of_executed_units|stat::peak_rss_mb|Done )|cov:' "$work/log" | tail -4 ;;
*) echo "usage: run_fuzz.sh build|run ..." >&2; exit 2 ;;
esac

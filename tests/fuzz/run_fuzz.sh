#!/usr/bin/env bash
# Build the libFuzzer harnesses with clang (ASan + UBSan) in their own build directory and run them.
#   run_fuzz.sh build BUILD_DIR                    configure and build every harness
#   run_fuzz.sh run BUILD_DIR HARNESS SECONDS [libFuzzer options...]
#   run_fuzz.sh cpu BUILD_DIR HARNESS CPU_SECONDS [libFuzzer options...]
# `cpu` is the long run of docs/reliability.md: it fuzzes until the harness has used CPU_SECONDS of CPU
# time (user + system, from /proc: a shared machine's wall time says nothing), then interrupts it,
# which prints libFuzzer's final statistics; the log is kept in $MSID_FUZZ_LOG (default ./fuzz-HARNESS.log).
# `run` fuzzes for SECONDS from the seed corpus tests/fuzz/corpus/HARNESS (copied: the repository's
# corpus is never changed) and fails on any crash, leak, timeout or sanitizer report; exit 77 (skipped)
# only if clang is missing (scripts/deps.sh installs it). Used by ctest (label fuzz) and docs/reliability.md.
# Both modes fail on any single allocation of MSID_FUZZ_MALLOC_MB (default 512) MiB or more
# (-malloc_limit_mb): an input no larger than a few KB that makes a reader ask for that much sized
# memory from a lie (a reader's memory is bounded by its file's size, docs/reliability.md).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
cmd=${1:?usage}; bdir=${2:?usage}
malloc_mb=${MSID_FUZZ_MALLOC_MB:-512}
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
      -malloc_limit_mb="$malloc_mb" -artifact_prefix="$work/" -print_final_stats=1 "$@" 2>"$work/log" || {
    tail -60 "$work/log"; for a in "$work"/crash-* "$work"/leak-* "$work"/timeout-* "$work"/oom-*; do
      [ -e "$a" ] && { echo "run_fuzz: reproducer (base64) $a:"; base64 -w0 "$a"; echo; }; done; exit 1; }
  grep -E '^(#[0-9]+.*DONE|stat::number_of_executed_units|stat::peak_rss_mb|Done )|cov:' "$work/log" | tail -4 ;;
cpu)
  h=${3:?harness}; cpu=${4:?cpu seconds}; shift 4
  [ -x "$bdir/$h" ] || { echo "run_fuzz: $bdir/$h is not built" >&2; exit 1; }
  log=${MSID_FUZZ_LOG:-$PWD/fuzz-$h.log}
  work=$(mktemp -d "${TMPDIR:-/tmp}/msid-fuzz-$h.XXXXXX")
  trap 'rm -rf "$work"' EXIT
  mkdir -p "$work/corpus"
  export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1}
  export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
  "$bdir/$h" "$work/corpus" "$here/corpus/$h" -seed="${MSID_FUZZ_SEED:-1}" -timeout=10 -rss_limit_mb=2048 \
      -malloc_limit_mb="$malloc_mb" -artifact_prefix="$work/" -print_final_stats=1 "$@" 2>"$log" &
  pid=$!; tick=$(getconf CLK_TCK)
  while kill -0 "$pid" 2>/dev/null; do
    used=$(awk -v t="$tick" '{print int(($14 + $15) / t)}' "/proc/$pid/stat" 2>/dev/null || echo 0)
    [ "$used" -ge "$cpu" ] && { kill -INT "$pid"; break; }
    sleep 10
  done
  rc=0; wait "$pid" || rc=$?
  # 72: libFuzzer's exit on SIGINT (the budget reached); anything else is a finding
  if [ "$rc" != 72 ] && [ "$rc" != 0 ]; then
    tail -60 "$log"; for a in "$work"/crash-* "$work"/leak-* "$work"/timeout-* "$work"/oom-*; do
      [ -e "$a" ] && { echo "run_fuzz: reproducer (base64) $a:"; base64 -w0 "$a"; echo; }; done; exit 1
  fi
  echo "run_fuzz: $h: ${used:-?} CPU-s, corpus $(ls "$work/corpus" | wc -l) inputs"
  grep -E '^stat::|cov:' "$log" | tail -8 ;;
*) echo "usage: run_fuzz.sh build|run|cpu ..." >&2; exit 2 ;;
esac

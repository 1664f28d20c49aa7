#!/usr/bin/env bash
# ctest demo_build_left_out (label integration): the demo build's msid (MSID_DEMO, cmake/msid_demo.cmake;
# here msid_demo_cli, the same objects as msid with msid/left_out.cpp for the bench, cissim, multi,
# ml --param poles, --on-device and lpm/etfe handlers) answers each left-out command with exactly one line
# naming it and `./bootstrap.sh build`, exit status 2, nothing on stdout, no file written; the commands it keeps still run.
# Negative control: the full msid (FULL) gets the same commands and must NOT pass the same check.
set -uo pipefail
demo=$(realpath "$1") full=${2:+$(realpath "$2")}
work=$(mktemp -d) && trap 'rm -rf "$work"' EXIT
fail() { echo "demo_left_out: $*" >&2; exit 1; }
# left_out BIN WHAT ARGS...: 0 if BIN prints the left-out message for WHAT and nothing else
left_out() {
  local bin=$1 what=$2; shift 2
  local want="msid $1: error: this msid was built by \`./bootstrap.sh demo\` without \`$what\`; build everything with \`./bootstrap.sh build\`"
  (cd "$work" && "$bin" "$@" > out.txt 2> err.txt); local rc=$?
  [ $rc -eq 2 ] && [ ! -s "$work/out.txt" ] && [ "$(cat "$work/err.txt")" = "$want" ] &&
    [ "$(ls "$work")" = "$(printf 'err.txt\nout.txt')" ] && return 0
  echo "  $(basename "$bin") $*: exit $rc, stderr '$(cat "$work/err.txt")'" >&2
  return 1
}
golden=$(realpath "$(dirname "$0")/golden")
cases=(
  "bench::bench --help"
  "bench::bench no-such-benchmark"
  "fit --method cissim::fit --method cissim --period 64 --lines 1,2 --experiment e.csv -o m.json"
  "fit --method multi::fit --method=multi --experiment r.csv --order 2 -o m.json"
  "fit --method ml --param poles::fit --method ml --param poles --order 4 $golden/periodic.json -o m.json"
  "modbus measure --on-device::modbus measure --on-device --tcp 127.0.0.1:1 --design d.json -o f.json"
  "can measure --on-device::can measure --on-device --iface vcan-none --design d.json -o f.json"
  "validate --experiment::validate m.json --experiment r.csv"
  "frf --method lpm|etfe::frf --method etfe --experiment r.csv -o f.json"
)
for c in "${cases[@]}"; do
  what=${c%%::*}; read -r -a args <<< "${c#*::}"
  left_out "$demo" "$what" "${args[@]}" || fail "the demo build's msid did not name \`$what\` as left out"
done
# what the demo build keeps still runs
# (the output is captured whole first: `grep -q` leaving a pipe early would SIGPIPE msid, and pipefail
# would report that as msid failing)
runs() { local out; out=$("$demo" "$@") && grep -q -- "$want" <<< "$out"; }
want="^msid " runs version || fail "msid version does not run in the demo build"
want="--method" runs fit --help || fail "msid fit --help does not run in the demo build"
want="msid-devsim" runs demo --help || fail "msid demo --help does not run in the demo build"
# negative control: the full build runs these commands (they fail on the missing files instead)
if [ -n "$full" ]; then
  for c in "${cases[@]}"; do
    what=${c%%::*}; read -r -a args <<< "${c#*::}"
    ! left_out "$full" "$what" "${args[@]}" 2> /dev/null || fail "negative control: the full msid passed the check for \`$what\`"
  done
fi
echo "demo_left_out: ok (${#cases[@]} left-out commands, negative control ${full:+run}${full:-skipped})"

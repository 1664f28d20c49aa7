#!/usr/bin/env bash
# `./bootstrap.sh demo` as a new user meets it: a fresh `git clone` of this repository (its HEAD, or REF),
# no build directory, no ccache, the dependencies already installed; timed as a whole, with the CPU of
# every compile and link (a compiler launcher that records user + sys per object: under load the wall
# time is an upper bound and the CPU is the work) and the load average before and after. The figures go
# to docs/benchmarks.md ("Demo build from a fresh clone") with the date and the machine.
#
#   scripts/bench_demo.sh [REF] [--keep]     REF: a commit or branch (default HEAD); --keep: leave the clone
#
# Needs what scripts/deps.sh demo installs (bootstrap.sh runs it; with everything present it only checks).
# Prints one report; exit status: bootstrap.sh's.
set -euo pipefail
ref=HEAD keep=0
for a in "$@"; do
  case "$a" in
    --keep) keep=1 ;;
    -h|--help) sed -n '2,10p' "$0"; exit 0 ;;
    *) ref=$a ;;
  esac
done
src=$(cd "$(dirname "$0")/.." && pwd)
commit=$(git -C "$src" rev-parse --verify "$ref^{commit}")
work=$(mktemp -d /tmp/msid-bench-demo.XXXXXX)
[ "$keep" = 1 ] || trap 'rm -rf "$work"' EXIT
log=$work/objects.log
# the launcher: user + sys seconds and the object of every compile (the path after -o)
cat > "$work/launcher" <<EOF
#!/bin/sh
out=""; prev=""
for a in "\$@"; do [ "\$prev" = "-o" ] && out=\$a; prev=\$a; done
exec /usr/bin/time -f "%U %S \$out" -a -o "$log" "\$@"
EOF
chmod +x "$work/launcher"
git clone --quiet --no-local "$src" "$work/msid"
git -C "$work/msid" checkout --quiet "$commit"
machine=$(grep -m1 'model name' /proc/cpuinfo | sed 's/.*: //')
echo "bench_demo: $commit, $(date -u '+%Y-%m-%d %H:%M UTC'), $machine, $(nproc) cores, $(uname -sr)"
echo "bench_demo: $(gcc --version | head -1), $(cmake --version | head -1), ninja $(ninja --version 2>/dev/null || echo none)"
load0=$(cut -d' ' -f1-3 /proc/loadavg)
# CMake takes the launcher from the environment at its first configure (CMAKE_<LANG>_COMPILER_LAUNCHER)
start=$(date +%s.%N)
set +e
(cd "$work/msid" && CCACHE_DISABLE=1 CMAKE_C_COMPILER_LAUNCHER="$work/launcher" CMAKE_CXX_COMPILER_LAUNCHER="$work/launcher" \
  /usr/bin/time -f "%e %U %S" -o "$work/total.time" ./bootstrap.sh demo > "$work/demo.out" 2>&1)
rc=$?
set -e
end=$(date +%s.%N)
load1=$(cut -d' ' -f1-3 /proc/loadavg)
read -r wall user sys < "$work/total.time" || true
objects=$(wc -l < "$log" 2>/dev/null || echo 0)
cpu=$(awk '{u += $1 + $2} END {printf "%.1f", u}' "$log" 2>/dev/null || echo 0)
ninja_wall=$(awk 'NR > 1 {if (min == "" || $1 < min) min = $1; if ($2 > max) max = $2} END {printf "%.1f", (max - min) / 1000}' \
  "$work/msid/build/.ninja_log" 2>/dev/null || echo "?")
echo "bench_demo: exit $rc, ${wall:-?} s wall ($(awk -v a="$start" -v b="$end" 'BEGIN {printf "%.1f", b - a}') s by the clock), ${user:-?} s user + ${sys:-?} s sys"
echo "bench_demo: the build: $objects compiles and links, $cpu s of CPU (user + sys); Ninja $ninja_wall s wall"
echo "bench_demo: load average $load0 before, $load1 after"
echo "bench_demo: the costliest objects (CPU s):"
sort -rn "$log" | awk '{printf "  %7.2f  %s\n", $1 + $2, $3}' | head -8
if [ $rc -ne 0 ]; then
  echo "bench_demo: ./bootstrap.sh demo failed; its output:" >&2
  tail -30 "$work/demo.out" >&2
else
  echo "bench_demo: the demo printed:"
  grep -E "poles:|inside|FRF error|validation|Hz" "$work/demo.out" | head -12 | sed 's/^/  /'
fi
[ "$keep" = 1 ] && echo "bench_demo: kept $work"
exit $rc

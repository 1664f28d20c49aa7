#!/usr/bin/env bash
# Instructions per sample of the core's per-sample work (generation + streaming estimation,
# tests/target/insn_linux.c) on Linux targets, counted by qemu-user: one instruction per translation
# block (-singlestep) and each block's execution logged (-d exec,nochain), so the log has one line per
# instruction executed. Two runs, of 4 and 8 periods (P = 256), differ by the instructions of 4 periods,
# period ends included; start-up and set-up cancel. Instructions, not cycles (docs/target.md).
#   scripts/insn_count.sh [BUILD_DIR...]    default: build build-aarch64 build-armhf (those that exist)
# Each build's tests/target/msid_insn_probe (and _scalar: the core without its vector kernel) runs under
# the emulator of its architecture, x86-64 too (qemu-x86_64), so every column is counted the same way.
set -euo pipefail
cd "$(dirname "$0")/.."
dirs=("$@")
[ ${#dirs[@]} -gt 0 ] || for d in build build-aarch64 build-armhf; do [ -x "$d/tests/target/msid_insn_probe" ] && dirs+=("$d"); done
[ ${#dirs[@]} -gt 0 ] || { echo "insn_count: no build with tests/target/msid_insn_probe" >&2; exit 1; }
N1=1024 N2=2048
emulator() {   # the qemu-user command for an executable's architecture
  case "$(readelf -h "$1" | sed -n 's/^ *Machine: *//p')" in
    *X86-64*) echo qemu-x86_64 ;;
    *AArch64*) echo "qemu-aarch64 -L /usr/aarch64-linux-gnu -E LD_LIBRARY_PATH=/usr/aarch64-linux-gnu/lib" ;;
    ARM) echo "qemu-arm -L /usr/arm-linux-gnueabihf -E LD_LIBRARY_PATH=/usr/arm-linux-gnueabihf/lib" ;;
    *) echo "insn_count: unknown architecture of $1" >&2; return 1 ;;
  esac
}
insns() {   # insns EXE CASE SAMPLES: instructions executed by the whole process
  local emu; emu=$(emulator "$1")
  # shellcheck disable=SC2086
  $emu -singlestep -d exec,nochain -D /dev/stderr "$1" "$2" "$3" 2>&1 >/dev/null | grep -c '^Trace'
}
printf '%-18s' case
cols=()
for d in "${dirs[@]}"; do
  for v in msid_insn_probe msid_insn_probe_scalar; do
    exe=$d/tests/target/$v
    [ -x "$exe" ] || continue
    cols+=("$exe")
    arch=$(readelf -h "$exe" | sed -n 's/^ *Machine: *//p' | sed 's/Advanced Micro Devices //')
    printf ' %16s' "$arch${v#msid_insn_probe}"
  done
done
echo
for c in siso1 siso50 mimo2x2_50 siso1_b16 siso50_b16 mimo2x2_50_b16; do
  printf '%-18s' "$c"
  for exe in "${cols[@]}"; do
    a=$(insns "$exe" "$c" $N1); b=$(insns "$exe" "$c" $N2)
    awk -v a="$a" -v b="$b" -v n=$((N2 - N1)) 'BEGIN { printf " %16.1f", (b - a) / n }'
  done
  echo
done

# The CSV reader per row (tests/target/insn_csv.cpp): two files of R1 and R2 rows of "u1,y1" (numbers of
# the shape loggers write, -?D.DDDDDDDDD), read on the vector cell path and on the scalar path.
csv_exes=()
for d in "${dirs[@]}"; do [ -x "$d/tests/target/msid_insn_csv" ] && csv_exes+=("$d/tests/target/msid_insn_csv"); done
[ ${#csv_exes[@]} -gt 0 ] || exit 0
R1=2000 R2=4000
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for r in $R1 $R2; do
  awk -v n=$r 'BEGIN { print "u1,y1"; x = 12345; for (i = 0; i < n; i++) {
    x = (x * 1103515245 + 12345) % 2147483648; a = x / 2147483648 * 4 - 2
    x = (x * 1103515245 + 12345) % 2147483648; b = x / 2147483648 * 4 - 2
    printf "%.9f,%.9f\n", a, b } }' > "$tmp/r$r.csv"
done
echo
printf '%-18s' "CSV, per row"
for exe in "${csv_exes[@]}"; do
  arch=$(readelf -h "$exe" | sed -n 's/^ *Machine: *//p' | sed 's/Advanced Micro Devices //')
  printf ' %16s %16s' "$arch cells" "$arch scalar"
done
echo
printf '%-18s' "u1,y1 (2 cells)"
for exe in "${csv_exes[@]}"; do
  for mode in cells scalar; do
    emu=$(emulator "$exe")
    # shellcheck disable=SC2086
    general=$($emu "$exe" $mode "$tmp/r$R1.csv" | sed -n 's/.*rows, \([0-9]*\) by the general parser/\1/p')
    a=$(insns "$exe" $mode "$tmp/r$R1.csv"); b=$(insns "$exe" $mode "$tmp/r$R2.csv")
    # a cell path that fell back to the general parser for every row is marked (no vector path)
    awk -v a="$a" -v b="$b" -v n=$((R2 - R1)) -v g="$general" -v m=$mode -v r=$R1 \
      'BEGIN { printf " %15.1f%s", (b - a) / n, (m == "cells" && g + 0 >= r) ? "*" : " " }'
  done
done
echo
echo "(* no vector path on this architecture: the cell path read every row with the general parser)"

#!/usr/bin/env bash
# Install what msid needs on Debian bookworm, only where it is missing.
# Called by ./bootstrap.sh; safe to run again.
set -euo pipefail
trap 'echo "deps: failed (exit $?) at line $LINENO: $BASH_COMMAND" >&2' ERR

APT_PKGS=(build-essential cmake ninja-build pkg-config libcmocka-dev libfftw3-dev libmatio-dev zlib1g-dev
          nlohmann-json3-dev libeigen3-dev python3 python3-pip)
# Device descriptions (msid-device/1, TOML): toml++, header-only (daq/src/msid_devdesc_file.cpp).
APT_PKGS+=(libtomlplusplus-dev)
# msid bench ticks --instructions: user-space instructions per tick under valgrind's callgrind.
APT_PKGS+=(valgrind)
PY_MODS=(numpy jsonschema pytest)
# Experiment-file tests and `msid bench io`: scipy (writes .mat v5), h5py (writes .mat v7.3), pandas (the CSV peer).
PY_MODS+=(scipy h5py pandas)
# The Python package (tools/python, docs/python.md): matplotlib draws `msid plot` and the reports
# (Debian python3-matplotlib; pip for another python3).
APT_PKGS+=(python3-matplotlib)
PY_MODS+=(matplotlib)
# The compiled module msid._msid (tools/python/CMakeLists.txt): Python's headers and pybind11.
APT_PKGS+=(python3-dev pybind11-dev)
# CAN tests in the vcan VM (tests/vcan): qemu, busybox for its initramfs, can-utils as the reference.
APT_PKGS+=(qemu-system-x86 busybox-static can-utils iproute2 xz-utils zstd)
# On target (tests/target, firmware_sim/baremetal): Cortex-M cross compiler, newlib, MPS2 boards in qemu.
APT_PKGS+=(gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm)
# Modbus (daq/, firmware_sim/, tests/modbus): libmodbus on both ends, socat for RTU pty pairs.
APT_PKGS+=(libmodbus-dev socat)
# Hardening (tests/fuzz, the sanitizer build): Debian's clang with libFuzzer, ASan and UBSan runtimes.
APT_PKGS+=(clang libclang-rt-dev)
# `scripts/deps.sh demo` (./bootstrap.sh demo): only what msid and msid-devsim need to build, and the plots.
DEMO_ONLY=0
if [ "${1:-}" = demo ]; then
  DEMO_ONLY=1
  APT_PKGS=(build-essential cmake ninja-build pkg-config libfftw3-dev libmatio-dev zlib1g-dev nlohmann-json3-dev
            libeigen3-dev libmodbus-dev libtomlplusplus-dev python3 python3-pip)
  PY_MODS=(numpy matplotlib)
fi

# `scripts/deps.sh cross-arm64|cross-armhf` (scripts/cross_test.sh, docs/target.md "Linux bench controller"):
# everything above (the tests' python3 runs on this machine) plus the cross compiler, qemu-user (no
# binfmt_misc is assumed: the emulator is named on each command line) and the target's libraries from Debian's
# multiarch archive. libmatio-dev:<arch> cannot sit beside the host's (its libhdf5-dev is not multiarch): only
# the run-time libmatio11:<arch>, which msid loads with dlopen; its headers are the host's, the same on every
# architecture (cmake/cross-pkgconfig/matio.pc).
CROSS_ARCH=""
CROSS_PKGS=()
CROSS_PY_PKGS=()
case "${1:-}" in
  ""|demo) ;;
  cross-arm64|cross-armhf)
    CROSS_ARCH=${1#cross-}
    APT_PKGS+=("crossbuild-essential-$CROSS_ARCH" qemu-user)
    for p in libfftw3-dev libmodbus-dev libcmocka-dev zlib1g-dev libmatio11; do CROSS_PKGS+=("$p:$CROSS_ARCH"); done
    # MSID_CROSS_PYTHON=1 (scripts/cross_test.sh all): the target's Python, its headers and NumPy, so that
    # msid._msid is cross-built and its tests run under the target's interpreter in qemu. Always into the
    # private sysroot: python3.11:<arch> cannot be installed beside the host's python3.11.
    if [ "${MSID_CROSS_PYTHON:-0}" = 1 ]; then
      for p in libpython3.11-dev python3.11 python3-numpy; do CROSS_PY_PKGS+=("$p:$CROSS_ARCH"); done
    fi ;;
  *) echo "usage: $0 [demo|cross-arm64|cross-armhf]" >&2; exit 2 ;;
esac

as_root() { if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else
  echo "deps: need root (or sudo) to run: $*" >&2; return 1; fi; }

# One dpkg-query for every package (a fresh clone with everything present spends no time here).
missing=()
# dpkg-query exits 1 when a package was never known to dpkg (a fresh machine): that is the answer, not an error.
installed=" $({ dpkg-query -W -f='${Package} ${Status}\n' "${APT_PKGS[@]}" 2>/dev/null || true; } |
             awk '$NF == "installed" && $(NF-1) == "ok" {printf "%s ", $1}')"
for p in "${APT_PKGS[@]}"; do
  case "$installed" in *" $p "*) ;; *) missing+=("$p") ;; esac
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "deps: installing ${missing[*]} (log: deps.log)"
  export DEBIAN_FRONTEND=noninteractive
  # An index that fails to download (a mirror in sync) leaves apt the lists it had: the install says
  # whether those were enough.
  as_root apt-get update -qq >> deps.log 2>&1 || echo "deps: apt-get update reported errors (deps.log); installing from the lists apt has" >&2
  as_root apt-get install -y -qq --no-install-recommends "${missing[@]}" \
    >> deps.log 2>&1 || { tail -30 deps.log; echo "deps: apt-get failed (see deps.log)" >&2; exit 1; }
fi

# The target's libraries (cross-arm64|cross-armhf), after the host's (the cross compiler among them).
#
# The normal way is Debian's multiarch: `dpkg --add-architecture <arch>`, `apt-get update`, `apt-get install
# libfftw3-dev:<arch> ...`. It needs every index of the target's architecture: a package of Multi-Arch:
# same must have the host's exact version on both architectures, and for one with a security update
# (libmodbus; libssl3 under matio's libcurl; linux-libc-dev under zlib's libc6-dev) only the security
# index has it. When that index cannot be downloaded ("File has unexpected size ... Mirror sync in
# progress?", as Debian's armhf security index on 2026-11-28), apt cannot install them, and the
# architecture, once registered with dpkg, makes every later `apt-get update` of the host fail with it.
#
# So the target's indices are downloaded first into an apt state of their own ($CROSS_ROOT/.apt: its own
# lists, cache and dpkg status; the host's sources, keyrings and proxy; only the target's architecture),
# which touches neither the host's dpkg database nor its lists (cross_probe):
#  - every index downloads: the multiarch install (cross_multiarch);
#  - an index of binary-<arch> fails to download, and only then: the private sysroot (cross_sysroot), and
#    the architecture is not registered with dpkg (removed again if this run registered it);
#  - anything else (no network): the multiarch install, which says what failed.
# MSID_CROSS_SYSROOT=1 takes the private sysroot without asking (a machine that must stay single-arch).
# Target packages unpacked into the sysroot (a marker each in $CROSS_ROOT/.unpacked) count as there.
CROSS_ROOT=""
cross_missing=()
if [ ${#CROSS_PKGS[@]} -gt 0 ]; then
  case "$CROSS_ARCH" in arm64) triplet=aarch64-linux-gnu ;; armhf) triplet=arm-linux-gnueabihf ;; esac
  CROSS_ROOT=${MSID_CROSS_ROOT:-/opt/msid-cross/$triplet}   # cmake/linux-cross.cmake reads the same place
  installed=" $({ dpkg-query -W -f='${binary:Package} ${Status}\n' "${CROSS_PKGS[@]}" 2>/dev/null || true; } |
               awk '$NF == "installed" && $(NF-1) == "ok" {printf "%s ", $1}')"
  # (a sysroot without MANIFEST is the first version's, 2026-11-28, which unpacked libmatio11 without the
  # HDF5 and curl libraries it loads: its markers do not count, and it is completed)
  for p in "${CROSS_PKGS[@]}"; do
    [ -e "$CROSS_ROOT/.unpacked/$p" ] && [ -e "$CROSS_ROOT/.unpacked/MANIFEST" ] && continue
    case "$installed" in *" $p "*) ;; *) cross_missing+=("$p") ;; esac
  done
fi

# The private apt of the target alone. APT::Architectures lists the target only, so neither the host's
# indices nor its packages enter; the status file is the one cross_fake_status writes.
PA=(-o "Dir::State=$CROSS_ROOT/.apt/state" -o "Dir::State::status=$CROSS_ROOT/.apt/status"
    -o "Dir::Cache=$CROSS_ROOT/.apt/cache" -o "Dir::Cache::archives=$CROSS_ROOT/.debs"
    -o "APT::Architecture=$CROSS_ARCH" -o "APT::Architectures::=$CROSS_ARCH"
    -o Acquire::IndexTargets::deb::DEP-11::DefaultEnabled=false -o APT::Sandbox::User=root)

# The libraries the cross toolchain already brings (libc6, libc6-dev, linux-libc-dev, libgcc-s1,
# libstdc++6, ...: the host's <name>-<arch>-cross packages), written into the private dpkg status as
# installed, with no dependencies of their own: the private apt does not take them again. Their version
# is the cross package's without its "crossN" (libc6 2.36-8 for libc6-armhf-cross 2.36-8cross1).
cross_fake_status() {
  dpkg-query -W -f='${db:Status-Abbrev}|${Package}|${Version}|${Provides}\n' "*-$CROSS_ARCH-cross" 2>/dev/null |
    awk -F'|' -v s="-$CROSS_ARCH-cross" -v a="$CROSS_ARCH" '$1 ~ /^ii/ {
      n = $2; sub(s "$", "", n); v = $3; sub(/cross[0-9]+$/, "", v); pr = ""
      k = split($4, P, /, */)
      for (i = 1; i <= k; i++) if (index(P[i], s)) { q = P[i]; sub(s, "", q); gsub(/cross[0-9]+/, "", q); pr = pr (pr ? ", " : "") q }
      printf "Package: %s\nStatus: install ok installed\nArchitecture: %s\nVersion: %s\n", n, a, v
      if (pr != "") printf "Provides: %s\n", pr
      print "" }' || true
}

# The target's indices named in apt-get update's output on stdin as failing to download.
failed_index() { grep -o "Failed to fetch [^ ]*/binary-$CROSS_ARCH/[^ ]*" | sort -u | sed 's/^Failed to fetch //' | paste -sd' '; }

# cross_probe: 0 when every index of the target downloaded into the private state, 1 when an index of
# binary-<arch> failed to download (the fallback's condition), 2 on any other failure.
cross_probe() {
  local out rc=0
  as_root mkdir -p "$CROSS_ROOT/.apt/state/lists/partial" "$CROSS_ROOT/.apt/cache/archives/partial" \
    "$CROSS_ROOT/.debs/partial"
  cross_fake_status | as_root tee "$CROSS_ROOT/.apt/status" > /dev/null
  out=$(as_root apt-get "${PA[@]}" update 2>&1) || rc=$?
  printf '%s\n' "$out" >> deps.log
  if grep -q "Failed to fetch .*/binary-$CROSS_ARCH/" <<< "$out"; then
    FAILED_INDEX=$(failed_index <<< "$out")
    return 1
  fi
  [ "$rc" = 0 ] || return 2
}

# cross_multiarch PKG...: the normal install. Returns 1 (the caller falls back to the sysroot) when the
# host's update fails on the target's index after all (a mirror changing between the two downloads; the
# architecture is then unregistered again if this run registered it), or when the install fails with the
# lists the host has.
cross_multiarch() {
  local added=0 out rc=0
  if ! dpkg --print-foreign-architectures | grep -qx "$CROSS_ARCH"; then
    as_root dpkg --add-architecture "$CROSS_ARCH"; added=1
  fi
  export DEBIAN_FRONTEND=noninteractive
  out=$(as_root apt-get update -qq 2>&1) || rc=$?
  printf '%s\n' "$out" >> deps.log
  if grep -q "Failed to fetch .*/binary-$CROSS_ARCH/" <<< "$out"; then
    FAILED_INDEX=$(failed_index <<< "$out")
    if [ "$added" = 1 ]; then as_root dpkg --remove-architecture "$CROSS_ARCH"; fi
    return 1
  fi
  [ "$rc" = 0 ] || echo "deps: apt-get update reported errors (deps.log); installing from the lists apt has" >&2
  # another foreign architecture's failing index costs this one its security lists too (armhf's did
  # arm64's, 2026-11-28): then the install fails although every index of this one downloaded
  if ! as_root apt-get install -y -qq --no-install-recommends "$@" >> deps.log 2>&1; then
    FAILED_INDEX="(apt-get install $* failed with the host's lists; see deps.log)"
    return 1
  fi
  echo "deps: $CROSS_ARCH: installed $* from Debian's multiarch archive (dpkg --add-architecture $CROSS_ARCH)" >&2
}

# cross_sysroot PKG...: the fallback. The private apt resolves PKG and what they depend on from the
# target's indices that did download (bookworm and bookworm-updates: the main archive), less what the
# cross toolchain brings (cross_fake_status); `apt-get install --download-only` fetches the .debs into
# $CROSS_ROOT/.debs and checks each against the SHA256 of its signed index (InRelease, verified with the
# host's Debian keyring), and `dpkg -x` unpacks them into $CROSS_ROOT, outside any dpkg database: the
# host's packages, its dpkg architectures and its apt lists stay as they were. The sysroot is then made
# merged-/usr (lib -> usr/lib, as the host), absolute symbolic links are pointed into it, and the .pc
# files' prefix too. cmake/linux-cross.cmake and scripts/cross_test.sh take it from $CROSS_ROOT/usr.
cross_sysroot() {
  local deb l t
  if ! ls "$CROSS_ROOT/.apt/state/lists/"*"_binary-${CROSS_ARCH}_Packages"* > /dev/null 2>&1; then
    echo "deps: no index of $CROSS_ARCH downloaded at all (deps.log): nothing to unpack from" >&2; exit 1
  fi
  as_root find "$CROSS_ROOT/.debs" -maxdepth 1 -name '*.deb' -delete
  as_root apt-get "${PA[@]}" install --download-only -y -qq --no-install-recommends "${@%:*}" >> deps.log 2>&1 || {
    tail -30 deps.log; echo "deps: apt-get download of $* from the $CROSS_ARCH main archive failed (see deps.log)" >&2; exit 1; }
  as_root mkdir -p "$CROSS_ROOT/.unpacked"
  for deb in "$CROSS_ROOT/.debs/"*.deb; do
    as_root dpkg -x "$deb" "$CROSS_ROOT"
    dpkg-deb -W --showformat='${Package} ${Version} ${Architecture}\n' "$deb" | as_root tee -a "$CROSS_ROOT/.unpacked/MANIFEST" > /dev/null
  done
  if [ -d "$CROSS_ROOT/lib" ] && [ ! -L "$CROSS_ROOT/lib" ]; then
    as_root mkdir -p "$CROSS_ROOT/usr/lib"
    as_root cp -a "$CROSS_ROOT/lib/." "$CROSS_ROOT/usr/lib/"
    as_root rm -rf "$CROSS_ROOT/lib"
    as_root ln -s usr/lib "$CROSS_ROOT/lib"
  fi
  as_root find "$CROSS_ROOT/usr" -type l -lname '/*' -print | while IFS= read -r l; do
    t=$(realpath -m --relative-to="$(dirname "$l")" "$CROSS_ROOT$(readlink "$l")"); as_root ln -sfn "$t" "$l"
  done
  for pc in "$CROSS_ROOT/usr/lib/$triplet/pkgconfig"/*.pc "$CROSS_ROOT/usr/share/pkgconfig"/*.pc; do
    [ -e "$pc" ] && as_root sed -i "s|^prefix=/usr\$|prefix=$CROSS_ROOT/usr|" "$pc"
  done
  for p in "$@"; do as_root touch "$CROSS_ROOT/.unpacked/$p"; done
  echo "deps: $CROSS_ARCH: unpacked $(ls "$CROSS_ROOT/.debs/"*.deb | wc -l) packages ($*, their dependencies) from" \
       "the main archive into $CROSS_ROOT (list: $CROSS_ROOT/.unpacked/MANIFEST); dpkg and the host's apt lists untouched" >&2
  if dpkg --print-foreign-architectures | grep -qx "$CROSS_ARCH"; then
    echo "deps: $CROSS_ARCH was registered with dpkg before this run and is left so; the host's apt-get update" \
         "reports the failing index until the mirror is in sync (or: remove the :$CROSS_ARCH packages, then" \
         "dpkg --remove-architecture $CROSS_ARCH)" >&2
  fi
}

if [ ${#cross_missing[@]} -gt 0 ]; then
  echo "deps: $CROSS_ARCH: ${cross_missing[*]} missing; downloading the $CROSS_ARCH indices apart from the host's (log: deps.log)"
  FAILED_INDEX=""
  probe=0
  if [ "${MSID_CROSS_SYSROOT:-0}" = 1 ]; then
    cross_probe || probe=$?
    echo "deps: $CROSS_ARCH: MSID_CROSS_SYSROOT=1: the private sysroot, not the multiarch install" >&2
    cross_sysroot "${cross_missing[@]}"
  else
    cross_probe || probe=$?
    if [ "$probe" = 1 ]; then
      echo "deps: $CROSS_ARCH: fallback: the index $FAILED_INDEX failed to download; multiarch apt cannot install" \
           "the target's libraries beside the host's, so they are unpacked into a private sysroot" >&2
      cross_sysroot "${cross_missing[@]}"
    elif ! cross_multiarch "${cross_missing[@]}"; then
      echo "deps: $CROSS_ARCH: fallback: the multiarch install failed: $FAILED_INDEX" >&2
      cross_sysroot "${cross_missing[@]}"
    fi
  fi
fi

# The target's Python (MSID_CROSS_PYTHON=1) into the private sysroot, once. NumPy's BLAS and LAPACK are
# found through links that update-alternatives would make (no maintainer script runs in a sysroot).
if [ ${#CROSS_PY_PKGS[@]} -gt 0 ]; then
  py_cross_missing=()
  for p in "${CROSS_PY_PKGS[@]}"; do [ -e "$CROSS_ROOT/.unpacked/$p" ] || py_cross_missing+=("$p"); done
  if [ ${#py_cross_missing[@]} -gt 0 ]; then
    echo "deps: $CROSS_ARCH: the target's Python (${py_cross_missing[*]}) into $CROSS_ROOT (log: deps.log)"
    cross_probe || [ $? = 1 ] || { tail -20 deps.log; echo "deps: the $CROSS_ARCH indices could not be downloaded" >&2; exit 1; }
    cross_sysroot "${py_cross_missing[@]}"
    for lib in blas/libblas.so.3 lapack/liblapack.so.3; do
      if [ -e "$CROSS_ROOT/usr/lib/$triplet/$lib" ]; then as_root ln -sfn "$lib" "$CROSS_ROOT/usr/lib/$triplet/${lib#*/}"; fi
    done
  fi
fi

# One interpreter, find_spec only (importing matplotlib alone takes a second): the modules not found.
py_missing() { python3 -c 'import importlib.util as u, sys
print(" ".join(m for m in sys.argv[1:] if u.find_spec(m) is None))' "${PY_MODS[@]}" 2>/dev/null ||
  echo "${PY_MODS[*]}"; }
need=$(py_missing)
if [ -n "$need" ]; then
  # Debian's own python3 takes Debian packages; any other python3 on PATH (pyenv, venv) takes pip.
  if [ "$(command -v python3)" = /usr/bin/python3 ]; then
    pk=(); for m in $need; do pk+=("python3-$m"); done
    export DEBIAN_FRONTEND=noninteractive
    as_root apt-get install -y -qq --no-install-recommends "${pk[@]}" >> deps.log 2>&1 || true
  fi
  need=$(py_missing)
  if [ -n "$need" ]; then
    echo "deps: pip installing $need"
    python3 -m pip install -q $need >> deps.log 2>&1 || {
      tail -20 deps.log; echo "deps: pip install $need failed (see deps.log)" >&2; exit 1; }
  fi
fi
need=$(py_missing)
[ -z "$need" ] || { echo "deps: python modules still missing: $need" >&2; exit 1; }
[ "$DEMO_ONLY" = 0 ] || exit 0

# python-can and cantools (PyPI names) for the interpreter that runs the tests (tests/vcan, tests/dbc);
# cantools pinned: it is the peer of msid's DBC codec (tests/dbc/test_dbc_peer.py).
CANTOOLS=45.1.0
can_missing() { local out=(); python3 -c "import can" 2>/dev/null || out+=(python-can)
  python3 -c "import cantools, sys; sys.exit(cantools.__version__ != '$CANTOOLS')" 2>/dev/null ||
    out+=("cantools==$CANTOOLS"); echo "${out[*]:-}"; }
need=$(can_missing)
if [ -n "$need" ]; then
  echo "deps: pip installing $need"
  { python3 -m pip install -q $need || python3 -m pip install -q --break-system-packages $need; } >> deps.log 2>&1 || {
    tail -20 deps.log; echo "deps: pip install $need failed (see deps.log)" >&2; exit 1; }
  [ -z "$(can_missing)" ] || { echo "deps: python modules still missing: $(can_missing)" >&2; exit 1; }
fi

# The DBC files tests/dbc compares on: cantools' source distribution (its tests/files/dbc) and the
# opendbc wheel (production DBCs), pinned, into a cache (never committed; the test fetches them too).
OPENDBC=0.3.1
DBC_CACHE=${MSID_DBC_CACHE:-/var/cache/msid-dbc}
if [ ! -f "$DBC_CACHE/cantools-$CANTOOLS.tar.gz" ] || ! ls "$DBC_CACHE"/opendbc-$OPENDBC-*.whl >/dev/null 2>&1; then
  as_root mkdir -p "$DBC_CACHE"
  echo "deps: fetching the DBC files of cantools $CANTOOLS and opendbc $OPENDBC into $DBC_CACHE"
  { as_root python3 -m pip download -q --no-deps --no-binary :all: -d "$DBC_CACHE" "cantools==$CANTOOLS" &&
    as_root python3 -m pip download -q --no-deps -d "$DBC_CACHE" "opendbc==$OPENDBC"; } >> deps.log 2>&1 ||
    echo "deps: could not fetch the DBC files (tests/dbc fetches them itself; see deps.log)" >&2
fi

# scikit-build-core (PyPI; not in bookworm): the build backend of tools/python/pyproject.toml, which
# tests/python's offline `pip install ./tools/python` (files only: -C wheel.cmake=false) needs.
skb_missing() { python3 -c "import scikit_build_core" 2>/dev/null || echo scikit-build-core; }
need=$(skb_missing)
if [ -n "$need" ]; then
  echo "deps: pip installing $need"
  { python3 -m pip install -q $need || python3 -m pip install -q --break-system-packages $need; } >> deps.log 2>&1 || {
    tail -20 deps.log; echo "deps: pip install $need failed (see deps.log)" >&2; exit 1; }
fi

# pip_pinned CHECK-FUNCTION NAME: install what CHECK-FUNCTION prints (a pinned spec) unless it prints nothing.
pip_pinned() {
  local need; need=$($1)
  [ -n "$need" ] || return 0
  echo "deps: pip installing $need"
  { python3 -m pip install -q "$need" || python3 -m pip install -q --break-system-packages "$need"; } >> deps.log 2>&1 || {
    tail -20 deps.log; echo "deps: pip install $need failed (see deps.log)" >&2; exit 1; }
  [ -z "$($1)" ] || { echo "deps: $2 still missing" >&2; exit 1; }
}

# pybind11 (PyPI, pinned) for the compiled module msid._msid when the test interpreter's NumPy is 2.x:
# Debian's pybind11-dev 2.10 predates NumPy 2 and reads a wrong item size from its dtypes (every element
# of a 1-D array built in C++ lands on the first). tools/python/CMakeLists.txt refuses that pair.
PYBIND11=3.1.0
pybind11_missing() { python3 - "$PYBIND11" <<'PY' 2>/dev/null || echo "pybind11==$PYBIND11"
import sys, numpy
if int(numpy.__version__.split(".")[0]) < 2:
    sys.exit(0)
import pybind11
sys.exit(pybind11.__version__ != sys.argv[1])
PY
}
pip_pinned pybind11_missing "pybind11 $PYBIND11"

# pymodbus (PyPI, pinned; needs Python >= 3.10) with pyserial: the independent Modbus peer (tests/modbus).
PYMODBUS=3.16.1
mb_missing() { python3 -c "import pymodbus, serial, sys; sys.exit(pymodbus.__version__ != '$PYMODBUS')" 2>/dev/null ||
  echo "pymodbus[serial]==$PYMODBUS"; }
pip_pinned mb_missing "pymodbus $PYMODBUS"

# canopen (PyPI, pinned): the independent CANopen node (a LocalNode from an EDS) of msid's CANopen master
# on vcan in the VM (tests/vcan/in_vm/test_canopen.py).
CANOPEN=2.4.1
co_missing() { python3 -c "import canopen, sys; sys.exit(canopen.__version__ != '$CANOPEN')" 2>/dev/null ||
  echo "canopen==$CANOPEN"; }
pip_pinned co_missing "canopen $CANOPEN"

# scikit-rf (PyPI, pinned): VectorFitting is the independent peer of the parametric fits
# (tests/integration/test_fit_structures.py, msid bench fit); its Touchstone reader and example files
# that of msid import (tests/integration/test_import.py).
SKRF=2.2.0
skrf_missing() { python3 -c "import skrf, sys; sys.exit(skrf.__version__ != '$SKRF')" 2>/dev/null || echo "scikit-rf==$SKRF"; }
pip_pinned skrf_missing "scikit-rf $SKRF"

# pyuff (PyPI, pinned): reads the UFF 58 files msid import reads (tests/integration/test_import.py).
PYUFF=2.5.8
pyuff_missing() { python3 -c "import pyuff, sys; sys.exit(pyuff.__version__ != '$PYUFF')" 2>/dev/null || echo "pyuff==$PYUFF"; }
pip_pinned pyuff_missing "pyuff $PYUFF"

# sdypy-EMA (PyPI, pinned): LSCF, the independent modal peer of ml on the real F-16 record
# (tests/integration/test_f16_record.py, msid bench fit --only modal).
SDYPY_EMA=0.31.0
ema_missing() { python3 -c "import sdypy.EMA, sys; sys.exit(sdypy.EMA.__version__ != '$SDYPY_EMA')" 2>/dev/null ||
  echo "sdypy-EMA==$SDYPY_EMA"; }
pip_pinned ema_missing "sdypy-EMA $SDYPY_EMA"

# Hypothesis (PyPI, pinned): the hostile-input campaign of the Python package (tests/python/test_py_hostile.py).
HYPOTHESIS=6.155.2
hypothesis_missing() { python3 -c "import hypothesis, sys; sys.exit(hypothesis.__version__ != '$HYPOTHESIS')" 2>/dev/null ||
  echo "hypothesis==$HYPOTHESIS"; }
pip_pinned hypothesis_missing "hypothesis $HYPOTHESIS"

# python-control (PyPI `control`, pinned): FRD/StateSpace/TransferFunction conversion of the Python package.
PYCONTROL=0.10.2
control_missing() { python3 -c "import control, sys; sys.exit(control.__version__ != '$PYCONTROL')" 2>/dev/null ||
  echo "control==$PYCONTROL"; }
pip_pinned control_missing "python-control $PYCONTROL"

# The vcan VM boots Debian's own kernel: the package linux-image-amd64 depends on, fetched
# with apt-get download and unpacked with dpkg -x, once (tests/vcan/vm.py reads it there).
VCAN_DIR=${MSID_VCAN_DIR:-/var/cache/msid-vcan/k}
kernel_pkg() { apt-cache depends linux-image-amd64 2>/dev/null |
  sed -n 's/^ *Depends: \(linux-image-[0-9][^ ]*-amd64\)$/\1/p' | head -1; }
if ! ls "$VCAN_DIR"/boot/vmlinuz-* >/dev/null 2>&1; then
  kpkg=$(kernel_pkg)
  if [ -z "$kpkg" ]; then as_root apt-get update -qq >> deps.log 2>&1 || true; kpkg=$(kernel_pkg); fi
  [ -n "$kpkg" ] || { echo "deps: cannot resolve the kernel package of linux-image-amd64" >&2; exit 1; }
  echo "deps: fetching $kpkg for the vcan VM (log: deps.log)"
  kdir=$(dirname "$VCAN_DIR")
  as_root mkdir -p "$kdir"
  ( cd "$kdir" && as_root apt-get download "$kpkg" ) >> deps.log 2>&1 || {
    tail -20 deps.log; echo "deps: apt-get download $kpkg failed (see deps.log)" >&2; exit 1; }
  as_root rm -rf "$VCAN_DIR.tmp"
  as_root dpkg -x "$(ls -t "$kdir/$kpkg"_*.deb | head -1)" "$VCAN_DIR.tmp" && as_root mv "$VCAN_DIR.tmp" "$VCAN_DIR" || {
    echo "deps: unpacking $kpkg failed" >&2; exit 1; }
fi

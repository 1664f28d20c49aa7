#!/usr/bin/env bash
# Install what msid needs on Debian bookworm, only where it is missing.
# Called by ./bootstrap.sh; safe to run again.
set -euo pipefail
trap 'echo "deps: failed (exit $?) at line $LINENO: $BASH_COMMAND" >&2' ERR

APT_PKGS=(build-essential cmake ninja-build pkg-config libcmocka-dev libfftw3-dev libmatio-dev zlib1g-dev
          nlohmann-json3-dev libeigen3-dev python3 python3-pip)
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
            libeigen3-dev libmodbus-dev python3 python3-pip)
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
case "${1:-}" in
  ""|demo) ;;
  cross-arm64|cross-armhf)
    CROSS_ARCH=${1#cross-}
    APT_PKGS+=("crossbuild-essential-$CROSS_ARCH" qemu-user)
    for p in libfftw3-dev libmodbus-dev libcmocka-dev zlib1g-dev libmatio11; do CROSS_PKGS+=("$p:$CROSS_ARCH"); done ;;
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
# The target's packages carry their architecture (binary:Package prints it, e.g. libfftw3-dev:arm64). One
# unpacked by cross_unpack below (a marker in its directory) counts as there.
CROSS_ROOT=""
cross_missing=()
if [ ${#CROSS_PKGS[@]} -gt 0 ]; then
  case "$CROSS_ARCH" in arm64) triplet=aarch64-linux-gnu ;; armhf) triplet=arm-linux-gnueabihf ;; esac
  CROSS_ROOT=${MSID_CROSS_ROOT:-/opt/msid-cross/$triplet}   # cmake/linux-cross.cmake reads the same place
  installed=" $({ dpkg-query -W -f='${binary:Package} ${Status}\n' "${CROSS_PKGS[@]}" 2>/dev/null || true; } |
               awk '$NF == "installed" && $(NF-1) == "ok" {printf "%s ", $1}')"
  for p in "${CROSS_PKGS[@]}"; do
    [ -e "$CROSS_ROOT/.unpacked/$p" ] && continue
    case "$installed" in *" $p "*) ;; *) cross_missing+=("$p") ;; esac
  done
  if [ ${#cross_missing[@]} -gt 0 ] && ! dpkg --print-foreign-architectures | grep -qx "$CROSS_ARCH"; then
    as_root dpkg --add-architecture "$CROSS_ARCH"
  fi
fi
if [ ${#missing[@]} -gt 0 ] || [ ${#cross_missing[@]} -gt 0 ]; then
  echo "deps: installing ${missing[*]} ${cross_missing[*]} (log: deps.log)"
  export DEBIAN_FRONTEND=noninteractive
  # An index that fails to download (a mirror in sync) leaves apt the lists it had: the install says
  # whether those were enough.
  as_root apt-get update -qq >> deps.log 2>&1 || echo "deps: apt-get update reported errors (deps.log); installing from the lists apt has" >&2
fi
if [ ${#missing[@]} -gt 0 ]; then
  as_root apt-get install -y -qq --no-install-recommends "${missing[@]}" \
    >> deps.log 2>&1 || { tail -30 deps.log; echo "deps: apt-get failed (see deps.log)" >&2; exit 1; }
fi

# cross_unpack PKG...: the target's packages apt cannot install beside the host's, from the main archive.
# A -dev package of Multi-Arch: same must have the host's exact version; when the host has a security
# update and the target's security index cannot be downloaded (a mirror in sync), apt has no such
# version. `apt-get download` takes the main archive's (checked against its signed index), `dpkg -x`
# unpacks it into CROSS_ROOT, outside dpkg's database (the host's packages are not touched), and the
# .pc files are pointed there. cmake/linux-cross.cmake and scripts/cross_test.sh find them there.
cross_unpack() {
  local p deb
  as_root mkdir -p "$CROSS_ROOT/.debs" "$CROSS_ROOT/.unpacked"
  for p in "$@"; do
    # the run-time library beside its -dev package
    local with=("$p")
    case "$p" in libmodbus-dev:*) with+=("libmodbus5:$CROSS_ARCH") ;; zlib1g-dev:*) with+=("zlib1g:$CROSS_ARCH") ;; esac
    ( cd "$CROSS_ROOT/.debs" && as_root apt-get download "${with[@]}" ) >> deps.log 2>&1 || {
      tail -20 deps.log; echo "deps: apt-get download ${with[*]} failed (see deps.log)" >&2; exit 1; }
    for deb in "${with[@]}"; do
      as_root dpkg -x "$(ls -t "$CROSS_ROOT/.debs/${deb%%:*}"_*_"$CROSS_ARCH".deb | head -1)" "$CROSS_ROOT"
    done
    as_root touch "$CROSS_ROOT/.unpacked/$p"
  done
  for pc in "$CROSS_ROOT/usr/lib/$triplet/pkgconfig"/*.pc; do
    [ -e "$pc" ] && as_root sed -i "s|^prefix=/usr\$|prefix=$CROSS_ROOT/usr|" "$pc"
  done
  echo "deps: unpacked $* from the main archive into $CROSS_ROOT (apt could not install them beside the host's)" >&2
}
if [ ${#cross_missing[@]} -gt 0 ]; then
  if ! as_root apt-get install -y -qq --no-install-recommends "${cross_missing[@]}" >> deps.log 2>&1; then
    # one at a time: what apt can install, it installs; the rest is unpacked
    unpack=()
    for p in "${cross_missing[@]}"; do
      as_root apt-get install -y -qq --no-install-recommends "$p" >> deps.log 2>&1 || unpack+=("$p")
    done
    cross_unpack "${unpack[@]}"
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

# python-can and cantools (PyPI names) for the interpreter that runs the tests (tests/vcan).
can_missing() { local out=(); python3 -c "import can" 2>/dev/null || out+=(python-can)
  python3 -c "import cantools" 2>/dev/null || out+=(cantools); echo "${out[*]:-}"; }
need=$(can_missing)
if [ -n "$need" ]; then
  echo "deps: pip installing $need"
  { python3 -m pip install -q $need || python3 -m pip install -q --break-system-packages $need; } >> deps.log 2>&1 || {
    tail -20 deps.log; echo "deps: pip install $need failed (see deps.log)" >&2; exit 1; }
  [ -z "$(can_missing)" ] || { echo "deps: python modules still missing: $(can_missing)" >&2; exit 1; }
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

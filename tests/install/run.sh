#!/usr/bin/env bash
# Install and reuse (docs/install.md), run by ctest (label integration):
#   install  BUILD WORK: cmake --install BUILD --prefix WORK/prefix, then an out-of-tree C consumer built
#            with CMake (find_package(msid)) and with pkg-config (msid.pc, --static), both run, and a C++ consumer
#            of the host libraries (msid::frfjob and msid::fitjob: the FRF job on samples in memory and a model
#            fitted to its FRF) and one of msid::acquire
#            (a device URI, a device that is not there) run; the installed
#            msid and msid-devsim run, and the installed msid finds its Python package (share/msid/python).
#   nomodbus SRC WORK: a configure without libmodbus visible to pkg-config builds the daq library and the
#            device simulator without any libmodbus symbol, and both name the option when Modbus is asked for.
#   nocan    SRC WORK: -DMSID_WITH_CAN=OFF builds the daq library (Modbus kept) and the device simulator
#            without the SocketCAN transport, and the simulator names the option when CAN is asked for.
set -euo pipefail
mode=$1
fail() { echo "install test: $*" >&2; exit 1; }
case "$mode" in
install)
  build=$2 work=$3
  rm -rf "$work" && mkdir -p "$work"
  P=$work/prefix
  cmake --install "$build" --prefix "$P" > "$work/install.log"
  for f in include/msid/msid.h include/msid_daq/msid_daq.h include/msid_fit/frf_data.hpp lib/libmsid.a \
           lib/libmsid_daq.a lib/libmsid_fit.a bin/msid bin/msid-devsim lib/cmake/msid/msidConfig.cmake \
           lib/cmake/msid/msidConfigVersion.cmake lib/pkgconfig/msid.pc share/msid/python/msid/plot.py \
           include/msid_host/msid_frf_job.hpp lib/libmsid_records.a lib/libmsid_frfjob.a \
           include/msid_host/msid_fit_job.hpp lib/libmsid_fitjob.a lib/libmsid_frfimport.a lib/libmsid_frfexport.a; do
    [ -e "$P/$f" ] || fail "$P/$f was not installed"
  done
  [ "$("$P/bin/msid" version | cut -d' ' -f1)" = msid ] || fail "installed msid does not run"
  "$P/bin/msid-devsim" --help > /dev/null 2>&1 || [ $? -le 2 ] || fail "installed msid-devsim does not run"
  # CMake consumer
  here=$(cd "$(dirname "$0")" && pwd)
  cmake -S "$here/consumer" -B "$work/cmake-build" -DCMAKE_PREFIX_PATH="$P" -DCMAKE_BUILD_TYPE=Release \
        > "$work/consumer-configure.log" 2>&1 || { cat "$work/consumer-configure.log"; fail "consumer configure failed"; }
  cmake --build "$work/cmake-build" > "$work/consumer-build.log" 2>&1 || { cat "$work/consumer-build.log"; fail "consumer build failed"; }
  "$work/cmake-build/consumer" || fail "the CMake consumer failed"
  [ -x "$work/cmake-build/host_consumer" ] || fail "find_package(msid) did not define msid::frfjob"
  "$work/cmake-build/host_consumer" || fail "the host-library consumer failed"
  grep -q MSID_CONSUMER_FIT "$work/cmake-build/CMakeFiles/host_consumer.dir/flags.make" ||
    fail "find_package(msid) did not define msid::fitjob (the consumer did not fit its FRF)"
  [ -x "$work/cmake-build/acquire_consumer" ] || fail "find_package(msid) did not define msid::acquire"
  "$work/cmake-build/acquire_consumer" || fail "the acquisition-library consumer failed"
  # pkg-config consumer (static libraries: --static pulls libmodbus and libm)
  export PKG_CONFIG_PATH=$P/lib/pkgconfig
  [ "$(pkg-config --modversion msid)" = "$("$P/bin/msid" version | cut -d' ' -f2)" ] || fail "msid.pc version differs"
  # shellcheck disable=SC2046
  cc -std=c11 -o "$work/consumer-pc" "$here/consumer/consumer.c" $(pkg-config --cflags --libs --static msid) ||
    fail "pkg-config consumer build failed"
  "$work/consumer-pc" || fail "the pkg-config consumer failed"
  # the installed msid finds the installed Python package (not the source tree): MSID_PYTHON_DIR unset
  grep -c "share/msid/python" "$P/bin/msid" > /dev/null || fail "msid does not look in share/msid/python"
  echo "install test: ok ($P)"
  ;;
nomodbus|nocan)
  src=$2 work=$3
  rm -rf "$work" && mkdir -p "$work/pc"
  launcher=${CMAKE_C_COMPILER_LAUNCHER:+-DCMAKE_C_COMPILER_LAUNCHER=$CMAKE_C_COMPILER_LAUNCHER}
  if [ "$mode" = nomodbus ]; then
    # pkg-config sees no libmodbus (nor anything else): MSID_WITH_MODBUS=AUTO must drop Modbus, not fail
    what="without libmodbus"
    PKG_CONFIG_LIBDIR=$work/pc PKG_CONFIG_PATH= cmake -S "$src" -B "$work/b" -DCMAKE_BUILD_TYPE=Release \
        -DMSID_BUILD_TOOLS=OFF -DMSID_BUILD_TESTS=OFF $launcher > "$work/configure.log" 2>&1 || rc=$?
  else
    what="with MSID_WITH_CAN=OFF"
    cmake -S "$src" -B "$work/b" -DCMAKE_BUILD_TYPE=Release -DMSID_WITH_CAN=OFF -DMSID_WITH_MODBUS=ON \
        -DMSID_BUILD_TOOLS=OFF -DMSID_BUILD_TESTS=OFF $launcher > "$work/configure.log" 2>&1 || rc=$?
  fi
  [ "${rc:-0}" = 0 ] || { cat "$work/configure.log"; fail "configure $what failed"; }
  cmake --build "$work/b" --target msid_daq msid_devsim -j2 > "$work/build.log" 2>&1 ||
    { tail -30 "$work/build.log"; fail "build $what failed"; }
  lib=$(find "$work/b" -name libmsid_daq.a | head -1)
  dev=$(find "$work/b" -name msid-devsim -type f | head -1)
  # (symbol lists to files: `nm | grep -q` under pipefail fails when grep stops reading early)
  nm "$lib" > "$work/nm.txt" 2>/dev/null
  has() { grep -q " $1" "$work/nm.txt"; }
  # the simulator refuses the left-out transport with a message naming the build option
  refuses() { local out rc; set +e; out=$("$dev" "$1" "$2" 2>&1); rc=$?; set -e
    [ $rc -ne 0 ] && [[ "$out" == *"$3"* ]] || fail "msid-devsim $1 $2: '$out' (exit $rc)"; }
  has 'T msid_candump_parse' || fail "the candump reader is missing (it needs neither transport)"
  if [ "$mode" = nomodbus ]; then
    grep -q "libmodbus not found: building without the Modbus transport" "$work/configure.log" ||
      fail "configure did not say that Modbus is left out"
    ! has 'U modbus_' || fail "libmsid_daq.a still needs libmodbus"
    has 'T msid_socketcan_open' || fail "the CAN transport is missing"
    ldd "$dev" > "$work/ldd.txt"
    ! grep -q libmodbus "$work/ldd.txt" || fail "msid-devsim still links libmodbus"
    refuses --modbus-tcp 127.0.0.1:1502 "built without Modbus"
    echo "install test: CAN-only build ok"
  else
    # the SocketCAN transport's object is left out of the archive; its entry point is the stub
    ar t "$lib" > "$work/members.txt"
    ! grep -q '^msid_socketcan\.c\.o$' "$work/members.txt" || fail "libmsid_daq.a still holds the SocketCAN transport"
    grep -q '^msid_transport_none\.c\.o$' "$work/members.txt" || fail "the left-out transport's stub is not in the archive"
    has 'T msid_socketcan_open' || fail "the SocketCAN entry point (stub) is missing"
    has 'T msid_modbus_open' || fail "the Modbus transport is missing"
    refuses --iface vcan0 "without SocketCAN"
    echo "install test: Modbus-only build ok"
  fi
  ;;
*) fail "usage: run.sh install BUILD WORK | nomodbus SRC WORK | nocan SRC WORK" ;;
esac

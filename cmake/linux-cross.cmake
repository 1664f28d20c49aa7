# Shared part of the Linux cross toolchains (aarch64-linux-gnu.cmake, arm-linux-gnueabihf.cmake): Debian's
# cross compiler for MSID_CROSS_TRIPLET and the target's libraries from the multiarch archive
# (/usr/lib/<triplet>, /usr/include/<triplet>; `scripts/deps.sh cross-arm64|cross-armhf` installs both).
# No sysroot: Debian's cross gcc already searches the multiarch directories.
# Tests run through qemu-user, named on every command (CMAKE_CROSSCOMPILING_EMULATOR): no binfmt_misc needed.
# -L makes the program's loader the cross toolchain's (/usr/<triplet>/lib/ld-linux-*), and LD_LIBRARY_PATH makes
# its libc the same build's: without it the loader finds the multiarch libc (libc6:<arch>, another Debian
# revision) through /etc/ld.so.cache, and the mismatched pair loops forever in the first pthread_create.
# The multiarch libraries (FFTW, libmodbus, ...) are found under /usr/lib/<triplet> as usual.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_C_COMPILER ${MSID_CROSS_TRIPLET}-gcc)
set(CMAKE_CXX_COMPILER ${MSID_CROSS_TRIPLET}-g++)
set(CMAKE_AR ${MSID_CROSS_TRIPLET}-ar)
set(CMAKE_RANLIB ${MSID_CROSS_TRIPLET}-ranlib)
set(CMAKE_NM ${MSID_CROSS_TRIPLET}-nm)
set(CMAKE_STRIP ${MSID_CROSS_TRIPLET}-strip)
# No contraction into fused multiply-add anywhere (lib/ sets it for itself): ARM has FMA in its base ISA and
# GCC fuses a*b+c in C++ by default, which would change the last bits of the command line's numbers
# against x86-64's (docs/target.md "Linux bench controller": what is bit-identical across architectures).
set(CMAKE_C_FLAGS_INIT "-ffp-contract=off")
set(CMAKE_CXX_FLAGS_INIT "-ffp-contract=off")
# The target's libraries that apt could not install beside the host's, unpacked by scripts/deps.sh into
# $MSID_CROSS_ROOT (default /opt/msid-cross/<triplet>; their .pc files point there): found by find_package,
# pkg-config and, at run time, the emulator's LD_LIBRARY_PATH.
set(MSID_CROSS_ROOT "$ENV{MSID_CROSS_ROOT}")
if(NOT MSID_CROSS_ROOT)
  set(MSID_CROSS_ROOT /opt/msid-cross/${MSID_CROSS_TRIPLET})
endif()
set(_msid_cross_ld /usr/${MSID_CROSS_TRIPLET}/lib)
set(_msid_cross_pc "")
if(EXISTS ${MSID_CROSS_ROOT}/usr/lib/${MSID_CROSS_TRIPLET})
  list(APPEND CMAKE_PREFIX_PATH ${MSID_CROSS_ROOT}/usr)
  string(APPEND _msid_cross_ld ":${MSID_CROSS_ROOT}/usr/lib/${MSID_CROSS_TRIPLET}")
  set(_msid_cross_pc "${MSID_CROSS_ROOT}/usr/lib/${MSID_CROSS_TRIPLET}/pkgconfig:")
endif()
find_program(MSID_CROSS_QEMU_PATH ${MSID_CROSS_QEMU})
if(MSID_CROSS_QEMU_PATH)
  set(CMAKE_CROSSCOMPILING_EMULATOR ${MSID_CROSS_QEMU_PATH} -L /usr/${MSID_CROSS_TRIPLET}
      -E LD_LIBRARY_PATH=${_msid_cross_ld})
endif()
# pkg-config sees the target's .pc files only, and matio's headers (matio.pc in cross-pkgconfig/: the
# headers are the same on every architecture; libmatio-dev:<arch> cannot be installed beside the host's,
# and msid loads libmatio.so.11 with dlopen, so nothing links it).
set(ENV{PKG_CONFIG_LIBDIR} "${_msid_cross_pc}/usr/lib/${MSID_CROSS_TRIPLET}/pkgconfig:/usr/share/pkgconfig:${CMAKE_CURRENT_LIST_DIR}/cross-pkgconfig")
set(ENV{PKG_CONFIG_PATH} "")
set(CMAKE_LIBRARY_ARCHITECTURE ${MSID_CROSS_TRIPLET})
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)

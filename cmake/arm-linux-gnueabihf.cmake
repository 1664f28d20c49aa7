# Cross toolchain for 32-bit ARM Linux bench controllers (BeagleBone, Raspberry Pi OS 32-bit, i.MX 6/7;
# Debian armhf: ARMv7-A, VFPv3-D16, hard-float ABI; size_t and long are 32 bits there):
#   scripts/deps.sh cross-armhf
#   cmake -S . -B build-armhf -G Ninja -DCMAKE_TOOLCHAIN_FILE=cmake/arm-linux-gnueabihf.cmake
# or scripts/cross_test.sh armhf (builds and runs the suites under qemu-arm). docs/target.md.
set(CMAKE_SYSTEM_PROCESSOR armv7l)
set(MSID_CROSS_TRIPLET arm-linux-gnueabihf)
set(MSID_CROSS_QEMU qemu-arm)
include(${CMAKE_CURRENT_LIST_DIR}/linux-cross.cmake)
# GCC 7.1 changed how 32-bit ARM passes some aggregates (the std::vector iterators of libstdc++ among them),
# and GCC notes it at every such call (-Wpsabi). It matters only when linking with code built by GCC < 7.1,
# which Debian armhf does not ship; the notes buried real warnings in the build log.
string(APPEND CMAKE_CXX_FLAGS_INIT " -Wno-psabi")

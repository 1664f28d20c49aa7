# Cross toolchain for 64-bit ARM Linux bench controllers (Raspberry Pi 4/5, i.MX 8, Jetson; Debian arm64):
#   scripts/deps.sh cross-arm64
#   cmake -S . -B build-aarch64 -G Ninja -DCMAKE_TOOLCHAIN_FILE=cmake/aarch64-linux-gnu.cmake
# or scripts/cross_test.sh aarch64 (builds and runs the suites under qemu-aarch64). docs/target.md.
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(MSID_CROSS_TRIPLET aarch64-linux-gnu)
set(MSID_CROSS_QEMU qemu-aarch64)
include(${CMAKE_CURRENT_LIST_DIR}/linux-cross.cmake)

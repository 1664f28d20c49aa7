# Cross toolchain for Cortex-M microcontrollers (Debian: gcc-arm-none-eabi, libnewlib-arm-none-eabi).
#   cmake -S tests/target/cross -B build-m7 -DCMAKE_TOOLCHAIN_FILE=cmake/arm-none-eabi.cmake -DMSID_TARGET_CPU=cortex-m7
# MSID_TARGET_CPU:
#   cortex-m4f  Cortex-M4 with FPv4-SP: single-precision FPU, double precision in software (libgcc)
#   cortex-m7   Cortex-M7 with FPv5-D16: double-precision FPU
# Both use the hard-float ABI. The library keeps -ffp-contract=off (lib/CMakeLists.txt), so
# no fused multiply-add changes a rounding: the double results equal the host's bit for bit.
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)
set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_CXX_COMPILER arm-none-eabi-g++)
set(CMAKE_ASM_COMPILER arm-none-eabi-gcc)
set(CMAKE_AR arm-none-eabi-ar)
set(CMAKE_RANLIB arm-none-eabi-ranlib)
set(CMAKE_NM arm-none-eabi-nm)
set(CMAKE_SIZE arm-none-eabi-size)
set(CMAKE_OBJCOPY arm-none-eabi-objcopy)
# try_compile links a static library: no startup code or linker script needed.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)

set(MSID_TARGET_CPU "cortex-m7" CACHE STRING "cortex-m4f | cortex-m7")
set_property(CACHE MSID_TARGET_CPU PROPERTY STRINGS cortex-m4f cortex-m7)
if(MSID_TARGET_CPU STREQUAL "cortex-m4f")
  set(_msid_cpu_flags "-mcpu=cortex-m4 -mfpu=fpv4-sp-d16 -mfloat-abi=hard -mthumb")
elseif(MSID_TARGET_CPU STREQUAL "cortex-m7")
  set(_msid_cpu_flags "-mcpu=cortex-m7 -mfpu=fpv5-d16 -mfloat-abi=hard -mthumb")
else()
  message(FATAL_ERROR "MSID_TARGET_CPU must be cortex-m4f or cortex-m7 (got '${MSID_TARGET_CPU}')")
endif()
set(CMAKE_C_FLAGS_INIT "${_msid_cpu_flags} -ffunction-sections -fdata-sections")
set(CMAKE_CXX_FLAGS_INIT "${_msid_cpu_flags} -ffunction-sections -fdata-sections")
set(CMAKE_ASM_FLAGS_INIT "${_msid_cpu_flags}")
set(CMAKE_EXE_LINKER_FLAGS_INIT "${_msid_cpu_flags} -Wl,--gc-sections")

# Never pick up the build machine's libraries (FFTW, cmocka) through pkg-config or find_*.
set(ENV{PKG_CONFIG_LIBDIR} "/nonexistent")
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

# The demo build (MSID_DEMO=ON, what `./bootstrap.sh demo` configures; docs/benchmarks.md "Demo build").
# It builds msid and msid-devsim only (bootstrap.sh asks for those two targets, MSID_BUILD_TESTS=OFF) and
# leaves out of msid what `msid demo` never runs: every `msid bench`, `fit --method cissim|multi`,
# `fit --method ml --param poles`, `modbus|can measure --on-device`, `frf --method lpm|etfe` and
# `frf --direct` (with the sources behind them); msid/left_out.cpp answers those commands with one
# message naming `./bootstrap.sh build`. The C++ host code is compiled at MSID_DEMO_OPT, msid_fit and
# most command-line objects as unity sources (msid_demo_unity below). With MSID_DEMO=OFF (the default,
# ./bootstrap.sh build|test, CI) every command is built and msid_demo_quick does nothing: -O3
# everywhere, one object per source, so `msid bench` measures what it always did.
option(MSID_DEMO "Build only what `msid demo` runs (./bootstrap.sh demo)" OFF)
# -O0 is no cheaper: eigen_inst_linear.cpp 29.9 s of CPU at -O0, 29.0 s at -O1; cmd_fit.cpp 16.9 / 18.0 s
# (the time is template instantiation; docs/benchmarks.md "Demo build, fourth pass")
set(MSID_DEMO_OPT "-O1" CACHE STRING "Optimisation of the C++ host code in the demo build (MSID_DEMO=ON)")

# msid_demo_quick(target): in the demo build, compile this C++ target at MSID_DEMO_OPT.
function(msid_demo_quick target)
  if(MSID_DEMO)
    target_compile_options(${target} PRIVATE ${MSID_DEMO_OPT})
  endif()
endfunction()

# msid_demo_unity(target): in the demo build, compile this target's sources as one unity source (CMake
# UNITY_BUILD), so that what they all instantiate (Eigen's matrix-product kernels, nlohmann-json) is
# compiled once instead of once per file: template instantiation and its code, not header parsing nor
# optimisation, is the build time (docs/benchmarks.md "Demo build"; a precompiled header of
# nlohmann-json and Eigen takes `cmd_demo.cpp` only from 6.0 to 4.8 s of CPU and costs 7.8 s to build).
# Sources marked SKIP_UNITY_BUILD_INCLUSION stay apart (tools/fit's explicit instantiations,
# eigen_inst_*.cpp, which the second core compiles meanwhile; sources with file-local names of their
# own). With MSID_UNITY_BUILD (the sanitizer build of scripts/sanitize.sh) the same, in batches of a few
# sources that both cores compile side by side. The sources themselves are unchanged; the full build
# compiles them one by one as before.
option(MSID_UNITY_BUILD "Compile the Eigen-heavy host libraries as unity sources of a few files each" OFF)
function(msid_demo_unity target)
  if(MSID_DEMO)
    set_target_properties(${target} PROPERTIES UNITY_BUILD ON UNITY_BUILD_BATCH_SIZE 0)
  elseif(MSID_UNITY_BUILD)
    set_target_properties(${target} PROPERTIES UNITY_BUILD ON UNITY_BUILD_BATCH_SIZE 4)
  endif()
endfunction()

# msid_demo_unity_only(target): as msid_demo_unity in the demo build; MSID_UNITY_BUILD compiles these
# targets (light ones, no Eigen) one source at a time.
function(msid_demo_unity_only target)
  if(MSID_DEMO)
    set_target_properties(${target} PROPERTIES UNITY_BUILD ON UNITY_BUILD_BATCH_SIZE 0)
  endif()
endfunction()

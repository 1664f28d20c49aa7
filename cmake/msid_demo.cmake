# The demo build (MSID_DEMO=ON, what `./bootstrap.sh demo` configures; docs/benchmarks.md "Demo build").
# It builds msid and msid-devsim only (bootstrap.sh asks for those two targets, MSID_BUILD_TESTS=OFF) and
# makes that build cheaper without touching what the normal build produces:
#   - precompiled headers (Eigen, nlohmann-json, the standard headers) for the C++ libraries and msid;
#   - the C++ host code (FRF file, fitting, estimators, the CLI) at -O1 instead of -O3: the Eigen-heavy
#     fitting sources cost 40-100 s of CPU each at -O3, and what `msid demo` runs of them (an ml fit of
#     order 4 on 2x2, 0.05 s at -O3) stays well under a second. Every command works; the fits and
#     benches run slower than in the normal build. lib/, daq/ and the simulator (C) keep -O3.
# With MSID_DEMO=OFF (the default, ./bootstrap.sh build|test, CI) msid_demo_quick does nothing.
option(MSID_DEMO "Quick build of what `msid demo` runs (./bootstrap.sh demo): PCH, C++ host code at -O1" OFF)

# msid_demo_quick(target [NOPCH]): in the demo build, compile this C++ target at -O1, with precompiled
# headers unless NOPCH (a one-source target gains nothing from them).
function(msid_demo_quick target)
  if(MSID_DEMO)
    target_compile_options(${target} PRIVATE -O1)
    if(NOT "NOPCH" IN_LIST ARGN)
      target_precompile_headers(${target} PRIVATE <Eigen/Dense> <nlohmann/json.hpp> <complex> <string> <vector>)
    endif()
  endif()
endfunction()

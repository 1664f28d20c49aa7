# The demo build (MSID_DEMO=ON, what `./bootstrap.sh demo` configures; docs/benchmarks.md "Demo build").
# It builds msid and msid-devsim only (bootstrap.sh asks for those two targets, MSID_BUILD_TESTS=OFF) and
# makes that build cheaper without touching what the normal build produces:
#   - precompiled headers (Eigen, nlohmann-json, the standard headers) for the C++ libraries and msid;
#   - the sources `msid demo` never runs (listed where their target is made: cissim, multi, the BLA,
#     the LPM/ETFE/direct estimators, the bench, export and CAN commands) compiled at -O1: every command
#     still works, those run slower than in the normal -O3 build.
# With MSID_DEMO=OFF (the default, ./bootstrap.sh build|test, CI) both functions do nothing.
option(MSID_DEMO "Quick build of what `msid demo` runs (./bootstrap.sh demo): PCH, -O1 for the rest" OFF)

# msid_demo_pch(target): precompile the heavy headers of a C++ target (demo build only).
function(msid_demo_pch target)
  if(MSID_DEMO)
    target_precompile_headers(${target} PRIVATE <Eigen/Dense> <nlohmann/json.hpp> <complex> <string> <vector>)
  endif()
endfunction()

# msid_demo_light(target src...): in the demo build, these sources of `target` (paths relative to the
# current source directory) are compiled at -O1 and without the precompiled header (it was made at -O3).
function(msid_demo_light target)
  if(MSID_DEMO)
    set_source_files_properties(${ARGN} TARGET_DIRECTORY ${target} PROPERTIES
      COMPILE_OPTIONS "-O1" SKIP_PRECOMPILE_HEADERS ON)
  endif()
endfunction()

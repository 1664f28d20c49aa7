# The demo build (MSID_DEMO=ON, what `./bootstrap.sh demo` configures; docs/benchmarks.md "Demo build").
# It builds msid and msid-devsim only (bootstrap.sh asks for those two targets, MSID_BUILD_TESTS=OFF) and
# leaves out of msid what `msid demo` never runs: every `msid bench`, `fit --method cissim` and
# `fit --method multi` (with the cissim and multi fitting sources behind them); msid/left_out.cpp
# answers those commands with one message naming `./bootstrap.sh build`. The C++ host code is compiled
# at MSID_DEMO_OPT. With MSID_DEMO=OFF (the default, ./bootstrap.sh build|test, CI) every command is
# built and msid_demo_quick does nothing: -O3 everywhere, so `msid bench` measures what it always did.
option(MSID_DEMO "Build only what `msid demo` runs (./bootstrap.sh demo)" OFF)
set(MSID_DEMO_OPT "-O1" CACHE STRING "Optimisation of the C++ host code in the demo build (MSID_DEMO=ON)")

# msid_demo_quick(target): in the demo build, compile this C++ target at MSID_DEMO_OPT.
function(msid_demo_quick target)
  if(MSID_DEMO)
    target_compile_options(${target} PRIVATE ${MSID_DEMO_OPT})
  endif()
endfunction()

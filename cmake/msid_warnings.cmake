# One warning set for every msid target. msid_strict_warnings(target) adds:
#   C:   -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wno-sign-conversion
#        (the set lib/ always had: every implicit narrowing of a value is written out)
#   C++: -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Woverloaded-virtual
#        -Wcast-qual, and with GCC -Wduplicated-cond -Wlogical-op
#        without -Wconversion: Eigen's Index is a signed long, so every size_t/int/Index
#        meeting would need a cast, hundreds of them in the fitting code, which hides the
#        real conversions rather than finding them; without -Wnull-dereference: at -O3 it
#        reports "potential" null pointers inside Eigen's inlined reductions (maxCoeff of a
#        vector the caller sized), not in our code (docs/architecture.md "Warnings").
# MSID_WERROR=ON (CI: .ci/run sets the environment variable MSID_WERROR=ON) turns every
# warning of these targets into an error.
option(MSID_WERROR "Treat the compiler warnings of lib/ and tools/ as errors (CI)" OFF)
if(DEFINED ENV{MSID_WERROR} AND NOT "$ENV{MSID_WERROR}" STREQUAL "")
  set(MSID_WERROR "$ENV{MSID_WERROR}")
endif()

set(MSID_WARNINGS_C -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wno-sign-conversion)
set(MSID_WARNINGS_CXX -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Woverloaded-virtual -Wcast-qual)
if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
  list(APPEND MSID_WARNINGS_CXX -Wduplicated-cond -Wlogical-op)
endif()

function(msid_strict_warnings target)
  target_compile_options(${target} PRIVATE
    "$<$<COMPILE_LANGUAGE:C>:${MSID_WARNINGS_C}>"
    "$<$<COMPILE_LANGUAGE:CXX>:${MSID_WARNINGS_CXX}>")
  if(MSID_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()

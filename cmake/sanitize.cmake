# Sanitizer builds, included by CMakeLists.txt (where the options are) before any target, so
# that the flags reach the core, the test utilities and the tests alike.
#
# GMM_MCL_SANITIZE: every C++ target with AddressSanitizer and UndefinedBehaviorSanitizer
# (scripts/test.sh builds the unit tests this way in their own folder and runs them).
#   -fno-sanitize-recover=all: the first UB report aborts the test (a failure, not a log line).
#   -fno-omit-frame-pointer, -g1: whole stacks with file:line in the reports, at low build cost.
#   GCC's -fsanitize=undefined leaves out float-cast-overflow (clang's includes it): a float
#   that does not fit the integer it is cast to (a projected pixel coordinate turned into an
#   index, a NaN depth) is undefined behaviour, so ask for it.
# GMM_MCL_BUILD_FUZZERS (clang only; test/CMakeLists.txt, scripts/fuzz.sh): the libFuzzer targets.
#   Implies GMM_MCL_SANITIZE and adds libFuzzer's coverage instrumentation
#   (-fsanitize=fuzzer-no-link) to every target, so that the core's branches guide the fuzzer.
if(GMM_MCL_BUILD_FUZZERS)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "GMM_MCL_BUILD_FUZZERS needs clang (-DCMAKE_CXX_COMPILER=clang++); "
                        "the fuzz_replay_* tests replay the inputs with any compiler")
  endif()
  set(GMM_MCL_SANITIZE ON CACHE BOOL "" FORCE)
endif()

if(GMM_MCL_SANITIZE)
  set(GMM_MCL_SANITIZE_FLAGS -fsanitize=address,undefined -fno-sanitize-recover=all
      -fno-omit-frame-pointer -g1)
  if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
    list(APPEND GMM_MCL_SANITIZE_FLAGS -fsanitize=float-cast-overflow)
  endif()
  if(GMM_MCL_BUILD_FUZZERS)
    list(APPEND GMM_MCL_SANITIZE_FLAGS -fsanitize=fuzzer-no-link)
  endif()
  foreach(flag ${GMM_MCL_SANITIZE_FLAGS})
    add_compile_options($<$<COMPILE_LANGUAGE:CXX>:${flag}>)
  endforeach()
  # Link flags through the variables: add_link_options needs CMake 3.13, the project takes 3.10.
  foreach(kind EXE SHARED MODULE)
    set(CMAKE_${kind}_LINKER_FLAGS "${CMAKE_${kind}_LINKER_FLAGS} -fsanitize=address,undefined")
  endforeach()
  message(STATUS "gmm_mcl: sanitizers on (${GMM_MCL_SANITIZE_FLAGS})")
endif()

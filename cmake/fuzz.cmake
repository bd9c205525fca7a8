# Fuzzing (docs/reliability_fuzz.md). Each target in test/fuzz/fuzz_<name>.cpp defines
# LLVMFuzzerTestOneInput and is built twice:
#  - fuzz_replay_<name> (any compiler, with the tests): runs the checked-in seed corpus
#    (test/fuzz/corpus/<name>) and the reproducers of fixed bugs (test/fuzz/regressions/<name>)
#    through the same entry function, without libFuzzer; a ctest.
#  - fuzz_<name> (GMM_MCL_BUILD_FUZZERS, clang): the libFuzzer binary, with ASan and UBSan;
#    scripts/fuzz.sh builds and runs them. fuzz_make_corpus writes the corpus and reproducers.
set(GMM_MCL_FUZZ_TARGETS map_loader depth_frame)
if(PNG_FOUND)
  list(APPEND GMM_MCL_FUZZ_TARGETS compressed_depth)  # the compressedDepth decoder needs libpng
endif()
set(GMM_MCL_FUZZ_DIR ${CMAKE_CURRENT_LIST_DIR}/../test/fuzz)

if(GMM_MCL_BUILD_TESTS)
  foreach(name ${GMM_MCL_FUZZ_TARGETS})
    add_executable(fuzz_replay_${name} ${GMM_MCL_FUZZ_DIR}/fuzz_${name}.cpp
                                       ${GMM_MCL_FUZZ_DIR}/replay_main.cpp)
    target_link_libraries(fuzz_replay_${name} PRIVATE gmm_mcl_core)
    target_compile_options(fuzz_replay_${name} PRIVATE -Wall -Wextra)
    add_test(NAME fuzz_replay_${name}
             COMMAND fuzz_replay_${name} ${GMM_MCL_FUZZ_DIR}/corpus/${name}
                     ${GMM_MCL_FUZZ_DIR}/regressions/${name})
  endforeach()
  # The fixed faults as named gtest cases with their messages.
  gmm_mcl_add_gtest(test_input_validation ${GMM_MCL_FUZZ_DIR}/test_input_validation.cpp
                    gmm_mcl_core)
  # The CPU backend's OpenMP path, short enough for the sanitizer stage of scripts/test.sh.
  gmm_mcl_add_gtest(test_backend_threads ${GMM_MCL_FUZZ_DIR}/test_backend_threads.cpp
                    gmm_mcl_test_utils)
endif()

if(GMM_MCL_BUILD_FUZZERS)
  foreach(name ${GMM_MCL_FUZZ_TARGETS})
    add_executable(fuzz_${name} ${GMM_MCL_FUZZ_DIR}/fuzz_${name}.cpp)
    target_link_libraries(fuzz_${name} PRIVATE gmm_mcl_core)
    target_compile_options(fuzz_${name} PRIVATE -Wall -Wextra -fsanitize=fuzzer)
    # Custom mutators (fuzz_map_loader's checksum repair) exist only in the libFuzzer build.
    target_compile_definitions(fuzz_${name} PRIVATE GMM_MCL_LIBFUZZER=1)
    # target_link_options needs CMake 3.13; a link flag in the link libraries works on 3.10.
    target_link_libraries(fuzz_${name} PRIVATE -fsanitize=fuzzer)
  endforeach()
endif()

# The corpus generator (any compiler; built on demand by scripts/fuzz.sh).
if((GMM_MCL_BUILD_TESTS OR GMM_MCL_BUILD_FUZZERS) AND PNG_FOUND)
  add_executable(fuzz_make_corpus EXCLUDE_FROM_ALL ${GMM_MCL_FUZZ_DIR}/make_corpus.cpp)
  target_link_libraries(fuzz_make_corpus PRIVATE gmm_mcl_core)
endif()

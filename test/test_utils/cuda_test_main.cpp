// main() of the CUDA test programs: exit status 77 (a skip for ctest) with the reason when this
// machine has no CUDA device, else every case. --gtest_list_tests lists the cases either way.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <string>

#include "cuda/cuda_backend.h"

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  if (::testing::GTEST_FLAG(list_tests)) return RUN_ALL_TESTS();
  std::string why;
  if (gmm_mcl::cudaDeviceCount(&why) == 0) {
    const char* slash = std::strrchr(argv[0], '/');
    std::printf("%s: skipped: %s\n", slash ? slash + 1 : argv[0], why.c_str());
    return 77;
  }
  return RUN_ALL_TESTS();
}

// Shared by the CUDA backend's test files: skip without a device, the synthetic world's noisy
// depth images.
#pragma once

#include <gtest/gtest.h>

#include <random>
#include <string>

#include "gmm_mcl/backend/cuda_backend.h"
#include "gmm_mcl/sim/box_scene.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace test {

inline bool haveDevice(std::string* why) { return cudaDeviceCount(why) > 0; }

// The synthetic world from T_map_cam with the sensor model's noise and 5 % dropout, to 6 m.
inline DepthImage noisyImage(const Intrinsics& K, const Eigen::Isometry3d& T_map_cam,
                             DepthEncoding enc, std::mt19937_64* rng) {
  sim::DepthNoise noise;
  noise.dropout = 0.05;
  return sim::renderDepth(test::world().scene, K, T_map_cam, enc, 6.0, noise, rng);
}

}  // namespace test
}  // namespace gmm_mcl

#define GMM_MCL_REQUIRE_DEVICE()                                 \
  do {                                                           \
    std::string why;                                             \
    if (!::gmm_mcl::test::haveDevice(&why)) GTEST_SKIP() << why; \
  } while (0)

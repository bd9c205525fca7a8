// Shared by the CUDA backend's test files: the fixture (skip without a device), the synthetic
// world's noisy depth images.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <random>
#include <string>

#include "cuda/cuda_backend.h"
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

// Every case of the CUDA backend: skipped without a device; a backend with no map yet.
class CudaBackendTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string why;
    if (!test::haveDevice(&why)) GTEST_SKIP() << why;
    gpu = std::make_unique<CudaBackend>();
  }

  std::unique_ptr<CudaBackend> gpu;
};

}  // namespace gmm_mcl

// Kidnapped robot. The filter tracks from the true start, the sensor is teleported
// at least 1 m inside the recovery region while odometry reports the old motion, and the
// estimate must be back under 10 cm (held for 30 frames) within 5 s of data. CI runs two
// seeded 7-Scenes trials and one on the built-in synthetic scene at 640x480 (gmm_mcl_kidnap
// runs the full ten of each) and checks on the synthetic scene that without recovery a kidnap
// is not recovered.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <string>

#include "gmm_mcl/experiments/reliability/kidnap.h"
#include "gmm_mcl/fit/em_fitter.h"
#include "gmm_mcl/fit/seven_scenes_cloud.h"
#include "gmm_mcl/map/gmm_map_io.h"
#include "gmm_mcl/sim/mesh_scene.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {
namespace {

void print(const reliability::KidnapResult& r) {
  std::printf(
      "seed %2llu: frames %d..%d -> %d, jump %.2f m %.0f deg, error before %.1f cm, "
      "recovered in %.2f s, final error %.1f cm, lost events %d, mean step %.0f ms\n",
      static_cast<unsigned long long>(r.seed), r.start_frame, r.from_frame - 1, r.to_frame,
      r.jump_m, r.jump_yaw_rad * 180.0 / M_PI, 100.0 * r.error_before_m, r.recovery_s,
      100.0 * r.final_error_m, r.lost_events, r.mean_step_ms);
  std::fflush(stdout);
}

TEST(KidnapTest, SevenScenesRecoversWithinFiveSeconds) {
  const std::string root = test::datasetsRoot();
  if (root.empty()) GTEST_SKIP() << "no ../shared/datasets (set GMM_MCL_DATASETS)";
  const std::string dir = root + "/7scenes_redkitchen/data";
  // The map exactly as scripts/build_map_7scenes.sh builds it (M = 1000, seed 1).
  const EmParams ep;
  const EmResult fit = fitGmm(buildSevenScenesCloud(dir, SevenScenesCloudParams()), ep);
  const std::string map = ::testing::TempDir() + "/gmm_mcl_kidnap_7scenes_m1000.gmm";
  saveMap(makeStorableMap(fit.components, ep.reg_covar_m2, "7-Scenes fit"), map);
  const auto src = reliability::makeSevenScenesSource(dir, map);
  reliability::KidnapParams kp;
  kp.localizer.frame.pixel_stride = 8;
  for (uint64_t seed = 1; seed <= 2; ++seed) {
    const reliability::KidnapResult r = reliability::runKidnapTrial(*src, kp, seed);
    print(r);
    EXPECT_LT(r.error_before_m, 0.10) << "seed " << seed << ": not tracking before the kidnap";
    EXPECT_GE(r.jump_m, kp.min_jump_m);
    EXPECT_FALSE(r.any_non_finite);
    EXPECT_TRUE(r.recovered) << "seed " << seed << ": recovery " << r.recovery_s
                             << " s, final error " << r.final_error_m << " m";
  }
}

// The built-in mesh scene through the sensor model at 640x480 (the tool's default), CPU backend.
TEST(KidnapTest, SyntheticRecoversWithinFiveSeconds) {
  const auto src = reliability::makeSyntheticSource(sim::defaultCamera(640), 1500);
  reliability::KidnapParams kp;
  kp.localizer.frame.pixel_stride = 8;
  kp.localizer.frame.max_range_m = 8.f;
  const reliability::KidnapResult r = reliability::runKidnapTrial(*src, kp, 2);
  print(r);
  EXPECT_LT(r.error_before_m, 0.10) << "not tracking before the kidnap";
  EXPECT_GE(r.jump_m, kp.min_jump_m);
  EXPECT_FALSE(r.any_non_finite);
  EXPECT_TRUE(r.recovered) << "recovery " << r.recovery_s << " s, final error " << r.final_error_m
                           << " m";
}

// Without odometry (docs/no_odometry.md): the constant-velocity model, turned by the gyro's
// heading (which, like the odometry, feels the old trajectory's turn across the kidnap), tracks
// and recovers; the frames' random draws are those of the odometry trial.
TEST(KidnapTest, SyntheticRecoversWithoutOdometry) {
  const auto src = reliability::makeSyntheticSource(test::smallCamera(), 1500);
  reliability::KidnapParams kp;
  kp.localizer.frame.pixel_stride = 8;
  kp.localizer.frame.max_range_m = 8.f;
  kp.odometry = false;
  const reliability::KidnapResult r = reliability::runKidnapTrial(*src, kp, 2);
  print(r);
  EXPECT_LT(r.error_before_m, 0.10) << "not tracking before the kidnap";
  EXPECT_FALSE(r.any_non_finite);
  EXPECT_TRUE(r.recovered) << "recovery " << r.recovery_s << " s, final error " << r.final_error_m
                           << " m";
}

// Without recovery (no augmented MCL, no lost detector) the kidnap is not recovered: the trial
// measures the recovery, not an easy teleport.
TEST(KidnapTest, WithoutRecoveryTheFilterStaysLost) {
  const auto src = reliability::makeSyntheticSource(test::smallCamera(), 1500);
  reliability::KidnapParams kp;
  kp.localizer.frame.pixel_stride = 8;
  kp.localizer.frame.max_range_m = 8.f;
  kp.localizer.filter.alpha_slow = 0.0;
  kp.localizer.lost.margin_nats = 0.0;
  const reliability::KidnapResult r = reliability::runKidnapTrial(*src, kp, 2);
  print(r);
  EXPECT_LT(r.error_before_m, 0.10);
  EXPECT_FALSE(r.recovered) << "final error " << r.final_error_m;
  EXPECT_GT(r.final_error_m, 0.5);
}

}  // namespace
}  // namespace gmm_mcl

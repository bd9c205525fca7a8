#include <gtest/gtest.h>

#include "gmm_mcl/filter/params.h"

namespace gmm_mcl {
namespace {

TEST(ParamsTest, DefaultsAreThePapers) {
  const LocalizerParams p;
  EXPECT_EQ(p.filter.num_particles, 1068);
  EXPECT_DOUBLE_EQ(p.filter.sigma_translation_m, 0.02);  // Table 1, desktop
  EXPECT_DOUBLE_EQ(p.filter.sigma_yaw_rad, 0.01);
  EXPECT_DOUBLE_EQ(p.filter.alpha_slow, 0.001);  // Table 1 pair, slow = smaller rate
  EXPECT_DOUBLE_EQ(p.filter.alpha_fast, 0.01);
  EXPECT_EQ(p.frame.patch_size_px, 32);
  EXPECT_EQ(p.frame.pixel_stride, 4);
  EXPECT_FLOAT_EQ(p.measurement.sigma_bound, 3.f);
  EXPECT_FLOAT_EQ(p.measurement.floor_log_density, -10.f);
  EXPECT_DOUBLE_EQ(p.init.half_extent_m.x(), 2.0);        // 4 m cube
  EXPECT_DOUBLE_EQ(p.init.yaw_half_range_rad, M_PI / 2);  // yaw range pi
  EXPECT_EQ(p.validate(), "");
}

TEST(ParamsTest, ValidateNamesEveryFault) {
  LocalizerParams p;
  p.filter.num_particles = 0;
  p.filter.alpha_slow = 0.01;
  p.filter.alpha_fast = 0.001;
  p.frame.pixel_stride = 0;
  p.measurement.floor_log_density = std::nanf("");
  p.backend = "tpu";
  p.lost.local_levels = 0;
  p.lost.start_local_stage_min_area_m2 = -1.0;
  const std::string err = p.validate();
  for (const char* what : {"num_particles", "alpha_slow", "pixel_stride", "floor_log_density",
                           "backend must be", "local_levels", "start_local_stage_min_area_m2"}) {
    EXPECT_NE(err.find(what), std::string::npos) << what << " missing from: " << err;
  }
  WeightingMode m;
  EXPECT_TRUE(parseWeightingMode("paper", &m));
  EXPECT_EQ(m, WeightingMode::kPaper);
  EXPECT_FALSE(parseWeightingMode("magic", &m));
}

}  // namespace
}  // namespace gmm_mcl

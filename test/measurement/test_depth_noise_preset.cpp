// The depth-noise presets (docs/measurement_model.md "Sensor presets"): every preset a valid,
// finite model; the default unchanged (custom: the Kinect v1 numbers); an unknown name an error
// naming the valid ones; a preset's numbers overridden by depth_noise_* given beside it.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>

#include "gmm_mcl/filter/parameter_table.h"
#include "gmm_mcl/measurement/depth_noise.h"
#include "gmm_mcl/measurement/depth_noise_preset.h"

namespace gmm_mcl {
namespace {

constexpr float kTightFloat = 1e-6f;  // relative, for numbers computed in float

ParamValue stringValue(const std::string& s) {
  ParamValue v;
  v.type = ParamType::kString;
  v.s = s;
  return v;
}

ParamValue doubleValue(double d) {
  ParamValue v;
  v.type = ParamType::kDouble;
  v.d = d;
  return v;
}

TEST(DepthNoisePresetTest, EveryPresetIsAFinitePositiveModel) {
  const std::vector<DepthNoisePreset>& presets = depthNoisePresets();
  ASSERT_GE(presets.size(), 10u);
  std::set<std::string> names;
  for (const DepthNoisePreset& p : presets) {
    EXPECT_TRUE(names.insert(p.name).second) << "duplicate " << p.name;
    EXPECT_NE(p.name, kCustomDepthNoisePreset);
    EXPECT_FALSE(p.camera.empty()) << p.name;
    EXPECT_FALSE(p.resolution.empty()) << p.name;
    const DepthNoiseModel& m = p.model;
    EXPECT_TRUE(std::isfinite(m.a_m) && std::isfinite(m.b_per_m) && std::isfinite(m.z0_m))
        << p.name;
    EXPECT_GE(m.a_m, 0.f) << p.name;
    EXPECT_GT(m.b_per_m, 0.f) << p.name;
    EXPECT_GE(m.z0_m, 0.f) << p.name;
    EXPECT_TRUE(m.enabled()) << p.name;
    ASSERT_LT(p.min_range_m, p.max_range_m) << p.name;
    EXPECT_GT(p.min_range_m, 0.0) << p.name;
    // Over its working range: positive, and below 10 cm (no camera here is worse at its range).
    for (double z = p.min_range_m; z <= p.max_range_m; z += 0.1) {
      const float s = depthNoiseSigma(m, static_cast<float>(z));
      EXPECT_GT(s, 0.f) << p.name << " at " << z << " m";
      EXPECT_LT(s, 0.1f) << p.name << " at " << z << " m";
    }
    // Through the table, as the nodelet and the tools set it: valid, the preset's numbers.
    LocalizerParams lp;
    findParam(localizerParamTable(), "depth_noise_preset")->set(&lp, stringValue(p.name));
    EXPECT_EQ(lp.validate(), "") << p.name;
    EXPECT_EQ(lp.measurement.depth_noise_preset, p.name);
    EXPECT_EQ(lp.measurement.depth_noise.a_m, m.a_m) << p.name;
    EXPECT_EQ(lp.measurement.depth_noise.b_per_m, m.b_per_m) << p.name;
    EXPECT_EQ(lp.measurement.depth_noise.z0_m, m.z0_m) << p.name;
  }
  // The parameter's choices: custom, then every preset.
  const auto* spec = findParam(localizerParamTable(), "depth_noise_preset");
  ASSERT_NE(spec, nullptr);
  EXPECT_EQ(spec->choices, depthNoisePresetChoices());
  EXPECT_EQ(spec->choices.size(), presets.size() + 1);
  EXPECT_FALSE(spec->runtime);  // a preset is chosen at start-up; a, b, z0 stay tunable
}

// The formulas the presets come from, evaluated independently.
TEST(DepthNoisePresetTest, PresetsFollowTheirSources) {
  // Intel: RMS = z^2 subpixel / (f baseline), subpixel 0.08; D435 at 848x480: f 424 px, 50 mm.
  const DepthNoisePreset* d435 = findDepthNoisePreset("realsense_d435_848x480");
  ASSERT_NE(d435, nullptr);
  for (double z : {0.5, 1.0, 2.0, 3.0}) {
    const double intel = z * z * 0.08 / (424.0 * 0.050);
    EXPECT_NEAR(depthNoiseSigma(d435->model, static_cast<float>(z)), intel, kTightFloat * 10) << z;
  }
  const DepthNoisePreset* d455 = findDepthNoisePreset("realsense_d455_1280x720");
  ASSERT_NE(d455, nullptr);
  EXPECT_NEAR(d455->model.b_per_m, 0.08 / (640.0 * 0.095), 1e-8);
  // Kinect v2 (Fankhauser et al. 2015, normal incidence): 1.5 - 0.5 z + 0.3 z^2 mm.
  const DepthNoisePreset* k2 = findDepthNoisePreset("kinect_v2");
  ASSERT_NE(k2, nullptr);
  for (double z : {0.5, 1.0, 2.0, 4.0}) {
    const double fankhauser = 1e-3 * (1.5 - 0.5 * z + 0.3 * z * z);
    EXPECT_NEAR(depthNoiseSigma(k2->model, static_cast<float>(z)), fankhauser, 1e-7) << z;
  }
  // Kinect v1 (Nguyen, Izadi and Lovell 2012) is the package's default model.
  const DepthNoisePreset* k1 = findDepthNoisePreset("kinect_v1");
  ASSERT_NE(k1, nullptr);
  const DepthNoiseModel defaults;
  EXPECT_EQ(k1->model.a_m, defaults.a_m);
  EXPECT_EQ(k1->model.b_per_m, defaults.b_per_m);
  EXPECT_EQ(k1->model.z0_m, defaults.z0_m);
}

TEST(DepthNoisePresetTest, DefaultIsUnchanged) {
  const LocalizerParams lp;
  EXPECT_EQ(lp.measurement.depth_noise_preset, "custom");
  EXPECT_EQ(lp.measurement.depth_noise.a_m, 0.0012f);
  EXPECT_EQ(lp.measurement.depth_noise.b_per_m, 0.0019f);
  EXPECT_EQ(lp.measurement.depth_noise.z0_m, 0.4f);
  const auto* spec = findParam(localizerParamTable(), "depth_noise_preset");
  ASSERT_NE(spec, nullptr);
  EXPECT_EQ(spec->defaultValue().s, "custom");
  // custom keeps the numbers as given, the defaults or others.
  LocalizerParams q;
  q.measurement.depth_noise.a_m = 0.003f;
  q.measurement.depth_noise.b_per_m = 0.f;
  spec->set(&q, stringValue("custom"));
  EXPECT_EQ(q.measurement.depth_noise.a_m, 0.003f);
  EXPECT_EQ(q.measurement.depth_noise.b_per_m, 0.f);
  EXPECT_EQ(q.measurement.depth_noise.z0_m, 0.4f);
  DepthNoiseModel m;
  EXPECT_EQ(applyDepthNoisePreset("custom", &m), "");
  EXPECT_EQ(m.a_m, 0.0012f);
}

TEST(DepthNoisePresetTest, UnknownNameIsAnErrorNamingTheValidOnes) {
  DepthNoiseModel m;
  const std::string why = applyDepthNoisePreset("realsense_d999", &m);
  EXPECT_NE(why.find("depth_noise_preset 'realsense_d999' is not one of custom kinect_v1 "),
            std::string::npos)
      << why;
  for (const std::string& name : depthNoisePresetChoices())
    EXPECT_NE(why.find(" " + name), std::string::npos) << name << ": " << why;
  EXPECT_EQ(m.a_m, 0.0012f);  // unchanged
  EXPECT_EQ(findDepthNoisePreset("custom"), nullptr);
  EXPECT_EQ(findDepthNoisePreset(""), nullptr);
  // The table refuses it before setting (ROS parameter, tool flag) ...
  const auto* spec = findParam(localizerParamTable(), "depth_noise_preset");
  const std::string check = spec->check(stringValue("kinect_v3"));
  EXPECT_NE(check.find("depth_noise_preset 'kinect_v3' is not one of custom kinect_v1"),
            std::string::npos)
      << check;
  EXPECT_NE(spec->check(stringValue("")), "");  // "" is not a name: custom is
  // ... and validate() catches one set directly.
  LocalizerParams lp;
  lp.measurement.depth_noise_preset = "kinect_v3";
  EXPECT_NE(lp.validate().find("depth_noise_preset 'kinect_v3' is not one of"), std::string::npos)
      << lp.validate();
}

// The loaders (ROS parameters, tool flags) apply the table in its order: the preset, then
// depth_noise_a_m, _b_per_m and _z0_m, so that the numbers given beside a preset override it.
TEST(DepthNoisePresetTest, ExplicitNumbersOverrideThePreset) {
  const ParamTable<LocalizerParams>& table = localizerParamTable();
  auto index = [&](const std::string& name) {
    for (size_t i = 0; i < table.size(); ++i) {
      if (table[i].name == name) return i;
    }
    return table.size();
  };
  const size_t preset = index("depth_noise_preset");
  ASSERT_LT(preset, table.size());
  EXPECT_LT(preset, index("depth_noise_a_m"));
  EXPECT_LT(preset, index("depth_noise_b_per_m"));
  EXPECT_LT(preset, index("depth_noise_z0_m"));

  // As loadRosParams and CommandLine::parse do: every given value in table order.
  std::map<std::string, ParamValue> given = {
      {"depth_noise_a_m", doubleValue(0.002)},
      {"depth_noise_preset", stringValue("realsense_d435_848x480")}};
  LocalizerParams lp;
  for (const auto& p : table) {
    const auto g = given.find(p.name);
    if (g == given.end()) continue;
    ASSERT_EQ(p.check(g->second), "") << p.name;
    p.set(&lp, g->second);
  }
  const DepthNoisePreset* d435 = findDepthNoisePreset("realsense_d435_848x480");
  EXPECT_FLOAT_EQ(lp.measurement.depth_noise.a_m, 0.002f);                 // given
  EXPECT_EQ(lp.measurement.depth_noise.b_per_m, d435->model.b_per_m);      // the preset's
  EXPECT_EQ(lp.measurement.depth_noise.z0_m, d435->model.z0_m);            // the preset's
  EXPECT_EQ(lp.measurement.depth_noise_preset, "realsense_d435_848x480");  // named in the log
  EXPECT_EQ(lp.validate(), "");
  const std::string described = describeParams(table, lp);
  EXPECT_NE(described.find("depth_noise_preset realsense_d435_848x480*"), std::string::npos)
      << described;
}

}  // namespace
}  // namespace gmm_mcl

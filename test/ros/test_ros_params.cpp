// The parameter tables against what is generated from them, without a master:
// dynamic_reconfigure's LocalizerConfig (cfg/Localizer.cfg) holds exactly the run-time
// parameters with the tables' types, defaults, ranges and help; docs/parameters.md and
// cfg/Localizer.cfg are current; a reconfigure request is checked, applied or refused whole.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

#include "gmm_mcl/common/enum_names.h"
#include "gmm_mcl/fit/fit_on_load.h"
#include "gmm_mcl/ros/ros_params.h"

namespace gmm_mcl {

namespace {

std::string readFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The dynamic_reconfigure type of each parameter type (none: not reconfigurable).
const EnumName<ParamType> kConfigTypes[] = {{"bool", ParamType::kBool},
                                            {"int", ParamType::kInt},
                                            {"double", ParamType::kDouble},
                                            {"str", ParamType::kString},
                                            {"none", ParamType::kVector3}};

const char* configType(ParamType t) { return enumNameOf(t, kConfigTypes); }

struct Entry {
  ParamType type;
  ParamValue def;
  double min, max;
  std::string help;
  std::vector<std::string> choices;
};

// Every run-time parameter of both tables, by name.
std::map<std::string, Entry> runtimeEntries() {
  std::map<std::string, Entry> out;
  for (const auto& p : localizerParamTable()) {
    if (p.runtime) out[p.name] = Entry{p.type, p.defaultValue(), p.min, p.max, p.help, p.choices};
  }
  for (const auto& p : rosOptionsTable()) {
    if (p.runtime) out[p.name] = Entry{p.type, p.defaultValue(), p.min, p.max, p.help, p.choices};
  }
  return out;
}

double configNumber(const dynamic_reconfigure::Config& msg, const std::string& name) {
  for (const auto& d : msg.doubles) {
    if (d.name == name) return d.value;
  }
  for (const auto& i : msg.ints) {
    if (i.name == name) return i.value;
  }
  return NAN;
}

}  // namespace

// The generated dynamic_reconfigure description holds exactly the run-time parameters, each
// with the table's type, default, range and help (what rqt_reconfigure shows).
TEST(RosParamsTest, ReconfigureDescriptionEqualsTheTables) {
  std::map<std::string, Entry> entries = runtimeEntries();
  dynamic_reconfigure::Config defaults, mins, maxs;
  LocalizerConfig::__getDefault__().__toMessage__(defaults);
  LocalizerConfig::__getMin__().__toMessage__(mins);
  LocalizerConfig::__getMax__().__toMessage__(maxs);
  size_t seen = 0;
  for (const auto& d : LocalizerConfig::__getParamDescriptions__()) {
    const auto it = entries.find(d->name);
    ASSERT_NE(it, entries.end()) << d->name << " is reconfigurable but no table marks it so";
    const Entry& e = it->second;
    ++seen;
    EXPECT_EQ(d->type, configType(e.type)) << d->name;
    EXPECT_EQ(d->description, e.help) << d->name;
    if (e.type == ParamType::kInt || e.type == ParamType::kDouble) {
      const double def = e.type == ParamType::kInt ? static_cast<double>(e.def.i) : e.def.d;
      // A float field's default reads back through the cfg's text as its shortest decimal.
      EXPECT_NEAR(configNumber(defaults, d->name), def, 1e-6 * std::max(1.0, std::abs(def)))
          << d->name;
      EXPECT_EQ(configNumber(mins, d->name), e.min) << d->name;
      EXPECT_EQ(configNumber(maxs, d->name), e.max) << d->name;
    }
    for (const std::string& c : e.choices) {
      EXPECT_NE(d->edit_method.find("'value': '" + c + "'"), std::string::npos)
          << d->name << ": " << c;
    }
  }
  EXPECT_EQ(seen, entries.size()) << "a run-time parameter is missing from cfg/Localizer.cfg";
  EXPECT_GE(seen, 60u);
  // The lost detector's parameters are among them.
  EXPECT_TRUE(entries.count("lost_margin_nats") && entries.count("lost_grace_frames"));
}

// cfg/Localizer.cfg and docs/parameters.md are what the tables generate now.
TEST(RosParamsTest, GeneratedFilesAreCurrent) {
  EXPECT_EQ(readFile(GMM_MCL_SOURCE_DIR "/cfg/Localizer.cfg"), dynamicReconfigureCfg())
      << "regenerate: gmm_mcl_params --cfg > cfg/Localizer.cfg";
  EXPECT_EQ(readFile(GMM_MCL_SOURCE_DIR "/docs/parameters.md"), parameterReferenceMarkdown())
      << "regenerate: gmm_mcl_params --markdown > docs/parameters.md";
  // Every parameter is in the reference, with its unit and whether it changes at run time.
  const std::string md = parameterReferenceMarkdown();
  for (const auto& p : localizerParamTable())
    EXPECT_NE(md.find("| `" + p.name + "` |"), std::string::npos) << p.name;
  for (const auto& p : rosOptionsTable())
    EXPECT_NE(md.find("| `" + p.name + "` |"), std::string::npos) << p.name;
  EXPECT_NE(md.find("| `update_min_d` | double | 0 | m | [0, 10] | yes |"), std::string::npos);
}

// A request goes through the tables and validate(): out of range, or breaking a rule between
// parameters, is refused whole and the config holds the previous values again.
TEST(RosParamsTest, ReconfigureAppliesOrRefusesWhole) {
  LocalizerParams core;
  RosOptions ros;
  ros.map_path = "m.gmm";
  LocalizerConfig config = toLocalizerConfig(core, ros);
  EXPECT_EQ(config.num_particles, core.filter.num_particles);
  config.sigma_translation_m = 0.05;
  config.lost_margin_nats = 5.0;
  config.update_min_d = 0.2;
  config.tf_broadcast = false;
  std::string changes;
  LocalizerParams applied;
  EXPECT_EQ(reconfigure(
                &config, &core, &ros, [&](const LocalizerParams& p) { applied = p; }, &changes),
            "");
  EXPECT_EQ(core.filter.sigma_translation_m, 0.05);
  EXPECT_EQ(applied.lost.margin_nats, 5.0);
  EXPECT_EQ(ros.update_min_d_m, 0.2);
  EXPECT_FALSE(ros.tf_broadcast);
  EXPECT_NE(changes.find("sigma_translation_m 0.02 -> 0.05"), std::string::npos) << changes;
  EXPECT_NE(changes.find("tf_broadcast true -> false"), std::string::npos) << changes;

  // alpha_slow above alpha_fast: refused by validate(), nothing changes.
  config.alpha_slow = 0.5;
  config.alpha_fast = 0.1;
  config.temperature = 3.0;
  const std::string why = reconfigure(
      &config, &core, &ros, [](const LocalizerParams&) {}, &changes);
  EXPECT_NE(why.find("alpha_slow"), std::string::npos) << why;
  EXPECT_EQ(core.filter.temperature, 1.0);
  EXPECT_EQ(config.temperature, 1.0) << "the server keeps the previous values";
  EXPECT_EQ(config.alpha_slow, core.filter.alpha_slow);
  // The core refusing (e.g. Localizer::setParams throwing): refused too.
  config.temperature = 2.0;
  EXPECT_EQ(reconfigure(
                &config, &core, &ros,
                [](const LocalizerParams&) { throw std::invalid_argument("no"); }, &changes),
            "no");
  EXPECT_EQ(core.filter.temperature, 1.0);
}

// The ~map_fit_* defaults are those of the map builder's FitOnLoadParams.
TEST(RosParamsTest, MapFitDefaultsAreTheFittersOwn) {
  const RosOptions ros;
  const FitOnLoadParams fit;
  EXPECT_EQ(ros.map_fit_components, fit.components);
  EXPECT_EQ(ros.map_fit_time_limit_s, fit.time_limit_s);
  EXPECT_EQ(ros.map_fit_cache, fit.cache);
}

TEST(RosParamsTest, InitialPoseNeedsAllFour) {
  RosOptions o;
  o.map_path = "m.gmm";
  EXPECT_FALSE(o.hasInitialPose());
  EXPECT_EQ(o.validate(), "");
  o.initial_pose_x_m = 1.0;
  EXPECT_NE(o.validate().find("together"), std::string::npos);
  o.initial_pose_y_m = 2.0;
  o.initial_pose_z_m = 1.2;
  o.initial_pose_yaw_rad = 0.5;
  EXPECT_TRUE(o.hasInitialPose());
  Eigen::Isometry3d T;
  Eigen::Matrix<double, 6, 6> cov;
  initialPose(o, &T, &cov);
  EXPECT_NEAR(T.translation().z(), 1.2, 1e-12);
  EXPECT_NEAR(cov(5, 5), o.initial_cov_yawyaw_rad2, 1e-12);
}

}  // namespace gmm_mcl

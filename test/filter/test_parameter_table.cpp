// The core's parameter table: names unique, defaults valid, each entry bound to its own field,
// and every parameter marked as changeable at run time accepted by Localizer::setParams.
#include <gtest/gtest.h>

#include <set>

#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/filter/parameter_table.h"
#include "test_utils/synthetic_fixtures.h"

namespace gmm_mcl {

void PrintTo(const ParamValue& v, std::ostream* os) {
  *os << paramTypeName(v.type) << " " << v.toString();
}

namespace {

// Another valid value of the parameter: inside its range or choices, different from `v`.
ParamValue otherValue(const ParamSpec<LocalizerParams>& p, ParamValue v) {
  switch (p.type) {
    case ParamType::kBool:
      v.b = !v.b;
      break;
    case ParamType::kInt:
      v.i = v.i + 1 <= p.max ? v.i + 1 : v.i - 1;
      break;
    case ParamType::kDouble: {
      double x = v.d == 0.0 ? 0.001 : v.d * 1.1;
      if (x > p.max) x = v.d * 0.9;
      v.d = x;
      break;
    }
    case ParamType::kString:
      for (const std::string& c : p.choices) {
        if (c != v.s) {
          v.s = c;
          break;
        }
      }
      break;
    case ParamType::kVector3:
      v.v += Eigen::Vector3d(0.1, 0.2, 0.3);
      break;
  }
  return v;
}

TEST(ParameterTableTest, NamesUniqueDefaultsValidAndDocumented) {
  const ParamTable<LocalizerParams>& table = localizerParamTable();
  EXPECT_GE(table.size(), 55u);
  std::set<std::string> names, fields;
  for (const auto& p : table) {
    EXPECT_TRUE(names.insert(p.name).second) << "duplicate name " << p.name;
    EXPECT_TRUE(fields.insert(p.field).second) << "duplicate field " << p.field;
    EXPECT_FALSE(p.help.empty()) << p.name;
    EXPECT_FALSE(p.group.empty()) << p.name;
    EXPECT_EQ(p.help.find('|'), std::string::npos) << p.name << ": '|' breaks the Markdown table";
    EXPECT_EQ(p.check(p.defaultValue()), "")
        << p.name << " default " << p.defaultValue().toString();
    EXPECT_EQ(p.defaultValue().type, p.type) << p.name;
    if (p.type == ParamType::kInt || p.type == ParamType::kDouble) {
      EXPECT_LT(p.min, p.max) << p.name;
    }
  }
  EXPECT_EQ(LocalizerParams().validate(), "");
}

// Setting one entry changes that entry only (no two entries share a field), and reads back.
TEST(ParameterTableTest, EachEntryOwnsItsField) {
  const ParamTable<LocalizerParams>& table = localizerParamTable();
  for (const auto& p : table) {
    LocalizerParams s;
    const ParamValue v = otherValue(p, p.defaultValue());
    ASSERT_NE(v, p.defaultValue()) << p.name;
    ASSERT_EQ(p.check(v), "") << p.name;
    p.set(&s, v);
    if (p.type == ParamType::kDouble) {
      EXPECT_NEAR(p.get(s).d, v.d, 1e-6 * std::abs(v.d)) << p.name;  // float fields round
    } else {
      EXPECT_EQ(p.get(s), v) << p.name;
    }
    for (const auto& q : table) {
      if (q.name != p.name) {
        EXPECT_EQ(q.get(s), q.defaultValue()) << "setting " << p.name << " changed " << q.name;
      }
    }
  }
}

TEST(ParameterTableTest, ChecksTypeRangeAndChoices) {
  const auto* n = findParam(localizerParamTable(), "num_particles");
  ASSERT_NE(n, nullptr);
  ParamValue v = n->defaultValue();
  v.i = 0;
  EXPECT_NE(n->check(v).find("num_particles must be in [1"), std::string::npos) << n->check(v);
  v.type = ParamType::kString;
  EXPECT_NE(n->check(v).find("must be a int"), std::string::npos) << n->check(v);
  const auto* w = findParam(localizerParamTable(), "weighting");
  ASSERT_NE(w, nullptr);
  v = w->defaultValue();
  v.s = "bogus";
  EXPECT_NE(w->check(v).find("weighting 'bogus' is not one of tempered paper"), std::string::npos)
      << w->check(v);
  EXPECT_EQ(findParam(localizerParamTable(), "no_such_parameter"), nullptr);

  LocalizerParams a, b;
  b.filter.sigma_translation_m = 0.05;
  EXPECT_EQ(describeChanges(localizerParamTable(), a, b), "sigma_translation_m 0.02 -> 0.05");
  const std::string described = describeParams(localizerParamTable(), b);
  EXPECT_NE(described.find("sigma_translation_m 0.05 m*"), std::string::npos) << described;
  EXPECT_NE(described.find("num_particles 1068,"), std::string::npos) << described;
  const std::string md = markdownReference(localizerParamTable());
  EXPECT_NE(md.find("| `lost_margin_nats` | double | 3 | nats/px | [0, 100] | yes |"),
            std::string::npos)
      << md;
}

// Every parameter marked as changeable at run time is accepted by Localizer::setParams (the
// belief kept); the others that setParams cannot take are refused.
TEST(ParameterTableTest, RuntimeParametersAreAcceptedBySetParams) {
  LocalizerParams base;
  base.filter.num_particles = 50;
  base.lost.candidates_per_particle = 1;
  Localizer loc(base, test::world().map);
  for (const auto& p : localizerParamTable()) {
    LocalizerParams q = loc.params();
    p.set(&q, otherValue(p, p.get(q)));
    if (q.validate() != "") continue;  // a cross-field rule (e.g. alpha_slow < alpha_fast)
    if (p.runtime) {
      EXPECT_NO_THROW(loc.setParams(q)) << p.name;
      EXPECT_EQ(p.get(loc.params()), p.get(q)) << p.name;
    } else if (p.name == "backend" || p.name == "seed" || p.name == "device_filter" ||
               p.group == "cuda") {
      EXPECT_THROW(loc.setParams(q), std::invalid_argument) << p.name;
    }
  }
}

// The CUDA backend's tuning is the table's "cuda" group, start-up only, its defaults those of
// CudaTuningParams (the choices measured on an H100, docs/cuda_backend.md).
TEST(ParameterTableTest, CudaTuningIsAStartupGroup) {
  const CudaTuningParams defaults;
  int count = 0;
  for (const auto& p : localizerParamTable()) {
    if (p.group != "cuda") continue;
    ++count;
    EXPECT_FALSE(p.runtime) << p.name;
    EXPECT_EQ(p.name.compare(0, 5, "cuda_"), 0) << p.name;
  }
  EXPECT_EQ(count, 8);
  const LocalizerParams lp;
  EXPECT_EQ(findParam(localizerParamTable(), "cuda_likelihood_shape")->get(lp).s,
            defaults.likelihood_shape);
  EXPECT_EQ(findParam(localizerParamTable(), "cuda_view_cull_min_pairs")->get(lp).i,
            defaults.view_cull_min_pairs);
  EXPECT_EQ(defaults.likelihood_shape, "auto");
  EXPECT_EQ(defaults.stage_members, "auto");
  EXPECT_EQ(defaults.band_patches, 0);
  EXPECT_EQ(defaults.view_cull_min_pairs, 2000000);
  EXPECT_EQ(findParam(localizerParamTable(), "cuda_local_lists_min_components")->get(lp).i,
            defaults.local_lists_min_components);
  EXPECT_EQ(findParam(localizerParamTable(), "cuda_z_order_min_components")->get(lp).i,
            defaults.z_order_min_components);
  EXPECT_EQ(defaults.membership_pass_words, 32);
  EXPECT_FALSE(defaults.place_groups);  // measured slower on an H100
}

}  // namespace
}  // namespace gmm_mcl

// Predicates for EXPECT_TRUE / ASSERT_TRUE shared by tests: each failure says what differed.
#pragma once

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "gmm_mcl/map/gmm_map.h"

namespace gmm_mcl {
namespace test {

// Whether call() throws an E whose message contains each of `parts`. Another exception type
// propagates (the test errs). EXPECT_TRUE(throwsWith<FitError>([&] { fit(cloud); }, {"fewer"})).
template <typename E, typename F>
::testing::AssertionResult throwsWith(F&& call, const std::vector<std::string>& parts) {
  try {
    call();
  } catch (const E& e) {
    const std::string what = e.what();
    for (const std::string& part : parts) {
      if (what.find(part) == std::string::npos) {
        return ::testing::AssertionFailure() << "the message lacks \"" << part << "\": " << what;
      }
    }
    return ::testing::AssertionSuccess();
  }
  return ::testing::AssertionFailure() << "nothing thrown";
}

// Whether two mixtures are the same to the bit: count, then each weight, mean and covariance.
inline ::testing::AssertionResult sameComponents(const std::vector<GaussianComponent>& a,
                                                 const std::vector<GaussianComponent>& b) {
  if (a.size() != b.size()) {
    return ::testing::AssertionFailure() << a.size() << " components against " << b.size();
  }
  for (size_t k = 0; k < a.size(); ++k) {
    if (a[k].weight != b[k].weight || a[k].mean_m != b[k].mean_m || a[k].cov_m2 != b[k].cov_m2) {
      return ::testing::AssertionFailure() << "component " << k << " differs";
    }
  }
  return ::testing::AssertionSuccess();
}

}  // namespace test
}  // namespace gmm_mcl

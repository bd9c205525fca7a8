// Wall-clock stage timers and the medians the tools and the localizer report.
#pragma once

#include <algorithm>
#include <chrono>
#include <vector>

namespace gmm_mcl {

using Clock = std::chrono::steady_clock;

// Milliseconds from a to b.
inline double msBetween(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

// Milliseconds since t0.
inline double msSince(Clock::time_point t0) { return msBetween(t0, Clock::now()); }

// The median (the mean of the two middle values of an even count); 0 for none.
inline double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// The upper median (the higher middle value of an even count); 0 for none.
inline double upperMedian(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace gmm_mcl

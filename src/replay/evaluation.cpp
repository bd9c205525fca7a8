#include "gmm_mcl/replay/evaluation.h"

#include <cmath>

namespace gmm_mcl {

TrialMetrics evaluateTrial(const std::vector<FrameError>& e, const EvaluationParams& p) {
  TrialMetrics m;
  const int n = static_cast<int>(e.size());
  m.frames = n;
  // First frame f with e[f .. f + hold - 1] all below the threshold (run length scan).
  int run = 0;
  for (int f = 0; f < n; ++f) {
    run = e[f].translation_m < p.converged_below_m ? run + 1 : 0;
    if (run == p.hold_frames) {
      m.converge_frame = f - p.hold_frames + 1;
      break;
    }
  }
  if (m.converge_frame < 0) return m;
  m.converged = true;
  m.converge_time_s = e[m.converge_frame].stamp_s - e[0].stamp_s;
  double st = 0.0, sy = 0.0, rt = 0.0, ry = 0.0;
  int refined = 0;
  for (int f = m.converge_frame; f < n; ++f) {
    st += e[f].translation_m * e[f].translation_m;
    sy += e[f].yaw_rad * e[f].yaw_rad;
    rt += e[f].refined_translation_m * e[f].refined_translation_m;
    ry += e[f].refined_yaw_rad * e[f].refined_yaw_rad;
    refined += e[f].refined ? 1 : 0;
  }
  const int count = n - m.converge_frame;
  m.ate_translation_m = std::sqrt(st / count);
  m.ate_yaw_rad = std::sqrt(sy / count);
  m.refined_ate_translation_m = std::sqrt(rt / count);
  m.refined_ate_yaw_rad = std::sqrt(ry / count);
  m.refined_fraction = static_cast<double>(refined) / count;
  m.success = true;
  for (int f = std::max(0, n - p.tail_frames); f < n; ++f) {
    if (!(e[f].translation_m < p.converged_below_m)) m.success = false;
  }
  return m;
}

}  // namespace gmm_mcl

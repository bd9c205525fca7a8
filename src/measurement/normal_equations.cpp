#include "gmm_mcl/measurement/normal_equations.h"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace gmm_mcl {
namespace {

// Work split of the pixel loop: patches in this many chunks; per chunk the log-likelihood, the
// 21 entries of the upper triangle of H, the 6 of g, and the depth scale's 7 of H and 1 of g.
constexpr int kChunks = 64;
constexpr int kPartial = 36;

std::vector<double>& scratchT() {
  static thread_local std::vector<double> v;
  return v;
}
std::vector<double>& scratchY() {
  static thread_local std::vector<double> v;
  return v;
}

Eigen::Matrix3d rowMajor(const double* m) {
  Eigen::Matrix3d out;
  out << m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8];
  return out;
}

}  // namespace

int NormalEquationsEvaluator::setPointsFromBackendFrame(const Eigen::Isometry3d&) {
  throw std::logic_error("normal equations: no frame on the backend's device");
}

void HostNormalEquations::setPoints(const std::vector<double>& x_m, const std::vector<double>& y_m,
                                    const std::vector<double>& z_m,
                                    const std::vector<int>& patch_begin) {
  px_ = x_m;
  py_ = y_m;
  pz_ = z_m;
  patch_begin_ = patch_begin;
}

void HostNormalEquations::setLinearisation(const std::vector<EvalComponentF>& eval_nats,
                                           const PatchMembership& membership) {
  eval_ = eval_nats;
  membership_ = membership;
}

void HostNormalEquations::evaluate(const PoseDerivatives& pose, float floor_log_density,
                                   bool linearise, NormalEquationSums* out) {
  const Eigen::Matrix3d R = rowMajor(pose.R);
  const Eigen::Vector3d t(pose.t[0], pose.t[1], pose.t[2]);
  const Eigen::Matrix3d D[3] = {rowMajor(pose.dR[0]), rowMajor(pose.dR[1]), rowMajor(pose.dR[2])};
  const Eigen::Vector3d o(pose.scale_origin[0], pose.scale_origin[1], pose.scale_origin[2]);
  const double f = pose.scale;
  const bool with_scale = pose.estimate_scale;
  const double floor = floor_log_density;
  const EvalComponentF* eval = eval_.data();
  *out = NormalEquationSums();
  // Patches in fixed chunks, one partial sum per chunk, added in chunk order: the result does
  // not depend on the thread count.
  const int patches = static_cast<int>(patch_begin_.size()) - 1;
  if (patches <= 0) return;
  const int chunks = std::min(patches, kChunks);
  partial_.assign(static_cast<size_t>(chunks) * kPartial, 0.0);
#pragma omp parallel for schedule(dynamic, 1)
  for (int ch = 0; ch < chunks; ++ch) {
    // loglik, h[21], g[6], hs[7], gs
    double* acc = partial_.data() + static_cast<size_t>(ch) * kPartial;
    std::vector<double>& t_ = scratchT();
    std::vector<double>& y_ = scratchY();
    for (int p = ch * patches / chunks; p < (ch + 1) * patches / chunks; ++p) {
      const int b = patch_begin_[p], e = patch_begin_[p + 1];
      if (b == e) continue;
      const int k = membership_.countFor(p);
      if (k == 0) {
        acc[0] += floor * (e - b);
        continue;
      }
      const int* members = membership_.comps.data() + membership_.begin[p];
      t_.resize(k);
      y_.resize(3 * k);
      for (int i = b; i < e; ++i) {
        const Eigen::Vector3d ray = Eigen::Vector3d(px_[i], py_[i], pz_[i]) - o;
        const Eigen::Vector3d p_base = o + f * ray;
        const Eigen::Vector3d q = R * p_base + t;
        double mx = floor;
        for (int j = 0; j < k; ++j) {
          const EvalComponentF& ev = eval[members[j]];
          const double y0 = ev.u00 * q.x() + ev.u01 * q.y() + ev.u02 * q.z() + ev.c[0];
          const double y1 = ev.u11 * q.y() + ev.u12 * q.z() + ev.c[1];
          const double y2 = ev.u22 * q.z() + ev.c[2];
          y_[3 * j] = y0;
          y_[3 * j + 1] = y1;
          y_[3 * j + 2] = y2;
          t_[j] = ev.log_norm - (y0 * y0 + y1 * y1 + y2 * y2);
          mx = std::max(mx, t_[j]);
        }
        double sum = std::exp(floor - mx);
        for (int j = 0; j < k; ++j) {
          t_[j] = std::exp(t_[j] - mx);
          sum += t_[j];
        }
        acc[0] += mx + std::log(sum);
        if (!linearise) continue;
        // dq / d(roll, pitch, yaw).
        const Eigen::Vector3d m[3] = {D[0] * p_base, D[1] * p_base, D[2] * p_base};
        const Eigen::Vector3d ms = R * ray;  // dq / df
        const double inv_sum = 1.0 / sum;
        for (int j = 0; j < k; ++j) {
          const double gamma = t_[j] * inv_sum;
          if (gamma < kMinResponsibility) continue;
          const EvalComponentF& ev = eval[members[j]];
          // Columns of J = U [I | dq/droll | dq/dpitch | dq/dyaw] (U upper triangular).
          double col[6][3] = {{ev.u00, 0.0, 0.0}, {ev.u01, ev.u11, 0.0}, {ev.u02, ev.u12, ev.u22}};
          for (int a = 0; a < 3; ++a) {
            col[3 + a][0] = ev.u00 * m[a].x() + ev.u01 * m[a].y() + ev.u02 * m[a].z();
            col[3 + a][1] = ev.u11 * m[a].y() + ev.u12 * m[a].z();
            col[3 + a][2] = ev.u22 * m[a].z();
          }
          const double y[3] = {y_[3 * j], y_[3 * j + 1], y_[3 * j + 2]};
          double* h = acc + 1;
          double* g = acc + 22;
          for (int r = 0, idx = 0; r < 6; ++r) {
            for (int c = r; c < 6; ++c, ++idx) {
              h[idx] +=
                  gamma * (col[r][0] * col[c][0] + col[r][1] * col[c][1] + col[r][2] * col[c][2]);
            }
            g[r] += gamma * (col[r][0] * y[0] + col[r][1] * y[1] + col[r][2] * y[2]);
          }
          if (with_scale) {
            const double cs[3] = {ev.u00 * ms.x() + ev.u01 * ms.y() + ev.u02 * ms.z(),
                                  ev.u11 * ms.y() + ev.u12 * ms.z(), ev.u22 * ms.z()};
            double* hs = acc + 28;
            for (int r = 0; r < 6; ++r) {
              hs[r] += gamma * (col[r][0] * cs[0] + col[r][1] * cs[1] + col[r][2] * cs[2]);
            }
            hs[6] += gamma * (cs[0] * cs[0] + cs[1] * cs[1] + cs[2] * cs[2]);
            acc[35] += gamma * (cs[0] * y[0] + cs[1] * y[1] + cs[2] * y[2]);
          }
        }
      }
    }
  }
  for (int ch = 0; ch < chunks; ++ch) {
    const double* acc = partial_.data() + static_cast<size_t>(ch) * kPartial;
    out->loglik += acc[0];
    for (int idx = 0; idx < 21; ++idx) out->h[idx] += acc[1 + idx];
    for (int r = 0; r < 6; ++r) out->g[r] += acc[22 + r];
    for (int r = 0; r < 7; ++r) out->hs[r] += acc[28 + r];
    out->gs += acc[35];
  }
}

}  // namespace gmm_mcl

#include "gmm_mcl/sim/pose_scatter.h"

#include <random>

#include "gmm_mcl/filter/pose.h"

namespace gmm_mcl {
namespace sim {

std::vector<RigidTransformF> scatterPoses(const Eigen::Isometry3d& T_true, int n, double spread_m,
                                          double spread_rad, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> um(-spread_m, spread_m), ur(-spread_rad, spread_rad);
  std::vector<RigidTransformF> out(n);
  out[0] = toRigidF(T_true);
  for (int i = 1; i < n; ++i) {
    Eigen::Isometry3d T = T_true;
    T.linear() =
        Eigen::AngleAxisd(ur(rng), Eigen::Vector3d::UnitZ()).toRotationMatrix() * T_true.linear();
    T.translation() += Eigen::Vector3d(um(rng), um(rng), um(rng));
    out[i] = toRigidF(T);
  }
  return out;
}

}  // namespace sim
}  // namespace gmm_mcl

#include "gmm_mcl/replay/seven_scenes_sequence.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>

#if defined(GMM_MCL_HAVE_PNG)
#include "gmm_mcl/camera/png_io.h"
#endif

namespace gmm_mcl {
namespace {

std::string framePath(const std::string& dir, int i, const char* suffix) {
  char name[64];
  std::snprintf(name, sizeof(name), "/frame-%06d.%s", i, suffix);
  return dir + name;
}

bool readNumbers(const std::string& path, int count, double* out) {
  std::ifstream in(path);
  for (int k = 0; k < count; ++k) {
    if (!(in >> out[k]) || !std::isfinite(out[k])) return false;
  }
  return true;
}

}  // namespace

Eigen::Matrix3d gravityAlignment(const Eigen::Vector3d& down_world) {
  const Eigen::Vector3d z = -down_world.normalized();
  Eigen::Vector3d x = Eigen::Vector3d::UnitX() - z * z.x();
  if (x.norm() < 1e-6) x = Eigen::Vector3d::UnitY() - z * z.y();
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;
  R.row(0) = x.transpose();
  R.row(1) = y.transpose();
  R.row(2) = z.transpose();
  return R;
}

SevenScenesSequence::SevenScenesSequence(const std::string& data_dir, int max_frames)
    : dir_(data_dir) {
  double K[9];
  const std::string kpath = dir_ + "/camera-intrinsics.txt";
  if (!readNumbers(kpath, 9, K)) {
    throw std::runtime_error(kpath + ": cannot read 9 finite numbers (3x3 camera matrix)");
  }
  intrinsics_ = makeIntrinsics(K, 640, 480);
  for (int i = 0; max_frames < 0 || i < max_frames; ++i) {
    const std::string ppath = framePath(dir_, i, "pose.txt");
    std::ifstream probe(ppath);
    if (!probe) break;
    double m[16];
    if (!readNumbers(ppath, 16, m)) {
      throw std::runtime_error(ppath + ": cannot read a 4x4 pose of finite numbers");
    }
    Eigen::Matrix4d M;
    for (int k = 0; k < 16; ++k) M(k / 4, k % 4) = m[k];
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    // Orthonormalise the rotation (text poses carry rounding).
    Eigen::Quaterniond q(Eigen::Matrix3d(M.topLeftCorner<3, 3>()));
    T.linear() = q.normalized().toRotationMatrix();
    T.translation() = M.topRightCorner<3, 1>();
    T_world_cam_.push_back(T);
  }
  if (T_world_cam_.empty()) {
    throw std::runtime_error(data_dir + ": no frame-000000.pose.txt: not a 7-Scenes sequence folder");
  }
  double g[3];
  const std::string gpath = dir_ + "/gravity-direction.txt";
  if (std::ifstream(gpath) && readNumbers(gpath, 3, g)) {
    R_aligned_world_ = gravityAlignment(Eigen::Vector3d(g[0], g[1], g[2]));
    has_gravity_ = true;
  }
}

std::string SevenScenesSequence::depthPath(int i) const { return framePath(dir_, i, "depth.png"); }

DepthImage SevenScenesSequence::loadDepth(int i) const {
#if defined(GMM_MCL_HAVE_PNG)
  DepthImage img = loadDepthPng16(depthPath(i));
  if (img.width_px != intrinsics_.width_px || img.height_px != intrinsics_.height_px) {
    throw std::runtime_error(depthPath(i) + ": unexpected image size");
  }
  return img;
#else
  (void)i;
  throw std::runtime_error("built without libpng: cannot read 7-Scenes depth PNGs");
#endif
}

}  // namespace gmm_mcl

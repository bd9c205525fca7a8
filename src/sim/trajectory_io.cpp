#include "gmm_mcl/sim/trajectory_io.h"

#include <Eigen/SVD>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <sstream>
#include <stdexcept>

#include "gmm_mcl/common/number_list.h"

namespace gmm_mcl {
namespace sim {

std::vector<Eigen::Isometry3d> readMatrixTrajectory(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open trajectory");
  std::vector<Eigen::Isometry3d> poses;
  auto onLine = [&](int line_no, const std::vector<double>& v) {
    auto fail = [&](const std::string& what) {
      throw std::runtime_error(path + ": line " + std::to_string(line_no) + ": " + what);
    };
    if (v.empty()) return;
    if (v.size() != 16)
      fail("expected 16 numbers (a row-major 4x4), found " + std::to_string(v.size()));
    Eigen::Matrix4d M;
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) M(r, c) = v[r * 4 + c];
    }
    if ((M.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-6) {
      fail("last row is not 0 0 0 1");
    }
    const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
    if ((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-3 ||
        R.determinant() < 0.0) {
      fail("the upper-left 3x3 is not a rotation");
    }
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = svd.matrixU() * svd.matrixV().transpose();
    T.translation() = M.topRightCorner<3, 1>();
    poses.push_back(T);
  };
  std::string why;
  if (!forEachNumberLine(in, onLine, &why)) throw std::runtime_error(path + ": " + why);
  if (poses.empty()) throw std::runtime_error(path + ": no poses");
  return poses;
}

namespace {

// The number after "key": in a flat JSON text (enough for cam_params.json).
bool jsonNumber(const std::string& text, const std::string& key, double* out) {
  const size_t k = text.find("\"" + key + "\"");
  if (k == std::string::npos) return false;
  size_t c = text.find(':', k + key.size() + 2);
  if (c == std::string::npos) return false;
  const char* start = text.c_str() + c + 1;
  char* end = nullptr;
  const double v = std::strtod(start, &end);
  if (end == start || !std::isfinite(v)) return false;
  *out = v;
  return true;
}

}  // namespace

void readReplicaCamera(const std::string& path, Intrinsics* K, double* depth_units_per_m) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open camera parameters");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  double v[7];
  const char* keys[7] = {"w", "h", "fx", "fy", "cx", "cy", "scale"};
  for (int i = 0; i < 7; ++i) {
    if (!jsonNumber(text, keys[i], &v[i])) {
      throw std::runtime_error(path + ": missing or non-numeric \"" + keys[i] + "\"");
    }
  }
  if (v[0] < 1 || v[1] < 1 || v[0] > 100000 || v[1] > 100000 || v[0] != std::floor(v[0]) ||
      v[1] != std::floor(v[1])) {
    throw std::runtime_error(path + ": bad image size");
  }
  if (!(v[2] > 0) || !(v[3] > 0) || !(v[6] > 0)) {
    throw std::runtime_error(path + ": focal lengths and scale must be positive");
  }
  K->width_px = static_cast<int>(v[0]);
  K->height_px = static_cast<int>(v[1]);
  K->fx_px = static_cast<float>(v[2]);
  K->fy_px = static_cast<float>(v[3]);
  K->cx_px = static_cast<float>(v[4]);
  K->cy_px = static_cast<float>(v[5]);
  *depth_units_per_m = v[6];
}

void writeTumTrajectory(const std::string& path, const std::vector<double>& stamps_s,
                        const std::vector<Eigen::Isometry3d>& T_world_frame,
                        const std::string& comment) {
  if (stamps_s.size() != T_world_frame.size()) {
    throw std::runtime_error(path + ": " + std::to_string(stamps_s.size()) + " stamps for " +
                             std::to_string(T_world_frame.size()) + " poses");
  }
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path + ": cannot write the trajectory");
  std::istringstream lines(comment);
  std::string line;
  while (std::getline(lines, line)) out << "# " << line << '\n';
  out << "# timestamp tx ty tz qx qy qz qw\n";
  for (size_t i = 0; i < stamps_s.size(); ++i) {
    const Eigen::Isometry3d& T = T_world_frame[i];
    const Eigen::Quaterniond q(T.linear());
    const Eigen::Vector3d& t = T.translation();
    char buf[256];
    std::snprintf(buf, sizeof(buf), "%.6f %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n", stamps_s[i], t.x(),
                  t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
    out << buf;
  }
  if (!out) throw std::runtime_error(path + ": write failed");
}

}  // namespace sim
}  // namespace gmm_mcl

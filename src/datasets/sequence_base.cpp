#include "gmm_mcl/datasets/sequence_base.h"

#include <dirent.h>
#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "gmm_mcl/common/number_list.h"
#include "gmm_mcl/datasets/seven_scenes_sequence.h"
#include "gmm_mcl/datasets/stanford_sequence.h"
#include "gmm_mcl/datasets/tum_sequence.h"
#include "gmm_mcl/filter/pose.h"
#include "sequence_io.h"

#if defined(GMM_MCL_HAVE_PNG)
#include "gmm_mcl/camera/png_io.h"
#endif

namespace gmm_mcl {
namespace seqio {

void fail(const std::string& path, const std::string& what) {
  throw std::runtime_error(path + ": " + what);
}

bool fileExists(const std::string& path) {
  struct stat st;
  return stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

bool isDirectory(const std::string& path) {
  struct stat st;
  return stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

std::vector<std::string> listDirectory(const std::string& dir) {
  DIR* d = opendir(dir.c_str());
  if (!d) fail(dir, "cannot open the folder");
  std::vector<std::string> names;
  while (const dirent* e = readdir(d)) {
    const std::string n = e->d_name;
    if (n != "." && n != "..") names.push_back(n);
  }
  closedir(d);
  std::sort(names.begin(), names.end());
  return names;
}

bool readNumberFile(const std::string& path, std::vector<double>* out, std::string* why) {
  std::ifstream in(path);
  if (!in) {
    *why = "cannot open";
    return false;
  }
  out->clear();
  return forEachNumberLine(
      in, [out](int, const std::vector<double>& v) { out->insert(out->end(), v.begin(), v.end()); },
      why);
}

Eigen::Matrix3d orthonormalise(const Eigen::Matrix3d& M, const std::string& where) {
  Eigen::Matrix3d R;
  std::string why;
  if (!nearestRotation(M, &R, &why)) fail(where, why);
  return R;
}

DepthImage loadDepthPngScaled(const std::string& path, double units_per_m) {
#if defined(GMM_MCL_HAVE_PNG)
  DepthImage img = loadDepthPng16(path);
  if (units_per_m == 1000.0) return img;
  const double to_mm = 1000.0 / units_per_m;
  for (int v = 0; v < img.height_px; ++v) {
    uint8_t* row = img.data.data() + static_cast<size_t>(v) * img.row_bytes;
    for (int u = 0; u < img.width_px; ++u) {
      const unsigned raw = row[2 * u] | (row[2 * u + 1] << 8);
      double mm = raw == 0 ? 0.0 : std::round(raw * to_mm);
      if (mm > 65534.0) mm = 0.0;
      const unsigned out = static_cast<unsigned>(mm);
      row[2 * u] = static_cast<uint8_t>(out & 0xff);
      row[2 * u + 1] = static_cast<uint8_t>(out >> 8);
    }
  }
  return img;
#else
  (void)units_per_m;
  fail(path, "built without libpng: cannot read depth PNGs");
#endif
}

}  // namespace seqio

DepthImage Sequence::loadDepth(int i) const {
  const std::string& path = depth_paths_[i];
  DepthImage img = seqio::loadDepthPngScaled(path, depth_units_per_m_);
  if (img.width_px != intrinsics_.width_px || img.height_px != intrinsics_.height_px) {
    seqio::fail(path, "image is " + std::to_string(img.width_px) + "x" +
                          std::to_string(img.height_px) + ", expected " +
                          std::to_string(intrinsics_.width_px) + "x" +
                          std::to_string(intrinsics_.height_px));
  }
  return img;
}

namespace {

Intrinsics preset(double fx, double fy, double cx, double cy, int w, int h) {
  const double K[9] = {fx, 0, cx, 0, fy, cy, 0, 0, 1};
  return makeIntrinsics(K, w, h);
}

}  // namespace

Intrinsics parseIntrinsicsOption(const std::string& value, int width_px, int height_px,
                                 const std::string& context) {
  const int w = width_px, h = height_px;
  try {
    // TUM: depth registered to colour, so the colour camera's calibration (file_formats page).
    if (value == "fr1") return preset(517.3, 516.5, 318.6, 255.3, w, h);
    if (value == "fr2") return preset(520.9, 521.0, 325.1, 249.7, w, h);
    if (value == "fr3") return preset(535.4, 539.2, 320.1, 247.6, w, h);
    // ICL-NUIM's TUM-format release lists fy = -480 for its flipped y; the depth PNGs are
    // written for a standard pinhole with fy = +480.
    if (value == "icl") return preset(481.20, 480.0, 319.5, 239.5, w, h);
    if (value == "kinect") return preset(525.0, 525.0, 319.5, 239.5, w, h);
    if (value.find(',') != std::string::npos) {
      const std::vector<double> v = parseNumberList(value);
      if (v.size() != 4) {
        throw std::runtime_error("'" + value + "' is not fx,fy,cx,cy (four numbers)");
      }
      return preset(v[0], v[1], v[2], v[3], w, h);
    }
    std::vector<double> v;
    std::string why;
    if (!seqio::fileExists(value)) {
      throw std::runtime_error("'" + value +
                               "' is neither a preset (fr1, fr2, fr3, icl, kinect), fx,fy,cx,cy, "
                               "nor a file");
    }
    if (!seqio::readNumberFile(value, &v, &why)) seqio::fail(value, why);
    if (v.size() == 4 || v.size() == 6) return preset(v[0], v[1], v[2], v[3], w, h);
    if (v.size() == 9) return makeIntrinsics(v.data(), w, h);
    seqio::fail(value, "expected fx fy cx cy [width height] or a 3x3 K, found " +
                           std::to_string(v.size()) + " numbers");
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(context + ": intrinsics '" + value + "': " + e.what());
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(context + ": intrinsics: " + e.what());
  }
}

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

Eigen::Matrix3d resolveGravity(const std::string& option, const std::string& dir,
                               const std::string& format_default,
                               const Eigen::Isometry3d& T_world_first_cam, std::string* source) {
  std::string mode = option;
  source->clear();
  if (mode.empty()) {
    const std::string gpath = dir + "/gravity-direction.txt";
    if (seqio::fileExists(gpath)) {
      std::vector<double> g;
      std::string why;
      if (!seqio::readNumberFile(gpath, &g, &why)) seqio::fail(gpath, why);
      if (g.size() != 3) {
        seqio::fail(gpath,
                    "expected 3 numbers (the down direction), found " + std::to_string(g.size()));
      }
      const Eigen::Vector3d down(g[0], g[1], g[2]);
      if (down.norm() < 1e-9) seqio::fail(gpath, "zero gravity vector");
      *source = gpath;
      return gravityAlignment(down);
    }
    mode = format_default;
    if (mode != "none") {
      // Said, not silent: a wrong up axis turns yaw into a tilt and the 4-DoF search fails.
      *source =
          mode + " (assumed: no gravity-direction.txt in " + dir +
          "; choose with --gravity x-up|y-up|z-up|x-down|y-down|z-down|first-camera|gx,gy,gz)";
    }
  }
  const std::string assumed = source->empty() ? "" : *source;
  if (mode == "none") {
    *source = "none";
    return Eigen::Matrix3d::Identity();
  }
  // An axis of the world frame pointing up or down: x-up, y-up, z-up, x-down, y-down, z-down.
  if (mode.size() >= 4 && (mode[0] == 'x' || mode[0] == 'y' || mode[0] == 'z') &&
      (mode.substr(1) == "-up" || mode.substr(1) == "-down")) {
    Eigen::Vector3d axis = Eigen::Vector3d::Zero();
    axis[mode[0] - 'x'] = 1.0;
    *source = assumed.empty() ? mode : assumed;
    return gravityAlignment(mode.substr(1) == "-up" ? Eigen::Vector3d(-axis) : axis);
  }
  if (mode == "first-camera") {
    // the first camera held level: its +y (optical down) is down
    *source = assumed.empty() ? "first-camera" : assumed;
    return gravityAlignment(T_world_first_cam.linear() * Eigen::Vector3d::UnitY());
  }
  const std::vector<double> g = parseNumberList(mode);
  if (g.size() != 3 || Eigen::Vector3d(g[0], g[1], g[2]).norm() < 1e-9) {
    throw std::runtime_error(dir + ": gravity option '" + mode +
                             "' is not x-up, y-up, z-up, x-down, y-down, z-down, first-camera or "
                             "a non-zero gx,gy,gz");
  }
  *source = "down " + mode;
  return gravityAlignment(Eigen::Vector3d(g[0], g[1], g[2]));
}

std::unique_ptr<Sequence> openSequence(const std::string& format, const std::string& dir,
                                       const SequenceOptions& options) {
  if (!seqio::isDirectory(dir)) seqio::fail(dir, "not a folder");
  if (format == "7scenes") {
    return std::unique_ptr<Sequence>(new SevenScenesSequence(dir, options.max_frames, options));
  }
  if (format == "tum") return std::unique_ptr<Sequence>(new TumSequence(dir, options));
  if (format == "stanford") return std::unique_ptr<Sequence>(new StanfordSequence(dir, options));
  throw std::runtime_error("unknown data-set format '" + format + "' (7scenes, tum, stanford)");
}

}  // namespace gmm_mcl

#include "gmm_mcl/datasets/sequence_writer.h"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <stdexcept>

#include "sequence_io.h"

#if defined(GMM_MCL_HAVE_PNG)
#include "gmm_mcl/camera/png_io.h"
#endif

namespace gmm_mcl {
namespace {

std::ofstream openOut(const std::string& path) {
  std::ofstream out(path);
  if (!out) seqio::fail(path, "cannot open for writing");
  out.precision(9);
  return out;
}

void writeCommon(const Sequence& seq, const std::string& dir) {
  const Intrinsics& K = seq.intrinsics();
  std::ofstream k = openOut(dir + "/intrinsics.txt");
  k << "# fx fy cx cy width height (pixels), written from " << seq.source() << "\n"
    << K.fx_px << ' ' << K.fy_px << ' ' << K.cx_px << ' ' << K.cy_px << ' ' << K.width_px << ' '
    << K.height_px << '\n';
  const Eigen::Vector3d down = seq.R_aligned_world().transpose() * Eigen::Vector3d(0, 0, -1);
  std::ofstream g = openOut(dir + "/gravity-direction.txt");
  g.precision(12);
  g << down.x() << ' ' << down.y() << ' ' << down.z() << '\n';
}

void savePng(const DepthImage& img, const std::string& path) {
#if defined(GMM_MCL_HAVE_PNG)
  saveDepthPng16(img, path);
#else
  (void)img;
  seqio::fail(path, "built without libpng: cannot write depth PNGs");
#endif
}

// Millimetres -> `units_per_m` raw units (values that do not fit become 0: no measurement);
// with keep_stride > 1 only pixels whose u and v are multiples of it keep their depth.
DepthImage rescaleFromMm(const DepthImage& mm, double units_per_m, int keep_stride = 1) {
  DepthImage out = mm;
  const double f = units_per_m / 1000.0;
  for (int v = 0; v < out.height_px; ++v) {
    uint8_t* row = out.data.data() + static_cast<size_t>(v) * out.row_bytes;
    for (int u = 0; u < out.width_px; ++u) {
      const unsigned raw = row[2 * u] | (row[2 * u + 1] << 8);
      const bool kept = u % keep_stride == 0 && v % keep_stride == 0;
      double x = raw == 65535 || !kept ? 0.0 : raw * f;
      if (x > 65535.0) x = 0.0;
      const unsigned q = static_cast<unsigned>(x + 0.5);
      row[2 * u] = static_cast<uint8_t>(q & 0xff);
      row[2 * u + 1] = static_cast<uint8_t>(q >> 8);
    }
  }
  return out;
}

void writeTumPose(std::ofstream& out, double t, const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.linear());
  char stamp[48];
  std::snprintf(stamp, sizeof(stamp), "%.6f", t);
  out << stamp << ' ' << T.translation().x() << ' ' << T.translation().y() << ' '
      << T.translation().z() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w()
      << '\n';
}

}  // namespace

void makeDirectories(const std::string& dir) {
  for (size_t pos = 1; pos <= dir.size(); ++pos) {
    if (pos == dir.size() || dir[pos] == '/') {
      const std::string part = dir.substr(0, pos);
      if (mkdir(part.c_str(), 0755) != 0 && errno != EEXIST) {
        seqio::fail(part, std::string("cannot create the folder: ") + std::strerror(errno));
      }
    }
  }
}

void writeTumFolder(const Sequence& seq, const std::string& dir, const TumWriteOptions& options) {
  const int n = options.max_frames > 0 ? std::min(options.max_frames, seq.size()) : seq.size();
  makeDirectories(dir + "/depth");
  writeCommon(seq, dir);
  std::ofstream list = openOut(dir + "/depth.txt");
  std::ofstream gt = openOut(dir + "/groundtruth.txt");
  list << "# depth maps\n# written from " << seq.source() << "\n# timestamp filename\n";
  gt << "# ground truth trajectory\n# written from " << seq.source()
     << "\n# timestamp tx ty tz qx qy qz qw\n";
  list.precision(6);
  list.setf(std::ios::fixed);
  gt.precision(9);
  for (int i = 0; i < n; ++i) {
    char name[64];
    std::snprintf(name, sizeof(name), "depth/%.6f.png", seq.stampS(i));
    list << seq.stampS(i) << ' ' << name << '\n';
    savePng(rescaleFromMm(seq.loadDepth(i), 5000.0, std::max(1, options.keep_stride_px)),
            dir + "/" + name);
    const Eigen::Isometry3d& A = seq.T_world_cam(i);
    const Eigen::Isometry3d& B = seq.T_world_cam(std::min(i + 1, n - 1));
    const double dt = i + 1 < n ? seq.stampS(i + 1) - seq.stampS(i) : 0.0;
    const int steps = i + 1 < n ? std::max(1, options.truth_per_frame) : 1;
    for (int s = 0; s < steps; ++s) {
      const double a = static_cast<double>(s) / steps;
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.linear() = Eigen::Quaterniond(A.linear())
                       .slerp(a, Eigen::Quaterniond(B.linear()))
                       .toRotationMatrix();
      T.translation() = (1 - a) * A.translation() + a * B.translation();
      writeTumPose(gt, seq.stampS(i) + a * dt + options.truth_offset_s, T);
    }
  }
  if (!list || !gt) seqio::fail(dir, "write failed");
}

void writeStanfordFolder(const Sequence& seq, const std::string& dir, int max_frames) {
  const int n = max_frames > 0 ? std::min(max_frames, seq.size()) : seq.size();
  makeDirectories(dir + "/depth");
  writeCommon(seq, dir);
  std::ofstream log = openOut(dir + "/trajectory.log");
  log.precision(12);
  for (int i = 0; i < n; ++i) {
    char name[64];
    std::snprintf(name, sizeof(name), "/depth/%06d.png", i + 1);
    savePng(seq.loadDepth(i), dir + name);
    log << i << ' ' << i << ' ' << i + 1 << '\n';
    const Eigen::Matrix4d M = seq.T_world_cam(i).matrix();
    for (int r = 0; r < 4; ++r) {
      log << M(r, 0) << ' ' << M(r, 1) << ' ' << M(r, 2) << ' ' << M(r, 3) << '\n';
    }
  }
  if (!log) seqio::fail(dir + "/trajectory.log", "write failed");
}

}  // namespace gmm_mcl

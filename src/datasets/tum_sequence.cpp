#include "gmm_mcl/datasets/tum_sequence.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "sequence_io.h"

namespace gmm_mcl {
namespace {

std::string where(const std::string& path, int line) { return path + ":" + std::to_string(line); }

// The tokens of a non-comment line; false for blank and '#' lines.
bool tokens(const std::string& line, std::vector<std::string>* out) {
  out->clear();
  const size_t first = line.find_first_not_of(" \t\r");
  if (first == std::string::npos || line[first] == '#') return false;
  std::istringstream ls(line);
  std::string tok;
  while (ls >> tok) out->push_back(tok);
  return true;
}

bool toDouble(const std::string& s, double* v) {
  char* end = nullptr;
  *v = std::strtod(s.c_str(), &end);
  return end != s.c_str() && *end == '\0' && std::isfinite(*v);
}

}  // namespace

std::vector<StampedPose> readTumTrajectory(const std::string& path) {
  std::ifstream in(path);
  if (!in) seqio::fail(path, "cannot open");
  std::vector<StampedPose> poses;
  std::string line;
  std::vector<std::string> tok;
  for (int n = 1; std::getline(in, line); ++n) {
    if (!tokens(line, &tok)) continue;
    if (tok.size() != 8) {
      seqio::fail(where(path, n), "expected 8 fields 't tx ty tz qx qy qz qw', found " +
                                      std::to_string(tok.size()));
    }
    double v[8];
    for (int k = 0; k < 8; ++k) {
      if (!toDouble(tok[k], &v[k])) {
        seqio::fail(where(path, n),
                    "field " + std::to_string(k + 1) + " '" + tok[k] + "' is not a finite number");
      }
    }
    const Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
    if (q.norm() < 0.5 || q.norm() > 1.5) {
      seqio::fail(where(path, n), "quaternion (qx qy qz qw) is far from unit length");
    }
    StampedPose p;
    p.stamp_s = v[0];
    p.T.linear() = q.normalized().toRotationMatrix();
    p.T.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
    if (!poses.empty() && p.stamp_s < poses.back().stamp_s) {
      seqio::fail(where(path, n), "timestamp goes backwards");
    }
    poses.push_back(p);
  }
  if (poses.empty()) seqio::fail(path, "no poses");
  return poses;
}

int nearestPose(const std::vector<StampedPose>& poses, double t_s, double tolerance_s) {
  const auto it = std::lower_bound(poses.begin(), poses.end(), t_s,
                                   [](const StampedPose& p, double t) { return p.stamp_s < t; });
  int best = -1;
  double best_dt = tolerance_s;
  for (auto c : {it, it == poses.begin() ? poses.end() : it - 1}) {
    if (c == poses.end()) continue;
    const double dt = std::abs(c->stamp_s - t_s);
    if (dt <= best_dt) {
      best_dt = dt;
      best = static_cast<int>(c - poses.begin());
    }
  }
  return best;
}

TumSequence::TumSequence(const std::string& dir, const SequenceOptions& options)
    : Sequence("tum", dir) {
  depth_units_per_m_ = options.depth_units_per_m > 0.0 ? options.depth_units_per_m : 5000.0;
  if (!(options.association_tolerance_s >= 0.0)) {
    seqio::fail(dir, "association tolerance must be >= 0");
  }
  const std::string list = dir + "/depth.txt";
  const std::string gt_path = dir + "/groundtruth.txt";
  if (!seqio::fileExists(list)) seqio::fail(list, "missing: not a TUM RGB-D folder");
  if (!seqio::fileExists(gt_path))
    seqio::fail(gt_path, "missing: no ground truth to replay against");
  const std::vector<StampedPose> gt = readTumTrajectory(gt_path);

  std::ifstream in(list);
  std::string line;
  std::vector<std::string> tok;
  double last_t = -INFINITY;
  for (int n = 1; std::getline(in, line); ++n) {
    if (!tokens(line, &tok)) continue;
    if (tok.size() != 2) {
      seqio::fail(where(list, n),
                  "expected 'timestamp filename', found " + std::to_string(tok.size()) + " fields");
    }
    double t;
    if (!toDouble(tok[0], &t)) seqio::fail(where(list, n), "'" + tok[0] + "' is not a timestamp");
    if (t <= last_t) seqio::fail(where(list, n), "timestamp not increasing");
    last_t = t;
    const int k = nearestPose(gt, t, options.association_tolerance_s);
    if (k < 0) {
      ++unassociated_;
      continue;
    }
    stamps_s_.push_back(t);
    depth_paths_.push_back(dir + "/" + tok[1]);
    T_world_cam_.push_back(gt[k].T);
    if (options.max_frames > 0 && size() >= options.max_frames) break;
  }
  if (stamps_s_.empty()) {
    std::ostringstream msg;
    msg.setf(std::ios::fixed);
    msg.precision(3);
    msg << "no depth frame has a ground-truth pose within " << options.association_tolerance_s
        << " s (" << unassociated_ << " frames listed; ground truth " << gt.front().stamp_s
        << " .. " << gt.back().stamp_s << " s)";
    seqio::fail(list, msg.str());
  }
  // Image size from the first frame.
  const DepthImage first = seqio::loadDepthPngScaled(depth_paths_.front(), depth_units_per_m_);
  const int w = first.width_px, h = first.height_px;
  std::string spec = options.intrinsics;
  if (spec.empty() && seqio::fileExists(dir + "/intrinsics.txt")) spec = dir + "/intrinsics.txt";
  if (spec.empty()) {
    for (const char* fr : {"fr1", "fr2", "fr3"}) {
      if (dir.find(std::string("freiburg") + fr[2]) != std::string::npos) spec = fr;
    }
  }
  if (spec.empty()) {
    seqio::fail(dir,
                "no intrinsics: no intrinsics.txt and not a freiburgN folder; give "
                "fr1|fr2|fr3|icl|kinect, fx,fy,cx,cy or a file");
  }
  intrinsics_ = parseIntrinsicsOption(spec, w, h, dir);
  intrinsics_source_ = spec;
  R_aligned_world_ =
      resolveGravity(options.gravity, dir, "z-up", T_world_cam_.front(), &gravity_source_);
}

}  // namespace gmm_mcl

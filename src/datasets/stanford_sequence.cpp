#include "gmm_mcl/datasets/stanford_sequence.h"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <stdexcept>

#include "gmm_mcl/common/number_list.h"
#include "sequence_io.h"

namespace gmm_mcl {
namespace {

std::string where(const std::string& path, int line) { return path + ":" + std::to_string(line); }

// Reads the next non-blank line's numbers; false at the end of the file.
bool nextNumbers(std::ifstream& in, const std::string& path, int* line_no,
                 std::vector<double>* out) {
  std::string line;
  while (std::getline(in, line)) {
    ++*line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    out->clear();
    std::string tok;
    if (!parseNumberLine(line, out, &tok)) {
      seqio::fail(where(path, *line_no), "'" + tok + "' is not a finite number");
    }
    return true;
  }
  return false;
}

}  // namespace

std::vector<LogEntry> readLogTrajectory(const std::string& path) {
  std::ifstream in(path);
  if (!in) seqio::fail(path, "cannot open");
  std::vector<LogEntry> entries;
  std::vector<double> v;
  int line_no = 0;
  while (nextNumbers(in, path, &line_no, &v)) {
    if (v.size() != 3 || v[2] != std::floor(v[2])) {
      seqio::fail(where(path, line_no),
                  "expected a header 'id id frame_index' (3 integers), found " +
                      std::to_string(v.size()) + " numbers");
    }
    LogEntry e;
    e.frame_index = static_cast<long>(v[2]);
    Eigen::Matrix4d M;
    for (int r = 0; r < 4; ++r) {
      if (!nextNumbers(in, path, &line_no, &v)) {
        seqio::fail(path, "ends inside the matrix of frame " + std::to_string(e.frame_index));
      }
      if (v.size() != 4) {
        seqio::fail(where(path, line_no),
                    "expected a matrix row of 4 numbers, found " + std::to_string(v.size()));
      }
      for (int c = 0; c < 4; ++c) M(r, c) = v[c];
    }
    if ((M.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-6) {
      seqio::fail(where(path, line_no), "last matrix row is not 0 0 0 1");
    }
    e.T.linear() = seqio::orthonormalise(M.topLeftCorner<3, 3>(), where(path, line_no));
    e.T.translation() = M.topRightCorner<3, 1>();
    if (!entries.empty() && e.frame_index <= entries.back().frame_index) {
      seqio::fail(where(path, line_no - 4),
                  "frame index " + std::to_string(e.frame_index) + " not increasing");
    }
    entries.push_back(e);
  }
  if (entries.empty()) seqio::fail(path, "no poses");
  return entries;
}

StanfordSequence::StanfordSequence(const std::string& dir, const SequenceOptions& options)
    : Sequence("stanford", dir) {
  if (options.depth_units_per_m > 0.0) depth_units_per_m_ = options.depth_units_per_m;
  if (!(options.frame_rate_hz > 0.0)) seqio::fail(dir, "frame rate must be positive");
  log_path_ = options.trajectory;
  if (log_path_.empty()) {
    for (const std::string& n : seqio::listDirectory(dir)) {
      if (n.size() > 4 && n.compare(n.size() - 4, 4, ".log") == 0) {
        if (!log_path_.empty()) {
          seqio::fail(dir, "more than one *.log trajectory; choose one with --trajectory");
        }
        log_path_ = dir + "/" + n;
      }
    }
    if (log_path_.empty()) seqio::fail(dir, "no *.log trajectory: not a Stanford folder");
  }
  const std::string depth_dir = dir + "/depth";
  if (!seqio::isDirectory(depth_dir)) seqio::fail(depth_dir, "missing: not a Stanford folder");
  // Depth images by number (000001.png -> 1).
  std::map<long, std::string> by_number;
  for (const std::string& n : seqio::listDirectory(depth_dir)) {
    if (n.size() < 5 || n.compare(n.size() - 4, 4, ".png") != 0) continue;
    const std::string stem = n.substr(0, n.size() - 4);
    char* end = nullptr;
    const long k = std::strtol(stem.c_str(), &end, 10);
    if (end == stem.c_str() || *end != '\0') continue;
    by_number[k] = depth_dir + "/" + n;
  }
  const std::vector<LogEntry> log = readLogTrajectory(log_path_);
  for (const LogEntry& e : log) {
    const auto it = by_number.find(e.frame_index);
    if (it == by_number.end()) {
      seqio::fail(log_path_, "frame index " + std::to_string(e.frame_index) +
                                 " has no depth image " + depth_dir + "/" +
                                 std::to_string(e.frame_index) + ".png (any zero padding)");
    }
    depth_paths_.push_back(it->second);
    T_world_cam_.push_back(e.T);
    stamps_s_.push_back((e.frame_index - log.front().frame_index) / options.frame_rate_hz);
    if (options.max_frames > 0 && size() >= options.max_frames) break;
  }
  const DepthImage first = seqio::loadDepthPngScaled(depth_paths_.front(), depth_units_per_m_);
  std::string spec = options.intrinsics;
  if (spec.empty() && seqio::fileExists(dir + "/intrinsics.txt")) spec = dir + "/intrinsics.txt";
  if (spec.empty()) spec = "kinect";
  intrinsics_ = parseIntrinsicsOption(spec, first.width_px, first.height_px, dir);
  R_aligned_world_ =
      resolveGravity(options.gravity, dir, "first-camera", T_world_cam_.front(), &gravity_source_);
}

}  // namespace gmm_mcl

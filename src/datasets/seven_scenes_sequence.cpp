#include "gmm_mcl/datasets/seven_scenes_sequence.h"

#include <cstdio>
#include <stdexcept>

#include "sequence_io.h"

namespace gmm_mcl {
namespace {

std::string framePath(const std::string& dir, int i, const char* suffix) {
  char name[64];
  std::snprintf(name, sizeof(name), "/frame-%06d.%s", i, suffix);
  return dir + name;
}

}  // namespace

SevenScenesSequence::SevenScenesSequence(const std::string& data_dir, int max_frames,
                                         const SequenceOptions& options)
    : Sequence("7scenes", data_dir), frame_rate_hz_(options.frame_rate_hz) {
  if (!(frame_rate_hz_ > 0.0)) seqio::fail(data_dir, "frame rate must be positive");
  std::vector<double> v;
  std::string why;
  const std::string kpath = data_dir + "/camera-intrinsics.txt";
  if (options.intrinsics.empty()) {
    if (!seqio::readNumberFile(kpath, &v, &why)) seqio::fail(kpath, why);
    if (v.size() != 9) {
      seqio::fail(kpath,
                  "expected 9 numbers (3x3 camera matrix), found " + std::to_string(v.size()));
    }
    try {
      intrinsics_ = makeIntrinsics(v.data(), 640, 480);
    } catch (const std::invalid_argument& e) {
      seqio::fail(kpath, e.what());
    }
  } else {
    intrinsics_ = parseIntrinsicsOption(options.intrinsics, 640, 480, data_dir);
  }
  for (int i = 0; max_frames < 0 || i < max_frames; ++i) {
    const std::string ppath = framePath(data_dir, i, "pose.txt");
    if (!seqio::fileExists(ppath)) break;
    if (!seqio::readNumberFile(ppath, &v, &why)) seqio::fail(ppath, why);
    if (v.size() != 16) {
      seqio::fail(ppath, "expected a 4x4 pose (16 numbers), found " + std::to_string(v.size()));
    }
    Eigen::Matrix4d M;
    for (int k = 0; k < 16; ++k) M(k / 4, k % 4) = v[k];
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = seqio::orthonormalise(M.topLeftCorner<3, 3>(), ppath);
    T.translation() = M.topRightCorner<3, 1>();
    T_world_cam_.push_back(T);
    stamps_s_.push_back(i / frame_rate_hz_);
    depth_paths_.push_back(framePath(data_dir, i, "depth.png"));
  }
  if (T_world_cam_.empty()) {
    seqio::fail(data_dir, "no frame-000000.pose.txt: not a 7-Scenes sequence folder");
  }
  R_aligned_world_ =
      resolveGravity(options.gravity, data_dir, "none", T_world_cam_.front(), &gravity_source_);
}

}  // namespace gmm_mcl

#include "gmm_mcl/bench/frame_set.h"

#include <cstdint>
#include <cstring>
#include <fstream>
#include <random>
#include <stdexcept>

#include "gmm_mcl/datasets/seven_scenes_sequence.h"
#include "gmm_mcl/datasets/tum_sequence.h"
#include "gmm_mcl/sim/box_scene.h"
#include "gmm_mcl/sim/mesh_scene.h"

namespace gmm_mcl {
namespace bench {

namespace {
const char kMagic[8] = {'G', 'M', 'M', 'F', 'R', 'M', '1', '\0'};

template <typename T>
void put(std::ofstream& f, const T& v) {
  f.write(reinterpret_cast<const char*>(&v), sizeof(T));
}
template <typename T>
void get(std::ifstream& f, T* v, const std::string& path) {
  if (!f.read(reinterpret_cast<char*>(v), sizeof(T))) {
    throw std::runtime_error(path + ": truncated frame file");
  }
}
}  // namespace

namespace {
// Frames first .. first + count - 1 of a data set's sequence with their ground-truth poses.
FrameSet framesOf(const Sequence& sequence, const std::string& source, const std::string& dir,
                  int first, int count) {
  if (sequence.size() < first + count) {
    throw std::runtime_error(dir + ": " + std::to_string(sequence.size()) + " frames, " +
                             std::to_string(first + count) + " needed");
  }
  FrameSet set;
  set.source = source + " " + dir;
  set.K = sequence.intrinsics();
  for (int i = first; i < first + count; ++i) {
    set.images.push_back(sequence.loadDepth(i));
    set.T_map_cam.push_back(sequence.T_world_cam(i));
  }
  return set;
}
}  // namespace

FrameSet loadSevenScenes(const std::string& dir, int first, int count) {
  return framesOf(SevenScenesSequence(dir, first + count), "7-Scenes", dir, first, count);
}

FrameSet loadTumFrames(const std::string& dir, int first, int count) {
  SequenceOptions options;
  options.max_frames = first + count;
  return framesOf(TumSequence(dir, options), "TUM RGB-D", dir, first, count);
}

void saveFrameSet(const FrameSet& set, const std::string& path) {
  std::ofstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error(path + ": cannot write");
  f.write(kMagic, 8);
  put<uint32_t>(f, static_cast<uint32_t>(set.images.size()));
  put<uint32_t>(f, static_cast<uint32_t>(set.K.width_px));
  put<uint32_t>(f, static_cast<uint32_t>(set.K.height_px));
  put<float>(f, set.K.fx_px);
  put<float>(f, set.K.fy_px);
  put<float>(f, set.K.cx_px);
  put<float>(f, set.K.cy_px);
  for (size_t i = 0; i < set.images.size(); ++i) {
    const Eigen::Matrix4d M = set.T_map_cam[i].matrix();
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) put<double>(f, M(r, c));
    }
    const DepthImage& img = set.images[i];
    if (img.encoding != DepthEncoding::kMono16Millimetres || img.width_px != set.K.width_px ||
        img.height_px != set.K.height_px) {
      throw std::runtime_error(path + ": frames must be 16UC1 of the camera's size");
    }
    for (int v = 0; v < img.height_px; ++v) {
      f.write(reinterpret_cast<const char*>(img.data.data() + v * img.row_bytes), 2 * img.width_px);
    }
  }
  if (!f) throw std::runtime_error(path + ": write failed");
}

FrameSet loadFrameSet(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error(path + ": cannot open");
  char magic[8];
  if (!f.read(magic, 8) || std::memcmp(magic, kMagic, 8) != 0) {
    throw std::runtime_error(path + ": not a frame file (bad magic)");
  }
  uint32_t count, w, h;
  FrameSet set;
  set.source = "raw frames " + path;
  get(f, &count, path);
  get(f, &w, path);
  get(f, &h, path);
  if (w == 0 || h == 0 || w > 16384 || h > 16384) throw std::runtime_error(path + ": bad size");
  set.K.width_px = static_cast<int>(w);
  set.K.height_px = static_cast<int>(h);
  get(f, &set.K.fx_px, path);
  get(f, &set.K.fy_px, path);
  get(f, &set.K.cx_px, path);
  get(f, &set.K.cy_px, path);
  std::vector<uint16_t> mm(size_t(w) * h);
  for (uint32_t i = 0; i < count; ++i) {
    Eigen::Matrix4d M;
    for (int r = 0; r < 4; ++r) {
      for (int c = 0; c < 4; ++c) get(f, &M(r, c), path);
    }
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = M.block<3, 3>(0, 0);
    T.translation() = M.block<3, 1>(0, 3);
    set.T_map_cam.push_back(T);
    if (!f.read(reinterpret_cast<char*>(mm.data()), mm.size() * 2)) {
      throw std::runtime_error(path + ": truncated frame file");
    }
    set.images.push_back(DepthImage::fromMillimetres(static_cast<int>(w), static_cast<int>(h), mm));
  }
  return set;
}

void makeSyntheticScene(int count, GmmMap* map, FrameSet* frames) {
  const sim::BoxScene scene = sim::makeDefaultScene();
  *map = sim::tileScene(scene, 0.4, 0.015);
  frames->source = "synthetic box scene";
  frames->K = sim::sevenScenesCamera();
  frames->images.clear();
  frames->T_map_cam.clear();
  const std::vector<Eigen::Isometry3d> traj = sim::makeTrajectory(count);
  const Eigen::Isometry3d T_base_cam = sim::defaultBaseToCamera();
  sim::DepthNoise noise;
  noise.sigma_at_1m_m = 0.002;
  noise.dropout = 0.02;
  std::mt19937_64 rng(1);
  for (int i = 0; i < count; ++i) {
    const Eigen::Isometry3d T = traj[i] * T_base_cam;
    frames->images.push_back(
        sim::renderDepth(scene, frames->K, T, DepthEncoding::kMono16Millimetres, 5.0, noise, &rng));
    frames->T_map_cam.push_back(T);
  }
}

}  // namespace bench
}  // namespace gmm_mcl

// Depth frames with ground-truth camera poses for the benchmark and the data-set parity test:
// 7-Scenes or TUM RGB-D PNGs (with libpng), a raw file (for machines without libpng or the data
// set), or the synthetic box scene.
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "gmm_mcl/camera/depth_image.h"
#include "gmm_mcl/map/gmm_map.h"

namespace gmm_mcl {
namespace bench {

struct FrameSet {
  std::string source;  // what the frames are (printed by the tools)
  Intrinsics K;
  std::vector<DepthImage> images;            // 16UC1 millimetres
  std::vector<Eigen::Isometry3d> T_map_cam;  // ground truth, camera optical frame -> map
};

// Frames first..first+count-1 of a 7-Scenes sequence folder, read by the data-set reader
// (SevenScenesSequence: its camera-intrinsics.txt, rotations made orthonormal). Throws
// std::runtime_error when libpng is not built in, a file is bad or the folder is shorter.
FrameSet loadSevenScenes(const std::string& dir, int first, int count);

// Frames first..first+count-1 of a TUM RGB-D folder (the building world's walks, which
// scripts/make_building.sh renders), read by the data-set reader (TumSequence: its
// intrinsics.txt, depth paired with the nearest ground-truth pose). The poses are the folder's
// world frame, as written (no gravity alignment), the frame its map is in. Throws
// std::runtime_error when libpng is not built in, a file is bad or the folder is shorter.
FrameSet loadTumFrames(const std::string& dir, int first, int count);

// Raw frame file: "GMMFRM1\0", uint32 count, width, height, float fx, fy, cx, cy; per frame 16
// doubles (T_map_cam, row-major) then width*height uint16 millimetres. Little-endian.
void saveFrameSet(const FrameSet& set, const std::string& path);
FrameSet loadFrameSet(const std::string& path);

// The synthetic box scene (sim/box_scene.h): its tiled map (0.4 m tiles, 1.5 cm normal sigma)
// and `count` frames rendered along its trajectory at 640x480, f = 585 px.
void makeSyntheticScene(int count, GmmMap* map, FrameSet* frames);

}  // namespace bench
}  // namespace gmm_mcl

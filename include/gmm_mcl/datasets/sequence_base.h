// A recorded depth sequence with ground truth, as input for offline replay and the bag
// converters: one Sequence holding the data (intrinsics, stamps, poses, depth paths and units,
// gravity), one reader per data-set format filling it (7-Scenes, TUM RGB-D / ICL-NUIM, Stanford
// lounge/copyroom, the synthetic box scene). Readers load every pose up front and depth images
// on demand; bad input throws std::runtime_error naming the file and the fault.
#pragma once

#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "gmm_mcl/camera/depth_image.h"

namespace gmm_mcl {

// The data of a sequence; a reader (the constructor of a subclass) fills it. Depth is read on
// demand: loadDepth() reads the PNG at depthPath(i) in depth_units_per_m_ raw units per metre;
// a sequence without files (a simulation) overrides it.
class Sequence {
 public:
  virtual ~Sequence() = default;

  // "7scenes", "tum", "stanford", "sim", ...
  const char* format() const { return format_; }
  // The folder (or a description) the frames come from.
  const std::string& source() const { return source_; }
  int size() const { return static_cast<int>(T_world_cam_.size()); }
  const Intrinsics& intrinsics() const { return intrinsics_; }
  // Capture time of frame i in seconds (any origin; increasing).
  double stampS(int i) const { return stamps_s_[i]; }
  // Camera-to-world pose of frame i (optical frame: x right, y down, z forward).
  const Eigen::Isometry3d& T_world_cam(int i) const { return T_world_cam_[i]; }
  // Rotation taking world coordinates into a gravity-aligned frame (z up).
  const Eigen::Matrix3d& R_aligned_world() const { return R_aligned_world_; }
  // Where that rotation came from (a file, an option, the format's convention).
  const std::string& gravitySource() const { return gravity_source_; }
  const std::string& depthPath(int i) const { return depth_paths_[i]; }
  // Depth of frame i as 16UC1 millimetres (rescaled from the format's unit where needed);
  // throws std::runtime_error naming the file when it cannot be read or its size differs from
  // the intrinsics'.
  virtual DepthImage loadDepth(int i) const;

 protected:
  Sequence(const char* format, std::string source) : format_(format), source_(std::move(source)) {}

  const char* format_;
  std::string source_;
  Intrinsics intrinsics_;
  double depth_units_per_m_ = 1000.0;
  // One entry per frame in each.
  std::vector<double> stamps_s_;
  std::vector<std::string> depth_paths_;
  std::vector<Eigen::Isometry3d> T_world_cam_;
  Eigen::Matrix3d R_aligned_world_ = Eigen::Matrix3d::Identity();
  std::string gravity_source_ = "none";
};

// Options of the folder readers; every field has a format-specific default when left empty.
struct SequenceOptions {
  int max_frames = -1;  // read at most this many frames (-1: all)
  // Depth intrinsics: "fr1", "fr2", "fr3" (TUM, registered depth = colour intrinsics), "icl"
  // (ICL-NUIM in TUM format), "kinect" (525/525/319.5/239.5), "fx,fy,cx,cy", or a file holding
  // "fx fy cx cy" (a 3x3 K also works). Empty: the folder's intrinsics.txt, else the format's
  // default (TUM: from a freiburgN folder name; Stanford: kinect; 7-Scenes: its own file).
  std::string intrinsics;
  // Raw depth units per metre (TUM 5000, Stanford and 7-Scenes 1000); <= 0: format default.
  double depth_units_per_m = 0.0;
  // TUM: largest |depth stamp - ground-truth stamp| for association (TUM's associate.py: 0.02 s).
  double association_tolerance_s = 0.02;
  // Gravity: "" (the folder's gravity-direction.txt, else the format's convention, TUM z up,
  // Stanford the first camera's +y down, and the source says it was assumed), an up or down
  // axis of the world frame ("x-up", "y-up", "z-up", "x-down", "y-down", "z-down"),
  // "first-camera", or "gx,gy,gz" (down, world).
  std::string gravity;
  // Stanford: the trajectory file (default: the folder's only *.log).
  std::string trajectory;
  // Frame rate where the format has no stamps (Stanford, 7-Scenes).
  double frame_rate_hz = 30.0;
};

// Opens `dir` as `format` ("7scenes", "tum", "stanford"); throws std::runtime_error.
std::unique_ptr<Sequence> openSequence(const std::string& format, const std::string& dir,
                                       const SequenceOptions& options = SequenceOptions());

// Intrinsics from an option value (see SequenceOptions::intrinsics) for an image of the given
// size; throws std::runtime_error naming the fault. `context` prefixes the message.
Intrinsics parseIntrinsicsOption(const std::string& value, int width_px, int height_px,
                                 const std::string& context);

// The gravity alignment of a folder: `option` as SequenceOptions::gravity; with it empty, the
// folder's gravity-direction.txt (three numbers, the down direction in world coordinates), else
// `format_default` ("none": identity, "z-up", "first-camera"). Sets *source to say which.
Eigen::Matrix3d resolveGravity(const std::string& option, const std::string& dir,
                               const std::string& format_default,
                               const Eigen::Isometry3d& T_world_first_cam, std::string* source);

// Rotation R with R * down = (0, 0, -1), keeping the x axis as close to world x as possible.
Eigen::Matrix3d gravityAlignment(const Eigen::Vector3d& down_world);

}  // namespace gmm_mcl

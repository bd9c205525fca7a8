// A recorded depth sequence with ground truth, as input for offline replay and the bag
// converters: one interface, one reader per data-set format (7-Scenes, TUM RGB-D / ICL-NUIM,
// Stanford lounge/copyroom, the synthetic box scene). Readers load every pose up front and
// depth images on demand; bad input throws std::runtime_error naming the file and the fault.
#pragma once

#include <memory>
#include <string>

#include <Eigen/Geometry>

#include "gmm_mcl/camera/depth_image.h"

namespace gmm_mcl {

class Sequence {
 public:
  virtual ~Sequence() = default;

  // "7scenes", "tum", "stanford", "sim".
  virtual const char* format() const = 0;
  // The folder (or a description) the frames come from.
  virtual const std::string& source() const = 0;
  virtual int size() const = 0;
  virtual const Intrinsics& intrinsics() const = 0;
  // Capture time of frame i in seconds (any origin; increasing).
  virtual double stampS(int i) const = 0;
  // Camera-to-world pose of frame i (optical frame: x right, y down, z forward).
  virtual const Eigen::Isometry3d& T_world_cam(int i) const = 0;
  // Rotation taking world coordinates into a gravity-aligned frame (z up).
  virtual const Eigen::Matrix3d& R_aligned_world() const = 0;
  // Where that rotation came from (a file, an option, the format's convention).
  virtual std::string gravitySource() const = 0;
  // Depth of frame i as 16UC1 millimetres (rescaled from the format's unit where needed).
  virtual DepthImage loadDepth(int i) const = 0;
  virtual std::string depthPath(int i) const = 0;
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

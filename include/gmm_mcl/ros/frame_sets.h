// Frame sets of a rig of depth cameras (~more_cameras): which frames go into one update. Plain
// bookkeeping by the frames' stamps, without a master or a clock (unit-tested in
// test/ros/test_frame_sets.cpp); the nodelet hands in every converted frame and arms a wall
// timer for the wait that a pending set reports.
//
// The rule (docs/ros.md, Several depth cameras):
// - The lead camera is the first one, in the order depth, more_cameras, that delivers: whose
//   newest frame is at most timeout_s older than the frame at hand. A frame of the lead camera,
//   stamped after the last set, opens a set at its stamp.
// - The set waits for the other cameras that delivered for the previous set (or later) and
//   within timeout_s: until each has a frame within window_s of the set's stamp, or a newer one
//   (it has none for this set), or the wait is over (expire(), armed by the caller). A camera
//   that has never delivered, or missed the previous set, is not waited for. A new lead frame
//   ends a pending set too.
// - Each camera's newest frame within the window is used; its older frames are dropped and
//   counted, newer ones kept for the next set.
// - So while the first camera delivers its frames trigger the updates; once it has been silent
//   for timeout_s the next camera's frames do, and the first takes the lead back with its next
//   frame. A camera missing for more than timeout_s has dropped out (reported once, as its
//   return).
#pragma once

#include <std_msgs/Header.h>

#include <deque>
#include <memory>
#include <string>
#include <vector>

#include "gmm_mcl/camera/depth_image.h"

namespace gmm_mcl {

struct CameraFrame {
  std_msgs::Header header;
  DepthImage depth;
  Intrinsics intrinsics;
};

struct FrameSetParams {
  double window_s = 0.02;  // ~camera_set_window
  double timeout_s = 0.5;  // ~camera_timeout
  double wait_s = 0.1;     // ~camera_set_wait (the caller's timer; 0: sets never wait)
};

// One update's frames.
struct FrameSet {
  int lead = 0;                                      // the camera whose frame opened it
  std_msgs::Header header;                           // the lead frame's
  std::vector<std::shared_ptr<CameraFrame>> frames;  // per camera; null: none in this set
  bool waited_in_vain = false;                       // completed by expire()
};

struct CameraSetStats {
  long long frames = 0;      // handed in
  long long used = 0;        // in a set
  long long missing = 0;     // sets without a frame of it, after its first frame
  long long dropped = 0;     // superseded by a newer frame, too late for their set, or a jump back
  double last_stamp_s = -1;  // its newest frame's stamp; < 0: none yet
  double last_used_s = -1;   // the stamp of the last set with a frame of it
  bool dropped_out = false;  // missing from the last set, its newest frame older than timeout_s
};

// A camera that dropped out or came back (at a set's stamp), for a log line.
struct CameraTransition {
  int camera = 0;
  bool dropped_out = false;  // false: back
  double gap_s = 0.0;  // dropped out: since its newest frame; back: since the last set it was in
};

class FrameSets {
 public:
  FrameSets(int cameras, const FrameSetParams& params);
  void setParams(const FrameSetParams& params) { params_ = params; }
  const FrameSetParams& params() const { return params_; }
  int cameras() const { return static_cast<int>(cams_.size()); }

  // A frame of `camera` (each camera's frames in stamp order; a stamp more than a second before
  // the newest seen is a jump back: everything held is dropped and the sets start afresh).
  void add(int camera, CameraFrame frame);
  // The pending set of this generation waited long enough: it completes with what is there.
  void expire(unsigned long generation);
  // Whether a set waits (for the caller's timer of params().wait_s) and which.
  bool pending() const { return pending_; }
  unsigned long generation() const { return generation_; }
  // The next completed set, oldest first.
  bool takeReady(FrameSet* out);
  std::vector<CameraTransition> takeTransitions();

  const CameraSetStats& stats(int camera) const { return cams_[camera].stats; }
  double lastSetStampS() const { return last_set_s_; }

 private:
  struct Camera {
    std::deque<std::shared_ptr<CameraFrame>> frames;  // not used yet, oldest first
    CameraSetStats stats;
    double period_s = -1.0;  // between its last two frames; < 0: not known yet
  };
  int leadFor(double stamp_s) const;
  bool delivers(int camera, double stamp_s) const;
  void open(int camera);
  void completeIfReady();
  void complete(bool waited_in_vain);
  void restart();  // a jump back

  FrameSetParams params_;
  std::vector<Camera> cams_;
  double newest_s_ = -1.0;
  double last_set_s_ = -1.0;  // stamp of the last completed set
  bool pending_ = false;
  FrameSet open_;              // the pending set (lead frame in open_.frames[lead])
  std::vector<bool> awaited_;  // per camera, for the pending set
  unsigned long generation_ = 0;
  std::deque<FrameSet> ready_;
  std::vector<CameraTransition> transitions_;
};

}  // namespace gmm_mcl

// The nodelet's bookkeeping as plain functions, unit-tested without a master: frame accounting,
// ~status filling and the /diagnostics summary.
#pragma once

#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "gmm_mcl/FilterStatus.h"
#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/filter/update_budget.h"
#include "gmm_mcl/ros/frame_sets.h"

namespace gmm_mcl {

// Why a depth message was not used.
enum class FrameDrop {
  kConversion,  // the image or cloud could not be read (encoding, layout)
  kCameraInfo,  // its CameraInfo was refused, or none came with its stamp
  kExtrinsics,  // no tf to base_frame (or odom_frame) at its stamp in time
  kFrameSet,    // several cameras: superseded by a newer frame, or too late for its set
};

// Every depth message (of the first camera, with several) that arrives ends in one of: processed (a
// core step ran), gated (no motion since the last update), dropped for a reason, or still waiting
// (for tf or for its CameraInfo): received == processed + gated + dropped() + waiting().
struct FrameCounters {
  long long received = 0;
  long long processed = 0;
  long long gated = 0;
  long long dropped_conversion = 0;     // image or cloud rejected (encoding, layout)
  long long dropped_camera_info = 0;    // CameraInfo rejected, or none with the image's stamp
  long long dropped_extrinsics = 0;     // tf to base_frame (or odom_frame) not there in time
  long long dropped_frame_set = 0;      // several cameras: superseded, or too late for its set
  long long updates_other_cameras = 0;  // several cameras: updates led by another camera
  long long missed_seq = 0;             // never arrived (subscriber queue), from header.seq gaps
  long long camera_info_received = 0;
  long long imu_received = 0;
  long long odometry_received = 0;
  long long odometry_gaps = 0, imu_missing = 0, tf_skipped = 0, time_jumps = 0, resets = 0;
  long long reinitialised_total = 0, lost_events_total = 0;
  long long rival_moves_total = 0;  // the set moved to a rival place (lost.rival_*)

  // A depth message arrived with this header.seq (a publisher's seq grows by one per message).
  void arrived(uint32_t seq);
  void drop(FrameDrop reason);
  long long dropped() const {
    return dropped_conversion + dropped_camera_info + dropped_extrinsics + dropped_frame_set;
  }
  long long waiting() const { return received - processed - gated - dropped(); }

 private:
  bool have_seq_ = false;
  uint32_t last_seq_ = 0;
};

// The frame-rate budget's fields of ~status.
void fillBudgetStatus(const BudgetState& b, FilterStatus* out);

// ~status for one frame: the core's step result, the node's counters, the inputs' warnings.
void fillStatus(const StepResult& r, const FrameCounters& c, const std::string& backend,
                const std::string& backend_warning, double callback_ms,
                const std::string& input_warnings, FilterStatus* out);

// Something due every period_s of ROS time (diagnostics, markers), checked by a frequent poll:
// due once per period, and at once when the clock has gone back (a looped bag), where a ROS
// timer would wait out the jump.
struct PeriodicSchedule {
  double period_s = 1.0;
  double last_s = -1.0;  // when it was last due; < 0: never
  bool due(double now_s) {
    if (last_s >= 0.0 && now_s >= last_s && now_s - last_s < period_s) return false;
    last_s = now_s;
    return true;
  }
};

// What /diagnostics summarises (a snapshot, times in seconds of ROS time).
// One camera of a rig (~more_cameras): what /diagnostics and ~status say about it.
struct CameraHealth {
  std::string name;             // depth (the first camera) or its ~more_cameras name
  std::string topic;            // its depth topic
  long long arrived = 0;        // depth messages (any outcome)
  long long dropped_input = 0;  // refused by its input (conversion, CameraInfo, tf)
  CameraSetStats sets;          // the frame sets' counts (frame_sets.h)
  bool leads = false, in_last_set = false, used_last = false;  // in the last update
  int pixels = 0;
  std::string problem;       // why not used in the last update
  double depth_scale = 1.0;  // its depth-scale estimate and whether it sits at its bound
  bool depth_scale_at_bound = false;
};

struct NodeHealth {
  std::string config_error;
  FrameCounters counters;
  double now_s = 0.0;
  double last_arrival_s = -1.0;  // last depth message (any outcome); < 0: none yet
  double last_used_s = -1.0;     // last frame processed or gated
  double last_camera_info_s = -1.0;
  std::string depth_topic, camera_info_topic;  // camera_info_topic empty for a cloud
  // The latest distinct problems (at most kRecentProblems) and when each last happened; those
  // of the last 5 s are warned about.
  static constexpr size_t kRecentProblems = 4;
  std::vector<std::pair<std::string, double>> problems;
  void problem(const std::string& what, double now_s);
  std::string backend, backend_warning;
  bool have_step = false;
  StepStatus last_step = StepStatus::kOk;
  std::string last_step_message;
  double sigma_xy_m = 0.0, sigma_yaw_rad = 0.0;  // of the last estimate (largest of x and y)
  double depth_scale = 1.0;                      // the camera's depth-scale estimate
  bool depth_scale_at_bound = false;             // StepResult::depth_scale_at_bound
  bool below_lost_reference =
      false;  // the last frame's best score was below the lost detector's line
  long long frames_since_lost = -1;  // -1: never lost
  double warn_sigma_xy_m = 0.25, warn_sigma_yaw_rad = 0.25;
  double neff = 0.0, update_ms = 0.0;
  BudgetState budget;  // the frame-rate budget's choice
  // Several cameras: each, the first one first; empty with one camera.
  std::vector<CameraHealth> cameras;
  double timeout_s = 0.5;  // ~camera_timeout
};

struct Diagnosis {
  uint8_t level = 0;  // diagnostic_msgs::DiagnosticStatus OK, WARN, ERROR
  std::string message;
  std::vector<std::pair<std::string, std::string>> values;
};
// One used frame (updated, or gated: not updated for lack of motion) into the counters and the
// diagnostics snapshot (imu/odometry counts set by the caller), and its ~status (header left to
// the caller).
// first_camera false: an update of several cameras led by another than the first (counted as
// updates_other_cameras, not as a frame of the first camera).
void recordFrame(const StepResult& r, bool gated, bool sent_tf, double now_s,
                 const LostDetectionParams& lost, const std::string& backend,
                 const std::string& backend_warning, double callback_ms,
                 const std::string& warnings, NodeHealth* h, FilterStatus* status,
                 bool first_camera = true);
// ~status' cameras from the health's (several cameras; nothing with one camera).
void fillCameraStatus(const NodeHealth& h, double set_stamp_s, FilterStatus* status);

// The most severe findings first (ERROR: bad configuration, a backend error; WARN: no input,
// images without CameraInfo, lost, not converged, a CPU fallback, a recent problem), joined by
// "; ", and the counters.
Diagnosis diagnose(const NodeHealth& h);

// The node's NodeHealth behind a lock: inputs report from any thread (a depth message arriving,
// a drop, a problem), the frame thread records its frames, the diagnostics read a snapshot.
class HealthMonitor {
 public:
  void set(const std::function<void(NodeHealth*)>& change);
  void setWarnLimits(double sigma_xy_m, double sigma_yaw_rad);
  void setBackend(const std::string& name, const std::string& warning);
  NodeHealth snapshot() const;
  void arrived(uint32_t seq, double now_s);
  void cameraInfo(double now_s);
  void dropped(FrameDrop reason);
  // Counts one of the counters (e.g. resets) by one.
  void count(long long FrameCounters::*counter);
  void problem(const std::string& what, double now_s);
  // recordFrame() under the lock; also takes the inputs' message counts.
  FilterStatus frame(const StepResult& r, bool gated, bool sent_tf, double now_s,
                     const LostDetectionParams& lost, const std::string& backend,
                     const std::string& backend_warning, double callback_ms,
                     const std::string& warnings, long long imu_received,
                     long long odometry_received, bool first_camera = true);
  // Several cameras: a depth message of camera i arrived, or its input refused one.
  void cameraArrived(size_t camera);
  void cameraDropped(size_t camera);

 private:
  mutable std::mutex mutex_;
  NodeHealth health_;
};

}  // namespace gmm_mcl

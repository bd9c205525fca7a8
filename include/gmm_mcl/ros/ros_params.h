// The nodelet's parameters: the core's LocalizerParams (described in
// gmm_mcl/filter/parameter_table.h) plus the ROS-side options below, described the same way.
// Both tables feed the private ROS parameters, dynamic_reconfigure (cfg/Localizer.cfg is
// generated from them: gmm_mcl_params --cfg), the parameter reference (docs/parameters.md:
// gmm_mcl_params --markdown) and the startup log.
#pragma once

#include <dynamic_reconfigure/Config.h>
#include <ros/node_handle.h>

#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "gmm_mcl/LocalizerConfig.h"
#include "gmm_mcl/filter/localizer.h"
#include "gmm_mcl/filter/parameter_table.h"
#include "gmm_mcl/filter/pose.h"
#include "gmm_mcl/filter/update_budget.h"

namespace gmm_mcl {

struct RosOptions {
  std::string map_path;
  // A point cloud or mesh given as map_path: fitted on load (fit/fit_on_load.h, whose
  // FitOnLoadParams has these defaults; not included here: the map builder's headers are not
  // installed).
  int map_fit_components = 0;  // 0 = from the cloud's surface
  double map_fit_time_limit_s = 30.0;
  bool map_fit_cache = true;
  std::string map_frame = "map";
  std::string odom_frame = "odom";  // "" = no odometry frame: publish map -> base_frame
  std::string base_frame = "base_link";
  std::string odometry_source = "tf";   // tf (odom_frame -> base_frame), topic (~odom), none
  std::string depth_input = "image";    // image (+ CameraInfo) or cloud (organized PointCloud2)
  std::string image_transport = "raw";  // raw or another image_transport plugin; compressedDepth
  bool use_imu = true;
  bool tf_broadcast = true;
  double transform_tolerance_s = 0.1;
  double odom_timeout_s = 0.2;
  double imu_timeout_s = 0.5;
  double input_wait_s = 0.1;  // at most, for a frame's IMU and odometry messages (StepInputs)
  // A rig of several depth cameras (docs/ros.md, Several depth cameras): the other cameras' names,
  // comma-separated (a YAML list is accepted too); each subscribes NAME/image + NAME/camera_info
  // (or NAME/points) and has its own parameters under ~NAME/ (RigCameraParams).
  std::string more_cameras;
  double camera_set_window_s = 0.02;  // frames within this of the leading frame's stamp: one set
  double camera_set_wait_s = 0.1;     // wall time a set waits at most for the other cameras
  double camera_timeout_s = 0.5;      // ROS time without a frame: a camera has dropped out
  int queue_size = 1;
  bool init_from_map_bounds = false;
  double initial_sigma_xy_m = 0.25;  // spread of a requested pose whose covariance gives none
  double initial_sigma_z_m = 0.1;
  double initial_sigma_yaw_rad = 0.2;
  // A single-pose start (amcl's initial_pose_*): all four set, or none (the initial region).
  double initial_pose_x_m = std::numeric_limits<double>::quiet_NaN();
  double initial_pose_y_m = std::numeric_limits<double>::quiet_NaN();
  double initial_pose_z_m = std::numeric_limits<double>::quiet_NaN();
  double initial_pose_yaw_rad = std::numeric_limits<double>::quiet_NaN();
  double initial_cov_xx_m2 = 0.25;
  double initial_cov_yy_m2 = 0.25;
  double initial_cov_zz_m2 = 0.01;
  double initial_cov_yawyaw_rad2 = 0.0685;
  double update_min_d_m = 0.0;
  double update_min_a_rad = 0.0;
  double save_pose_rate_hz = 0.5;
  double diagnostics_period_s = 1.0;
  double markers_period_s = 5.0;
  // A map of more components than markers_max: ~gmm_markers holds those within markers_radius_m of
  // the estimate (every k-th where still more), renewed as it moves (rviz stays usable).
  int markers_max = 5000;
  double markers_radius_m = 15.0;
  double warn_sigma_xy_m = 0.25;
  double warn_sigma_yaw_rad = 0.25;
  // The frame-rate budget (update_budget.h): what each update evaluates so that it keeps up
  // with the camera on a slow machine. Wall-time dependent, so only the nodelet has it.
  UpdateBudgetParams budget;

  bool hasInitialPose() const;
  // No odometry frame (none given, or odometry_source none): the published transform is
  // map -> base_frame instead of map -> odom_frame.
  bool mapToBase() const { return odom_frame.empty() || odometry_source == "none"; }
  Eigen::Vector4d defaultPoseSigma() const {  // x, y, z, yaw
    return Eigen::Vector4d(initial_sigma_xy_m, initial_sigma_xy_m, initial_sigma_z_m,
                           initial_sigma_yaw_rad);
  }
  // Cross-field rules (the table checks each value's range): "" when valid.
  std::string validate() const;
};

const ParamTable<RosOptions>& rosOptionsTable();

// One more depth camera of the rig (RosOptions::more_cameras): its own input and frame and noise
// parameters, read from ~NAME/ with the first camera's values as defaults.
struct RigCameraParams {
  std::string name;                  // its namespace: NAME/image + NAME/camera_info, or NAME/points
  std::string topic;                 // ~NAME/topic: its image (or cloud) topic instead (any name)
  std::string depth_input;           // ~NAME/depth_input: image or cloud
  std::string image_transport;       // ~NAME/image_transport
  FrameParams frame;                 // ~NAME/pixel_stride, min_range_m, max_range_m
  MeasurementParams measurement;     // ~NAME/depth_noise_preset, depth_noise_a_m, _b_per_m, _z0_m
  double depth_scale_initial = 1.0;  // ~NAME/refine_depth_scale_initial (1, not the first's)
};
// The names in more_cameras (split at commas and blanks); "" in *error unless each is a valid
// ROS name, not "depth" (the first camera's namespace) and given once.
std::vector<std::string> moreCameraNames(const RosOptions& ros, std::string* error);
// The parameter names a rig camera reads under ~NAME/ (mirroring the first camera's).
const std::vector<std::string>& rigCameraParamNames();
// Reads each camera of ros.more_cameras from ~NAME/ (defaults: the first camera's values in
// core and ros). Returns "" when valid, else every fault; *unknown: parameters under ~NAME/ that
// a rig camera does not read.
std::string loadRigCameras(const ros::NodeHandle& pnh, const LocalizerParams& core,
                           const RosOptions& ros, std::vector<RigCameraParams>* cameras,
                           std::vector<std::string>* unknown = nullptr);

// Reads the private parameters into *core and *ros (defaults where absent). Returns "" when
// valid, else every fault (wrong types, values out of range, unknown modes, the core's
// validate()). *unknown: private parameters that no table describes (typing mistakes).
std::string loadRosParams(const ros::NodeHandle& pnh, LocalizerParams* core, RosOptions* ros,
                          std::vector<std::string>* unknown = nullptr);

// The map at `path` as the nodelet loads it: a map file, or a point cloud or mesh fitted with
// ros.map_fit (or taken from its cache), the progress logged (ROS_INFO, ROS_WARN). Throws with
// a message naming the file and the fault; *summary: what was loaded, for the log.
GmmMap loadNodeMap(const std::string& path, const RosOptions& ros, std::string* summary);

// The localizer of the parameters: loads the map (loadNodeMap) (and, with init_from_map_bounds,
// makes its bounds the initial region). nullptr with *error saying why.
std::unique_ptr<Localizer> makeLocalizer(LocalizerParams* core, const RosOptions& ros,
                                         std::string* error);

// The effective parameters for the startup log (both tables, one group per line).
std::string describeParams(const LocalizerParams& core, const RosOptions& ros);

// dynamic_reconfigure: every run-time parameter of both tables, by name.
void toReconfigure(const LocalizerParams& core, const RosOptions& ros,
                   dynamic_reconfigure::Config* msg);
LocalizerConfig toLocalizerConfig(const LocalizerParams& core, const RosOptions& ros);
// The inverse; "" when every value fits its table entry, else why (nothing is written then).
std::string fromReconfigure(const dynamic_reconfigure::Config& msg, LocalizerParams* core,
                            RosOptions* ros);

// A dynamic_reconfigure request: the values in *config checked against the tables and the
// structs' validate(), then handed to `apply` (e.g. Localizer::setParams, which may throw).
// Accepted: *core and *ros updated, "" returned, *changes lists "name old -> new". Refused: why,
// with *config set back to the previous values (which the server then keeps).
std::string reconfigure(LocalizerConfig* config, LocalizerParams* core, RosOptions* ros,
                        const std::function<void(const LocalizerParams&)>& apply,
                        std::string* changes);

// amcl's pose persistence: the estimate written to ~initial_pose_* and ~initial_cov_*, which a
// restart reads back (RosOptions::hasInitialPose).
// (and the depth-scale estimate as ~refine_depth_scale_initial when it is not 1, a rig camera's
// as ~NAME/refine_depth_scale_initial)
using CameraScales = std::vector<std::pair<std::string, double>>;  // rig camera name, estimate
void savePoseParams(const ros::NodeHandle& pnh, const Particle& mean,
                    const Eigen::Matrix<double, 6, 6>& covariance, double depth_scale = 1.0,
                    const CameraScales& camera_scales = {});
// The same at save_pose_rate, off the update thread: offer() keeps a frame's estimate when a
// save is due by the frame stamps (cheap, the update thread); flush() writes the kept one (eight
// blocking calls to the master, another thread), so an update never waits for the master.
class PoseSaver {
 public:
  void offer(double rate_hz, const ros::Time& stamp, const Particle& mean,
             const Eigen::Matrix<double, 6, 6>& covariance, double depth_scale = 1.0,
             const CameraScales& camera_scales = {});
  void restart();  // the stamps jumped back: the next offer is due
  void flush(const ros::NodeHandle& pnh);

 private:
  std::mutex mutex_;
  ros::Time last_;
  bool pending_ = false;
  Particle mean_;
  Eigen::Matrix<double, 6, 6> covariance_;
  double depth_scale_ = 1.0;
  CameraScales camera_scales_;
};
// The single-pose start of the options as a pose in the map frame with its covariance.
void initialPose(const RosOptions& ros, Eigen::Isometry3d* T_map_base,
                 Eigen::Matrix<double, 6, 6>* covariance);

// cfg/Localizer.cfg's text, generated from the tables.
std::string dynamicReconfigureCfg();
// docs/parameters.md's text, generated from the tables.
std::string parameterReferenceMarkdown();
// Every parameter with its default as a ROS parameter file (unset ones commented out).
std::string defaultsYaml();

}  // namespace gmm_mcl

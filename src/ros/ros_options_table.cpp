// The node's own options (RosOptions): their checks and their table (name, field, unit,
// group, range, when they apply, help), one function per group.
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "gmm_mcl/ros/ros_params.h"

namespace gmm_mcl {
namespace {

using R = RosOptions;
constexpr bool kRuntime = true, kStartup = false;

void add(ParamTable<R>* t, ParamSpec<R> p, std::vector<std::string> choices = {}) {
  p.choices = std::move(choices);
  t->push_back(std::move(p));
}

void addNodeOptions(ParamTable<R>* t) {
  const char* g = "node";
  add(t, paramSpec<R>(
             "map", GMM_MCL_PARAM_FIELD(R, map_path), "", g, {}, kStartup,
             "The map: a GMM map file (gmm_mcl_fit's format), or a point cloud or mesh (.pcd, "
             ".ply, .xyz, .txt) fitted on load with the map builder's defaults and cached beside "
             "it as MAP.fit-KEY.gmm; required. ~reload_map loads another one while running"));
  add(t, paramSpec<R>("map_fit_components", GMM_MCL_PARAM_FIELD(R, map_fit_components), "", g,
                      {0, 1e7}, kStartup,
                      "A cloud given as the map: its component count; 0: from its surface (10 per "
                      "m^2, at least 10)"));
  add(t, paramSpec<R>("map_fit_time_limit", GMM_MCL_PARAM_FIELD(R, map_fit_time_limit_s), "s", g,
                      {1, 86400}, kStartup,
                      "A cloud given as the map whose fit is estimated to take longer is refused "
                      "(fit it offline with gmm_mcl_fit)"));
  add(t, paramSpec<R>("map_fit_cache", GMM_MCL_PARAM_FIELD(R, map_fit_cache), "", g, {}, kStartup,
                      "A cloud given as the map: read and write its fitted map beside it (keyed "
                      "by the cloud's content and the fit parameters)"));
  add(t, paramSpec<R>("map_frame", GMM_MCL_PARAM_FIELD(R, map_frame), "", g, {}, kStartup,
                      "Frame of the map, the pose and the published transform"));
  add(t, paramSpec<R>("odom_frame", GMM_MCL_PARAM_FIELD(R, odom_frame), "", g, {}, kStartup,
                      "Odometry frame; empty: the transform published is map -> base_frame"));
  add(t, paramSpec<R>("base_frame", GMM_MCL_PARAM_FIELD(R, base_frame), "", g, {}, kStartup,
                      "The robot's body frame (the particles' pose)"));
  add(t,
      paramSpec<R>("odometry_source", GMM_MCL_PARAM_FIELD(R, odometry_source), "", g, {}, kStartup,
                   "tf: odom_frame -> base_frame at each frame's stamp (frames wait for it); "
                   "topic: nav_msgs/Odometry on odom; none: no odometry, the core's "
                   "constant-velocity model predicts (cv_model, docs/no_odometry.md)"),
      {"tf", "topic", "none"});
  add(t,
      paramSpec<R>("depth_input", GMM_MCL_PARAM_FIELD(R, depth_input), "", g, {}, kStartup,
                   "image: depth/image + depth/camera_info; cloud: an organized PointCloud2 on "
                   "depth/points"),
      {"image", "cloud"});
  add(t,
      paramSpec<R>("image_transport", GMM_MCL_PARAM_FIELD(R, image_transport), "", g, {}, kStartup,
                   "Transport of depth/image: raw, compressedDepth (decoded by the nodelet) or "
                   "another installed plugin"));
  add(t, paramSpec<R>("use_imu", GMM_MCL_PARAM_FIELD(R, use_imu), "", g, {}, kStartup,
                      "Roll and pitch from sensor_msgs/Imu on imu at each frame's stamp; otherwise "
                      "from odometry"));
  add(t, paramSpec<R>("queue_size", GMM_MCL_PARAM_FIELD(R, queue_size), "", g, {1, 100}, kStartup,
                      "Depth frames queued while an update runs (1: the newest; older ones are "
                      "dropped and counted)"));
  add(t, paramSpec<R>("odom_timeout", GMM_MCL_PARAM_FIELD(R, odom_timeout_s), "s", g, {1e-3, 10},
                      kRuntime,
                      "odometry_source topic: odometry farther than this from a frame's stamp is a "
                      "gap (the frame predicts with the constant-velocity model, cv_model)"));
  add(t, paramSpec<R>("imu_timeout", GMM_MCL_PARAM_FIELD(R, imu_timeout_s), "s", g, {1e-3, 10},
                      kRuntime,
                      "IMU attitude farther than this from a frame's stamp is missing (roll and "
                      "pitch from odometry, warned)"));
  add(t, paramSpec<R>("input_wait", GMM_MCL_PARAM_FIELD(R, input_wait_s), "s", g, {0, 10}, kRuntime,
                      "A frame whose IMU sample or odometry message (odometry_source topic) at its "
                      "stamp has not arrived yet waits for them at most this long; sources that "
                      "never delivered and have no publisher are not waited for (0 = never "
                      "wait)"));
  add(t, paramSpec<R>(
             "more_cameras", GMM_MCL_PARAM_FIELD(R, more_cameras), "", g, {}, kStartup,
             "The rig's other depth cameras (docs/ros.md, Several depth cameras): names, "
             "comma-separated or a YAML list ([down]); camera NAME subscribes NAME/image + "
             "NAME/camera_info (or NAME/points) and reads ~NAME/depth_input, image_transport, "
             "pixel_stride, min_range_m, max_range_m, depth_noise_preset, depth_noise_a_m, "
             "_b_per_m, _z0_m (defaults: the first camera's) and refine_depth_scale_initial "
             "(default 1); extrinsics from tf. Empty: one "
             "camera"));
  add(t, paramSpec<R>("camera_set_window", GMM_MCL_PARAM_FIELD(R, camera_set_window_s), "s", g,
                      {0, 1}, kRuntime,
                      "Several cameras: frames whose stamps lie within this of the leading "
                      "frame's are one frame set, one update (the newest in the window is used)"));
  add(t, paramSpec<R>("camera_set_wait", GMM_MCL_PARAM_FIELD(R, camera_set_wait_s), "s", g, {0, 10},
                      kRuntime,
                      "Several cameras: a frame set waits at most this long (wall time) for the "
                      "cameras whose next frame is due within the window (by their period, else "
                      "when they were in the previous set); cameras that never delivered are not "
                      "waited for (0 = never wait)"));
  add(t, paramSpec<R>("camera_timeout", GMM_MCL_PARAM_FIELD(R, camera_timeout_s), "s", g,
                      {1e-3, 60}, kRuntime,
                      "Several cameras: a camera without a frame for this long (ROS time, by the "
                      "other cameras' stamps) has dropped out (reported, the others update); the "
                      "first camera that still delivers, in the order depth, more_cameras, "
                      "leads the frame sets"));
  add(t, paramSpec<R>(
             "update_min_d", GMM_MCL_PARAM_FIELD(R, update_min_d_m), "m", g, {0, 10}, kRuntime,
             "Motion gate (amcl's): a frame updates the filter once the odometry moved more "
             "than this or turned more than update_min_a since the last update; both 0: "
             "every frame. Frames in between only carry the estimate by odometry"));
  add(t, paramSpec<R>("update_min_a", GMM_MCL_PARAM_FIELD(R, update_min_a_rad), "rad", g, {0, 3.15},
                      kRuntime,
                      "Motion gate: the yaw turn that lets a frame update (see update_min_d)"));
}

void addOutputOptions(ParamTable<R>* t) {
  const char* g = "output";
  add(t, paramSpec<R>("tf_broadcast", GMM_MCL_PARAM_FIELD(R, tf_broadcast), "", g, {}, kRuntime,
                      "Publish map -> odom (false: only the pose, e.g. beside another localizer)"));
  add(t, paramSpec<R>(
             "transform_tolerance", GMM_MCL_PARAM_FIELD(R, transform_tolerance_s), "s", g, {0, 10},
             kRuntime,
             "map -> odom is stamped with the frame's stamp plus this (future-dated, as amcl)"));
  add(t, paramSpec<R>("save_pose_rate", GMM_MCL_PARAM_FIELD(R, save_pose_rate_hz), "Hz", g,
                      {0, 100}, kRuntime,
                      "Rate of writing the estimate back to ~initial_pose_* and ~initial_cov_* "
                      "(amcl's; 0 = never): a restart resumes there"));
  add(t, paramSpec<R>("diagnostics_period", GMM_MCL_PARAM_FIELD(R, diagnostics_period_s), "s", g,
                      {1e-2, 60}, kStartup, "Period of /diagnostics (ROS time)"));
  add(t, paramSpec<R>("markers_period", GMM_MCL_PARAM_FIELD(R, markers_period_s), "s", g, {0, 3600},
                      kRuntime,
                      "~gmm_markers is published again this often while subscribed, and after a "
                      "time jump (rviz drops markers on a reset; 0 = once)"));
  add(t, paramSpec<R>(
             "markers_max", GMM_MCL_PARAM_FIELD(R, markers_max), "", g, {1, 1000000}, kRuntime,
             "At most this many ellipsoids in ~gmm_markers: a larger map (a building) shows "
             "those within markers_radius of the estimate, every k-th where still more"));
  add(t, paramSpec<R>("markers_radius", GMM_MCL_PARAM_FIELD(R, markers_radius_m), "m", g,
                      {0.5, 10000}, kRuntime,
                      "How far from the estimate ~gmm_markers reaches in a map larger than "
                      "markers_max; renewed when the estimate has moved a quarter of it"));
  add(t, paramSpec<R>("warn_sigma_xy", GMM_MCL_PARAM_FIELD(R, warn_sigma_xy_m), "m", g, {1e-3, 100},
                      kRuntime,
                      "/diagnostics warns while the estimate's x or y standard deviation is above "
                      "this (not converged)"));
  add(t,
      paramSpec<R>("warn_sigma_yaw", GMM_MCL_PARAM_FIELD(R, warn_sigma_yaw_rad), "rad", g,
                   {1e-3, 3.15}, kRuntime,
                   "/diagnostics warns while the estimate's yaw standard deviation is above this"));
}

void addStartOptions(ParamTable<R>* t) {
  const char* g = "start";
  add(t, paramSpec<R>("init_from_map_bounds", GMM_MCL_PARAM_FIELD(R, init_from_map_bounds), "", g,
                      {}, kStartup,
                      "Start uniform over the whole map (its bounding box, any yaw) instead of "
                      "init_centre / init_half_extent"));
  add(t,
      paramSpec<R>(
          "initial_pose_x", GMM_MCL_PARAM_FIELD(R, initial_pose_x_m), "m", g, {-1e6, 1e6}, kStartup,
          "Single-pose start: x in the map frame (all of initial_pose_x, _y, _z, _yaw, or none)"));
  add(t, paramSpec<R>("initial_pose_y", GMM_MCL_PARAM_FIELD(R, initial_pose_y_m), "m", g,
                      {-1e6, 1e6}, kStartup, "Single-pose start: y"));
  add(t, paramSpec<R>("initial_pose_z", GMM_MCL_PARAM_FIELD(R, initial_pose_z_m), "m", g,
                      {-1e6, 1e6}, kStartup, "Single-pose start: z (the base's height)"));
  add(t, paramSpec<R>("initial_pose_yaw", GMM_MCL_PARAM_FIELD(R, initial_pose_yaw_rad), "rad", g,
                      {-7, 7}, kStartup, "Single-pose start: yaw"));
  add(t, paramSpec<R>("initial_cov_xx", GMM_MCL_PARAM_FIELD(R, initial_cov_xx_m2), "m^2", g,
                      {0, 1e4}, kStartup, "Single-pose start: variance in x"));
  add(t, paramSpec<R>("initial_cov_yy", GMM_MCL_PARAM_FIELD(R, initial_cov_yy_m2), "m^2", g,
                      {0, 1e4}, kStartup, "Single-pose start: variance in y"));
  add(t, paramSpec<R>("initial_cov_zz", GMM_MCL_PARAM_FIELD(R, initial_cov_zz_m2), "m^2", g,
                      {0, 1e4}, kStartup, "Single-pose start: variance in z"));
  add(t, paramSpec<R>("initial_cov_yawyaw", GMM_MCL_PARAM_FIELD(R, initial_cov_yawyaw_rad2),
                      "rad^2", g, {0, 100}, kStartup, "Single-pose start: variance in yaw"));
  add(t, paramSpec<R>("initial_sigma_xy", GMM_MCL_PARAM_FIELD(R, initial_sigma_xy_m), "m", g,
                      {1e-4, 100}, kRuntime,
                      "x and y spread of a requested pose (initialpose, ~reset_to_pose) whose "
                      "covariance gives none"));
  add(t, paramSpec<R>("initial_sigma_z", GMM_MCL_PARAM_FIELD(R, initial_sigma_z_m), "m", g,
                      {1e-4, 100}, kRuntime,
                      "z spread of a requested pose whose covariance gives none"));
  add(t, paramSpec<R>("initial_sigma_yaw", GMM_MCL_PARAM_FIELD(R, initial_sigma_yaw_rad), "rad", g,
                      {1e-4, 3.15}, kRuntime,
                      "yaw spread of a requested pose whose covariance gives none"));
}

void addBudgetOptions(ParamTable<R>* t) {
  const char* g = "budget";
  add(t, paramSpec<R>("update_budget", GMM_MCL_PARAM_FIELD(R, budget.enabled), "", g, {}, kRuntime,
                      "Frame-rate budget: when updates take longer than max_update_ms, use a "
                      "coarser pixel stride (up to budget_max_pixel_stride), then skip the pose "
                      "refinement, then fewer particles (down to budget_min_particles); step back "
                      "when there is headroom. ~status and /diagnostics report what is in force"));
  add(t, paramSpec<R>("max_update_ms", GMM_MCL_PARAM_FIELD(R, budget.max_update_ms), "ms", g,
                      {0, 1e5}, kRuntime,
                      "Budget per update, wall time (the whole depth callback); 0: the camera's "
                      "frame period, from the CameraInfo stamps (the clouds' with depth_input "
                      "cloud) divided by the clock's rate (a bag played at rate 0.5 gets twice the "
                      "time)"));
  add(t, paramSpec<R>("budget_max_pixel_stride", GMM_MCL_PARAM_FIELD(R, budget.max_pixel_stride),
                      "px", g, {1, 64}, kRuntime,
                      "Frame-rate budget: the coarsest pixel stride it may choose (never finer "
                      "than pixel_stride)"));
  add(t, paramSpec<R>("budget_min_particles", GMM_MCL_PARAM_FIELD(R, budget.min_particles), "", g,
                      {1, 1e7}, kRuntime,
                      "Frame-rate budget: the fewest particles it may cap the count at (never more "
                      "than num_particles)"));
  add(t, paramSpec<R>("budget_over_updates", GMM_MCL_PARAM_FIELD(R, budget.over_updates), "", g,
                      {1, 1000}, kRuntime,
                      "Frame-rate budget: consecutive updates over the budget before it makes them "
                      "cheaper"));
  add(t, paramSpec<R>("budget_headroom_updates", GMM_MCL_PARAM_FIELD(R, budget.headroom_updates),
                      "", g, {1, 100000}, kRuntime,
                      "Frame-rate budget: consecutive updates with headroom before it steps back "
                      "(more particles first, then a finer stride)"));
  add(t, paramSpec<R>("budget_headroom_fraction", GMM_MCL_PARAM_FIELD(R, budget.headroom_fraction),
                      "", g, {0.05, 0.95}, kRuntime,
                      "Frame-rate budget: an update has headroom when, at the cost of the step "
                      "back, it would stay under this fraction of the budget"));
  add(t, paramSpec<R>("budget_target_fraction", GMM_MCL_PARAM_FIELD(R, budget.target_fraction), "",
                      g, {0.1, 1}, kRuntime,
                      "Frame-rate budget: a cut aims at this fraction of the budget (cost taken "
                      "as proportional to particles times pixels)"));
}

}  // namespace

bool RosOptions::hasInitialPose() const {
  return std::isfinite(initial_pose_x_m) && std::isfinite(initial_pose_y_m) &&
         std::isfinite(initial_pose_z_m) && std::isfinite(initial_pose_yaw_rad);
}

std::string RosOptions::validate() const {
  std::string err;
  if (map_path.empty()) err += "~map (the GMM map file) is required; ";
  if (map_frame.empty()) err += "~map_frame is empty; ";
  if (base_frame.empty()) err += "~base_frame is empty; ";
  if (odometry_source == "tf" && odom_frame.empty())
    err += "~odometry_source tf needs ~odom_frame; ";
  if (image_transport.empty()) err += "~image_transport is empty; ";
  const int pose_set = std::isfinite(initial_pose_x_m) + std::isfinite(initial_pose_y_m) +
                       std::isfinite(initial_pose_z_m) + std::isfinite(initial_pose_yaw_rad);
  if (pose_set != 0 && pose_set != 4) {
    err += "~initial_pose_x, _y, _z and _yaw must be given together (a single-pose start); ";
  }
  if (camera_set_window_s * 2 >= camera_timeout_s)
    err += "~camera_set_window must be below half of ~camera_timeout; ";
  std::string names;
  moreCameraNames(*this, &names);
  err += names;
  err += budget.validate();
  return err;
}

const ParamTable<RosOptions>& rosOptionsTable() {
  static const ParamTable<R> table =
      makeParamTable<R>({addNodeOptions, addOutputOptions, addStartOptions, addBudgetOptions});
  return table;
}

}  // namespace gmm_mcl

#include "gmm_mcl/ros/ros_params.h"

#include <sstream>
#include <vector>

namespace gmm_mcl {
namespace {

class Reader {
 public:
  explicit Reader(const ros::NodeHandle& nh) : nh_(nh) {}

  template <typename T>
  void get(const std::string& name, T* value) {
    if (!nh_.hasParam(name)) return;
    T v;
    if (!nh_.getParam(name, v)) {
      faults_ << "~" << name << " has the wrong type; ";
      return;
    }
    *value = v;
  }
  void getFloat(const std::string& name, float* value) {
    double v = *value;
    get(name, &v);
    *value = static_cast<float>(v);
  }
  void getVector3(const std::string& name, Eigen::Vector3d* value) {
    if (!nh_.hasParam(name)) return;
    std::vector<double> v;
    if (!nh_.getParam(name, v) || v.size() != 3) {
      faults_ << "~" << name << " must be a list of 3 numbers; ";
      return;
    }
    *value = Eigen::Vector3d(v[0], v[1], v[2]);
  }
  void fault(const std::string& what) { faults_ << what << "; "; }
  std::string faults() const { return faults_.str(); }

 private:
  const ros::NodeHandle& nh_;
  std::ostringstream faults_;
};

}  // namespace

std::string loadRosParams(const ros::NodeHandle& pnh, LocalizerParams* core, RosOptions* ros) {
  Reader r(pnh);
  r.get("map", &ros->map_path);
  r.get("map_frame", &ros->map_frame);
  r.get("odom_frame", &ros->odom_frame);
  r.get("base_frame", &ros->base_frame);
  r.get("odometry_source", &ros->odometry_source);
  r.get("depth_input", &ros->depth_input);
  r.get("image_transport", &ros->image_transport);
  r.get("use_imu", &ros->use_imu);
  r.get("transform_tolerance", &ros->transform_tolerance_s);
  r.get("tf_timeout", &ros->tf_timeout_s);
  r.get("odom_timeout", &ros->odom_timeout_s);
  r.get("imu_timeout", &ros->imu_timeout_s);
  r.get("queue_size", &ros->queue_size);
  r.get("init_from_map_bounds", &ros->init_from_map_bounds);
  r.get("initial_sigma_xy", &ros->initial_sigma_xy_m);
  r.get("initial_sigma_z", &ros->initial_sigma_z_m);
  r.get("initial_sigma_yaw", &ros->initial_sigma_yaw_rad);
  r.get("diagnostics_period", &ros->diagnostics_period_s);

  ParticleFilterParams& f = core->filter;
  r.get("num_particles", &f.num_particles);
  r.get("sigma_translation_m", &f.sigma_translation_m);
  r.get("sigma_yaw_rad", &f.sigma_yaw_rad);
  r.get("alpha_slow", &f.alpha_slow);
  r.get("alpha_fast", &f.alpha_fast);
  r.get("recovery_threshold", &f.recovery_threshold);
  std::string weighting = weightingModeName(f.weighting);
  r.get("weighting", &weighting);
  if (!parseWeightingMode(weighting, &f.weighting)) {
    r.fault("~weighting '" + weighting + "' is not paper or tempered");
  }
  r.get("temperature", &f.temperature);
  r.get("neff_floor_fraction", &f.neff_floor_fraction);
  r.get("paper_min_nll_per_pixel", &f.paper_min_nll_per_pixel);
  r.get("resample_groups", &f.resample_groups);
  r.get("resample_neff_fraction", &f.resample_neff_fraction);
  r.get("attitude_sigma_rad", &f.attitude_sigma_rad);
  int seed = static_cast<int>(f.seed);
  r.get("seed", &seed);
  if (seed < 0) r.fault("~seed must be >= 0");
  f.seed = static_cast<uint64_t>(seed);

  r.get("pixel_stride", &core->frame.pixel_stride);
  r.get("patch_size_px", &core->frame.patch_size_px);
  r.getFloat("min_range_m", &core->frame.min_range_m);
  r.getFloat("max_range_m", &core->frame.max_range_m);
  r.getFloat("min_component_depth_m", &core->measurement.min_component_depth_m);
  r.getFloat("sigma_bound", &core->measurement.sigma_bound);
  r.getFloat("floor_log_density", &core->measurement.floor_log_density);

  r.getVector3("init_centre", &core->init.centre_m);
  r.getVector3("init_half_extent", &core->init.half_extent_m);
  r.get("init_yaw_centre", &core->init.yaw_centre_rad);
  r.get("init_yaw_half_range", &core->init.yaw_half_range_rad);
  r.get("max_odometry_step_m", &core->max_odometry_step_m);
  r.get("backend", &core->backend);

  if (ros->map_path.empty()) r.fault("~map (the GMM map file) is required");
  if (ros->map_frame.empty()) r.fault("~map_frame is empty");
  if (ros->base_frame.empty()) r.fault("~base_frame is empty");
  if (ros->odometry_source != "tf" && ros->odometry_source != "topic" &&
      ros->odometry_source != "none") {
    r.fault("~odometry_source '" + ros->odometry_source + "' is not tf, topic or none");
  }
  if (ros->odometry_source == "tf" && ros->odom_frame.empty()) {
    r.fault("~odometry_source tf needs ~odom_frame");
  }
  if (ros->depth_input != "image" && ros->depth_input != "cloud") {
    r.fault("~depth_input '" + ros->depth_input + "' is not image or cloud");
  }
  if (ros->image_transport.empty()) r.fault("~image_transport is empty");
  if (core->backend != "cpu" && core->backend != "cuda") {
    r.fault("~backend '" + core->backend + "' is not cpu or cuda");
  }
  if (!(ros->transform_tolerance_s >= 0.0)) r.fault("~transform_tolerance must be >= 0");
  if (!(ros->tf_timeout_s >= 0.0)) r.fault("~tf_timeout must be >= 0");
  if (!(ros->odom_timeout_s > 0.0)) r.fault("~odom_timeout must be > 0");
  if (!(ros->imu_timeout_s > 0.0)) r.fault("~imu_timeout must be > 0");
  if (ros->queue_size < 1) r.fault("~queue_size must be >= 1");
  if (!(ros->initial_sigma_xy_m > 0.0 && ros->initial_sigma_z_m > 0.0 &&
        ros->initial_sigma_yaw_rad > 0.0)) {
    r.fault("~initial_sigma_* must be > 0");
  }
  if (!(ros->diagnostics_period_s > 0.0)) r.fault("~diagnostics_period must be > 0");
  std::string faults = r.faults();
  const std::string core_faults = core->validate();
  if (!core_faults.empty()) faults += core_faults;
  return faults;
}

std::string describeParams(const LocalizerParams& c, const RosOptions& r) {
  std::ostringstream s;
  s << "map " << r.map_path << ", frames " << r.map_frame << " / "
    << (r.odom_frame.empty() ? "(no odom frame)" : r.odom_frame) << " / " << r.base_frame
    << ", odometry " << r.odometry_source << ", depth " << r.depth_input << " (" << r.image_transport << "), imu "
    << (r.use_imu ? "on" : "off") << "\n  particles " << c.filter.num_particles << ", sigma "
    << c.filter.sigma_translation_m << " m / " << c.filter.sigma_yaw_rad << " rad, alpha slow "
    << c.filter.alpha_slow << " fast " << c.filter.alpha_fast << ", recovery threshold "
    << c.filter.recovery_threshold << ", weighting " << weightingModeName(c.filter.weighting)
    << " (T " << c.filter.temperature << ", Neff floor " << c.filter.neff_floor_fraction
    << "), seed " << c.filter.seed << "\n  stride " << c.frame.pixel_stride << " px, patch "
    << c.frame.patch_size_px << " px, range [" << c.frame.min_range_m << ", "
    << c.frame.max_range_m << "] m, floor " << c.measurement.floor_log_density
    << ", backend " << c.backend << "\n  init "
    << (r.init_from_map_bounds ? std::string("map bounds") : std::string("region"))
    << " centre (" << c.init.centre_m.transpose() << ") half extent ("
    << c.init.half_extent_m.transpose() << ") yaw " << c.init.yaw_centre_rad << " +- "
    << c.init.yaw_half_range_rad << ", transform_tolerance " << r.transform_tolerance_s
    << " s, queue " << r.queue_size;
  return s.str();
}

}  // namespace gmm_mcl

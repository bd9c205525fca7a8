// What the nodelet publishes for each depth frame: ~pose, ~refined_pose, the map -> odom (or
// map -> base) transform, ~particles and ~debug_image while someone listens, and ~status.
#pragma once

#include <image_transport/image_transport.h>
#include <ros/ros.h>
#include <tf2_ros/transform_broadcaster.h>

#include <memory>
#include <string>

#include "gmm_mcl/FilterStatus.h"
#include "gmm_mcl/filter/localizer.h"

namespace gmm_mcl {

class FrameOutputs {
 public:
  void advertise(ros::NodeHandle& pnh, image_transport::ImageTransport& it);
  // ~pose, and ~refined_pose when the frame was used and the refinement converged (with the
  // particles' covariance).
  void poses(const std_msgs::Header& header, const StepResult& r,
             const Eigen::Isometry3d& T_map_base, bool gated, const std::string& map_frame);
  // parent -> child stamped `stamp` (the frame stamp plus transform_tolerance, never now()),
  // sent only forward in time; true when sent.
  bool transform(const Eigen::Isometry3d& T_parent_child, const std::string& parent,
                 const std::string& child, const ros::Time& stamp);
  void restartTransforms() { last_tf_stamp_ = ros::Time(); }  // the clock went back
  void particles(const std_msgs::Header& header, const Localizer& localizer,
                 const std::string& map_frame);
  void status(const FilterStatus& s) { status_pub_.publish(s); }
  // The map projected over the frame (renderDebugImage), rendered only while someone listens.
  void debugImage(const std_msgs::Header& header, const DepthImage& depth, const Intrinsics& K,
                  const Localizer& localizer, const Eigen::Isometry3d& T_map_cam);

 private:
  ros::Publisher pose_pub_, refined_pose_pub_, particles_pub_, status_pub_;
  image_transport::Publisher debug_image_pub_;
  std::unique_ptr<tf2_ros::TransformBroadcaster> tf_broadcaster_;
  ros::Time last_tf_stamp_;
};

}  // namespace gmm_mcl

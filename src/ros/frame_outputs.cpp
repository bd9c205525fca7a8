#include "gmm_mcl/ros/frame_outputs.h"

#include <geometry_msgs/PoseArray.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>

#include "gmm_mcl/ros/conversions.h"
#include "gmm_mcl/ros/debug_image.h"

namespace gmm_mcl {

void FrameOutputs::advertise(ros::NodeHandle& pnh, image_transport::ImageTransport& it) {
  pose_pub_ = pnh.advertise<geometry_msgs::PoseWithCovarianceStamped>("pose", 10);
  refined_pose_pub_ = pnh.advertise<geometry_msgs::PoseWithCovarianceStamped>("refined_pose", 10);
  particles_pub_ = pnh.advertise<geometry_msgs::PoseArray>("particles", 2);
  status_pub_ = pnh.advertise<FilterStatus>("status", 10);
  debug_image_pub_ = it.advertise("debug_image", 1);
  tf_broadcaster_ = std::make_unique<tf2_ros::TransformBroadcaster>();
}

void FrameOutputs::poses(const std_msgs::Header& header, const StepResult& r,
                         const Eigen::Isometry3d& T_map_base, bool gated,
                         const std::string& map_frame) {
  pose_pub_.publish(ros_conv::poseWithCovarianceStamped(T_map_base, r.estimate.covariance,
                                                        map_frame, header.stamp));
  const RefinementResult& rf = r.refinement;
  if (!gated && rf.refined)
    refined_pose_pub_.publish(
        ros_conv::poseWithCovarianceStamped(particleToPose(rf.pose, rf.roll_rad, rf.pitch_rad),
                                            r.estimate.covariance, map_frame, header.stamp));
}

bool FrameOutputs::transform(const Eigen::Isometry3d& T_parent_child, const std::string& parent,
                             const std::string& child, const ros::Time& stamp) {
  if (!last_tf_stamp_.isZero() && stamp <= last_tf_stamp_) return false;
  tf_broadcaster_->sendTransform(ros_conv::transformStamped(T_parent_child, parent, child, stamp));
  last_tf_stamp_ = stamp;
  return true;
}

void FrameOutputs::particles(const std_msgs::Header& header, const Localizer& localizer,
                             const std::string& map_frame) {
  if (particles_pub_.getNumSubscribers() == 0) return;
  geometry_msgs::PoseArray particles;
  particles.header.stamp = header.stamp;
  particles.header.frame_id = map_frame;
  ros_conv::poseArrayFromParticles(localizer.filter().particles(), localizer.rollRad(),
                                   localizer.pitchRad(), &particles);
  particles_pub_.publish(particles);
}

void FrameOutputs::debugImage(const std_msgs::Header& header, const DepthImage& depth,
                              const Intrinsics& K, const Localizer& localizer,
                              const Eigen::Isometry3d& T_map_cam) {
  if (debug_image_pub_.getNumSubscribers() == 0) return;
  sensor_msgs::Image img;
  renderDebugImage(depth, K, localizer.map(), T_map_cam, localizer.params().frame,
                   localizer.params().measurement, &img);
  img.header = header;
  debug_image_pub_.publish(img);
}

}  // namespace gmm_mcl

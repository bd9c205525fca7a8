#include "gmm_mcl/ros/map_markers.h"

#include "gmm_mcl/ros/conversions.h"

namespace gmm_mcl {

void MapMarkers::advertise(ros::NodeHandle& pnh, const std::string& topic) {
  std::lock_guard<std::mutex> lock(mutex_);
  pub_ = pnh.advertise<visualization_msgs::MarkerArray>(topic, 1, true);
}

void MapMarkers::set(const GmmMap& map, const std::string& frame) {
  std::lock_guard<std::mutex> lock(mutex_);
  ros_conv::markersFromMap(map, frame, &markers_);
  pub_.publish(markers_);
}

void MapMarkers::publish() {
  std::lock_guard<std::mutex> lock(mutex_);
  pub_.publish(markers_);
}

void MapMarkers::setPeriod(double period_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  due_.period_s = period_s;
}

void MapMarkers::poll(double now_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (pub_ && due_.period_s > 0 && due_.due(now_s) && pub_.getNumSubscribers() > 0)
    pub_.publish(markers_);
}

}  // namespace gmm_mcl

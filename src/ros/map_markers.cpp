#include "gmm_mcl/ros/map_markers.h"

#include <algorithm>
#include <vector>

#include "gmm_mcl/ros/conversions.h"

namespace gmm_mcl {

void MapMarkers::advertise(ros::NodeHandle& pnh, const std::string& topic) {
  std::lock_guard<std::mutex> lock(mutex_);
  pub_ = pnh.advertise<visualization_msgs::MarkerArray>(topic, 1, true);
}

void MapMarkers::set(const GmmMap& map, const std::string& frame) {
  std::lock_guard<std::mutex> lock(mutex_);
  frame_ = frame;
  have_centre_ = false;
  if (static_cast<int>(map.size()) <= max_components_) {
    map_.reset();
    ros_conv::markersFromMap(map, frame, &markers_);
  } else {
    // Until an estimate comes: around the map's centre.
    map_ = std::make_shared<const GmmMap>(map);
    makeNear(0.5 * (map.minBound() + map.maxBound()));
  }
  pub_.publish(markers_);
}

void MapMarkers::setLimits(int max_components, double radius_m) {
  std::lock_guard<std::mutex> lock(mutex_);
  max_components_ = max_components;
  radius_m_ = radius_m;
  have_centre_ = false;  // the next estimate renews them
}

void MapMarkers::follow(const Eigen::Vector3d& centre_m) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!map_ || !centre_m.allFinite()) return;
  if (have_centre_ && (centre_m - centre_m_).norm() < 0.25 * radius_m_) return;
  makeNear(centre_m);
  have_centre_ = true;
  pub_.publish(markers_);
}

void MapMarkers::makeNear(const Eigen::Vector3d& centre_m) {
  centre_m_ = centre_m;
  Box3 box;
  box.extend(centre_m - Eigen::Vector3d::Constant(radius_m_));
  box.extend(centre_m + Eigen::Vector3d::Constant(radius_m_));
  std::vector<int> near;
  map_->grid().query(box, &near);
  near.erase(std::remove_if(near.begin(), near.end(),
                            [&](int i) {
                              return (map_->components()[i].mean_m - centre_m).norm() > radius_m_;
                            }),
             near.end());
  const size_t step = (near.size() + max_components_ - 1) / std::max(1, max_components_);
  std::vector<int> shown;
  for (size_t k = 0; k < near.size(); k += std::max<size_t>(step, 1)) shown.push_back(near[k]);
  ros_conv::markersFromMap(*map_, frame_, &markers_, &shown);
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

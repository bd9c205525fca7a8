// ~gmm_markers: the map's 3-sigma ellipsoids, latched, and published again every period of ROS
// time while someone listens and whenever asked (a time jump, a new map): rviz drops its
// markers on a jump back or a Reset and a latched message is not sent twice. Thread-safe.
#pragma once

#include <ros/ros.h>
#include <visualization_msgs/MarkerArray.h>

#include <mutex>
#include <string>

#include "gmm_mcl/map/gmm_map.h"
#include "gmm_mcl/ros/node_status.h"

namespace gmm_mcl {

class MapMarkers {
 public:
  void advertise(ros::NodeHandle& pnh, const std::string& topic);
  // The markers of `map` in `frame`, published now.
  void set(const GmmMap& map, const std::string& frame);
  void publish();
  void setPeriod(double period_s);
  // Publishes when the period has passed (or the clock went back) and someone listens.
  void poll(double now_s);

 private:
  std::mutex mutex_;
  ros::Publisher pub_;
  visualization_msgs::MarkerArray markers_;
  PeriodicSchedule due_;
};

}  // namespace gmm_mcl

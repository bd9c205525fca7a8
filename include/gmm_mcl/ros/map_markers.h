// ~gmm_markers: the map's 3-sigma ellipsoids, latched, and published again every period of ROS
// time while someone listens and whenever asked (a time jump, a new map): rviz drops its
// markers on a jump back or a Reset and a latched message is not sent twice. A map of more than
// the limit's components (a building) shows those near the estimate instead, renewed as it
// moves. Thread-safe.
#pragma once

#include <ros/ros.h>
#include <visualization_msgs/MarkerArray.h>

#include <memory>
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
  // At most max_components ellipsoids; a larger map shows those within radius_m of the estimate
  // (every k-th where still more).
  void setLimits(int max_components, double radius_m);
  // The estimate's position: with a large map, the markers around it are renewed once it has
  // moved a quarter of the radius from where they were made.
  void follow(const Eigen::Vector3d& centre_m);
  // Publishes when the period has passed (or the clock went back) and someone listens.
  void poll(double now_s);

 private:
  void makeNear(const Eigen::Vector3d& centre_m);  // mutex_ held

  std::mutex mutex_;
  ros::Publisher pub_;
  visualization_msgs::MarkerArray markers_;
  PeriodicSchedule due_;
  std::shared_ptr<const GmmMap> map_;  // a large map's copy (the ellipsoids near the estimate)
  std::string frame_;
  int max_components_ = 5000;
  double radius_m_ = 15.0;
  bool have_centre_ = false;
  Eigen::Vector3d centre_m_ = Eigen::Vector3d::Zero();
};

}  // namespace gmm_mcl

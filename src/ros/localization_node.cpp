// Standalone node: loads the LocalizationNodelet in-process (same code as in a manager).
#include <nodelet/loader.h>
#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "gmm_mcl");
  nodelet::Loader loader;
  nodelet::M_string remappings(ros::names::getRemappings());
  nodelet::V_string args(argv + 1, argv + argc);
  if (!loader.load(ros::this_node::getName(), "gmm_mcl/LocalizationNodelet", remappings, args)) {
    ROS_FATAL("gmm_mcl: could not load the nodelet gmm_mcl/LocalizationNodelet");
    return 1;
  }
  ros::spin();
  return 0;
}

# Shared by the ROS scripts: Debian packages of the ROS layer, a private roscore.
# Debian 12's ROS 1 (Noetic-era) packages that the nodelet, its tools and its tests use.
ROS_PACKAGES=(ros-base-dev catkin libnodeletlib-dev libnodeletlib-tools libtf2-ros-dev
  libtf2-eigen-dev libtf2-msgs-dev libimage-transport-dev librosbag-dev python3-rosbag
  librostest-dev python3-rostest python3-roslaunch rosbash libdiagnostic-updater-dev
  libdiagnostic-msgs-dev libdynamic-reconfigure-config-init-mutex-dev python3-tf2-msgs
  python3-dynamic-reconfigure libstd-srvs-dev libnav-msgs-dev libvisualization-msgs-dev
  ros-message-generation python3-gencpp python3-genpy python3-rospy python3-diagnostic-msgs
  python3-geometry-msgs python3-std-msgs python3-std-srvs python3-nav-msgs python3-sensor-msgs
  python3-rostopic python3-rosservice python3-rosmsg python3-rosbag python3-yaml)

ROS_MASTER_PID=""
# ros_start_master LOG: a roscore on $ROS_MASTER_URI's port, waits until it answers.
ros_start_master() {
  local port="${ROS_MASTER_URI##*:}"
  roscore -p "$port" > "$1" 2>&1 &
  ROS_MASTER_PID=$!
  for _ in $(seq 1 60); do
    rosparam get /run_id > /dev/null 2>&1 && return 0
    sleep 0.5
  done
  echo "roscore did not start (see $1)" >&2
  return 1
}
ros_stop_master() {
  if [ -n "$ROS_MASTER_PID" ]; then
    kill -INT "$ROS_MASTER_PID" 2> /dev/null || true
    wait "$ROS_MASTER_PID" 2> /dev/null || true
    ROS_MASTER_PID=""
  fi
}

#!/usr/bin/python3
"""The launch files without starting anything:
- every argument of every launch file has a doc (roslaunch --ros-args lists optional arguments
  as optional, with their doc);
- `roslaunch --dump-params localization.launch config:=config/tx2.yaml` shows the config's
  values (the backend, image_transport and depth_input arguments override them only when given);
- replay.launch and cow_and_lady.launch with rviz:=true do not end with the bag (rviz stays);
  without rviz the bag player ends the launch;
- package.xml: nothing of the ground station (rviz, matplotlib) on the drone, message_generation
  a build dependency, every ROS package the sources include declared.
Run in the package's environment (catkin's env_cached.sh): test_launch_files.py SOURCE_DIR."""
import os
import re
import subprocess
import sys
import unittest
import xml.etree.ElementTree as ElementTree

import roslaunch.config
import roslaunch.xmlloader
import yaml

SOURCE = sys.argv.pop(1) if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "..")
LAUNCH = os.path.join(SOURCE, "launch")


def run(args):
    return subprocess.run(["roslaunch"] + args, capture_output=True, text=True, check=False)


def load(launch, argv):
    config = roslaunch.config.ROSLaunchConfig()
    roslaunch.xmlloader.XmlLoader().load(os.path.join(LAUNCH, launch), config, argv=argv, verbose=False)
    return config


class LaunchFiles(unittest.TestCase):
    def test_every_argument_is_documented(self):
        for launch in sorted(os.listdir(LAUNCH)):
            out = run(["--ros-args", os.path.join(LAUNCH, launch)])
            self.assertEqual(out.returncode, 0, out.stderr)
            self.assertNotIn("undocumented", out.stdout, "%s:\n%s" % (launch, out.stdout))
            required = out.stdout.split("Optional Arguments:")[0]
            for name in ("backend", "config", "rviz", "rate", "manager"):
                self.assertNotIn("  %s:" % name, required, "%s lists %s as required" % (launch, name))

    def test_config_values_are_not_overridden(self):
        tx2 = os.path.join(SOURCE, "config", "tx2.yaml")
        out = run(["--dump-params", os.path.join(LAUNCH, "localization.launch"), "map:=/x.gmm", "config:=" + tx2])
        self.assertEqual(out.returncode, 0, out.stderr)
        params = yaml.safe_load(out.stdout)
        with open(tx2) as f:
            config = yaml.safe_load(f)
        self.assertEqual(params["/gmm_mcl/backend"], "cuda")
        for key, value in config.items():
            self.assertEqual(params.get("/gmm_mcl/" + key), value, key)
        # An argument given explicitly still wins.
        out = run(["--dump-params", os.path.join(LAUNCH, "localization.launch"), "map:=/x.gmm", "config:=" + tx2,
                   "backend:=cpu", "depth_input:=cloud"])
        params = yaml.safe_load(out.stdout)
        self.assertEqual(params["/gmm_mcl/backend"], "cpu")
        self.assertEqual(params["/gmm_mcl/depth_input"], "cloud")
        self.assertEqual(params["/gmm_mcl/sigma_yaw_rad"], config["sigma_yaw_rad"])

    def test_rviz_stays_open_when_the_bag_ends(self):
        for launch in ("replay.launch", "cow_and_lady.launch"):
            player = [n for n in load(launch, ["bag:=/x.bag", "map:=/x.gmm", "rviz:=true"]).nodes if n.name == "player"]
            self.assertEqual(len(player), 1, launch)
            self.assertFalse(player[0].required, "%s: the bag's end closes rviz" % launch)
            player = [n for n in load(launch, ["bag:=/x.bag", "map:=/x.gmm"]).nodes if n.name == "player"]
            self.assertTrue(player[0].required, "%s: without rviz the launch should end with the bag" % launch)

    def test_replay_restores_wall_time(self):
        for launch in ("replay.launch", "cow_and_lady.launch"):
            nodes = [n.type for n in load(launch, ["bag:=/x.bag", "map:=/x.gmm"]).nodes]
            self.assertIn("restore_wall_time.py", nodes, launch)


class PackageXml(unittest.TestCase):
    def setUp(self):
        root = ElementTree.parse(os.path.join(SOURCE, "package.xml")).getroot()
        self.deps = {}
        for element in root:
            self.deps.setdefault(element.tag, set()).add((element.text or "").strip())
        self.runtime = self.deps.get("depend", set()) | self.deps.get("exec_depend", set())
        self.build = self.deps.get("depend", set()) | self.deps.get("build_depend", set())

    def test_no_ground_station_packages_on_the_drone(self):
        for name in ("rviz", "python3-matplotlib", "rqt_reconfigure"):
            self.assertNotIn(name, self.runtime, name + " is the ground station's")

    def test_message_generation_is_a_build_dependency(self):
        self.assertIn("message_generation", self.deps.get("build_depend", set()))
        self.assertNotIn("message_generation", self.deps.get("exec_depend", set()))
        self.assertIn("message_runtime", self.runtime)

    def test_every_included_ros_package_is_declared(self):
        # The ROS packages whose headers the ROS sources include (rosdep installs from this list).
        known = {"ros": "roscpp", "nodelet": "nodelet", "pluginlib": "pluginlib", "sensor_msgs": "sensor_msgs",
                 "geometry_msgs": "geometry_msgs", "nav_msgs": "nav_msgs", "std_msgs": "std_msgs",
                 "std_srvs": "std_srvs", "diagnostic_msgs": "diagnostic_msgs",
                 "diagnostic_updater": "diagnostic_updater", "visualization_msgs": "visualization_msgs",
                 "tf2": "tf2", "tf2_ros": "tf2_ros", "tf2_eigen": "tf2_eigen",
                 "tf2_geometry_msgs": "tf2_geometry_msgs", "image_transport": "image_transport",
                 "message_filters": "message_filters", "dynamic_reconfigure": "dynamic_reconfigure",
                 "rosbag": "rosbag", "image_geometry": "image_geometry", "cv_bridge": "cv_bridge",
                 "tf2_msgs": "tf2_msgs", "rosgraph_msgs": "rosgraph_msgs", "topic_tools": "topic_tools"}
        used = {}  # package -> where it is included
        for folder in ("src/ros", "include/gmm_mcl/ros", "test/ros"):
            for dirpath, _, files in os.walk(os.path.join(SOURCE, folder)):
                for name in files:
                    if name.endswith((".cpp", ".h")):
                        with open(os.path.join(dirpath, name)) as f:
                            for match in re.finditer(r'#include [<"]([a-z0-9_]+)/', f.read()):
                                if match.group(1) in known:
                                    used.setdefault(known[match.group(1)], set()).add(folder)
        self.assertIn("tf2_eigen", used, "tf2_eigen is declared: the conversions should use it")
        self.assertIn("message_filters", used)
        tests = self.deps.get("test_depend", set())
        for package, folders in sorted(used.items()):
            if folders == {"test/ros"}:
                self.assertIn(package, self.build | tests, package + " is included by a test but not declared")
            else:
                self.assertIn(package, self.build & self.runtime, package + " is included but not a build and run dependency")

if __name__ == "__main__":
    unittest.main(argv=sys.argv[:1], verbosity=2)

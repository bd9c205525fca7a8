#!/usr/bin/python3
"""The launch files without starting anything:
- every argument of every launch file has a doc (roslaunch --ros-args lists optional arguments
  as optional, with their doc);
- `roslaunch --dump-params localization.launch config:=config/tx2.yaml` shows the config's
  values (the backend, image_transport and depth_input arguments override them only when given);
- replay.launch and cow_and_lady.launch with rviz:=true do not end with the bag (rviz stays);
  without rviz the bag player ends the launch.
Run in the package's environment (catkin's env_cached.sh): test_launch_files.py SOURCE_DIR."""
import os
import subprocess
import sys
import unittest

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


if __name__ == "__main__":
    unittest.main(argv=sys.argv[:1], verbosity=2)

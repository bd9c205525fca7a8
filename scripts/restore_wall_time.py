#!/usr/bin/python3
"""Started by launch/replay.launch and cow_and_lady.launch beside their /use_sim_time: removes
/use_sim_time from the parameter server when the launch ends, so that nodes started later
against the same master run on wall time again."""
import rospy


def restore():
    try:
        rospy.delete_param("/use_sim_time")
    except KeyError:
        pass


if __name__ == "__main__":
    rospy.init_node("restore_wall_time", anonymous=True, disable_signals=False)
    rospy.on_shutdown(restore)
    rospy.spin()

#!/usr/bin/env python3
"""Plays a bag into the localization nodelet in lockstep: /clock follows the bag, and each depth
frame is published only once the nodelet has answered the previous one on ~status (the messages
in between, tf, IMU and odometry, go out first). Every frame is used however long an update
takes: a reference run for comparisons with real-time playback. Needs /use_sim_time true.

usage: lockstep_play.py BAG [--depth-topic T] [--status-topic T] [--timeout S]
"""
from __future__ import division, print_function

import argparse
import sys
import threading
import time

import rosbag
import rospy
from rosgraph_msgs.msg import Clock


def wait_until(cond, done, timeout_s):
    """Condition.wait_for (Python 3 only): True once done(), False after timeout_s; cond held."""
    end = time.time() + timeout_s
    while not done():
        left = end - time.time()
        if left <= 0:
            return False
        cond.wait(left)
    return True


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("bag")
    ap.add_argument("--depth-topic", default="/camera/depth/image_raw")
    ap.add_argument("--status-topic", default="/gmm_mcl/status")
    ap.add_argument("--timeout", type=float, default=120.0, help="wall seconds per frame at most")
    args = ap.parse_args(rospy.myargv()[1:])
    rospy.init_node("lockstep_play", disable_signals=True)
    answered = set()
    cond = threading.Condition()

    def on_status(m):
        with cond:
            answered.add(m.header.stamp.to_nsec())
            cond.notify_all()

    from gmm_mcl.msg import FilterStatus
    rospy.Subscriber(args.status_topic, FilterStatus, on_status, queue_size=100)
    clock = rospy.Publisher("/clock", Clock, queue_size=10)
    bag = rosbag.Bag(args.bag)
    frames = bag.get_message_count(args.depth_topic)
    # Every publisher first, then time for the subscribers to connect: a message published on a
    # publisher nobody has connected to yet is lost.
    pubs = {}
    for topic, msg, t in bag.read_messages():
        if topic not in pubs:
            pubs[topic] = rospy.Publisher(topic, type(msg), queue_size=100,
                                          latch=(topic == "/tf_static"))
        if len(pubs) == len(bag.get_type_and_topic_info().topics):
            break
    while pubs[args.depth_topic].get_num_connections() == 0 and not rospy.is_shutdown():
        threading.Event().wait(0.1)
    threading.Event().wait(3.0)
    pending = None  # the stamp of the last depth frame sent, not yet answered
    sent = answered_count = timeouts = 0
    for topic, msg, t in bag.read_messages():
        if topic == args.depth_topic and pending is not None:
            with cond:
                ok = wait_until(cond, lambda: pending in answered, args.timeout)
            answered_count += ok
            timeouts += not ok
            pending = None
        clock.publish(Clock(clock=t))
        pubs[topic].publish(msg)
        if topic == args.depth_topic:
            pending = msg.header.stamp.to_nsec()
            sent += 1
            if sent % 100 == 0:
                print("lockstep_play: %d / %d frames" % (sent, frames))
                sys.stdout.flush()
    if pending is not None:
        with cond:
            ok = wait_until(cond, lambda: pending in answered, args.timeout)
        answered_count += ok
        timeouts += not ok
    print("lockstep_play: %d frames sent, %d answered, %d timed out" % (sent, answered_count, timeouts))
    return 0 if timeouts == 0 else 1


if __name__ == "__main__":
    sys.exit(main())

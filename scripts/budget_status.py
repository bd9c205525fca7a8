#!/usr/bin/env python3
"""Summarises a recorded run of the nodelet: frame accounting and the frame-rate budget's choice,
from the ~status messages in a bag (replay.launch record:=...).

usage: budget_status.py RECORDED.bag [FRAMES_SENT]
Prints one line of key=value pairs: frames received / used, the budget and the stride and
particle count it settled on (the last status), and how often it changed them.
"""
from __future__ import division, print_function

import sys

import rosbag


def main():
    if len(sys.argv) < 2:
        print(__doc__)
        return 2
    sent = int(sys.argv[2]) if len(sys.argv) > 2 else 0
    last = None
    statuses = 0
    strides, caps, particles, callback_ms = [], [], [], []
    with rosbag.Bag(sys.argv[1]) as bag:
        for _, m, _ in bag.read_messages(topics=["/gmm_mcl/status"]):
            last = m
            statuses += 1
            strides.append(m.budget_pixel_stride)
            caps.append(m.budget_particle_cap)
            particles.append(m.particles)
            callback_ms.append(m.callback_ms)
    if last is None:
        print("no /gmm_mcl/status in " + sys.argv[1])
        return 1
    tail = callback_ms[len(callback_ms) // 2:]
    tail.sort()
    out = {
        "frames_sent": sent,
        "frames_received": last.frames_received,
        "frames_used": last.frames_processed,
        "used_of_sent": "%.3f" % (last.frames_processed / sent) if sent else "n/a",
        "budget_enabled": last.budget_enabled,
        "budget_ms": "%.1f" % last.budget_ms,
        "stride_final": last.budget_pixel_stride,
        "particle_cap_final": last.budget_particle_cap,
        "refine_final": last.budget_refine,
        "particles_final": last.particles,
        "stride_range": "%d-%d" % (min(strides), max(strides)),
        "particle_cap_range": "%d-%d" % (min(caps), max(caps)),
        "cuts": last.budget_cuts,
        "restores": last.budget_restores,
        "callback_ms_median_2nd_half": "%.1f" % tail[len(tail) // 2],
    }
    print(" ".join("%s=%s" % kv for kv in out.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())

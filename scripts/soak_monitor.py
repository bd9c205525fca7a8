#!/usr/bin/python3
"""Soak-test monitor (docs/soak.md): watches the localization nodelet while
gmm_mcl_soak_publisher feeds it, and prints one table of the figures with PASS/FAIL per target.

Measures: the manager process's VmRSS (from /proc/<pid>/status every --rss-period s) at the end
of warm-up and at the end; every map -> odom tf publication (receipt wall time, stamp); the
frame accounting (publisher's sent count, the nodelet's received / processed / dropped counters
from ~status and /diagnostics); NaN in ~pose and its covariance; frames/s; the position error
against /ground_truth (reported, not a target). Exits 0 when every target is met, 1 otherwise,
2 on a setup problem (no data, timeout).

Python 2.7 (ROS Melodic's rospy) and 3.
"""

from __future__ import division, print_function

import argparse
import csv
import math
import os
import sys
import threading
import time

import rospy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from std_msgs.msg import UInt64
from tf2_msgs.msg import TFMessage

from gmm_mcl.msg import FilterStatus

# Python 2.7 (ROS Melodic) has neither; wall time serves for the periods measured here.
if not hasattr(time, "monotonic"):
    time.monotonic = time.time
if not hasattr(math, "isfinite"):
    math.isfinite = lambda v: not (math.isinf(v) or math.isnan(v))

# Counter fields of FilterStatus and the /diagnostics keys that carry the same numbers.
DIAG_KEYS = {
    "frames received": "frames_received",
    "frames used": "frames_processed",
    "frames not used: no motion": "frames_gated",
    "frames waiting": "frames_waiting",
    "dropped: conversion": "dropped_conversion",
    "dropped: camera info": "dropped_camera_info",
    "dropped: no extrinsics": "dropped_extrinsics",
    "missed before a callback (seq gaps)": "frames_missed_seq",
    "tf not published": "tf_skipped",
    "odometry gaps": "odometry_gaps",
    "frames without IMU": "imu_missing",
    "time jumps back": "time_jumps",
}
DROP_FIELDS = ("dropped_conversion", "dropped_camera_info", "dropped_extrinsics")


def read_rss_kb(pid):
    try:
        with open("/proc/%d/status" % pid) as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


class Monitor:
    def __init__(self, args):
        self.args = args
        self.lock = threading.Lock()
        self.t_start = time.monotonic()
        self.statuses = 0
        self.status_first_wall = None
        self.status_last_wall = None
        self.last_status = None
        self.status_nonfinite = 0
        self.sum_total_ms = 0.0
        self.sum_callback_ms = 0.0
        self.step_status_counts = {}
        self.poses = 0
        self.pose_nonfinite = 0
        self.first_nonfinite = ""
        self.tf = []  # (receipt wall s, stamp s)
        self.truth = {}  # stamp ns -> (x, y, z)
        self.errors = []  # (frames processed so far, position error m)
        self.diag = None
        self.diag_wall = None
        self.sent = 0
        self.timeouts = 0
        self.done = None
        self.done_wall = None
        self.rss = []  # (wall s, frames processed, VmRSS kB)

    # ---- callbacks ----------------------------------------------------------------------------
    def on_status(self, m):
        now = time.monotonic()
        with self.lock:
            self.statuses += 1
            if self.status_first_wall is None:
                self.status_first_wall = now
            self.status_last_wall = now
            self.last_status = m
            self.step_status_counts[m.step_status] = self.step_status_counts.get(m.step_status, 0) + 1
            self.sum_total_ms += m.total_ms
            self.sum_callback_ms += m.callback_ms
            values = (m.neff, m.mean_loglik_per_pixel, m.best_loglik_per_pixel, m.total_ms)
            if not all(math.isfinite(v) for v in values):
                self.status_nonfinite += 1

    def on_pose(self, m):
        p = m.pose.pose
        values = [p.position.x, p.position.y, p.position.z, p.orientation.x, p.orientation.y,
                  p.orientation.z, p.orientation.w] + list(m.pose.covariance)
        with self.lock:
            self.poses += 1
            if not all(math.isfinite(v) for v in values):
                self.pose_nonfinite += 1
                if not self.first_nonfinite:
                    self.first_nonfinite = "pose at %.3f" % m.header.stamp.to_sec()
                return
            truth = self.truth.pop(m.header.stamp.to_nsec(), None)
            if truth is not None:
                err = math.sqrt(sum((a - b) ** 2 for a, b in
                                    zip(truth, (p.position.x, p.position.y, p.position.z))))
                processed = self.last_status.frames_processed if self.last_status else 0
                self.errors.append((processed, err))

    def on_truth(self, m):
        p = m.pose.position
        with self.lock:
            self.truth[m.header.stamp.to_nsec()] = (p.x, p.y, p.z)
            if len(self.truth) > 1000:  # poses that never came (dropped frames)
                for k in sorted(self.truth)[:500]:
                    del self.truth[k]

    def on_tf(self, m):
        now = time.monotonic()
        for t in m.transforms:
            if t.header.frame_id == self.args.map_frame and t.child_frame_id == self.args.odom_frame:
                with self.lock:
                    self.tf.append((now, t.header.stamp.to_sec()))

    def on_diag(self, m):
        for s in m.status:
            if s.name.endswith("localization"):
                values = {kv.key: kv.value for kv in s.values}
                with self.lock:
                    self.diag = values
                    self.diag_wall = time.monotonic()

    def on_sent(self, m):
        with self.lock:
            self.sent = m.data

    def on_timeouts(self, m):
        with self.lock:
            self.timeouts = m.data

    def on_done(self, m):
        with self.lock:
            self.done = m.data
            self.done_wall = time.monotonic()

    # ---- sampling -----------------------------------------------------------------------------
    def sample_rss(self):
        kb = read_rss_kb(self.args.pid)
        with self.lock:
            processed = self.last_status.frames_processed if self.last_status else 0
            if kb is not None:
                self.rss.append((time.monotonic() - self.t_start, processed, kb))
        return kb, processed

    def run(self):
        a = self.args
        ns = a.nodelet.rstrip("/")
        rospy.Subscriber(ns + "/status", FilterStatus, self.on_status, queue_size=10000)
        rospy.Subscriber(ns + "/pose", PoseWithCovarianceStamped, self.on_pose, queue_size=10000)
        rospy.Subscriber("/tf", TFMessage, self.on_tf, queue_size=10000)
        rospy.Subscriber("/ground_truth", PoseStamped, self.on_truth, queue_size=10000)
        rospy.Subscriber("/diagnostics", DiagnosticArray, self.on_diag, queue_size=100)
        rospy.Subscriber("/soak/sent", UInt64, self.on_sent, queue_size=10)
        rospy.Subscriber("/soak/timeouts", UInt64, self.on_timeouts, queue_size=10)
        rospy.Subscriber("/soak/done", UInt64, self.on_done, queue_size=1)
        if read_rss_kb(a.pid) is None:
            print("soak_monitor: no process %d to sample" % a.pid, file=sys.stderr)
            return 2
        deadline = time.monotonic() + a.timeout
        next_rss = 0.0
        next_report = time.monotonic() + a.report_period
        last_report = (time.monotonic(), 0)
        while not rospy.is_shutdown():
            now = time.monotonic()
            if now >= next_rss:
                self.sample_rss()
                next_rss = now + a.rss_period
            if now >= next_report:
                kb, processed = self.sample_rss()
                fps = (processed - last_report[1]) / max(now - last_report[0], 1e-9)
                print("soak_monitor: %d frames processed, %.1f frames/s, RSS %s kB, %d tf" %
                      (processed, fps, kb, len(self.tf)), flush=True)
                last_report = (now, processed)
                next_report = now + a.report_period
            with self.lock:
                finished = (self.done is not None and self.diag_wall is not None and
                            self.diag_wall > self.done_wall + 2.5 * a.diagnostics_period + 0.2)
            if finished:
                break
            if a.publisher_pid and self.done is None and not os.path.exists("/proc/%d" % a.publisher_pid):
                time.sleep(1.0)  # its last messages
                if self.done is None:
                    print("soak_monitor: the publisher (pid %d) exited before /soak/done" %
                          a.publisher_pid, file=sys.stderr)
                    self.report(timed_out=True)
                    return 2
            if now > deadline:
                print("soak_monitor: timed out after %.0f s (publisher done: %s)" %
                      (a.timeout, self.done is not None), file=sys.stderr)
                self.report(timed_out=True)
                return 2
            time.sleep(0.05)
        self.sample_rss()
        return self.report(timed_out=False)

    # ---- the table ----------------------------------------------------------------------------
    def report(self, timed_out):
        a = self.args
        with self.lock:
            rows = []
            failed = []

            def row(name, value, target="", ok=None):
                verdict = "" if ok is None else ("PASS" if ok else "FAIL")
                if ok is False:
                    failed.append(name)
                rows.append((name, value, target, verdict))

            st = self.last_status
            counters = {}
            if self.diag is not None:
                for key, field in DIAG_KEYS.items():
                    if key in self.diag:
                        counters[field] = int(float(self.diag[key]))
            # The last ~status carries the same counters (up to its frame): take the larger.
            if st is not None:
                for field in DIAG_KEYS.values():
                    counters[field] = max(counters.get(field, 0), int(getattr(st, field)))
            sent = self.done if self.done is not None else self.sent
            received = counters.get("frames_received", 0)
            processed = counters.get("frames_processed", 0)
            dropped = sum(counters.get(f, 0) for f in DROP_FIELDS)
            gated = counters.get("frames_gated", 0)
            waiting = counters.get("frames_waiting", 0)
            missed = counters.get("frames_missed_seq", 0)
            tf_skipped = counters.get("tf_skipped", 0)

            wall = (self.status_last_wall - self.status_first_wall) if self.statuses > 1 else 0.0
            fps = (self.statuses - 1) / wall if wall > 0 else 0.0
            row("frames sent (publisher)", "%d" % sent, ">= %d" % a.frames, sent >= a.frames)
            row("frames received (nodelet)", "%d" % received)
            row("frames processed (core step ran)", "%d" % processed)
            row("frames dropped", "%d (conversion %d, camera info %d, extrinsics %d)" %
                (dropped, counters.get("dropped_conversion", 0), counters.get("dropped_camera_info", 0),
                 counters.get("dropped_extrinsics", 0)))
            row("frames not used (no motion) / waiting", "%d / %d" % (gated, waiting))
            row("received == processed + not used + dropped + waiting",
                "%d == %d" % (received, processed + gated + dropped + waiting), "equal",
                received == processed + gated + dropped + waiting)
            row("missed before a callback (seq gaps)", "%d" % missed)
            row("sent == received + missed", "%d == %d" % (sent, received + missed), "equal",
                sent == received + missed)
            row("lockstep timeouts (publisher)", "%d" % self.timeouts)
            row("~status messages (monitor)", "%d" % self.statuses, "== processed",
                self.statuses == processed)
            row("step statuses", ", ".join("%s %d" % kv for kv in sorted(self.step_status_counts.items())))
            row("odometry gaps / frames without IMU", "%d / %d" % (counters.get("odometry_gaps", 0),
                                                              counters.get("imu_missing", 0)))
            row("frames/s (processed, wall)", "%.1f over %.1f s" % (fps, wall))
            if self.statuses:
                row("mean core step / depth callback", "%.2f ms / %.2f ms" %
                    (self.sum_total_ms / self.statuses, self.sum_callback_ms / self.statuses))

            # tf continuity.
            n_tf = len(self.tf)
            row("map -> odom tf received", "%d" % n_tf, "== processed - tf_skipped (%d)" %
                (processed - tf_skipped), n_tf == processed - tf_skipped and n_tf > 0)
            if n_tf >= 2:
                stamp_gaps = [b[1] - a_[1] for a_, b in zip(self.tf, self.tf[1:])]
                recv_gaps = [b[0] - a_[0] for a_, b in zip(self.tf, self.tf[1:])]
                max_stamp_gap = max(stamp_gaps)
                i_stamp = stamp_gaps.index(max_stamp_gap)
                max_recv_gap = max(recv_gaps)
                i_recv = recv_gaps.index(max_recv_gap)
                mean_recv = (self.tf[-1][0] - self.tf[0][0]) / (n_tf - 1)
                bound = a.max_stamp_gap_periods * a.period
                row("largest tf stamp gap", "%.4f s = %.2f periods (after tf %d)" %
                    (max_stamp_gap, max_stamp_gap / a.period, i_stamp + 1),
                    "<= %.2f periods (%.4f s)" % (a.max_stamp_gap_periods, bound),
                    max_stamp_gap <= bound + 1e-6)
                row("tf stamps strictly increasing", "min step %.4f s" % min(stamp_gaps), "> 0",
                    min(stamp_gaps) > 0)
                row("largest tf receipt gap (wall)", "%.3f s = %.1f x mean %.4f s (after tf %d)" %
                    (max_recv_gap, max_recv_gap / max(mean_recv, 1e-9), mean_recv, i_recv + 1),
                    "<= %.2f s" % a.max_receipt_gap, max_recv_gap <= a.max_receipt_gap)
            else:
                row("largest tf stamp gap", "fewer than 2 tf", "", False)

            # NaN.
            row("non-finite pose / covariance", "%d of %d poses%s" %
                (self.pose_nonfinite, self.poses, (" (first: %s)" % self.first_nonfinite)
                 if self.first_nonfinite else ""), "0", self.pose_nonfinite == 0 and self.poses > 0)
            row("non-finite ~status values", "%d" % self.status_nonfinite, "0",
                self.status_nonfinite == 0)

            # Memory.
            warm = [r for r in self.rss if r[1] >= a.warmup]
            if warm and self.rss:
                rss_warm = warm[0][2]
                rss_end = self.rss[-1][2]
                peak = max(r[2] for r in warm)
                growth = rss_end - rss_warm
                row("RSS at warm-up (>= %d frames, at %d)" % (a.warmup, warm[0][1]), "%d kB" % rss_warm)
                row("RSS at end (%d frames)" % self.rss[-1][1], "%d kB (peak after warm-up %d kB)" %
                    (rss_end, peak))
                row("RSS growth after warm-up", "%+d kB (%d samples every %.0f s)" %
                    (growth, len(warm), a.rss_period),
                    "< 1024 kB" if a.check_rss else "not checked (short run)",
                    growth < 1024 if a.check_rss else None)
            else:
                row("RSS growth after warm-up", "no sample after warm-up (%d samples)" % len(self.rss),
                    "< 1024 kB" if a.check_rss else "not checked (short run)",
                    False if a.check_rss else None)

            # Tracking (reported only).
            late = [e for p, e in self.errors if p >= a.warmup] or [e for _, e in self.errors]
            if late:
                late_sorted = sorted(late)
                row("position error after warm-up", "median %.3f m, max %.3f m (%d poses)" %
                    (late_sorted[len(late_sorted) // 2], late_sorted[-1], len(late)))
            if timed_out:
                failed.append("timeout")

        w0 = max(len(r[0]) for r in rows)
        w1 = max(len(r[1]) for r in rows)
        w2 = max(len(r[2]) for r in rows)
        print("\n== soak: %d frames, manager pid %d" % (a.frames, a.pid))
        for r in rows:
            print("%-*s  %-*s  %-*s  %s" % (w0, r[0], w1, r[1], w2, r[2], r[3]))
        if a.out:
            os.makedirs(a.out, exist_ok=True)
            with open(os.path.join(a.out, "rss.csv"), "w", newline="") as f:
                wr = csv.writer(f)
                wr.writerow(["wall_s", "frames_processed", "vmrss_kb"])
                wr.writerows(self.rss)
            with open(os.path.join(a.out, "tf.csv"), "w", newline="") as f:
                wr = csv.writer(f)
                wr.writerow(["receipt_wall_s", "stamp_s"])
                wr.writerows(self.tf)
            with open(os.path.join(a.out, "summary.txt"), "w") as f:
                for r in rows:
                    f.write("%s\t%s\t%s\t%s\n" % r)
        print("== soak: %s" % ("PASS" if not failed else "FAIL: " + "; ".join(failed)), flush=True)
        return 0 if not failed else 1


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--pid", type=int, required=True, help="nodelet manager process to sample")
    p.add_argument("--frames", type=int, required=True, help="frames the publisher sends")
    p.add_argument("--warmup", type=int, default=5000, help="frames processed before the RSS baseline")
    p.add_argument("--period", type=float, default=1.0 / 30.0, help="publisher's stamp period, s")
    p.add_argument("--max-stamp-gap-periods", type=float, default=1.5)
    p.add_argument("--max-receipt-gap", type=float, default=2.0, help="s of wall time")
    p.add_argument("--rss-period", type=float, default=2.0)
    p.add_argument("--report-period", type=float, default=30.0)
    p.add_argument("--diagnostics-period", type=float, default=0.5)
    p.add_argument("--timeout", type=float, default=7200.0, help="whole run, s")
    p.add_argument("--no-rss-check", dest="check_rss", action="store_false")
    p.add_argument("--publisher-pid", type=int, default=0, help="stop when it exits early")
    p.add_argument("--nodelet", default="/gmm_mcl")
    p.add_argument("--map-frame", default="map")
    p.add_argument("--odom-frame", default="odom")
    p.add_argument("--out", default="", help="folder for rss.csv, tf.csv, summary.txt")
    args = p.parse_args(rospy.myargv()[1:])
    rospy.init_node("soak_monitor", disable_signals=True)
    sys.exit(Monitor(args).run())


if __name__ == "__main__":
    main()

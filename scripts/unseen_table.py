#!/usr/bin/env python3
"""Tables of scripts/eval_unseen.sh: one row per protocol (pooled) and one per trial, markdown.

usage: scripts/unseen_table.py OUT_DIR

Reads OUT_DIR/<run>/trial_<seed>_metrics.csv (gmm_mcl_replay --out) and
OUT_DIR/<run>/kidnap_<seed>.csv (gmm_mcl_kidnap --out). Runs: start_seg<first>, map_seg<first>,
kidnap_seg<first>, 7s-disjoint, 7s, 7s-m4000. Convergence (replay): the first frame after which the error
stays under 10 cm for 30 frames; success: converged and the last 100 frames under 10 cm; the
whole-map start counts convergence within 10 s, the others within 5 s. ATE pooled over the
frames after convergence of every converged trial (RMSE), for the particle mean and the refined
pose. Kidnap: recovered within 5 s of the teleport and under 10 cm at the end.
"""
import csv
import glob
import math
import os
import re
import sys

PROTOCOLS = [
    ("start", "unseen scene (Replica), paper start", 5.0),
    ("map", "unseen scene (Replica), whole-map start", 10.0),
    ("kidnap", "unseen scene (Replica), kidnap", 5.0),
    ("7s-disjoint", "7-Scenes, map from disjoint frames", 5.0),
    ("7s", "7-Scenes, DESIGN.md protocol", 5.0),
    ("7s-m4000", "7-Scenes, DESIGN.md protocol with an M=4000 map", 5.0),
]


def rows(pattern, skip=None):
    """Rows of every file matching pattern, by seed; names ending in `skip` left out (the
    kidnap tool's per-frame files beside its per-trial ones)."""
    out = []
    seed = lambda p: int(re.sub(r"\D", "", os.path.basename(p)) or 0)
    paths = [p for p in glob.glob(pattern) if not (skip and p.endswith(skip))]
    for path in sorted(paths, key=seed):
        with open(path) as f:
            out.extend(csv.DictReader(f))
    return out


def run_dirs(root, key):
    if key.startswith("7s"):
        d = os.path.join(root, key)
        return [d] if os.path.isdir(d) else []
    return sorted(glob.glob(os.path.join(root, key + "_seg*")),
                  key=lambda d: int(re.sub(r"\D", "", os.path.basename(d)) or 0))


def replay_summary(trials, limit_s):
    n = len(trials)
    conv = [t for t in trials if t["converged"] == "1"]
    within = [t for t in conv if float(t["converge_time_s"]) <= limit_s]
    times = [float(t["converge_time_s"]) for t in conv]
    frames = sum(int(t["converged_frames"]) for t in conv)

    def pooled(col):
        if frames == 0:
            return float("nan")
        return math.sqrt(sum(float(t[col]) ** 2 * int(t["converged_frames"]) for t in conv) / frames)

    return {
        "n": n,
        "success": sum(t["success"] == "1" for t in trials),
        "within": len(within),
        "mean_t": sum(times) / len(times) if times else float("nan"),
        "worst_t": max(times) if times else float("nan"),
        "ate": pooled("ate_cm"), "ate_yaw": pooled("ate_yaw_deg"),
        "rate": pooled("refined_ate_cm"), "rate_yaw": pooled("refined_ate_yaw_deg"),
        "lost": sum(int(t["lost_events"]) for t in trials),
        "step": sum(float(t["mean_step_ms"]) for t in trials) / n if n else float("nan"),
    }


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else "build/eval_unseen"
    lines = ["| protocol | trials | succeeded | converged in time | mean / worst time (s) | "
             "ATE mean (cm / deg) | ATE refined (cm / deg) | lost events | mean step (ms) |",
             "|---|---|---|---|---|---|---|---|---|"]
    details = []
    for key, label, limit in PROTOCOLS:
        dirs = run_dirs(root, key)
        if not dirs:
            continue
        if key == "kidnap":
            trials = [r for d in dirs for r in rows(os.path.join(d, "kidnap_*.csv"), skip="_frames.csv")]
            if not trials:
                continue
            rec = [t for t in trials if t["recovered"] == "1"]
            times = [float(t["recovery_s"]) for t in rec]
            ate = [float(t["ate_after_m"]) * 100 for t in rec]
            lines.append("| %s | %d | %d recovered | %d/%d within 5 s | %s | %s | | %d | %.1f |" % (
                label, len(trials), len(rec), len(rec), len(trials),
                "%.2f / %.2f" % (sum(times) / len(times), max(times)) if times else "-",
                "%.2f (after recovery)" % (math.sqrt(sum(a * a for a in ate) / len(ate))) if ate else "-",
                sum(int(t["lost_events"]) for t in trials),
                sum(float(t["mean_step_ms"]) for t in trials) / len(trials)))
            details.append("\n%s:\n\n| run | seed | jump (m) | recovered in (s) | final error (cm) | "
                           "lost events |\n|---|---|---|---|---|---|" % label)
            for d in dirs:
                for t in rows(os.path.join(d, "kidnap_*.csv"), skip="_frames.csv"):
                    details.append("| %s | %s | %.2f | %s | %.1f | %s |" % (
                        os.path.basename(d), t["seed"], float(t["jump_m"]),
                        "%.2f" % float(t["recovery_s"]) if t["recovered"] == "1" else "never",
                        float(t["final_error_m"]) * 100, t["lost_events"]))
            continue
        trials = [r for d in dirs for r in rows(os.path.join(d, "trial_*_metrics.csv"))]
        if not trials:
            continue
        s = replay_summary(trials, limit)
        lines.append("| %s | %d | %d | %d/%d within %.0f s | %.2f / %.2f | %.2f / %.2f | %.2f / %.2f "
                     "| %d | %.1f |" % (label, s["n"], s["success"], s["within"], s["n"], limit,
                                        s["mean_t"], s["worst_t"], s["ate"], s["ate_yaw"],
                                        s["rate"], s["rate_yaw"], s["lost"], s["step"]))
        details.append("\n%s:\n\n| run | seed | converged at (s) | ATE (cm) | refined ATE (cm) | "
                       "lost events | success |\n|---|---|---|---|---|---|---|" % label)
        for d in dirs:
            for t in rows(os.path.join(d, "trial_*_metrics.csv")):
                details.append("| %s | %s | %s | %s | %s | %s | %s |" % (
                    os.path.basename(d), t["seed"],
                    "%.2f" % float(t["converge_time_s"]) if t["converged"] == "1" else "never",
                    t["ate_cm"], t["refined_ate_cm"], t["lost_events"],
                    "yes" if t["success"] == "1" else "no"))
    print("\n".join(lines))
    print("\n".join(details))


if __name__ == "__main__":
    main()

#!/usr/bin/python3
"""PNG plots of a gmm_mcl_replay output folder.

usage: scripts/plot_replay.py OUT_DIR [--rewrite-summary] [--dpi N]

Reads what gmm_mcl_replay writes into OUT_DIR: trial_<seed>.csv (per frame: stamp, error,
estimate, truth, Neff, ...), and, where the CSV lacks a column, trial_<seed>_estimate.tum /
trial_<seed>_truth.tum. Writes into OUT_DIR:
  trial_<seed>.png   top view (x-y) of the estimate vs the ground truth; translation error (cm)
                     and yaw error (deg) over time with the convergence point marked
  overview.png       all trials: error over time, top view, ATE per trial
  summary.md/.csv    the DESIGN.md protocol table, only when replay did not write them (or with
                     --rewrite-summary): converged = first frame after which the error stays
                     below 10 cm for 30 frames; ATE RMSE from there on; success = converged and
                     the last 100 frames below 10 cm (as src/replay/evaluation.cpp).
Frames without ground truth (empty error fields) are drawn without error and left out of the
metrics. Needs matplotlib (Debian python3-matplotlib; run with /usr/bin/python3).
"""
import argparse
import csv
import glob
import math
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from plot_common import import_pyplot, to_float  # noqa: E402

CONVERGED_BELOW_M = 0.10
HOLD_FRAMES = 30
TAIL_FRAMES = 100


def read_trial_csv(path):
    """Columns of a trial CSV as lists of floats (empty or non-numeric fields -> NaN), plus the
    raw 'status' column when present."""
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        cols = {name: [] for name in reader.fieldnames or []}
        for row in reader:
            for name in cols:
                cols[name].append(row.get(name, ""))
    out = {}
    for name, values in cols.items():
        out[name] = values if name == "status" else [to_float(v) for v in values]
    return out


def read_tum(path):
    """t, x, y, z, yaw from a TUM trajectory (yaw of the quaternion)."""
    rows = []
    with open(path) as f:
        for line in f:
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            v = [float(x) for x in line.split()]
            if len(v) < 8:
                continue
            t, x, y, z, qx, qy, qz, qw = v[:8]
            yaw = math.atan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz))
            rows.append((t, x, y, z, yaw))
    return rows


def evaluate(stamps, errors_m, yaw_errors_deg):
    """The protocol metrics over frames with a finite error (src/replay/evaluation.cpp)."""
    idx = [i for i, e in enumerate(errors_m) if math.isfinite(e)]
    e = [errors_m[i] for i in idx]
    m = {"frames": len(e), "converged": False, "converge_index": None, "converge_time_s": math.nan,
         "ate_cm": math.nan, "ate_yaw_deg": math.nan, "success": False}
    run = 0
    start = None
    for k, err in enumerate(e):
        run = run + 1 if err < CONVERGED_BELOW_M else 0
        if run == HOLD_FRAMES:
            start = k - HOLD_FRAMES + 1
            break
    if start is None:
        return m
    m["converged"] = True
    m["converge_index"] = idx[start]
    m["converge_time_s"] = stamps[idx[start]] - stamps[idx[0]]
    tail = e[start:]
    yaw = [yaw_errors_deg[i] for i in idx[start:]]
    m["ate_cm"] = 100.0 * math.sqrt(sum(x * x for x in tail) / len(tail))
    finite_yaw = [y for y in yaw if math.isfinite(y)]
    if finite_yaw:
        m["ate_yaw_deg"] = math.sqrt(sum(y * y for y in finite_yaw) / len(finite_yaw))
    m["success"] = all(x < CONVERGED_BELOW_M for x in e[max(0, len(e) - TAIL_FRAMES):])
    m["pooled_count"] = len(tail)
    return m


def load_trial(out_dir, seed):
    base = os.path.join(out_dir, "trial_%s" % seed)
    cols = read_trial_csv(base + ".csv")
    n = len(cols.get("stamp_s", []))
    trial = {"seed": seed, "n": n}
    stamps = cols.get("stamp_s", [math.nan] * n)
    t0 = next((t for t in stamps if math.isfinite(t)), 0.0)
    trial["t"] = [t - t0 for t in stamps]
    for key in ("est_x", "est_y", "true_x", "true_y", "error_m", "error_yaw_deg", "neff"):
        trial[key] = cols.get(key)
    # Older or other writers: positions from the TUM files.
    if trial["est_x"] is None and os.path.exists(base + "_estimate.tum"):
        est = read_tum(base + "_estimate.tum")
        trial["est_x"] = [r[1] for r in est]
        trial["est_y"] = [r[2] for r in est]
    if trial["true_x"] is None and os.path.exists(base + "_truth.tum"):
        tru = read_tum(base + "_truth.tum")
        trial["true_x"] = [r[1] for r in tru]
        trial["true_y"] = [r[2] for r in tru]
    if trial["error_m"] is None:
        raise ValueError("%s.csv has no error_m column" % base)
    if trial["error_yaw_deg"] is None:
        trial["error_yaw_deg"] = [math.nan] * n
    trial["metrics"] = evaluate(stamps, trial["error_m"], trial["error_yaw_deg"])
    return trial


def find_seeds(out_dir):
    seeds = []
    for path in glob.glob(os.path.join(out_dir, "trial_*.csv")):
        m = re.match(r"trial_(.+)\.csv$", os.path.basename(path))
        if m:
            seeds.append(m.group(1))
    return sorted(seeds, key=lambda s: (0, int(s)) if s.isdigit() else (1, s))


def write_summary(out_dir, trials):
    md = ["| seed | converged at (s) | ATE (cm) | yaw ATE (deg) | success |", "|---|---|---|---|---|"]
    rows = ["seed,converged,converge_time_s,ate_cm,ate_yaw_deg,success"]
    sum_t = sum_y = 0.0
    pooled = 0
    conv = []
    ok = 0
    for tr in trials:
        m = tr["metrics"]
        md.append("| %s | %s | %.2f | %.2f | %s |" % (
            tr["seed"], "%.2f" % m["converge_time_s"] if m["converged"] else "never",
            m["ate_cm"] if m["converged"] else 0.0, m["ate_yaw_deg"] if m["converged"] else 0.0,
            "yes" if m["success"] else "no"))
        rows.append("%s,%d,%.3f,%.3f,%.3f,%d" % (
            tr["seed"], m["converged"], m["converge_time_s"] if m["converged"] else 0.0,
            m["ate_cm"] if m["converged"] else 0.0, m["ate_yaw_deg"] if m["converged"] else 0.0,
            m["success"]))
        ok += 1 if m["success"] else 0
        if m["converged"]:
            conv.append(m["converge_time_s"])
            c = m["pooled_count"]
            sum_t += (m["ate_cm"] ** 2) * c
            sum_y += (m["ate_yaw_deg"] ** 2) * c if math.isfinite(m["ate_yaw_deg"]) else 0.0
            pooled += c
    nan = float("nan")
    md.append("| all | mean %.2f | %.2f | %.2f | %d/%d |" % (
        sum(conv) / len(conv) if conv else nan, math.sqrt(sum_t / pooled) if pooled else nan,
        math.sqrt(sum_y / pooled) if pooled else nan, ok, len(trials)))
    with open(os.path.join(out_dir, "summary.md"), "w") as f:
        f.write("\n".join(md) + "\n")
    with open(os.path.join(out_dir, "summary.csv"), "w") as f:
        f.write("\n".join(rows) + "\n")


def _finite_pairs(xs, ys):
    return [(x, y) for x, y in zip(xs or [], ys or []) if math.isfinite(x) and math.isfinite(y)]


def plot_trial(plt, tr, path, dpi):
    fig = plt.figure(figsize=(12, 5))
    gs = fig.add_gridspec(2, 2, width_ratios=[1, 1.4])
    ax_top = fig.add_subplot(gs[:, 0])
    ax_t = fig.add_subplot(gs[0, 1])
    ax_y = fig.add_subplot(gs[1, 1], sharex=ax_t)
    m = tr["metrics"]

    truth = _finite_pairs(tr["true_x"], tr["true_y"])
    est = _finite_pairs(tr["est_x"], tr["est_y"])
    if truth:
        ax_top.plot([p[0] for p in truth], [p[1] for p in truth], "k-", lw=1.5, label="ground truth")
        ax_top.plot(truth[0][0], truth[0][1], "ko", ms=5)
    if est:
        ax_top.plot([p[0] for p in est], [p[1] for p in est], "-", color="tab:orange", lw=1.0,
                    label="estimate (mean)")
        ax_top.plot(est[0][0], est[0][1], "o", color="tab:orange", ms=5)
    if m["converged"] and tr["est_x"] is not None:
        i = m["converge_index"]
        if i < len(tr["est_x"]) and math.isfinite(tr["est_x"][i]):
            ax_top.plot(tr["est_x"][i], tr["est_y"][i], "*", color="tab:green", ms=12,
                        label="converged")
    ax_top.set_aspect("equal", adjustable="datalim")
    ax_top.set_xlabel("x (m)")
    ax_top.set_ylabel("y (m)")
    ax_top.set_title("top view, seed %s" % tr["seed"])
    ax_top.grid(True, alpha=0.3)
    ax_top.legend(loc="best", fontsize=8)

    t = tr["t"]
    err_cm = [100.0 * e for e in tr["error_m"]]
    ax_t.semilogy(t, [max(e, 1e-2) if math.isfinite(e) else math.nan for e in err_cm],
                  color="tab:blue", lw=1)
    ax_t.axhline(100.0 * CONVERGED_BELOW_M, color="gray", ls="--", lw=0.8, label="10 cm")
    ax_t.set_ylabel("translation error (cm)")
    ax_y.plot(t, tr["error_yaw_deg"], color="tab:purple", lw=1)
    ax_y.set_ylabel("yaw error (deg)")
    ax_y.set_xlabel("time (s)")
    title = "seed %s: " % tr["seed"]
    if m["converged"]:
        tc = t[m["converge_index"]]
        for ax in (ax_t, ax_y):
            ax.axvline(tc, color="tab:green", lw=1.2, label="converged %.2f s" % m["converge_time_s"])
        title += "converged at %.2f s, ATE %.2f cm / %.2f deg, %s" % (
            m["converge_time_s"], m["ate_cm"], m["ate_yaw_deg"],
            "success" if m["success"] else "FAILURE")
    else:
        title += "never converged"
    ax_t.set_title(title, fontsize=10)
    ax_t.legend(loc="upper right", fontsize=8)
    for ax in (ax_t, ax_y):
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)


def plot_overview(plt, trials, path, dpi):
    fig, axes = plt.subplots(1, 3, figsize=(16, 5), gridspec_kw={"width_ratios": [1.4, 1, 1]})
    ax_e, ax_top, ax_bar = axes
    cmap = plt.get_cmap("tab10")
    for k, tr in enumerate(trials):
        c = cmap(k % 10)
        err_cm = [max(100.0 * e, 1e-2) if math.isfinite(e) else math.nan for e in tr["error_m"]]
        ax_e.semilogy(tr["t"], err_cm, color=c, lw=0.8, label="seed %s" % tr["seed"])
        m = tr["metrics"]
        if m["converged"]:
            ax_e.plot(tr["t"][m["converge_index"]], err_cm[m["converge_index"]], "o", color=c, ms=4)
        est = _finite_pairs(tr["est_x"], tr["est_y"])
        if est:
            ax_top.plot([p[0] for p in est], [p[1] for p in est], color=c, lw=0.6)
    if trials:
        truth = _finite_pairs(trials[0]["true_x"], trials[0]["true_y"])
        if truth:
            ax_top.plot([p[0] for p in truth], [p[1] for p in truth], "k-", lw=1.8, label="ground truth")
    ax_e.axhline(100.0 * CONVERGED_BELOW_M, color="gray", ls="--", lw=0.8)
    ax_e.set_xlabel("time (s)")
    ax_e.set_ylabel("translation error (cm)")
    ax_e.set_title("error of the mean, all trials (dots: convergence)")
    ax_e.grid(True, alpha=0.3)
    if len(trials) <= 12:
        ax_e.legend(fontsize=7, ncol=2)
    ax_top.set_aspect("equal", adjustable="datalim")
    ax_top.set_xlabel("x (m)")
    ax_top.set_ylabel("y (m)")
    ax_top.set_title("top view: estimates and ground truth")
    ax_top.grid(True, alpha=0.3)
    ax_top.legend(fontsize=8)
    labels = [str(tr["seed"]) for tr in trials]
    ate = [tr["metrics"]["ate_cm"] if tr["metrics"]["converged"] else 0.0 for tr in trials]
    colors = ["tab:green" if tr["metrics"]["success"] else "tab:red" for tr in trials]
    ax_bar.bar(range(len(trials)), ate, color=colors)
    ax_bar.set_xticks(range(len(trials)))
    ax_bar.set_xticklabels(labels)
    ax_bar.set_xlabel("seed (red: failure)")
    ax_bar.set_ylabel("ATE after convergence (cm)")
    ok = sum(1 for tr in trials if tr["metrics"]["success"])
    ax_bar.set_title("%d/%d trials succeed" % (ok, len(trials)))
    ax_bar.grid(True, axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out_dir")
    ap.add_argument("--rewrite-summary", action="store_true",
                    help="write summary.md/.csv even when replay already did")
    ap.add_argument("--dpi", type=int, default=110)
    args = ap.parse_args(argv)
    plt = import_pyplot("plot_replay")
    if plt is None:
        return 3
    seeds = find_seeds(args.out_dir)
    if not seeds:
        print("plot_replay: no trial_<seed>.csv in %s" % args.out_dir, file=sys.stderr)
        return 1
    trials = [load_trial(args.out_dir, s) for s in seeds]
    written = []
    for tr in trials:
        path = os.path.join(args.out_dir, "trial_%s.png" % tr["seed"])
        plot_trial(plt, tr, path, args.dpi)
        written.append(path)
    path = os.path.join(args.out_dir, "overview.png")
    plot_overview(plt, trials, path, args.dpi)
    written.append(path)
    have_summary = all(os.path.exists(os.path.join(args.out_dir, f))
                       for f in ("summary.md", "summary.csv"))
    if args.rewrite_summary or not have_summary:
        write_summary(args.out_dir, trials)
        written += [os.path.join(args.out_dir, "summary.md"), os.path.join(args.out_dir, "summary.csv")]
    for tr in trials:
        m = tr["metrics"]
        print("seed %s: %s, ATE %.2f cm / %.2f deg, %s" % (
            tr["seed"], "converged at %.2f s" % m["converge_time_s"] if m["converged"] else "never converged",
            m["ate_cm"], m["ate_yaw_deg"], "success" if m["success"] else "FAILURE"))
    print("wrote " + ", ".join(os.path.relpath(p, args.out_dir) for p in written))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

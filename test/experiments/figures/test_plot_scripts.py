#!/usr/bin/python3
"""The plot scripts on fixture folders this test writes itself.

usage: test_plot_scripts.py WORK_DIR

scripts/plot_replay.py: a replay folder with two trials in gmm_mcl_replay's formats (per-frame
CSV with its header, TUM files; one trial converges at a known frame, one never does, frames
without ground truth have empty error fields) -> non-empty PNGs per trial and an overview; the
summary it writes has the expected convergence time, ATE and success; an existing summary is
kept unless --rewrite-summary. scripts/plot_figures.py: nll_sweep.csv and
sensitivity_summary.csv fixtures -> non-empty PNGs.
Exit 77 (a skip for ctest) when matplotlib is missing.
"""
import importlib.util
import math
import os
import shutil
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
# The package root: the folder above test/ (this file sits in test/experiments/figures).
ROOT = HERE
while os.path.basename(ROOT) != "test" and os.path.dirname(ROOT) != ROOT:
    ROOT = os.path.dirname(ROOT)
SCRIPTS = os.path.join(os.path.dirname(ROOT), "scripts")
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
MIN_PNG_BYTES = 5000  # a blank 1000x500 figure is about 4 kB; ours carry curves and text

# gmm_mcl_replay's writeFrameCsv header (src/replay/replay.cpp).
HEADER = ("stamp_s,error_m,error_yaw_deg,est_x,est_y,est_z,est_yaw,true_x,true_y,true_z,true_yaw,"
          "neff,loglik_best_per_px,loglik_mean_per_px,floor_hit_fraction,relevant_per_patch,"
          "beta_fraction,reinitialised,status,pixels,frame_prep_ms,membership_ms,likelihood_ms,"
          "resample_ms,total_ms")
FRAMES = 200
CONVERGE_FRAME = 40  # seed 1: error 0.5 m before, 2 cm from here on


failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what)
    if not cond:
        failures.append(what)


def write_trial(out, seed, errors_m, no_truth=()):
    rows = [HEADER]
    est, tru = [], []
    for f in range(FRAMES):
        t = 1305031102.0 + f / 30.0  # absolute stamps, as TUM sequences have
        a = 0.01 * f
        tx, ty, tz, tyaw = 1.0 + math.cos(a), 2.0 + math.sin(a), 1.2, a
        e = errors_m[f]
        ex, ey, ez, eyaw = tx + e, ty, tz, tyaw + 0.01
        if f in no_truth:
            rows.append("%.6f,,,%f,%f,%f,%f,,,,,500,-1,-1.2,0.01,14,1,0,ok,4800,1,2,3,0.1,7" % (
                t, ex, ey, ez, eyaw))
        else:
            rows.append("%.6f,%f,%f,%f,%f,%f,%f,%f,%f,%f,%f,500,-1,-1.2,0.01,14,1,0,ok,4800,1,2,3,"
                        "0.1,7" % (t, e, math.degrees(0.01), ex, ey, ez, eyaw, tx, ty, tz, tyaw))
            tru.append("%.6f %f %f %f 0 0 %f %f" % (t, tx, ty, tz, math.sin(tyaw / 2), math.cos(tyaw / 2)))
        est.append("%.6f %f %f %f 0 0 %f %f" % (t, ex, ey, ez, math.sin(eyaw / 2), math.cos(eyaw / 2)))
    with open(os.path.join(out, "trial_%d.csv" % seed), "w") as f:
        f.write("\n".join(rows) + "\n")
    with open(os.path.join(out, "trial_%d_estimate.tum" % seed), "w") as f:
        f.write("\n".join(est) + "\n")
    with open(os.path.join(out, "trial_%d_truth.tum" % seed), "w") as f:
        f.write("\n".join(tru) + "\n")


def check_png(path):
    ok = os.path.exists(path) and os.path.getsize(path) >= MIN_PNG_BYTES
    if ok:
        with open(path, "rb") as f:
            ok = f.read(8) == PNG_SIGNATURE
    check(ok, "%s is a PNG of at least %d bytes" % (os.path.basename(path), MIN_PNG_BYTES))


_modules = {}


def run(args):
    """Runs a script's main(argv) in this process (one matplotlib import for all runs)."""
    path = args[0]
    if path not in _modules:
        spec = importlib.util.spec_from_file_location(os.path.basename(path)[:-3], path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        _modules[path] = module
    return _modules[path].main(args[1:])


def test_replay(work):
    out = os.path.join(work, "replay")
    os.makedirs(out)
    e1 = [0.5] * CONVERGE_FRAME + [0.02] * (FRAMES - CONVERGE_FRAME)
    e1[80] = 0.15  # one excursion after convergence (the hold rule needs only 30 frames) and
    # before the last 100 frames (success)
    e2 = [0.4 if f % 20 < 15 else 0.05 for f in range(FRAMES)]  # never 30 frames below 10 cm
    write_trial(out, 1, e1, no_truth=(150, 151))
    write_trial(out, 2, e2)
    # Once as a program, as users run it.
    rc = subprocess.call([sys.executable, os.path.join(SCRIPTS, "plot_replay.py"), out])
    check(rc == 0, "plot_replay.py exits 0 (got %d)" % rc)
    for name in ("trial_1.png", "trial_2.png", "overview.png"):
        check_png(os.path.join(out, name))
    with open(os.path.join(out, "summary.csv")) as f:
        lines = [l.strip().split(",") for l in f if l.strip()]
    check(lines[0] == ["seed", "converged", "converge_time_s", "ate_cm", "ate_yaw_deg", "success"],
          "summary.csv header as gmm_mcl_replay writes it")
    row1 = dict(zip(lines[0], lines[1]))
    row2 = dict(zip(lines[0], lines[2]))
    check(row1["converged"] == "1" and abs(float(row1["converge_time_s"]) - CONVERGE_FRAME / 30.0) < 1e-3,
          "seed 1 converges at frame %d (%.3f s), got %s" % (CONVERGE_FRAME, CONVERGE_FRAME / 30.0,
                                                              row1["converge_time_s"]))
    # RMSE over frames from convergence on that have truth: 157 frames of 2 cm and one of 15 cm.
    n = FRAMES - CONVERGE_FRAME - 2
    expected = 100.0 * math.sqrt(((n - 1) * 0.02 ** 2 + 0.15 ** 2) / n)
    check(abs(float(row1["ate_cm"]) - expected) < 1e-2,
          "seed 1 ATE %.3f cm expected, got %s" % (expected, row1["ate_cm"]))
    check(row1["success"] == "1", "seed 1 succeeds (last 100 frames below 10 cm)")
    check(row2["converged"] == "0" and row2["success"] == "0", "seed 2 never converges")
    with open(os.path.join(out, "summary.md")) as f:
        md = f.read()
    check("| all |" in md and "1/2" in md, "summary.md has the overall row with 1/2 successes")

    # An existing summary (replay's own) is kept unless asked.
    with open(os.path.join(out, "summary.md"), "w") as f:
        f.write("replay's table\n")
    run([os.path.join(SCRIPTS, "plot_replay.py"), out, "--dpi", "40"])
    with open(os.path.join(out, "summary.md")) as f:
        check(f.read() == "replay's table\n", "an existing summary.md is kept")
    run([os.path.join(SCRIPTS, "plot_replay.py"), out, "--rewrite-summary", "--dpi", "40"])
    with open(os.path.join(out, "summary.md")) as f:
        check("| all |" in f.read(), "--rewrite-summary rewrites it")

    empty = os.path.join(work, "empty")
    os.makedirs(empty)
    check(run([os.path.join(SCRIPTS, "plot_replay.py"), empty]) != 0,
          "a folder without trials is an error")


def test_figures(work):
    out = os.path.join(work, "figures")
    os.makedirs(out)
    rows = ["axis,offset,unit,pixels,approx_nll,exact_nll,approx_nll_per_px,exact_nll_per_px,"
            "approx_floor_hits,exact_floor_hits,approx_evaluations,exact_evaluations"]
    for axis in ("x", "y", "z", "yaw"):
        for k in range(-10, 11):
            off = 0.05 * k
            ex = 1000.0 * (0.3 + min(9.0, 20 * off * off))
            ap = ex + 3.0 * abs(k)
            rows.append("%s,%g,%s,1000,%g,%g,%g,%g,0,0,15000,1000000" % (
                axis, off, "rad" if axis == "yaw" else "m", ap, ex, ap / 1000, ex / 1000))
    with open(os.path.join(out, "nll_sweep.csv"), "w") as f:
        f.write("\n".join(rows) + "\n")
    with open(os.path.join(out, "nll_sweep.txt"), "w") as f:
        f.write("scene=fixture\nframe=0\ncomponents=1000\nstride_px=8\npixels=1000\n")
    summary = ["sweep,value,runs,frames,variance_kl,log10_variance_kl,pooled_variance_kl,mean_kl,"
               "median_kl,mean_error_m,mean_step_ms"]
    for n in (50, 100, 200, 500, 1068):
        v = 100.0 / n
        summary.append("particles,%d,5,30,%g,%g,%g,%g,%g,0.02,%g" % (n, v, math.log10(v), v, 3 * v,
                                                                      2 * v, n * 0.05))
    summary.append("particles,16200,1,30,,,,,,0.015,800")
    for m in (50, 250, 1000):
        v = 10.0 / m
        summary.append("components,%d,5,30,%g,%g,%g,%g,%g,0.03,%g" % (m, v, math.log10(v), v, v, v, 50))
    summary.append("components,2500,1,30,,,,,,0.015,800")
    with open(os.path.join(out, "sensitivity_summary.csv"), "w") as f:
        f.write("\n".join(summary) + "\n")
    with open(os.path.join(out, "sensitivity.txt"), "w") as f:
        f.write("scene=fixture\nruns=5\nframes=60\neval_from=30\nstride_px=16\ninit=local\n"
                "reference_particles=16200\nreference_components=2500\n")
    rc = run([os.path.join(SCRIPTS, "plot_figures.py"), out])
    check(rc == 0, "plot_figures.py exits 0 (got %d)" % rc)
    check_png(os.path.join(out, "nll_sweep.png"))
    check_png(os.path.join(out, "sensitivity.png"))


def main():
    try:
        import matplotlib  # noqa: F401
    except ImportError as e:
        print("SKIPPED: matplotlib is missing (%s): install python3-matplotlib" % e)
        return 77
    work = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.getcwd(), "plot_scripts_test")
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    test_replay(work)
    test_figures(work)
    print("%d failure(s)" % len(failures))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

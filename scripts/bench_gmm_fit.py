#!/usr/bin/env python3
"""Benchmark: gmm_mcl_fit against scikit-learn's GaussianMixture on the stitched 7-Scenes cloud.

Both fit the same training points (default 100k drawn from the stitched redkitchen cloud, M=1000,
full covariance) with the same tolerance, reg_covar and iteration cap, one after the other in
this run on this machine; then both maps are scored by sklearn's GaussianMixture.score on the
same held-out points (drawn from the rest of the cloud). gmm_mcl_fit's map is read back from its
float32 file. Prints both wall times, the ratio, train and held-out mean log-likelihoods, and
the map file size. sklearn with M=1000 on 100k points takes many minutes: run it in the
background and read the log.

Run with the Debian python (it has numpy and sklearn): /usr/bin/python3 scripts/bench_gmm_fit.py
"""
import argparse
import json
import os
import platform
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import sklearn_common as sc  # noqa: E402


def cpu_name():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--gmm-fit", default=os.path.join(HERE, "..", "build-fit", "gmm_mcl_fit"))
    ap.add_argument("--datasets", default=None,
                    help="data sets root (default $GMM_MCL_DATASETS or ../shared/datasets)")
    ap.add_argument("--cloud", default=None, help="stitched cloud .pcd (default: build it)")
    ap.add_argument("--work", default="/tmp/gmm_fit_bench")
    ap.add_argument("--points", type=int, default=100000)
    ap.add_argument("--holdout", type=int, default=20000)
    ap.add_argument("--components", type=int, default=1000)
    ap.add_argument("--max-iter", type=int, default=30)
    ap.add_argument("--tol", type=float, default=1e-3)
    ap.add_argument("--reg-covar", type=float, default=1e-6)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--sklearn-init", default="kmeans", choices=["kmeans", "k-means++"],
                    help="sklearn init_params (its default is kmeans)")
    ap.add_argument("--skip-sklearn", action="store_true", help="time gmm_mcl_fit only")
    args = ap.parse_args()

    import sklearn
    from sklearn.mixture import GaussianMixture

    os.makedirs(args.work, exist_ok=True)
    cloud_path = args.cloud
    if cloud_path is None:
        data = os.path.join(sc.datasets_dir(args.datasets), "7scenes_redkitchen", "data")
        if not os.path.isdir(data):
            print("SKIP: 7-Scenes data not found at %s" % data)
            return 77
        cloud_path = os.path.join(args.work, "7scenes_redkitchen_2cm.pcd")
        if not os.path.exists(cloud_path):
            subprocess.run([args.gmm_fit, "--7scenes", data, "--save-cloud", cloud_path, "-q"],
                           check=True)
    cloud = sc.read_pcd(cloud_path)
    rng = np.random.default_rng(args.seed)
    idx = rng.permutation(len(cloud))
    if args.points + args.holdout > len(cloud):
        sys.exit("cloud has %d points, fewer than %d + %d" % (len(cloud), args.points,
                                                             args.holdout))
    train = cloud[idx[:args.points]]
    test = cloud[idx[args.points:args.points + args.holdout]]
    train64, test64 = train.astype(np.float64), test.astype(np.float64)
    train_pcd = os.path.join(args.work, "train.pcd")
    sc.write_pcd(train_pcd, train)

    print("machine: %s, %d CPUs (os.cpu_count); python %s, numpy %s, scikit-learn %s"
          % (cpu_name(), os.cpu_count(), platform.python_version(), np.__version__,
             sklearn.__version__))
    print("data: %s, %d points; train %d, held-out %d (disjoint, seed %d)"
          % (cloud_path, len(cloud), len(train), len(test), args.seed))
    print("fit: M=%d full covariance, tol %g, reg_covar %g, max_iter %d (both)"
          % (args.components, args.tol, args.reg_covar, args.max_iter))
    sys.stdout.flush()

    map_path = os.path.join(args.work, "bench.gmm")
    stats_path = os.path.join(args.work, "bench.json")
    cmd = [args.gmm_fit, train_pcd, "-o", map_path, "-m", str(args.components),
           "--max-iter", str(args.max_iter), "--tol", repr(args.tol), "--reg-covar",
           repr(args.reg_covar), "--seed", str(args.seed), "--stats-json", stats_path, "-q"]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True)
    ours_wall = time.perf_counter() - t0
    with open(stats_path) as f:
        st = json.load(f)
    ours_train, ours_test = sc.map_score(map_path, train64), sc.map_score(map_path, test64)
    size = os.path.getsize(map_path)
    print("gmm_mcl_fit : %7.2f s wall (process; init %.2f s, EM+init %.2f s), %d iterations, "
          "converged %s, %d threads" % (ours_wall, st["init_s"], st["total_s"], st["iterations"],
                                        st["converged"], st["threads"]))
    print("          mean LL train %.5f  held-out %.5f; map %d bytes" % (ours_train, ours_test,
                                                                        size))
    sys.stdout.flush()
    if args.skip_sklearn:
        return 0

    gm = GaussianMixture(args.components, covariance_type="full", tol=args.tol,
                         reg_covar=args.reg_covar, max_iter=args.max_iter,
                         init_params=args.sklearn_init, random_state=args.seed)
    t0 = time.perf_counter()
    gm.fit(train64)
    sk_wall = time.perf_counter() - t0
    sk_train, sk_test = gm.score(train64), gm.score(test64)
    print("sklearn : %7.2f s wall (fit, init_params=%s), %d iterations, converged %s"
          % (sk_wall, args.sklearn_init, gm.n_iter_, gm.converged_))
    print("          mean LL train %.5f  held-out %.5f" % (sk_train, sk_test))
    ratio = sk_wall / ours_wall
    rel = (ours_test - sk_test) / abs(sk_test)
    print("speed-up: %.1fx (sklearn wall / gmm_mcl_fit wall; target >= 20x)  %s"
          % (ratio, "OK" if ratio >= 20 else "MISSED"))
    print("held-out: gmm_mcl_fit - sklearn = %+.5f nats/point (%+.2f %% of |sklearn|; target >= "
          "-0.5 %%)  %s" % (ours_test - sk_test, 100 * rel, "OK" if rel >= -0.005 else "MISSED"))
    print("map size: %d bytes for M=%d (paper: 40 KB)  %s"
          % (size, args.components, "OK" if size <= 40 * 1024 else "MISSED"))
    return 0


if __name__ == "__main__":
    sys.exit(main())

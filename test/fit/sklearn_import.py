#!/usr/bin/env python3
"""scikit-learn GaussianMixture -> scripts/sklearn_to_gmm_csv.py -> gmm_mcl_fit --import -> map file:
for every covariance type, the map's weights, means and covariances (read back through
gmm_mcl_inspect --csv) equal scikit-learn's to float32 precision, and the mixture's log-density at
held-out points agrees. usage: sklearn_import.py GMM_FIT GMM_INSPECT WORK_DIR (exit 77: no sklearn)
"""
import csv
import os
import pickle
import subprocess
import sys

try:
    import numpy as np
    from sklearn.mixture import GaussianMixture
except ImportError as e:
    print("SKIP: %s" % e)
    sys.exit(77)

gmm_mcl_fit, gmm_mcl_inspect, work = sys.argv[1:4]
os.makedirs(work, exist_ok=True)
root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
script = os.path.join(root, "scripts", "sklearn_to_gmm_csv.py")
rng = np.random.default_rng(3)
# A small room-like cloud: two walls and a floor with 5 mm noise, metres.
pts = np.concatenate([
    np.c_[rng.uniform(0, 4, 3000), np.zeros(3000), rng.uniform(0, 2.5, 3000)],
    np.c_[np.zeros(3000), rng.uniform(0, 3, 3000), rng.uniform(0, 2.5, 3000)],
    np.c_[rng.uniform(0, 4, 3000), rng.uniform(0, 3, 3000), np.zeros(3000)]])
pts += rng.normal(0, 0.005, pts.shape)
held = pts[rng.choice(len(pts), 200, replace=False)]
worst = 0.0
for kind in ("full", "tied", "diag", "spherical"):
    gm = GaussianMixture(20, covariance_type=kind, random_state=1, max_iter=50).fit(pts)
    model = os.path.join(work, "gm_%s.pkl" % kind)
    with open(model, "wb") as f:
        pickle.dump(gm, f)
    csv_in = os.path.join(work, "gm_%s.csv" % kind)
    gmm = os.path.join(work, "gm_%s.gmm" % kind)
    csv_out = os.path.join(work, "gm_%s_back.csv" % kind)
    subprocess.run([sys.executable, script, model, csv_in], check=True)
    subprocess.run([gmm_mcl_fit, "--import", csv_in, "-o", gmm, "-q"], check=True)
    subprocess.run([gmm_mcl_inspect, gmm, "--csv", csv_out], check=True, stdout=subprocess.DEVNULL)
    rows = list(csv.DictReader(open(csv_out)))
    w = np.array([float(r["weight"]) for r in rows])
    mu = np.array([[float(r[k]) for k in ("mean_x_m", "mean_y_m", "mean_z_m")] for r in rows])
    cov = np.array([[[float(r["cov_%s%s_m2" % tuple(sorted(a + b, key="xyz".index))])
                      for b in "xyz"] for a in "xyz"] for r in rows])
    full = {"full": lambda c: c,
            "tied": lambda c: np.repeat(c[None], 20, 0),
            "diag": lambda c: np.stack([np.diag(v) for v in c]),
            "spherical": lambda c: np.stack([np.eye(3) * v for v in c])}[kind](gm.covariances_)
    assert np.allclose(w, gm.weights_, rtol=1e-6, atol=1e-7), kind
    assert np.allclose(mu, gm.means_, rtol=1e-6, atol=1e-6), kind
    assert np.allclose(cov, full, rtol=1e-5, atol=1e-10), kind
    # Log-density of held-out points from the imported parameters against scikit-learn's.
    d = held[:, None, :] - mu[None]
    inv = np.linalg.inv(cov)
    maha = np.einsum("nki,kij,nkj->nk", d, inv, d)
    logn = np.log(w) - 1.5 * np.log(2 * np.pi) - 0.5 * np.log(np.linalg.det(cov))
    ours = np.logaddexp.reduce(logn[None] - 0.5 * maha, axis=1)
    diff = np.max(np.abs(ours - gm.score_samples(held)))
    worst = max(worst, diff)
    print("[ measured ] %s: parameters equal to float32, worst log-density difference %.2e" % (kind, diff))
assert worst < 1e-3, worst
# A bad file is an error naming the fault, never a map.
bad = os.path.join(work, "bad.csv")
open(bad, "w").write("weight,mean_x_m,mean_y_m,mean_z_m,cov_xx_m2,cov_xy_m2,cov_xz_m2,cov_yy_m2,"
                     "cov_yz_m2,cov_zz_m2\n1,0,0,0,1,0,0,-1,0,1\n")
r = subprocess.run([gmm_mcl_fit, "--import", bad, "-o", os.path.join(work, "bad.gmm")],
                   capture_output=True, text=True)
assert r.returncode != 0 and "positive-definite" in r.stderr, r.stderr
print("OK")

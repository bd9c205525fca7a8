#!/usr/bin/env python3
"""gmm_mcl_fit agrees with scikit-learn's GaussianMixture (the oracle) on the same data and the
same initial parameters: final mean log-likelihood per point within 1 % on the training points
and on held-out points.

Data: a synthetic room (floor, two walls, a table top and legs, a pillar) sampled with 3 mm
noise, 20,000 training and 5,000 held-out points, M = 50. Initial means: 50 training points
chosen by a fixed seed; both fitters then assign every point to its nearest mean to get the
first weights and covariances (sklearn: weights_init, means_init and precisions_init computed
that way). Same tol (1e-3), reg_covar (1e-6) and iteration cap (300) for both. Both maps are
scored by sklearn's GaussianMixture.score; gmm_mcl_fit's map is read back from its float32 file.

Exit codes: 0 pass, 1 fail, 77 skipped (numpy or sklearn missing), as ctest SKIP_RETURN_CODE.

usage: sklearn_agreement.py GMM_FIT WORK_DIR
"""
import json
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "scripts"))

try:
    import numpy as np
    import sklearn
    from sklearn.mixture import GaussianMixture
except ImportError as e:  # the oracle is optional at build time; say so and skip
    print("SKIP: scikit-learn oracle unavailable in %s (%s); install python3-sklearn"
          % (sys.executable, e))
    sys.exit(77)

import sklearn_common as sc  # noqa: E402

N_TRAIN, N_TEST, M = 20000, 5000, 50
TOL, REG, MAX_ITER = 1e-3, 1e-6, 300
REL_TOL = 0.01  # 1 %


def synthetic_room(n, rng):
    """Points on the surfaces of a 4 x 3 x 2.5 m room corner with furniture, 3 mm noise."""
    def plane(count, origin, u, v):
        a, b = rng.random((count, 1)), rng.random((count, 1))
        return origin + a * u + b * v

    parts = [
        plane(n * 40 // 100, np.array([0, 0, 0.0]), np.array([4, 0, 0.0]), np.array([0, 3, 0.0])),
        plane(n * 20 // 100, np.array([0, 0, 0.0]), np.array([4, 0, 0.0]), np.array([0, 0, 2.5])),
        plane(n * 15 // 100, np.array([0, 0, 0.0]), np.array([0, 3, 0.0]), np.array([0, 0, 2.5])),
        plane(n * 10 // 100, np.array([1.5, 1, 0.75]), np.array([1.2, 0, 0.0]),
              np.array([0, 0.8, 0.0])),
    ]
    legs = []
    for x, y in [(1.55, 1.05), (2.65, 1.05), (1.55, 1.75), (2.65, 1.75)]:
        legs.append(plane(n * 1 // 100, np.array([x, y, 0.0]), np.array([0.04, 0, 0.0]),
                          np.array([0, 0, 0.75])))
    k = n - sum(len(p) for p in parts + legs)
    th, z = rng.random(k) * 2 * np.pi, rng.random(k) * 2.5
    pillar = np.stack([3.3 + 0.15 * np.cos(th), 2.4 + 0.15 * np.sin(th), z], axis=1)
    pts = np.concatenate(parts + legs + [pillar])
    pts += rng.normal(0.0, 0.003, pts.shape)
    return pts[rng.permutation(len(pts))].astype(np.float32)


def run_gmm_fit(gmm_mcl_fit, work, name, extra):
    out = os.path.join(work, name + ".gmm")
    stats = os.path.join(work, name + ".json")
    cmd = [gmm_mcl_fit, os.path.join(work, "train.pcd"), "-o", out, "-m", str(M),
           "--init-means", os.path.join(work, "means.xyz"), "--tol", repr(TOL),
           "--reg-covar", repr(REG), "--max-iter", str(MAX_ITER), "-q",
           "--stats-json", stats] + extra
    t0 = time.time()
    subprocess.run(cmd, check=True)
    wall = time.time() - t0
    with open(stats) as f:
        return out, json.load(f), wall


def main():
    if len(sys.argv) != 3:
        print(__doc__)
        return 2
    gmm_mcl_fit, work = sys.argv[1], sys.argv[2]
    os.makedirs(work, exist_ok=True)
    rng = np.random.default_rng(20180618)
    pts = synthetic_room(N_TRAIN + N_TEST, rng)
    train, test = pts[:N_TRAIN], pts[N_TRAIN:]
    means = train[rng.choice(N_TRAIN, M, replace=False)]
    sc.write_pcd(os.path.join(work, "train.pcd"), train)
    np.savetxt(os.path.join(work, "means.xyz"), means.astype(np.float64), fmt="%.9g")
    train64, test64 = train.astype(np.float64), test.astype(np.float64)

    print("oracle: scikit-learn %s, numpy %s (%s)" % (sklearn.__version__, np.__version__,
                                                     sys.executable))
    weights0, precisions0 = sc.hard_assignment_init(train64, means, REG)
    t0 = time.time()
    gm = GaussianMixture(M, covariance_type="full", tol=TOL, reg_covar=REG, max_iter=MAX_ITER,
                         weights_init=weights0, means_init=means.astype(np.float64),
                         precisions_init=precisions0, random_state=0).fit(train64)
    sk_wall = time.time() - t0
    sk_train, sk_test = gm.score(train64), gm.score(test64)
    print("sklearn  : %3d iterations, converged %s, %.2f s; mean LL train %.6f held-out %.6f"
          % (gm.n_iter_, gm.converged_, sk_wall, sk_train, sk_test))

    ok = True
    for name, extra in [("pruned", []), ("exact", ["--prune-sigma", "0"])]:
        out, st, wall = run_gmm_fit(gmm_mcl_fit, work, name, extra)
        tr, te = sc.map_score(out, train64), sc.map_score(out, test64)
        rel_tr = abs(tr - sk_train) / abs(sk_train)
        rel_te = abs(te - sk_test) / abs(sk_test)
        print("gmm_mcl_fit %-6s: %3d iterations, converged %s, %.2f s; mean LL train %.6f held-out "
              "%.6f; relative difference train %.2e held-out %.2e"
              % (name, st["iterations"], st["converged"], wall, tr, te, rel_tr,
                 rel_te))
        ok = ok and rel_tr <= REL_TOL and rel_te <= REL_TOL
    print("PASS" if ok else "FAIL: a relative difference exceeds %.1f %%" % (100 * REL_TOL))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

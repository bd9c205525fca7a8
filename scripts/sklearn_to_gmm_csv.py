#!/usr/bin/env python3
"""A scikit-learn GaussianMixture as the CSV that `gmm_mcl_fit --import` reads.

usage: scripts/sklearn_to_gmm_csv.py MODEL OUT.csv

MODEL: a pickled or joblib-saved sklearn.mixture.GaussianMixture (.pkl, .pickle, .joblib), or
an .npz with arrays weights (M), means (M x 3) and covariances in any of scikit-learn's
covariance types (full: M x 3 x 3, tied: 3 x 3, diag: M x 3, spherical: M), with the type in
an array named covariance_type when it is not full. Means and covariances in metres, in the
map frame. Then: gmm_mcl_fit --import OUT.csv -o MAP.gmm (validated there: positive weights summing
to 1, positive-definite covariances).
"""
import sys

import numpy as np


def full_covariances(cov, kind, m):
    cov = np.asarray(cov, dtype=float)
    if kind == "full":
        return cov.reshape(m, 3, 3)
    if kind == "tied":
        return np.repeat(cov.reshape(1, 3, 3), m, axis=0)
    if kind == "diag":
        return np.stack([np.diag(c) for c in cov.reshape(m, 3)])
    if kind == "spherical":
        return np.stack([np.eye(3) * c for c in cov.reshape(m)])
    raise ValueError("unknown covariance_type '%s'" % kind)


def load(path):
    if path.endswith(".npz"):
        z = np.load(path)
        kind = str(z["covariance_type"]) if "covariance_type" in z else "full"
        return np.asarray(z["weights"], float), np.asarray(z["means"], float), z["covariances"], kind
    if path.endswith(".joblib"):
        import joblib
        model = joblib.load(path)
    else:
        import pickle
        with open(path, "rb") as f:
            model = pickle.load(f)
    for attr in ("weights_", "means_", "covariances_", "covariance_type"):
        if not hasattr(model, attr):
            raise ValueError("%s: not a fitted GaussianMixture (no %s)" % (path, attr))
    return (np.asarray(model.weights_, float), np.asarray(model.means_, float),
            model.covariances_, model.covariance_type)


def main():
    if len(sys.argv) != 3:
        sys.stderr.write(__doc__)
        return 2
    try:
        w, mu, cov, kind = load(sys.argv[1])
        if mu.ndim != 2 or mu.shape[1] != 3 or w.shape != (mu.shape[0],):
            raise ValueError("%s: expected M weights and M x 3 means, got %s and %s"
                             % (sys.argv[1], w.shape, mu.shape))
        cov = full_covariances(cov, kind, mu.shape[0])
    except Exception as e:  # the message names the fault
        sys.stderr.write("sklearn_to_gmm_csv: %s\n" % e)
        return 1
    with open(sys.argv[2], "w") as out:
        out.write("weight,mean_x_m,mean_y_m,mean_z_m,cov_xx_m2,cov_xy_m2,cov_xz_m2,cov_yy_m2,"
                  "cov_yz_m2,cov_zz_m2\n")
        for k in range(mu.shape[0]):
            c = cov[k]
            vals = [w[k], mu[k, 0], mu[k, 1], mu[k, 2], c[0, 0], c[0, 1], c[0, 2], c[1, 1],
                    c[1, 2], c[2, 2]]
            out.write(",".join("%.17g" % v for v in vals) + "\n")
    print("wrote %s: %d components (%s covariances)" % (sys.argv[2], mu.shape[0], kind))
    return 0


if __name__ == "__main__":
    sys.exit(main())

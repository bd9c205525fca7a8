"""Shared helpers for the map builder's scikit-learn comparisons (agreement test, benchmark).

Reads and writes binary PCD clouds, reads gmm_mcl map files (validating magic, size and CRC),
and turns a map into a fitted sklearn GaussianMixture so that both models are scored by the
same oracle code (GaussianMixture.score: mean log-likelihood per point, nats, density per m^3).
"""
import os
import struct
import zlib

import numpy as np

MAP_MAGIC = b"GMMMCL\x00\x1a"


def write_pcd(path, points):
    pts = np.ascontiguousarray(points, dtype="<f4")
    header = (
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\n"
        "SIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH %d\nHEIGHT 1\n"
        "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\nDATA binary\n" % (len(pts), len(pts)))
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(pts.tobytes())


def read_pcd(path):
    """Reads a PCD with float32 x y z as its first fields, binary or ascii."""
    with open(path, "rb") as f:
        data = f.read()
    pos = 0
    fields, sizes, points, kind = None, None, None, None
    while kind is None:
        end = data.index(b"\n", pos)
        line = data[pos:end].decode("ascii").strip()
        pos = end + 1
        tok = line.split()
        if not tok or tok[0].startswith("#"):
            continue
        key = tok[0].upper()
        if key == "FIELDS":
            fields = tok[1:]
        elif key == "SIZE":
            sizes = [int(t) for t in tok[1:]]
        elif key == "POINTS":
            points = int(tok[1])
        elif key == "DATA":
            kind = tok[1]
    if fields[:3] != ["x", "y", "z"] or sizes[:3] != [4, 4, 4]:
        raise ValueError("%s: expected float32 x y z as the first fields" % path)
    if kind == "binary":
        rec = sum(sizes)
        raw = np.frombuffer(data[pos:pos + rec * points], dtype=np.uint8).reshape(points, rec)
        return raw[:, :12].copy().view("<f4").reshape(points, 3)
    if kind == "ascii":
        return np.loadtxt(data[pos:].decode("ascii").splitlines(), usecols=(0, 1, 2),
                          dtype=np.float32).reshape(-1, 3)
    raise ValueError("%s: unsupported DATA %s" % (path, kind))


def read_map(path):
    """Returns (weights (M,), means (M,3), covariances (M,3,3)) as float64 from a map file."""
    with open(path, "rb") as f:
        b = f.read()
    if b[:8] != MAP_MAGIC:
        raise ValueError("%s: bad magic" % path)
    version, count, scalar, _ = struct.unpack_from("<4I", b, 8)
    if version != 1 or scalar != 1:
        raise ValueError("%s: unsupported version %d / scalar %d" % (path, version, scalar))
    if len(b) != 24 + 40 * count + 4:
        raise ValueError("%s: size %d does not match %d components" % (path, len(b), count))
    (crc,) = struct.unpack_from("<I", b, len(b) - 4)
    if crc != zlib.crc32(b[:-4]) & 0xFFFFFFFF:
        raise ValueError("%s: checksum mismatch" % path)
    off = 24
    w = np.frombuffer(b, "<f4", count, off).astype(np.float64)
    off += 4 * count
    mu = np.frombuffer(b, "<f4", 3 * count, off).astype(np.float64).reshape(count, 3)
    off += 12 * count
    u = np.frombuffer(b, "<f4", 6 * count, off).astype(np.float64).reshape(count, 6)
    cov = np.empty((count, 3, 3))
    idx = [(0, 0, 0), (1, 0, 1), (2, 0, 2), (3, 1, 1), (4, 1, 2), (5, 2, 2)]
    for k, i, j in idx:
        cov[:, i, j] = u[:, k]
        cov[:, j, i] = u[:, k]
    return w, mu, cov


def gmm_from_params(weights, means, covariances):
    """A fitted sklearn GaussianMixture holding the given full-covariance parameters."""
    from sklearn.mixture import GaussianMixture

    gm = GaussianMixture(n_components=len(weights), covariance_type="full")
    gm.weights_ = np.asarray(weights, dtype=np.float64)
    gm.means_ = np.asarray(means, dtype=np.float64)
    gm.covariances_ = np.asarray(covariances, dtype=np.float64)
    chol = np.linalg.cholesky(gm.covariances_)
    eye = np.eye(3)
    gm.precisions_cholesky_ = np.stack(
        [np.linalg.solve(c, eye).T for c in chol])  # upper-triangular L^-T, as sklearn stores
    gm.precisions_ = gm.precisions_cholesky_ @ np.transpose(gm.precisions_cholesky_, (0, 2, 1))
    gm.converged_ = True
    gm.n_iter_ = 0
    gm.lower_bound_ = -np.inf
    return gm


def map_score(map_path, points):
    """Mean log-likelihood per point of a gmm_mcl map file, scored by sklearn."""
    return gmm_from_params(*read_map(map_path)).score(np.asarray(points, dtype=np.float64))


def hard_assignment_init(points, means, reg_covar):
    """weights, precisions from assigning every point to its nearest mean (what gmm_mcl_fit
    --init-means does, and what sklearn's _initialize does with one-hot responsibilities)."""
    from sklearn.mixture._gaussian_mixture import _estimate_gaussian_parameters

    x = np.asarray(points, dtype=np.float64)
    mu = np.asarray(means, dtype=np.float64)
    d2 = ((x * x).sum(1)[:, None] - 2.0 * x @ mu.T + (mu * mu).sum(1)[None, :])
    labels = np.argmin(d2, axis=1)
    resp = np.zeros((len(x), len(mu)))
    resp[np.arange(len(x)), labels] = 1.0
    weights, _, covs = _estimate_gaussian_parameters(x, resp, reg_covar, "full")
    weights /= len(x)
    precisions = np.linalg.inv(covs)
    return weights, 0.5 * (precisions + np.transpose(precisions, (0, 2, 1)))


def datasets_dir(arg=None):
    """The shared data sets: argument, then $GMM_MCL_DATASETS, then ../shared/datasets."""
    if arg:
        return arg
    env = os.environ.get("GMM_MCL_DATASETS")
    if env:
        return env
    here = os.path.dirname(os.path.abspath(__file__))
    return os.path.normpath(os.path.join(here, "..", "..", "shared", "datasets"))

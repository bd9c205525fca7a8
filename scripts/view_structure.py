#!/usr/bin/env python3
"""What a depth sequence's frames show besides the floor and the ceiling.

A frame whose pixels within the filter's range all lie on the floor (or the ceiling) pins the
camera's height, roll and pitch but not x, y or yaw: no localizer can tell two places apart on
it. This counts, per sampled frame of a TUM RGB-D folder with ground truth (the layout that
`gmm_mcl_render` and `scripts/make_building.sh` write; depth PNGs at 5000 units per metre), the
pixels within [--min-range, --max-range] and those of them whose point, put into the world by
the ground-truth camera pose, lies off the floor and the ceiling planes (the world's z up).

usage: scripts/view_structure.py DIR [--every N] [--stride PX] [--max-range M] [--min-range M]
                                     [--floor-z Z] [--ceiling-z Z] [--seconds S]
Prints one line per sampled frame (time, pixels in range, of them off floor and ceiling) and
the time within the first S seconds during which fewer than 1 % of the pixels are off them.
"""
import argparse
import os
import sys

import numpy as np
from PIL import Image


def read_list(path):
    rows = []
    with open(path) as f:
        for line in f:
            if line.startswith('#') or not line.strip():
                continue
            rows.append(line.split())
    return rows


def rotation(qx, qy, qz, qw):
    n = np.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    x, y, z, w = qx / n, qy / n, qz / n, qw / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('dir')
    ap.add_argument('--every', type=int, default=10, help='every N-th frame (10)')
    ap.add_argument('--stride', type=int, default=8, help='pixel stride (8)')
    ap.add_argument('--min-range', type=float, default=0.1, help='metres (0.1)')
    ap.add_argument('--max-range', type=float, default=4.0, help='metres (4, the filter default)')
    ap.add_argument('--floor-z', type=float, default=0.0, help='the floor plane (0)')
    ap.add_argument('--ceiling-z', type=float, default=3.0, help='the ceiling plane (3)')
    ap.add_argument('--margin', type=float, default=0.05, help='metres off a plane (0.05)')
    ap.add_argument('--seconds', type=float, default=10.0, help='summary window (10)')
    a = ap.parse_args()
    for name in ('depth.txt', 'groundtruth.txt', 'intrinsics.txt'):
        if not os.path.isfile(os.path.join(a.dir, name)):
            sys.exit(f'view_structure: {a.dir} has no {name} (a TUM folder with ground truth)')
    fx, fy, cx, cy, width, height = [float(v) for v in read_list(
        os.path.join(a.dir, 'intrinsics.txt'))[0][:6]]
    depth = read_list(os.path.join(a.dir, 'depth.txt'))
    truth = read_list(os.path.join(a.dir, 'groundtruth.txt'))
    t_truth = np.array([float(r[0]) for r in truth])
    v, u = np.mgrid[0:int(height):a.stride, 0:int(width):a.stride]
    t0 = float(depth[0][0])
    bare = 0.0
    print('# time_s pixels_in_range off_floor_and_ceiling')
    for i in range(0, len(depth), a.every):
        t = float(depth[i][0])
        pose = truth[int(np.argmin(np.abs(t_truth - t)))]
        d = np.asarray(Image.open(os.path.join(a.dir, depth[i][1])), dtype=float)
        d = d[::a.stride, ::a.stride] / 5000.0
        ok = (d > a.min_range) & (d < a.max_range)
        z = d[ok]
        cam = np.stack([(u[ok] - cx) / fx * z, (v[ok] - cy) / fy * z, z], axis=1)
        R = rotation(*[float(q) for q in pose[4:8]])
        wz = cam @ R[2] + float(pose[3])
        off = int(np.count_nonzero((wz > a.floor_z + a.margin) & (wz < a.ceiling_z - a.margin)))
        print(f'{t - t0:.2f} {int(ok.sum())} {off}')
        if t - t0 < a.seconds and off < 0.01 * u.size:
            bare += a.every * (float(depth[1][0]) - t0 if len(depth) > 1 else 0.0)
    print(f'# {a.dir}: {bare:.1f} s of the first {a.seconds:g} s with fewer than 1 % of the '
          f'pixels off the floor and the ceiling')


if __name__ == '__main__':
    main()

#!/usr/bin/env python3
"""Simulated USBL/GNSS fixes for `sonar3d map --fixes` (docs/mapping.md, issue 26).

Reads a simulated dataset's true navigation (DATASET/truth/navigation.tum, TUM:
t x y z qx qy qz qw), samples it every --every seconds and adds Gaussian noise of --sigma metres
per axis (seeded), optionally a gross outlier (--outlier METRES added to one fix, east), and
writes the fixes CSV `time_s,x_m,y_m[,z_m],sigma_m`.

  python3 bench/fixes_from_truth.py field/ -o fixes.csv --every 10 --sigma 1 --outlier 25
"""
import argparse
import bisect
import os
import random
import sys


def read_tum(path):
    t, p = [], []
    with open(path) as f:
        for line in f:
            s = line.strip()
            if not s or s.startswith('#'):
                continue
            v = [float(x) for x in s.split()]
            t.append(v[0])
            p.append(v[1:4])
    return t, p


def interpolate(t, p, x):
    k = bisect.bisect_left(t, x)
    if k <= 0:
        return p[0]
    if k >= len(t):
        return p[-1]
    w = (x - t[k - 1]) / (t[k] - t[k - 1])
    return [a + w * (b - a) for a, b in zip(p[k - 1], p[k])]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument('dataset')
    ap.add_argument('-o', '--output', required=True)
    ap.add_argument('--every', type=float, default=10.0, help='seconds between fixes')
    ap.add_argument('--sigma', type=float, default=1.0, help='noise per axis, metres')
    ap.add_argument('--outlier', type=float, default=0.0,
                    help='metres added (east) to the fix in the middle of the survey; 0: none')
    ap.add_argument('--z', action='store_true', help='write z_m as well')
    ap.add_argument('--seed', type=int, default=1)
    a = ap.parse_args()
    if os.path.exists(a.output):
        sys.exit(f'{a.output} exists: choose a new name')
    t, p = read_tum(os.path.join(a.dataset, 'truth', 'navigation.tum'))
    rng = random.Random(a.seed)
    times = []
    x = t[0] + a.every / 2
    while x <= t[-1]:
        times.append(x)
        x += a.every
    mid = len(times) // 2
    with open(a.output + '.tmp', 'w') as f:
        f.write('time_s,x_m,y_m' + (',z_m' if a.z else '') + ',sigma_m\n')
        for k, tt in enumerate(times):
            q = interpolate(t, p, tt)
            q = [c + rng.gauss(0.0, a.sigma) for c in q]
            if a.outlier and k == mid:
                q[0] += a.outlier
            cols = q if a.z else q[:2]
            f.write(f'{tt:.3f},' + ','.join(f'{c:.4f}' for c in cols) + f',{a.sigma:g}\n')
    os.replace(a.output + '.tmp', a.output)
    print(f'{len(times)} fixes every {a.every:g} s, sigma {a.sigma:g} m'
          + (f', outlier of {a.outlier:g} m at t = {times[mid]:.3f} s' if a.outlier else '')
          + f' -> {a.output}')


if __name__ == '__main__':
    main()

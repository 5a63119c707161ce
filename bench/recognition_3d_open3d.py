#!/usr/bin/env python3
"""Open3D's global registration (FPFH + RANSAC, FGR) against sonar3d's 3D method (issue 28).

Benchmark only (docs/recognition.md "Global registration: Open3D measured"): needs Debian's
python3-open3d 0.16 (`apt-get install -y python3-open3d`, run with /usr/bin/python3) and the
sonar3d Python module (build/python) to read the catalogue's meshes as sonar3d does. Neither the
build nor the tests need Open3D.

    /usr/bin/python3 bench/recognition_3d_open3d.py WORK RUNS OUT [FIELDS...] [--max-regions N]

WORK: the benchmark of bench/recognition_fields.sh (fields.json, <field>_cloud.ply or _map.ply,
<field>_catalogue.yaml); RUNS: a folder of WORK holding the 3D method's <field>.3d.json (its
placements and rejected candidates give the candidate regions); OUT: where the per-field JSON and
the Markdown table go.

Per field: the seabed is removed as the 3D method does (a per-cell ground, points below it + 5 cm
dropped), the rest subsampled to 3 cm voxels (the thesis' subsampling), normals (radius 6 cm) and
FPFH features (radius 15 cm) computed once over the field. Per catalogue model (meshes sampled to
points, the samples a survey from above can see: normals not pointing down, above the base + 5
cm; reference models without a mesh are skipped): the candidate regions are the 3D method's
placements and candidates of that model, one per cell of max(r_model, 0.5 m), the most confident
first, at most --max-regions; each region holds the scene points within r_model + 0.4 m
(horizontally) of the candidate's model centre. In each region: FPFH + RANSAC (100,000
iterations, 0.999) and FGR, each refined by point-to-plane ICP (6 cm), without any orientation
prior. A registration is accepted when its ICP fitness (the fraction of the model's seen samples
within 6 cm of a scene point, as the 3D method's coverage) is at least 0.5 and it tilts the model
at most 10° (the 3D method's max_tilt_deg; without the upright prior shells are otherwise placed
rolled or on end); per model the accepted placements are kept best fitness first, farther than
r_model from one kept. Truth matching as bench_recognition: the same model within 0.75 m
horizontally.
"""
import json
import math
import os
import sys
import time

import numpy as np
import open3d as o3d
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, 'build', 'python'))
import sonar3d  # noqa: E402

VOXEL = 0.03
FPFH_R = 0.15
NORMAL_R = 0.06
ICP_D = 0.06
MIN_FITNESS = 0.5
MAX_TILT_DEG = 10.0


def ground_removed(pts, cell=0.25, window=2.0, clearance=0.05):
    """Points above a per-cell seabed: the 25 % quantile of the lowest point per cell within
    `window` (the 3D method's fallback estimate), + clearance."""
    lo = pts[:, :2].min(0)
    ij = np.floor((pts[:, :2] - lo) / cell).astype(int)
    nx, ny = ij.max(0) + 1
    low = np.full((nx, ny), np.inf)
    np.minimum.at(low, (ij[:, 0], ij[:, 1]), pts[:, 2])
    k = int(round(window / 2 / cell))
    g = np.full((nx, ny), np.nan)
    for i in range(nx):
        for j in range(ny):
            w = low[max(0, i - k):i + k + 1, max(0, j - k):j + k + 1]
            w = w[np.isfinite(w)]
            if w.size:
                g[i, j] = np.quantile(w, 0.25)
    gz = g[ij[:, 0], ij[:, 1]]
    return pts[pts[:, 2] > gz + clearance]


def model_points(mesh_path):
    m = sonar3d.load_mesh(mesh_path)
    om = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(np.array(m.vertices, dtype=np.float64)),
                                   o3d.utility.Vector3iVector(np.array(m.triangles, dtype=np.int32)))
    om.compute_triangle_normals()
    area = om.get_surface_area()
    pc = om.sample_points_uniformly(number_of_points=int(min(200000, max(2000, area / 0.01 ** 2))),
                                    use_triangle_normal=True)
    p, n = np.asarray(pc.points), np.asarray(pc.normals)
    base = p[:, 2].min()
    keep = (n[:, 2] > -0.3) & (p[:, 2] > base + 0.05)
    if keep.sum() < 50:
        keep = np.ones(len(p), bool)
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(p[keep]))
    pc.normals = o3d.utility.Vector3dVector(n[keep])
    pc = pc.voxel_down_sample(VOXEL)
    full = np.asarray(m.vertices, float)
    centre = 0.5 * (full.min(0) + full.max(0))
    r = float(np.linalg.norm(full - centre, axis=1).max())
    return pc, centre, r


def fpfh(pc):
    return o3d.pipelines.registration.compute_fpfh_feature(
        pc, o3d.geometry.KDTreeSearchParamHybrid(radius=FPFH_R, max_nn=100))


def sub_feature(f, idx):
    g = o3d.pipelines.registration.Feature()
    g.data = np.asarray(f.data)[:, idx]
    return g


def rot_error_deg(R_est, R_true, sym):
    """Rotation error modulo the catalogue symmetry about the model's vertical axis."""
    if sym == 'full':  # only the tilt is defined
        c = np.clip(np.dot(R_est[:, 2], R_true[:, 2]), -1, 1)
        return math.degrees(math.acos(c))
    steps = {'none': [0.0], '180': [0.0, math.pi]}.get(sym, [0.0])
    best = 180.0
    for a in steps:
        Rz = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
        D = R_true.T @ R_est @ Rz
        best = min(best, math.degrees(math.acos(np.clip((np.trace(D) - 1) / 2, -1, 1))))
    return best


def rpy_matrix(rpy_deg):
    r, p, y = [math.radians(a) for a in rpy_deg]
    Rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    Ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    Rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def tilt_deg(R):
    return math.degrees(math.acos(np.clip(R[2, 2], -1, 1)))


def register(method, src, src_f, tgt, tgt_f):
    reg = o3d.pipelines.registration
    if method == 'ransac':
        r = reg.registration_ransac_based_on_feature_matching(
            src, tgt, src_f, tgt_f, False, 1.5 * VOXEL,
            reg.TransformationEstimationPointToPoint(False), 3,
            [reg.CorrespondenceCheckerBasedOnEdgeLength(0.9),
             reg.CorrespondenceCheckerBasedOnDistance(1.5 * VOXEL)],
            reg.RANSACConvergenceCriteria(100000, 0.999))
    else:
        try:
            r = reg.registration_fgr_based_on_feature_matching(
                src, tgt, src_f, tgt_f,
                reg.FastGlobalRegistrationOption(maximum_correspondence_distance=1.5 * VOXEL))
        except RuntimeError:  # FGR 0.16 throws when no correspondence passes its tuple test
            return np.eye(4), 0.0, float('nan')
    icp = reg.registration_icp(src, tgt, ICP_D, r.transformation,
                               reg.TransformationEstimationPointToPlane())
    return icp.transformation, icp.fitness, icp.inlier_rmse


def run_field(work, runs, field, max_regions):
    idx = json.load(open(os.path.join(work, 'fields.json')))
    fl = [f for f in idx['fields'] if f['name'] == field][0]
    cloud = os.path.join(work, field + '_cloud.ply')
    if not os.path.exists(cloud):
        cloud = os.path.join(work, field + '_map.ply')
    pts = np.asarray(o3d.io.read_point_cloud(cloud).points)
    t0, c0 = time.time(), time.process_time()
    scene = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(ground_removed(pts)))
    scene = scene.voxel_down_sample(VOXEL)
    scene.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=NORMAL_R, max_nn=30))
    scene.orient_normals_to_align_with_direction(np.array([0.0, 0.0, 1.0]))
    scene_f = fpfh(scene)
    sp = np.asarray(scene.points)
    prep_cpu, prep_wall = time.process_time() - c0, time.time() - t0
    cat = yaml.safe_load(open(os.path.join(work, field + '_catalogue.yaml')))['models']
    j3 = json.load(open(os.path.join(work, runs, field + '.3d.json')))
    out = {'field': field, 'scene_points': int(len(sp)), 'prep_cpu_s': prep_cpu,
           'prep_wall_s': prep_wall, 'models': {}, 'skipped': []}
    for mdl in cat:
        name, sym = mdl['name'], str(mdl.get('symmetry', 'none'))
        if 'mesh' not in mdl:
            out['skipped'].append(name)
            continue
        src, centre, r_model = model_points(mdl['mesh'])
        src_f = fpfh(src)
        cands = [(p.get('confidence') or 0.0, p) for p in j3['placements'] if p['model'] == name]
        cands += [((c.get('confidence') if c.get('confidence') is not None else -1.0), c)
                  for c in j3.get('candidates', []) if c['model'] == name]
        cands.sort(key=lambda x: -x[0])
        cellsz = max(r_model, 0.5)
        regions, used = [], set()
        for _, c in cands:
            R = rpy_matrix(c['rpy_deg']) if 'rpy_deg' in c else np.array(c['T_world_model'])[:3, :3]
            ctr = R @ centre + np.array(c['translation'])
            key = (int(math.floor(ctr[0] / cellsz)), int(math.floor(ctr[1] / cellsz)))
            if key in used:
                continue
            used.add(key)
            regions.append(ctr)
            if len(regions) >= max_regions:
                break
        res = {}
        for method in ('ransac', 'fgr'):
            c0, t0 = time.process_time(), time.time()
            found = []
            for ctr in regions:
                sel = np.where(np.hypot(sp[:, 0] - ctr[0], sp[:, 1] - ctr[1]) < r_model + 0.4)[0]
                if len(sel) < 30:
                    continue
                tgt = scene.select_by_index(sel)
                T, fit, rmse = register(method, src, src_f, tgt, sub_feature(scene_f, sel))
                T = np.asarray(T)
                found.append({'T': T.tolist(), 'fitness': fit, 'rmse': rmse,
                              'tilt_deg': tilt_deg(T[:3, :3]), 'region': list(map(float, ctr))})
            cpu, wall = time.process_time() - c0, time.time() - t0
            acc = [f for f in sorted(found, key=lambda f: -f['fitness'])
                   if f['fitness'] >= MIN_FITNESS and f['tilt_deg'] <= MAX_TILT_DEG]
            kept = []
            for f in acc:
                c = np.array(f['T'])[:3, :3] @ centre + np.array(f['T'])[:3, 3]
                if all(np.hypot(*(c - k['c'])[:2]) > r_model for k in kept):
                    f['c'] = c
                    kept.append(f)
            for f in kept:
                f['c'] = f['c'].tolist()
            res[method] = {'regions': len(regions), 'registered': found, 'placed': kept,
                           'cpu_s': cpu, 'wall_s': wall}
        out['models'][name] = {'symmetry': sym, 'r_model': r_model, **res}
    return fl, out


def evaluate(fl, out, method):
    """Recall, precision, errors; and per true structure the best registration near it."""
    tr = fl['structures']
    used, tp, placed, pos, rot = set(), 0, 0, [], []
    near = []
    for name, m in out['models'].items():
        for f in m[method]['placed']:
            placed += 1
            T = np.array(f['T'])
            best = None
            for i, o in enumerate(tr):
                if o['model'] != name or i in used:
                    continue
                d = math.hypot(T[0, 3] - o['translation'][0], T[1, 3] - o['translation'][1])
                if d <= 0.75 and (best is None or d < best[1]):
                    best = (i, d)
            if best:
                used.add(best[0])
                tp += 1
                pos.append(best[1])
                rot.append(rot_error_deg(T[:3, :3], rpy_matrix(tr[best[0]]['rpy_deg']),
                                         m['symmetry']))
    for o in tr:  # registration quality at the truth, whatever the acceptance
        m = out['models'].get(o['model'])
        if m is None:
            near.append((o['name'], None, None, None))
            continue
        best = None
        for f in m[method]['registered']:
            T = np.array(f['T'])
            d = math.hypot(T[0, 3] - o['translation'][0], T[1, 3] - o['translation'][1])
            e = rot_error_deg(T[:3, :3], rpy_matrix(o['rpy_deg']), m['symmetry'])
            if best is None or d + e / 30 < best[0] + best[1] / 30:
                best = (d, e, f['fitness'])
        near.append((o['name'],) + (best if best else (None, None, None)))
    return tp, len(tr), placed, pos, rot, near


def main():
    args = [a for a in sys.argv[1:]]
    max_regions = 30
    if '--max-regions' in args:
        k = args.index('--max-regions')
        max_regions = int(args[k + 1])
        del args[k:k + 2]
    if len(args) < 3:
        sys.exit(__doc__.split('\n\n')[2])
    work, runs, outdir = args[0], args[1], args[2]
    fields = args[3:] or [f['name'] for f in json.load(open(os.path.join(work, 'fields.json')))['fields']]
    os.makedirs(outdir, exist_ok=True)
    rows = []
    for field in fields:
        fl, out = run_field(work, runs, field, max_regions)
        with open(os.path.join(outdir, field + '.open3d.json'), 'w') as f:
            json.dump(out, f, indent=1)
        for method in ('ransac', 'fgr'):
            tp, n, placed, pos, rot, near = evaluate(fl, out, method)
            cpu = out['prep_cpu_s'] + sum(m[method]['cpu_s'] for m in out['models'].values())
            wall = out['prep_wall_s'] + sum(m[method]['wall_s'] for m in out['models'].values())
            nr = sum(m[method]['regions'] for m in out['models'].values())
            good = sum(1 for x in near if x[1] is not None and x[1] <= 0.10 and x[2] <= 3.0)
            fmt = lambda v: '%.1f' % v if v is not None else '–'  # noqa: E731
            nears = '; '.join('%s %s cm %s°' % (x[0], fmt(None if x[1] is None else 100 * x[1]),
                                                 fmt(x[2])) for x in near)
            rows.append((field, method, tp, n, placed, pos, rot, cpu, wall, nr, good, nears,
                         out['skipped']))
            print(field, method, 'recall %d/%d precision %d/%d' % (tp, n, tp, placed),
                  'cpu %.1f s wall %.1f s regions %d' % (cpu, wall, nr), 'near truth:', nears,
                  flush=True)
    with open(os.path.join(outdir, 'table.md'), 'w') as f:
        f.write('| field | method | recall | precision | position cm (median, max) | rotation ° '
                '(median, max) | registered within 10 cm and 3° at the truth | regions | CPU s | '
                'wall s | skipped (no mesh) |\n|---|---|---|---|---|---|---|---|---|---|---|\n')
        for (field, method, tp, n, placed, pos, rot, cpu, wall, nr, good, nears, sk) in rows:
            pm = ('%.1f, %.1f' % (100 * np.median(pos), 100 * max(pos))) if pos else '–'
            rm = ('%.1f, %.1f' % (np.median(rot), max(rot))) if rot else '–'
            f.write('| %s | %s | %d/%d | %d/%d | %s | %s | %d/%d | %d | %.1f | %.1f | %s |\n' % (
                field, method, tp, n, tp, placed, pm, rm, good, n, nr, cpu, wall,
                ', '.join(sk)))
        for method in ('ransac', 'fgr'):
            rs = [r for r in rows if r[1] == method]
            tp, n, pl = sum(r[2] for r in rs), sum(r[3] for r in rs), sum(r[4] for r in rs)
            f.write('| **all** | %s | %d/%d | %d/%d | | | %d/%d | %d | %.1f | %.1f | |\n' % (
                method, tp, n, tp, pl, sum(r[10] for r in rs), n, sum(r[9] for r in rs),
                sum(r[7] for r in rs), sum(r[8] for r in rs)))
    print(open(os.path.join(outdir, 'table.md')).read())


if __name__ == '__main__':
    main()

#!/usr/bin/python3
"""Recognition benchmark of unseen fields (issue 28, docs/recognition.md "Benchmark of unseen
fields"). Driven by bench/recognition_fields.sh; four subcommands:

  generate WORK [--meshes DIR]  structure meshes (OBJ, generated here: code, not files), scene and
                                catalogue YAML of every field, and WORK/fields.json (truth, radii)
  label WORK RUNS OUT.csv       every candidate of every placements JSON (accepted placements and
                                the searches' rejected candidates) labelled true/false against the
                                scene's truth, one CSV over all fields and methods
  table WORK RUNS               the summary table (Markdown) from the runs' logs
  crop IN.ply OUT.ply XMIN YMIN XMAX YMAX   a cloud cut to a rectangle (the fields' seabed edges)

Public meshes: ../shared/data/meshes (Apache-2.0, README.md there): bop_panel, valve, hot_stab,
sonobuoy, torpedo_mk46/mk48 (ordnance stand-ins), erov (a small ROV), mossy_cinder_block,
munkholmen_seabed. Needs the Debian python3-numpy and python3-yaml (/usr/bin/python3).
"""
import csv
import glob
import json
import math
import os
import random
import re
import sys
import xml.etree.ElementTree as ET

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# ---------------------------------------------------------------------------------------------
# Meshes: generated structures (boxes and cylinders, written as OBJ) and the public Collada files.


class Mesh:
    def __init__(self):
        self.v, self.f = [], []

    def add(self, verts, faces):
        o = len(self.v)
        self.v.extend(verts)
        self.f.extend([tuple(i + o for i in t) for t in faces])

    def write_obj(self, path):
        with open(path + '.tmp', 'w') as f:
            f.write('# sonar3d bench/recognition_fields.py: generated structure, metres, z up\n')
            for p in self.v:
                f.write('v %.5f %.5f %.5f\n' % tuple(p))
            for t in self.f:
                f.write('f %d %d %d\n' % (t[0] + 1, t[1] + 1, t[2] + 1))
        os.replace(path + '.tmp', path)


def rot(rpy_deg):
    r, p, y = [math.radians(a) for a in rpy_deg]
    cx, sx, cy, sy, cz, sz = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def box(m, center, size, rpy=(0, 0, 0)):
    sx, sy, sz = [s / 2 for s in size]
    R = rot(rpy)
    c = np.array(center, float)
    v = [c + R @ np.array([x, y, z]) for x in (-sx, sx) for y in (-sy, sy) for z in (-sz, sz)]
    # vertex index = 4*ix + 2*iy + iz; outward-facing triangles
    faces = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
             (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    m.add(v, faces)


def cylinder(m, center, radius, length, rpy=(0, 0, 0), n=20):
    """A closed cylinder along its local z, centred on `center`."""
    R = rot(rpy)
    c = np.array(center, float)
    v = []
    for z in (-length / 2, length / 2):
        for k in range(n):
            a = 2 * math.pi * k / n
            v.append(c + R @ np.array([radius * math.cos(a), radius * math.sin(a), z]))
    v.append(c + R @ np.array([0, 0, -length / 2]))
    v.append(c + R @ np.array([0, 0, length / 2]))
    b, t = 2 * n, 2 * n + 1
    faces = []
    for k in range(n):
        k1 = (k + 1) % n
        faces += [(k, k1, n + k1), (k, n + k1, n + k), (b, k1, k), (t, n + k, n + k1)]
    m.add(v, faces)


def member(m, a, b, s=0.1):
    """A square member of side s from point a to point b."""
    a, b = np.array(a, float), np.array(b, float)
    d = b - a
    L = np.linalg.norm(d)
    yaw = math.degrees(math.atan2(d[1], d[0]))
    pitch = -math.degrees(math.atan2(d[2], math.hypot(d[0], d[1])))
    box(m, (a + b) / 2, (L, s, s), (0, pitch, yaw))


def lattice_frame(L=3.0, W=2.4, H=1.6, s=0.1, braces=True, diagonals=True):
    """An open protection frame: four legs, top and bottom rings, mid braces, side diagonals
    (unchanged by a 180° turn about z: catalogued with symmetry "180")."""
    m = Mesh()
    x, y = L / 2 - s / 2, W / 2 - s / 2
    for sx in (-x, x):
        for sy in (-y, y):
            box(m, (sx, sy, H / 2), (s, s, H))
    for z in (s / 2, H - s / 2):
        box(m, (0, -y, z), (L - 2 * s, s, s))
        box(m, (0, y, z), (L - 2 * s, s, s))
        box(m, (-x, 0, z), (s, W - 2 * s, s))
        box(m, (x, 0, z), (s, W - 2 * s, s))
    if braces:
        box(m, (0, -y, H / 2), (L - 2 * s, s, s))
        box(m, (0, y, H / 2), (L - 2 * s, s, s))
        box(m, (0, 0, H - s / 2), (s, W - 2 * s, s))  # a top cross member
    if diagonals:
        member(m, (-x, -y + s, s), (-x, y - s, H - s), s)
        member(m, (x, -y + s, H - s), (x, y - s, s), s)
    return m


def panel_frame():
    """An open panel: two skids, a solid 1.9 x 1.2 m panel standing on them off-centre, two struts
    and a small valve box on the open side (2.0 x 1.1 x 1.45 m)."""
    m = Mesh()
    for y in (-0.45, 0.45):
        box(m, (0, y, 0.075), (2.0, 0.15, 0.15))
    box(m, (0, -0.2, 0.15 + 0.65), (1.9, 0.06, 1.3))
    for x in (-0.8, 0.8):
        member(m, (x, 0.45, 0.15), (x, -0.17, 1.2), 0.08)
    box(m, (0.55, 0.25, 0.3), (0.4, 0.3, 0.3))
    return m


def manifold(kind='a'):
    """A small manifold: a 2.6 x 1.8 x 0.2 m base, valve stacks with handwheels, a header on
    saddles (kind a); kind b (a distractor of the same base): two taller towers, no header."""
    m = Mesh()
    box(m, (0, 0, 0.1), (2.6, 1.8, 0.2))
    if kind == 'a':
        for x in (-0.8, 0.0, 0.8):
            cylinder(m, (x, 0.5, 0.2 + 0.35), 0.13, 0.7)
            cylinder(m, (x, 0.5, 0.2 + 0.7 + 0.03), 0.22, 0.06)
        for x in (-0.9, 0.9):
            box(m, (x, -0.4, 0.2 + 0.12), (0.2, 0.3, 0.24))
        cylinder(m, (0, -0.4, 0.2 + 0.24 + 0.12), 0.12, 2.4, (0, 90, 0))
        box(m, (1.05, 0.5, 0.2 + 0.2), (0.3, 0.4, 0.4))
    else:
        cylinder(m, (-0.9, 0.55, 0.2 + 0.5), 0.22, 1.0)
        cylinder(m, (0.9, -0.55, 0.2 + 0.5), 0.22, 1.0)
        box(m, (0, 0, 0.2 + 0.15), (1.2, 0.8, 0.3))
    return m


def spool():
    """A rigid jumper spool: a 4 m pipe (r 0.11) on three sleepers, rising 0.7 m at both ends."""
    m = Mesh()
    r, z = 0.11, 0.25 + 0.11
    cylinder(m, (0, 0, z), r, 4.0, (0, 90, 0))
    for x in (-1.5, 0, 1.5):
        box(m, (x, 0, 0.125), (0.3, 0.9, 0.25))
    for x in (-2.0, 2.0):
        cylinder(m, (x, 0, z + 0.35), r, 0.7 + 2 * r)
        cylinder(m, (x, 0, z + 0.7 + r), 0.2, 0.12)  # hub flange
    return m


def drum(length=2.64, radius=0.162):
    """A plain cylinder lying along x, axis at z = 0 like the torpedo meshes (a distractor)."""
    m = Mesh()
    cylinder(m, (0, 0, 0), radius, length, (0, 90, 0), n=24)
    return m


def solid_box(size):
    m = Mesh()
    box(m, (0, 0, size[2] / 2), size)
    return m


GENERATED = {
    'lattice_frame': lambda: lattice_frame(),
    'lattice_frame_b': lambda: lattice_frame(2.8, 2.2, 1.4, 0.1, braces=False, diagonals=False),
    'panel_frame': panel_frame,
    'manifold': lambda: manifold('a'),
    'manifold_b': lambda: manifold('b'),
    'spool': spool,
    'drum': drum,
    'box_panel': lambda: solid_box((2.0, 1.0, 1.3)),
    'box_block': lambda: solid_box((1.3, 0.6, 0.6)),
    'box_bop': lambda: solid_box((0.5, 0.8, 0.36)),
}


def dae_vertices(path):
    """Vertices of a Collada file as Assimp + sonar3d load a Z_UP file: node matrices applied,
    <unit meter> applied, z kept up (docs/design.md)."""
    root = ET.parse(path).getroot()
    ns = root.tag.split('}')[0] + '}'
    unit = root.find(f'{ns}asset/{ns}unit')
    meter = float(unit.get('meter')) if unit is not None else 1.0
    geoms = {}
    for g in root.iter(f'{ns}geometry'):
        mesh = g.find(f'{ns}mesh')
        vid = mesh.find(f'{ns}vertices/{ns}input[@semantic="POSITION"]').get('source')[1:]
        for s in mesh.findall(f'{ns}source'):
            if s.get('id') == vid:
                geoms[g.get('id')] = np.array(s.find(f'{ns}float_array').text.split(), float).reshape(-1, 3)
    out = []

    def walk(node, M):
        mt = node.find(f'{ns}matrix')
        if mt is not None:
            M = M @ np.array(mt.text.split(), float).reshape(4, 4)
        for ig in node.findall(f'{ns}instance_geometry'):
            p = geoms[ig.get('url')[1:]]
            out.append((np.c_[p, np.ones(len(p))] @ M.T)[:, :3])
        for c in node.findall(f'{ns}node'):
            walk(c, M)
    for vs in root.iter(f'{ns}visual_scene'):
        for n in vs.findall(f'{ns}node'):
            walk(n, np.eye(4))
    return np.vstack(out) * meter


def model_geometry(verts):
    """As the recognition's model template (src/recog/model.cpp): the bounding box's centre in xy,
    the radius = the farthest vertex from it horizontally, base and top heights."""
    lo, hi = verts.min(0), verts.max(0)
    c = (lo[:2] + hi[:2]) / 2
    r = float(np.max(np.linalg.norm(verts[:, :2] - c, axis=1)))
    return {'center_xy': [float(c[0]), float(c[1])], 'radius_m': r, 'base_z': float(lo[2]),
            'top_z': float(hi[2]), 'size': [float(s) for s in hi - lo]}


# ---------------------------------------------------------------------------------------------
# Fields


def fmt(v):
    return '[' + ', '.join('%.3f' % x for x in v) + ']'


class Field:
    def __init__(self, name, size, seed, relief=0.1, trenches=0, rocks=20, slope_deg=0.0,
                 note=''):
        self.name, self.size, self.seed = name, size, seed
        self.relief, self.trenches, self.rocks, self.slope = relief, trenches, rocks, slope_deg
        self.objects, self.structures, self.clutter, self.catalogue = [], [], [], []
        self.note = note
        self.count = {}
        self.navigation_error = None  # e.g. data/scenes/field.yaml's dead reckoning

    def ground(self, x):
        """Seabed height of the sloped plane (the terrain is pitched about y: z = -x tan(slope))."""
        return -x * math.tan(math.radians(self.slope))

    def place(self, name, source, xy, yaw, z_off=0.0, scale=1.0, refl=0.8, structure=True,
              rp=(0.0, 0.0)):
        """An object whose model frame has its base at z = 0 (or, for the torpedo-like meshes, its
        axis: z_off lifts it), put on the sloped seabed at xy with yaw."""
        k = self.count.get(name, 0)
        self.count[name] = k + 1
        oname = name if k == 0 else '%s@%d' % (name, k + 1)
        if not structure:  # clutter: a name no catalogue model matches
            oname = 'clutter_' + oname
        z = self.ground(xy[0]) + z_off
        rpy = (rp[0], rp[1] + self.slope, yaw)
        src = ('mesh: %s' % source) if not source.startswith('reference:') else source
        line = '{name: "%s", %s, pose: {translation: %s, rpy_deg: %s}%s, reflectivity: %.2f}' % (
            oname, src, fmt([xy[0], xy[1], z]), fmt(rpy), (', scale: %g' % scale) if scale != 1 else '', refl)
        self.objects.append(line)
        entry = {'name': oname, 'model': name, 'translation': [xy[0], xy[1], z], 'rpy_deg': list(rpy),
                 'scale': scale}
        (self.structures if structure else self.clutter).append(entry)
        return oname

    def prim(self, name, prim, xyz, rpy=(0, 0, 0), refl=0.6):
        rpy = (rpy[0], rpy[1] + self.slope, rpy[2])
        z = self.ground(xyz[0]) + xyz[2]
        self.objects.append('{name: %s, primitive: %s, pose: {translation: %s, rpy_deg: %s}, reflectivity: %.2f}'
                            % (name, prim, fmt([xyz[0], xyz[1], z]), fmt(rpy), refl))
        self.clutter.append({'name': name, 'model': None, 'translation': [xyz[0], xyz[1], z]})

    def pipeline(self, name, a, b, radius=0.15, burial=0.5):
        a3 = [a[0], a[1], self.ground(a[0])]
        b3 = [b[0], b[1], self.ground(b[0])]
        self.objects.append('{name: %s, pipeline: {from: %s, to: %s, radius: %.2f, burial: %.2f}, reflectivity: 0.7}'
                            % (name, fmt(a3), fmt(b3), radius, burial))

    def trajectory(self):
        X, Y = self.size
        hx, hy = X / 2 - 2.0, Y / 2 - 2.0
        return ('{type: lawnmower, x: [%.1f, %.1f], y: [%.1f, %.1f], z: 4.0, line_spacing: 2.0, '
                'spacing: 0.04, turn_radius: 1.0, period: 0.1}' % (-hx, hx, -hy, hy))

    def scene_yaml(self):
        X, Y = self.size
        lines = [
            '# Recognition benchmark field "%s" (bench/recognition_fields.py; issue 28): %s' % (self.name, self.note),
            'seed: %d' % self.seed,
        ] + (['navigation_error: ' + self.navigation_error] if self.navigation_error else []) + [
            'sensor: {preset: mb2250, r_min: 1.0, r_max: 6.0, range_bins: 250, T_vehicle_sonar: {rpy_deg: [0, 90, 0]}}',
            'simulation: {elevation_step_deg: 0.1}',
            'objects:',
            '  - {name: seabed, primitive: {type: terrain, size: [%g, %g], cell: 0.05, relief: %.2f, wavelength: 6, '
            'trenches: %d, rocks: %d, seed: %d}, pose: {rpy_deg: [0, %.1f, 0]}, reflectivity: 0.3}'
            % (X, Y, self.relief, self.trenches, self.rocks, self.seed, self.slope),
        ]
        lines += ['  - ' + o for o in self.objects]
        lines.append('trajectory: ' + self.trajectory())
        return '\n'.join(lines) + '\n'


def growth(f, rng, cx, cy, yaw, pts, z_top, n, tag):
    """Marine growth (crude, as recognition_scenes.sh): spheres of 3-7 cm on a structure's top,
    at model-frame points `pts` (x, y) rotated by yaw about (cx, cy)."""
    c, s = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
    for i in range(n):
        u, v = pts[rng.randrange(len(pts))]
        u += rng.uniform(-0.04, 0.04)
        v += rng.uniform(-0.04, 0.04)
        r = rng.uniform(0.03, 0.07)
        x, y = cx + c * u - s * v, cy + s * u + c * v
        f.prim('growth_%s%d' % (tag, i), '{type: sphere, radius: %.3f}' % r, (x, y, z_top + 0.3 * r))


def wreck_pile(f, rng, cx, cy, n=14, spread=(3.0, 2.2), tag='wreck'):
    """A wreck-like pile: tilted plates, beams and drums heaped in a few metres."""
    for i in range(n):
        x = cx + rng.uniform(-spread[0] / 2, spread[0] / 2)
        y = cy + rng.uniform(-spread[1] / 2, spread[1] / 2)
        kind = rng.random()
        rpy = (rng.uniform(-35, 35), rng.uniform(-35, 35), rng.uniform(0, 180))
        if kind < 0.45:
            s = (rng.uniform(0.6, 1.6), rng.uniform(0.3, 1.0), rng.uniform(0.04, 0.15))
            f.prim('%s%d' % (tag, i), '{type: box, size: %s}' % fmt(s), (x, y, rng.uniform(0.1, 0.6)), rpy)
        elif kind < 0.75:
            s = (rng.uniform(0.8, 2.0), rng.uniform(0.1, 0.25), rng.uniform(0.1, 0.25))
            f.prim('%s%d' % (tag, i), '{type: box, size: %s}' % fmt(s), (x, y, rng.uniform(0.1, 0.7)), rpy)
        else:
            f.prim('%s%d' % (tag, i), '{type: cylinder, radius: %.2f, height: %.2f}' % (rng.uniform(0.15, 0.35), rng.uniform(0.4, 1.1)),
                   (x, y, rng.uniform(0.1, 0.4)), (rng.uniform(60, 90), 0, rng.uniform(0, 180)))


def make_fields(meshes_dir, gen_dir):
    D = lambda n: os.path.join(meshes_dir, n + '.dae')  # noqa: E731
    G = lambda n: os.path.join(gen_dir, n + '.obj')  # noqa: E731
    SYM = {'torpedo_mk46': '180', 'torpedo_mk48': '180', 'drum': '180', 'sonobuoy': 'full',
           'valve': 'full', 'spool': '180', 'box_block': '180', 'box_bop': '180', 'box_panel': '180',
           'lattice_frame': '180', 'lattice_frame_b': '180', 'tank': 'full', 'pillar': '180'}
    src = lambda n: D(n) if os.path.exists(D(n)) else G(n)  # noqa: E731

    def cat(f, names):
        for n in names:
            if n in ('tank', 'riser', 'pillar'):
                f.catalogue.append({'name': n, 'mesh': None, 'reference': n, 'symmetry': SYM.get(n, 'none')})
            else:
                f.catalogue.append({'name': n, 'mesh': src(n), 'symmetry': SYM.get(n, 'none')})

    fields = []
    rng = random.Random(28)

    # 1. Ordnance: two mk46 shells (one 35 % buried), one mk48 (45 % buried), on relief with a
    # half-buried pipeline, 25 rocks, two cinder blocks and a hull-like drum of debris.
    f = Field('ordnance', (16, 12), 11, relief=0.1, rocks=25,
              note='2 torpedo_mk46 (one 35 % buried), 1 torpedo_mk48 45 % buried; clutter: pipeline, 25 rocks, '
                   '2 cinder blocks, a sonobuoy lying, a scaled seabed mound')
    f.place('torpedo_mk46', D('torpedo_mk46'), (-3.5, 1.8), 35, z_off=0.162 - 0.05)
    f.place('torpedo_mk46', D('torpedo_mk46'), (2.5, -2.2), -60, z_off=0.162 - 0.35 * 0.324)
    f.place('torpedo_mk48', D('torpedo_mk48'), (1.5, 2.3), 100 - 180 + 5, z_off=0.283 - 0.45 * 0.567)
    f.pipeline('pipeline', (-8, -3.5), (8, -0.5), 0.15, 0.5)
    f.place('mossy_cinder_block', D('mossy_cinder_block'), (-2.0, -2.5), 20, z_off=-0.05, refl=0.6, structure=False)
    f.place('mossy_cinder_block', D('mossy_cinder_block'), (4.8, 0.8), 75, z_off=-0.15, refl=0.6, structure=False,
            rp=(0, 8))
    f.place('sonobuoy', D('sonobuoy'), (-5.5, -1.0), 140, z_off=0.06, refl=0.7, structure=False, rp=(90, 0))
    f.place('munkholmen_seabed', D('munkholmen_seabed'), (-5.0, 3.0), 30, z_off=0.05, scale=0.0015, refl=0.4,
            structure=False)
    cat(f, ['torpedo_mk46', 'torpedo_mk48', 'drum', 'bop_panel', 'tank', 'hot_stab'])
    fields.append(f)

    # 2. Subsea kit: a BOP panel, a parked ROV, a hot stab, on a trenched seabed with rocks and
    # cinder-block debris; distractors include a solid box the size of the BOP panel.
    f = Field('subsea_kit', (14, 12), 12, relief=0.1, trenches=1, rocks=30,
              note='bop_panel, erov, hot_stab; clutter: a trench, 30 rocks, 2 cinder blocks, a 1 m drum')
    f.place('bop_panel', D('bop_panel'), (-2.5, 1.5), 25, z_off=-0.03)
    f.place('erov', D('erov'), (2.0, -1.0), -40, z_off=-0.05)
    f.place('hot_stab', D('hot_stab'), (-1.5, -2.0), 70, z_off=0.056 - 0.01)
    f.place('mossy_cinder_block', D('mossy_cinder_block'), (3.5, 2.5), 10, z_off=-0.05, refl=0.6, structure=False)
    f.place('mossy_cinder_block', D('mossy_cinder_block'), (-4.0, -1.5), 55, z_off=-0.1, refl=0.6, structure=False)
    f.prim('debris_drum', '{type: cylinder, radius: 0.3, height: 1.0}', (0.5, 2.8, 0.25), (90, 0, 20))
    cat(f, ['bop_panel', 'erov', 'hot_stab', 'box_bop', 'riser', 'torpedo_mk46', 'sonobuoy'])
    fields.append(f)

    # 3. Lattice: a 3 x 2.4 x 1.6 m open frame and an open panel among a wreck-like pile and a
    # pipeline; distractors: a frame of nearly the same size without braces, a solid box the panel's
    # size, the pillar and the ROV.
    f = Field('lattice', (18, 14), 13, relief=0.1, rocks=20,
              note='lattice_frame (3 x 2.4 x 1.6 m), panel_frame (2 x 1.1 x 1.45 m); clutter: a wreck-like pile '
                   'of 14 plates/beams/drums, a pipeline, 20 rocks')
    f.place('lattice_frame', G('lattice_frame'), (-4.0, 1.5), 20, z_off=-0.05)
    f.place('panel_frame', G('panel_frame'), (3.5, 2.5), -75, z_off=-0.05)
    wreck_pile(f, rng, 2.5, -2.8)
    f.pipeline('pipeline', (-9, -1.5), (9, -5.5), 0.2, 0.4)
    cat(f, ['lattice_frame', 'panel_frame', 'lattice_frame_b', 'box_panel', 'pillar', 'erov'])
    fields.append(f)

    # 4. Manifold on a 5° slope with marine growth: a manifold and a jumper spool; distractors: a
    # manifold of the same base with other towers, the tank, the BOP panel, the mk48.
    f = Field('manifold_slope', (16, 12), 14, relief=0.08, rocks=15, slope_deg=5.0,
              note='5° slope; manifold (2.6 x 1.8 x 1.1 m) and spool (4.2 m jumper) with marine growth; '
                   'clutter: 15 rocks, a half-buried pipeline, 2 cinder blocks')
    f.place('manifold', G('manifold'), (-3.0, 1.0), 110, z_off=-0.04)
    f.place('spool', G('spool'), (3.0, -1.5), 15, z_off=-0.04)
    growth(f, rng, -3.0, 1.0, 110, [(-0.8, 0.5), (0, 0.5), (0.8, 0.5), (-1.1, -0.7), (1.1, 0.7), (0, -0.4)],
           f.ground(-3.0) - 0.04 + 0.2, 12, 'm')
    growth(f, rng, 3.0, -1.5, 15, [(-1.5, 0.3), (0, -0.3), (1.5, 0.3), (-0.8, 0), (0.8, 0)],
           f.ground(3.0) - 0.04 + 0.25, 8, 's')
    f.pipeline('pipeline', (-7.5, -4.0), (7.5, 4.0), 0.15, 0.5)
    f.place('mossy_cinder_block', D('mossy_cinder_block'), (0.0, 3.5), 40, z_off=-0.05, refl=0.6, structure=False)
    f.place('mossy_cinder_block', D('mossy_cinder_block'), (5.5, 2.0), 100, z_off=-0.1, refl=0.6, structure=False)
    cat(f, ['manifold', 'spool', 'manifold_b', 'tank', 'bop_panel', 'torpedo_mk48'])
    fields.append(f)

    # 5. Mixed, buried: a cinder block 40 % buried, a BOP panel, an mk46 fully exposed, a sonobuoy
    # standing, a second lattice frame turned 75°; rocks, two trenches, a seabed mound.
    f = Field('mixed_buried', (18, 14), 15, relief=0.1, trenches=2, rocks=35,
              note='mossy_cinder_block 40 % buried, bop_panel, torpedo_mk46, sonobuoy upright, lattice_frame; '
                   'clutter: 2 trenches, 35 rocks, a seabed mound, 8 beams/plates of debris')
    f.place('mossy_cinder_block', D('mossy_cinder_block'), (-4.5, -2.5), 30, z_off=-0.4 * 0.61)
    f.place('bop_panel', D('bop_panel'), (4.5, -2.0), -20, z_off=-0.03)
    f.place('torpedo_mk46', D('torpedo_mk46'), (0.5, -3.5), 165, z_off=0.162 - 0.04)
    f.place('sonobuoy', D('sonobuoy'), (-1.0, 0.5), 0, z_off=0.45 - 0.15)
    f.place('lattice_frame', G('lattice_frame'), (3.5, 2.5), 75, z_off=-0.05)
    f.place('munkholmen_seabed', D('munkholmen_seabed'), (-5.0, 3.5), 200, z_off=0.05, scale=0.0015, refl=0.4,
            structure=False)
    wreck_pile(f, rng, -2.0, 3.5, n=8, spread=(3.0, 1.5), tag='debris')
    cat(f, ['mossy_cinder_block', 'bop_panel', 'torpedo_mk46', 'sonobuoy', 'lattice_frame', 'box_block', 'riser',
            'hot_stab', 'lattice_frame_b'])
    fields.append(f)

    # 6. Clutter only: no catalogue structure (the right answer is no placement).
    f = Field('clutter_only', (16, 12), 16, relief=0.12, trenches=1, rocks=45,
              note='no catalogue structure: a wreck-like pile, an ROV (not catalogued), 3 cinder blocks, a drum-like '
                   'pipe section, 2 pipelines, a trench, 45 rocks, a seabed mound')
    wreck_pile(f, rng, -3.0, 1.0, n=16, spread=(3.5, 2.5))
    f.place('erov', D('erov'), (3.5, 2.0), 60, z_off=-0.05, refl=0.7, structure=False)
    for i, (x, y, yaw) in enumerate([(1.0, -2.5, 10), (4.5, -1.5, 80), (-5.5, -3.0, 45)]):
        f.place('mossy_cinder_block', D('mossy_cinder_block'), (x, y), yaw, z_off=-0.1, refl=0.6, structure=False)
    f.prim('pipe_section', '{type: cylinder, radius: 0.16, height: 2.6}', (-1.0, -3.5, 0.12), (0, 90, 25))
    f.pipeline('pipeline_a', (-8, 4.5), (8, 3.5), 0.15, 0.5)
    f.pipeline('pipeline_b', (-8, -1.0), (8, -5.0), 0.2, 0.6)
    f.place('munkholmen_seabed', D('munkholmen_seabed'), (5.0, -4.0), 0, z_off=0.05, scale=0.0015, refl=0.4,
            structure=False)
    cat(f, ['torpedo_mk46', 'bop_panel', 'lattice_frame', 'manifold', 'tank', 'riser', 'box_panel'])
    fields.append(f)

    # 7. Dead-reckoning drift (data/scenes/field.yaml's navigation error): an open panel, a spool,
    # the ROV and an mk48 half buried, on relief with rocks and a trench; the map's own placement
    # error enters the position errors.
    f = Field('drift', (18, 14), 17, relief=0.12, trenches=1, rocks=30,
              note='navigation drift as data/scenes/field.yaml; panel_frame, spool, erov, torpedo_mk48 50 % buried; '
                   'clutter: a trench, 30 rocks, 6 pieces of debris, a pipeline')
    f.navigation_error = '{velocity_scale: 0.01, bias_walk: 0.00005, heading_bias_deg: 0.2, depth_offset: 0.05}'
    f.place('panel_frame', G('panel_frame'), (-4.5, 2.0), 140, z_off=-0.05)
    f.place('spool', G('spool'), (3.5, 3.0), -30, z_off=-0.04)
    f.place('erov', D('erov'), (-3.0, -3.0), 10, z_off=-0.05)
    f.place('torpedo_mk48', D('torpedo_mk48'), (3.0, -2.5), 50, z_off=0.283 - 0.5 * 0.567)
    wreck_pile(f, rng, 0.0, 0.0, n=6, spread=(2.0, 2.0), tag='debris')
    f.pipeline('pipeline', (-9, 5.5), (9, 4.5), 0.15, 0.5)
    cat(f, ['panel_frame', 'spool', 'erov', 'torpedo_mk48', 'box_panel', 'drum', 'tank', 'pillar'])
    fields.append(f)

    # 8. Held out (recog28f; never tuned on): a 6.5° slope with a manifold, a BOP panel, a low
    # hot stab lying and a 40 % buried mk46 among rocks, a pipeline, cinder blocks and debris;
    # four distractors (its own random stream: the fields above are unchanged).
    hr = random.Random(2808)
    f = Field('heldout_slope', (16, 12), 18, relief=0.1, rocks=25, slope_deg=6.5,
              note='held out (recog28f): 6.5° slope; manifold, bop_panel, hot_stab lying, torpedo_mk46 40 % buried; '
                   'clutter: 25 rocks, a pipeline, 2 cinder blocks, 6 pieces of debris')
    f.place('manifold', G('manifold'), (3.5, 2.0), -35, z_off=-0.04)
    f.place('bop_panel', D('bop_panel'), (-4.0, 2.5), 150, z_off=-0.03)
    f.place('hot_stab', D('hot_stab'), (0.5, -1.0), -20, z_off=0.056 - 0.01)
    f.place('torpedo_mk46', D('torpedo_mk46'), (-3.0, -2.5), 80, z_off=0.162 - 0.4 * 0.324)
    f.pipeline('pipeline', (-8, -5.0), (8, 0.0), 0.15, 0.5)
    f.place('mossy_cinder_block', D('mossy_cinder_block'), (1.5, 3.5), 65, z_off=-0.05, refl=0.6, structure=False)
    f.place('mossy_cinder_block', D('mossy_cinder_block'), (-0.5, -3.8), 15, z_off=-0.1, refl=0.6, structure=False)
    wreck_pile(f, hr, -1.0, 1.5, n=6, spread=(2.0, 1.5), tag='debris')
    cat(f, ['manifold', 'bop_panel', 'hot_stab', 'torpedo_mk46', 'manifold_b', 'drum', 'box_bop', 'tank'])
    fields.append(f)
    return fields


def write_if_changed(path, text):
    """Atomically, and only when the content changes (a field being simulated keeps its file)."""
    if os.path.exists(path):
        with open(path) as f:
            if f.read() == text:
                return
    with open(path + '.tmp', 'w') as o:
        o.write(text)
    os.replace(path + '.tmp', path)


def generate(work, meshes_dir):
    gen = os.path.join(work, 'meshes')
    os.makedirs(gen, exist_ok=True)
    for n in ('torpedo_mk46', 'torpedo_mk48', 'bop_panel', 'erov', 'hot_stab', 'sonobuoy',
              'mossy_cinder_block', 'munkholmen_seabed', 'valve'):
        if not os.path.exists(os.path.join(meshes_dir, n + '.dae')):
            sys.exit('recognition_fields.py: %s.dae not found in %s (the public meshes, '
                     '../shared/data/meshes; pass --meshes DIR)' % (n, meshes_dir))
    geom = {}
    for n, fn in GENERATED.items():
        m = fn()
        m.write_obj(os.path.join(gen, n + '.obj'))
        geom[n] = model_geometry(np.array(m.v))
    for p in glob.glob(os.path.join(meshes_dir, '*.dae')):
        n = os.path.basename(p)[:-4]
        if n != 'munkholmen_seabed':
            geom[n] = model_geometry(dae_vertices(p))
    # The procedural reference objects (docs/formats.md): sizes as documented there.
    geom['tank'] = {'center_xy': [0, 0], 'radius_m': 0.25, 'base_z': 0, 'top_z': 1.2}
    geom['riser'] = {'center_xy': [0, 0], 'radius_m': 1.0, 'base_z': 0, 'top_z': 2.0}
    geom['pillar'] = {'center_xy': [0, 0], 'radius_m': 1.0, 'base_z': 0, 'top_z': 2.5}
    fields = make_fields(meshes_dir, gen)
    index = {'fields': [], 'models': geom}
    for f in fields:
        write_if_changed(os.path.join(work, f.name + '.yaml'), f.scene_yaml())
        cat_lines = ['# Catalogue of field "%s": its true structures and distractors (bench/recognition_fields.py)'
                     % f.name, 'models:']
        for c in f.catalogue:
            s = 'reference: %s' % c['reference'] if c.get('reference') else 'mesh: %s' % c['mesh']
            cat_lines.append('  - {name: %s, %s, symmetry: "%s"}' % (c['name'], s, c['symmetry']))
        write_if_changed(os.path.join(work, f.name + '_catalogue.yaml'), '\n'.join(cat_lines) + '\n')
        index['fields'].append({'name': f.name, 'size': f.size, 'note': f.note, 'slope_deg': f.slope,
                                'structures': f.structures, 'clutter': f.clutter,
                                'catalogue': [c['name'] for c in f.catalogue],
                                'symmetry': {c['name']: c['symmetry'] for c in f.catalogue}})
    write_if_changed(os.path.join(work, 'fields.json'), json.dumps(index, indent=1))
    print('\n'.join(f.name for f in fields))


# ---------------------------------------------------------------------------------------------
# Labelling


def flatten(prefix, v, out):
    """Every numeric (or boolean) value under v as a column: lists of numbers as key_0, key_1, ...
    nested objects as key.sub; 4 x 4 matrices (lists of lists) are left out (translation and
    rpy_deg carry the pose)."""
    if isinstance(v, bool):
        out[prefix] = int(v)
    elif isinstance(v, (int, float)):
        out[prefix] = v
    elif v is None:
        out[prefix] = ''
    elif isinstance(v, dict):
        for k, x in v.items():
            flatten(prefix + '.' + k if prefix else k, x, out)
    elif isinstance(v, list):
        if all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v) and len(v) <= 6:
            for i, x in enumerate(v):
                out['%s_%d' % (prefix, i)] = x
        # lists of lists (pose matrices) or of objects: skipped here (nested candidates are
        # collected by candidates_of)


def position_of(c):
    """The candidate's model-frame origin in the world, or None."""
    for k in ('translation', 'step1_translation'):
        if isinstance(c.get(k), list) and len(c[k]) == 3:
            return np.array(c[k], float), k
    T = c.get('T_world_model')
    if isinstance(T, list) and len(T) == 4:
        return np.array([T[0][3], T[1][3], T[2][3]], float), 'T_world_model'
    return None, None


def yaw_of(c):
    r = c.get('rpy_deg')
    if isinstance(r, list) and len(r) == 3:
        return float(r[2])
    T = c.get('T_world_model')
    if isinstance(T, list) and len(T) == 4:
        return math.degrees(math.atan2(T[1][0], T[0][0]))
    return None


def candidates_of(j):
    """(source, entry) for every candidate: the placements (accepted), every 'searches' entry and
    any list of objects carrying a 'model' nested in them (e.g. per-search candidate lists), and a
    top-level 'candidates' list if present. A search entry duplicating a placement is kept once."""
    out = []
    for p in j.get('placements', []):
        out.append(('placement', p))
    seen = [tuple(np.round(position_of(p)[0], 4)) + (p.get('model'),) for p in j.get('placements', [])
            if position_of(p)[0] is not None]

    def walk(src, lst):
        for e in lst:
            if not isinstance(e, dict):
                continue
            pos = position_of(e)[0]
            if pos is None:
                pass  # no pose: an accepted search (its placement is listed) or a 3D summary
            elif tuple(np.round(pos, 4)) + (e.get('model'),) in seen:
                pass  # the same candidate as an accepted placement
            else:
                out.append((src, e))
            for k, v in e.items():
                if isinstance(v, list) and v and isinstance(v[0], dict) and 'model' in v[0]:
                    walk(src + '.' + k, v)
    walk('search', j.get('searches', []))
    if isinstance(j.get('candidates'), list):
        walk('candidate', j['candidates'])
    return out


def load_json(path):
    with open(path) as f:
        return json.load(f)


def label(work, runs, out_csv):
    idx = load_json(os.path.join(work, 'fields.json'))
    models = idx['models']
    rows, keys = [], []
    for fld in idx['fields']:
        truths = fld['structures']
        all_objs = fld['structures'] + fld['clutter']
        for path in sorted(glob.glob(os.path.join(work, runs, fld['name'] + '.*.json'))):
            method = os.path.basename(path).split('.')[-2]
            try:
                j = load_json(path)
            except Exception as e:  # a run that failed or timed out leaves no JSON
                print('label: skipping %s: %s' % (path, e), file=sys.stderr)
                continue
            for src, c in candidates_of(j):
                model = c.get('model', '')
                g = models.get(model, {'center_xy': [0, 0], 'radius_m': 0.5})
                pos, pos_key = position_of(c)
                flat = {}
                for k, v in c.items():
                    if k in ('model', 'field', 'source', 'label', 'truth'):
                        continue
                    if isinstance(v, str):  # a short text (reason, method) kept as it is
                        flat['text_' + k if k == 'method' else k] = v
                    else:
                        flatten(k, v, flat)
                row = {'field': fld['name'], 'method': method, 'source': src, 'model': model,
                       'has_position': int(pos is not None), 'position_key': pos_key or ''}
                if src == 'placement' and 'accepted' not in flat:
                    row['accepted'] = 1
                row.update(flat)
                tol = max(0.3, 0.25 * g['radius_m'])
                d_same = d_any = float('nan')
                yaw_err = float('nan')
                if pos is not None:
                    yaw = yaw_of(c) or 0.0
                    cxy = np.array(g['center_xy'])
                    cs, sn = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
                    # the model's centre (bbox centre in xy) in the world, yaw only (tilt is small)
                    p = pos[:2] + np.array([cs * cxy[0] - sn * cxy[1], sn * cxy[0] + cs * cxy[1]])
                    best = None
                    for t in truths:
                        tg = models.get(t['model'], {'center_xy': [0, 0]})
                        ty = t['rpy_deg'][2]
                        tc, ts = math.cos(math.radians(ty)), math.sin(math.radians(ty))
                        txy = np.array(tg['center_xy']) * t.get('scale', 1)
                        q = np.array(t['translation'][:2]) + np.array([tc * txy[0] - ts * txy[1], ts * txy[0] + tc * txy[1]])
                        d = float(np.linalg.norm(p - q))
                        d_any = d if not (d >= d_any) else d_any  # min, NaN-safe
                        if t['model'] == model and (best is None or d < best[0]):
                            best = (d, t)
                    # any structure or clutter object (its pose origin) for the nearest-object distance
                    d_obj = min([float(np.linalg.norm(p - np.array(o['translation'][:2]))) for o in all_objs] or [float('nan')])
                    row['dist_nearest_object_m'] = d_obj
                    if best is not None:
                        d_same = best[0]
                        sym = fld['symmetry'].get(model, 'none')
                        per = {'none': 360.0, '180': 180.0, 'full': 0.0}.get(sym, 360.0)
                        if per > 0:
                            e = (yaw - best[1]['rpy_deg'][2]) % per
                            yaw_err = min(e, per - e)
                        row['truth'] = best[1]['name']
                row['dist_same_model_m'] = d_same
                row['dist_any_structure_m'] = d_any
                row['yaw_error_deg'] = yaw_err
                row['tolerance_m'] = tol
                row['label'] = int(d_same <= tol) if pos is not None and d_same == d_same else 0
                rows.append(row)
                for k in row:
                    if k not in keys:
                        keys.append(k)
    head = ['field', 'method', 'source', 'model']
    tail = ['label', 'dist_same_model_m', 'dist_any_structure_m', 'dist_nearest_object_m', 'yaw_error_deg',
            'tolerance_m', 'truth']
    cols = head + [k for k in keys if k not in head and k not in tail] + [k for k in tail if k in keys or k == 'truth']
    tmp = out_csv + '.tmp'
    with open(tmp, 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=cols, restval='')
        w.writeheader()
        for r in rows:
            w.writerow({k: ('%.6g' % v if isinstance(v, float) else v) for k, v in r.items()})
    os.replace(tmp, out_csv)
    n_true = sum(r['label'] for r in rows)
    print('%s: %d candidates (%d true, %d false), %d columns' % (out_csv, len(rows), n_true, len(rows) - n_true, len(cols)))


# ---------------------------------------------------------------------------------------------
# Summary table from the logs of recognition_fields.sh


def parse_time_v(path):
    out = {}
    if not os.path.exists(path):
        return out
    for line in open(path):
        if 'Maximum resident set size' in line:
            out['rss_mb'] = int(line.split(':')[1]) / 1024.0
        if 'Elapsed (wall clock) time' in line:
            t = line.split('):')[1].strip().split(':')
            out['wall_s'] = sum(float(x) * 60 ** (len(t) - 1 - i) for i, x in enumerate(t))
        if 'Exit status' in line:
            out['exit'] = int(line.split(':')[1])
    return out


def table(work, runs):
    idx = load_json(os.path.join(work, 'fields.json'))
    print('| field | method | structures | recall | precision | horizontal position error cm (median, max) | '
          'yaw error ° (median, max) | step 1 → step 2 median cm (median over found) | '
          'wall s (recognize) | s per structure | peak MB (recognize) | false placements (model × count) |')
    print('|---|---|---|---|---|---|---|---|---|---|---|---|')
    totals = {}
    med = lambda v: '%.1f' % float(np.median(v)) if v else '–'  # noqa: E731
    mx = lambda v: '%.1f' % max(v) if v else '–'  # noqa: E731
    for method in ('2d', '3d'):
        for fld in idx['fields']:
            n = fld['name']
            log = os.path.join(work, runs, '%s.%s.bench.txt' % (n, method))
            tv = parse_time_v(os.path.join(work, runs, '%s.%s.time.txt' % (n, method)))
            if not os.path.exists(log):
                continue
            txt = open(log).read()
            m = re.search(r'precision (\d+)/(\d+), recall (\d+)/(\d+)', txt)
            pos, yaw, s1, s2, false = [], [], [], [], []
            for line in txt.splitlines():
                cells = [c.strip() for c in line.strip().strip('|').split('|')]
                if len(cells) >= 10 and cells[1] == 'yes':
                    pos.append(float(cells[2].split()[1].strip('()')))
                    if cells[3] not in ('', 'nan', '-nan'):
                        yaw.append(float(cells[3]))
                    s1.append(float(cells[5].split()[0]))
                    s2.append(float(cells[6].split()[0]))
                elif len(cells) >= 2 and cells[0].endswith('(false)'):
                    false.append(cells[0].replace(' (false)', ''))
            if m:
                tp, np_, _, nt = [int(x) for x in m.groups()]
                t = totals.setdefault(method, [0, 0, 0, [], [], 0.0, 0.0])
                t[0] += tp
                t[1] += np_
                t[2] += nt
                t[3] += pos
                t[4] += yaw
                t[5] += tv.get('wall_s', 0.0)
                t[6] = max(t[6], tv.get('rss_mb', 0.0))
                rec = '%d/%d' % (tp, nt) if nt else '–'
                prec = '%d/%d' % (tp, np_) if np_ else ('–' if nt else '0 placed ✓')
            else:
                rec = prec = 'failed'
                nt = len(fld['structures'])
            wall = tv.get('wall_s')
            timed_out = tv.get('exit') not in (None, 0)
            wall_s = ('%.1f' % wall if wall is not None else '–') + (' (timeout)' if timed_out else '')
            per = '%.1f' % (wall / nt) if wall is not None and nt else '–'
            rss = '%.0f' % tv['rss_mb'] if 'rss_mb' in tv else '–'
            print('| %s | %s | %d | %s | %s | %s, %s | %s, %s | %s → %s | %s | %s | %s | %s |' % (
                n, method, nt, rec, prec, med(pos), mx(pos), med(yaw), mx(yaw), med(s1), med(s2),
                wall_s, per, rss, ', '.join('%s ×%d' % (k, false.count(k)) for k in sorted(set(false), key=lambda k: -false.count(k)))))
    for method, t in totals.items():
        print('| **all** | %s | %d | **%d/%d = %.2f** | **%d/%d = %.2f** | %s, %s | %s, %s | | %.1f | %s | %.0f | |' % (
            method, t[2], t[0], t[2], t[0] / t[2] if t[2] else 0, t[0], t[1], t[0] / t[1] if t[1] else 1,
            med(t[3]), mx(t[3]), med(t[4]), mx(t[4]), t[5], '%.1f' % (t[5] / t[2]) if t[2] else '–', t[6]))


def crop_ply(src, dst, xmin, ymin, xmax, ymax):
    """Keep the points of a binary little-endian PLY point cloud inside [xmin, xmax] x [ymin, ymax]
    (every vertex property kept). The fields' seabed is a finite mesh: at its edge the swaths see
    a drop that the 2D method took for BOP panels, and a real seabed has no such edge."""
    types = {'float': 'f4', 'float32': 'f4', 'double': 'f8', 'float64': 'f8', 'uchar': 'u1', 'uint8': 'u1',
             'char': 'i1', 'int8': 'i1', 'ushort': 'u2', 'uint16': 'u2', 'short': 'i2', 'int16': 'i2',
             'uint': 'u4', 'uint32': 'u4', 'int': 'i4', 'int32': 'i4'}
    with open(src, 'rb') as f:
        hdr = b''
        while not hdr.endswith(b'end_header\n'):
            line = f.readline()
            if not line:
                sys.exit('crop: %s: no end_header' % src)
            hdr += line
        lines = hdr.decode().split('\n')
        if 'format binary_little_endian 1.0' not in lines:
            sys.exit('crop: %s: only binary little-endian PLY' % src)
        n, props, in_vertex = 0, [], False
        for ln in lines:
            w = ln.split()
            if w[:2] == ['element', 'vertex']:
                n, in_vertex = int(w[2]), True
            elif w[:1] == ['element']:
                in_vertex = False
            elif w[:1] == ['property'] and in_vertex:
                props.append((w[2], '<' + types[w[1]]))
        a = np.frombuffer(f.read(n * np.dtype(props).itemsize), dtype=props)
    keep = a[(a['x'] >= xmin) & (a['x'] <= xmax) & (a['y'] >= ymin) & (a['y'] <= ymax)]
    out = hdr.decode().replace('element vertex %d\n' % n, 'element vertex %d\n' % len(keep))
    with open(dst + '.tmp', 'wb') as f:
        f.write(out.encode())
        f.write(keep.tobytes())
    os.replace(dst + '.tmp', dst)
    print('%s: %d of %d points inside [%g, %g] x [%g, %g]' % (dst, len(keep), n, xmin, xmax, ymin, ymax))


def main():
    a = sys.argv[1:]
    if len(a) >= 2 and a[0] == 'generate':
        meshes = os.path.join(ROOT, '..', 'shared', 'data', 'meshes')
        if '--meshes' in a:
            meshes = a[a.index('--meshes') + 1]
        generate(a[1], os.path.abspath(meshes))
    elif len(a) == 4 and a[0] == 'label':
        label(a[1], a[2], a[3])
    elif len(a) == 7 and a[0] == 'crop':
        crop_ply(a[1], a[2], *[float(x) for x in a[3:]])
    elif len(a) == 3 and a[0] == 'table':
        table(a[1], a[2])
    else:
        sys.exit(__doc__)


if __name__ == '__main__':
    main()

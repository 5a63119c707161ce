#!/usr/bin/env bash
# The 3D method (thesis sec. 6.3.1) on a 24 x 18 m field like issue 28's (docs/recognition.md, "The
# 3D method, issue 28"): a 7 x 6 x 1.6 m open lattice frame and a 3 x 2 x 2.3 m panel frame (meshes
# of our own design, written here), the BOP panel, a torpedo partly buried and a hot stab (public
# meshes, ../shared/data/meshes), a wreck-like pile of boxes as clutter, on 25 cm relief with rocks
# and a trench; a downward MB2250-like sonar 5 m up on lines 3 m apart, carved at 2 cm; a catalogue
# of the five plus five distractors (a second torpedo, a sonobuoy, a 14.5 cm valve, the reference
# tank and pillar). Prints per-model subspaces, times and nearest misses, then recall/precision
# (bench_recognition).
# Usage: bench/recognition_3d_field.sh BUILD_DIR WORK_DIR [MESH_DIR]
set -euo pipefail
BUILD=${1:-build}
WORK=${2:-/tmp/sonar3d_recognition_3d_field}
MESHES=${3:-$(dirname "$0")/../../shared/data/meshes}
S3D="$BUILD/bin/sonar3d"
BENCH="$BUILD/bench/bench_recognition"
mkdir -p "$WORK"
for m in bop_panel hot_stab valve torpedo_mk46 torpedo_mk48 sonobuoy; do cp "$MESHES/$m.dae" "$WORK/"; done
python3 - "$WORK" <<'PY'
import sys
out = sys.argv[1]
def box(c, s):
    cx, cy, cz = c; sx, sy, sz = [x / 2 for x in s]
    v = [(cx + dx * sx, cy + dy * sy, cz + dz * sz) for dx in (-1, 1) for dy in (-1, 1) for dz in (-1, 1)]
    return v, [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
def write(name, boxes):
    V, F = [], []
    for c, s in boxes:
        v, f = box(c, s); o = len(V); V += v
        for q in f: F += [(q[0] + o, q[1] + o, q[2] + o), (q[0] + o, q[2] + o, q[3] + o)]
    with open(f"{out}/{name}", "w") as f:
        f.writelines("v %.4f %.4f %.4f\n" % p for p in V)
        f.writelines("f %d %d %d\n" % (t[0] + 1, t[1] + 1, t[2] + 1) for t in F)
# Lattice frame 7 x 6 x 1.6 m: 20 posts on a 5 x 4 grid, top beams both ways, mid beams along x,
# a deck plate over one bay, two skids.
L, xs, ys = [], [-3.45, -1.725, 0, 1.725, 3.45], [-2.95, -0.983, 0.983, 2.95]
L += [((x, y, 0.8), (0.1, 0.1, 1.6)) for x in xs for y in ys]
for y in ys: L += [((0, y, 1.55), (7.0, 0.1, 0.1)), ((0, y, 0.8), (7.0, 0.08, 0.08))]
L += [((x, 0, 1.55), (0.1, 6.0, 0.1)) for x in xs]
L += [((-2.59, -1.97, 1.22), (1.6, 1.9, 0.04))] + [((0, y, 0.05), (7.2, 0.3, 0.1)) for y in (-2.95, 2.95)]
write("lattice_frame.obj", L)
# Panel frame 3 x 2 x 2.3 m: 4 posts, top and bottom rings, two side panels, a roof over half.
P = [((x, y, 1.15), (0.12, 0.12, 2.3)) for x in (-1.44, 1.44) for y in (-0.94, 0.94)]
for z in (0.06, 2.24):
    P += [((0, y, z), (3.0, 0.12, 0.12)) for y in (-0.94, 0.94)] + [((x, 0, z), (0.12, 2.0, 0.12)) for x in (-1.44, 1.44)]
P += [((0, y, 0.7), (2.76, 0.03, 1.2)) for y in (-0.95, 0.95)] + [((-0.72, 0, 2.29), (1.5, 1.88, 0.03))]
write("panel_frame.obj", P)
PY
cat > "$WORK/field.yaml" <<'YAML'
seed: 8
sensor: {preset: mb2250, r_min: 3.0, r_max: 8.0, range_bins: 250, T_vehicle_sonar: {rpy_deg: [0, 90, 0]}}
simulation: {elevation_step_deg: 0.1}
objects:
  - {name: seabed, primitive: {type: terrain, size: [26, 20], cell: 0.05, relief: 0.25, wavelength: 7, trenches: 1, rocks: 30, seed: 8}, reflectivity: 0.3}
  - {name: lattice_frame, mesh: lattice_frame.obj, pose: {translation: [-6.5, 3.0, -0.05], rpy_deg: [0, 0, 15]}, reflectivity: 0.8}
  - {name: panel_frame, mesh: panel_frame.obj, pose: {translation: [5.0, 4.5, -0.05], rpy_deg: [0, 0, -30]}, reflectivity: 0.8}
  - {name: bop_panel, mesh: bop_panel.dae, pose: {translation: [2.5, -4.0, -0.03], rpy_deg: [0, 0, 50]}, reflectivity: 0.8}
  - {name: torpedo_mk46, mesh: torpedo_mk46.dae, pose: {translation: [-5.0, -4.5, 0.02], rpy_deg: [0, 0, 110]}, reflectivity: 0.8}
  - {name: hot_stab, mesh: hot_stab.dae, pose: {translation: [8.5, -3.5, 0.04], rpy_deg: [0, 0, -20]}, reflectivity: 0.8}
  - {name: wreck_a, primitive: {type: box, size: [2.2, 0.9, 0.7]}, pose: {translation: [-0.5, 5.5, 0.2], rpy_deg: [6, -4, 30]}, reflectivity: 0.6}
  - {name: wreck_b, primitive: {type: box, size: [1.1, 0.8, 1.0]}, pose: {translation: [0.6, 6.2, 0.3], rpy_deg: [0, 12, 75]}, reflectivity: 0.6}
  - {name: wreck_c, primitive: {type: box, size: [0.8, 0.5, 0.4]}, pose: {translation: [-1.4, 4.6, 0.15], rpy_deg: [15, 0, 10]}, reflectivity: 0.6}
  - {name: wreck_d, primitive: {type: box, size: [1.5, 0.3, 0.3]}, pose: {translation: [1.0, 4.8, 0.1], rpy_deg: [0, 0, -40]}, reflectivity: 0.6}
trajectory: {type: lawnmower, x: [-11, 11], y: [-8, 8], z: 5.0, line_spacing: 3, spacing: 0.04, turn_radius: 1.5, period: 0.1}
YAML
cat > "$WORK/catalogue.yaml" <<'YAML'
models:
  - {name: lattice_frame, mesh: lattice_frame.obj, symmetry: "180"}
  - {name: panel_frame, mesh: panel_frame.obj, symmetry: none}
  - {name: bop_panel, mesh: bop_panel.dae, symmetry: none}
  - {name: torpedo_mk46, mesh: torpedo_mk46.dae, symmetry: "180"}
  - {name: hot_stab, mesh: hot_stab.dae, symmetry: none}
  - {name: torpedo_mk48, mesh: torpedo_mk48.dae, symmetry: "180"}
  - {name: sonobuoy, mesh: sonobuoy.dae, symmetry: full}
  - {name: valve, mesh: valve.dae, symmetry: full}
  - {name: tank, reference: tank, symmetry: full}
  - {name: pillar, reference: pillar, symmetry: "180"}
YAML
if [ ! -f "$WORK/field.ply" ]; then
  rm -rf "$WORK/field.ds"
  "$S3D" simulate "$WORK/field.yaml" -o "$WORK/field.ds" -q
  "$S3D" reconstruct "$WORK/field.ds" -o "$WORK/field.ply" --voxel-size 0.02 -q
fi
/usr/bin/time -v "$S3D" recognize "$WORK/field.ply" --catalogue "$WORK/catalogue.yaml" \
  -o "$WORK/placements_3d.json" --method 3d --overwrite -q 2> "$WORK/time_3d.txt"
grep -E "Elapsed|Maximum resident" "$WORK/time_3d.txt"
"$BENCH" "$WORK/field.yaml" "$WORK/field.ply" "$WORK/catalogue.yaml" --method 3d --label "field 24x18, 3d"

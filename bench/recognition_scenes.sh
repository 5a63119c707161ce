#!/usr/bin/env bash
# Robustness measurements of CAD-model recognition (docs/recognition.md): small simulated scenes
# (10 x 8 m of seabed with relief and rocks, a downward-looking MB2250-like sonar 4 m up, four
# lines 2 m apart), each carved (2 cm voxels) and recognised, then compared to the scene's truth
# by bench_recognition. Usage: bench/recognition_scenes.sh BUILD_DIR WORK_DIR
set -euo pipefail
BUILD=${1:-build}
WORK=${2:-/tmp/sonar3d_recognition_scenes}
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
S3D="$BUILD/bin/sonar3d"
BENCH="$BUILD/bench/bench_recognition"
mkdir -p "$WORK"

scene() {  # name, rocks, seabed pose, objects...
  local name=$1 rocks=$2 seabed_pose=$3; shift 3
  {
    echo "seed: 4"
    echo "sensor: {preset: mb2250, r_min: 1.0, r_max: 6.0, range_bins: 250, T_vehicle_sonar: {rpy_deg: [0, 90, 0]}}"
    echo "simulation: {elevation_step_deg: 0.1}"
    echo "objects:"
    echo "  - {name: seabed, primitive: {type: terrain, size: [12, 10], cell: 0.05, relief: 0.15, wavelength: 6, trenches: 0, rocks: $rocks, seed: 4}, pose: $seabed_pose, reflectivity: 0.3}"
    for o in "$@"; do echo "  - $o"; done
    echo "trajectory: {type: lawnmower, x: [-4, 4], y: [-3, 3], z: 4.0, line_spacing: 2.0, spacing: 0.04, period: 0.1}"
  } > "$WORK/$name.yaml"
}

catalogue() {  # name, scale, extra lines...
  local name=$1 scale=$2; shift 2
  {
    echo "models:"
    echo "  - {name: riser, reference: riser, symmetry: none, scale: $scale}"
    echo "  - {name: tank, reference: tank, symmetry: full, scale: $scale}"
    echo "  - {name: pillar, reference: pillar, symmetry: \"180\", scale: $scale}"
    for l in "$@"; do echo "  - $l"; done
  } > "$WORK/$name.yaml"
}

RISER="{name: riser, reference: riser, pose: {translation: [-2.0, 1.0, -0.05], rpy_deg: [0, 0, 20]}, reflectivity: 0.8}"
TANK="{name: tank, reference: tank, pose: {translation: [2.2, -1.0, -0.05]}, reflectivity: 0.8}"
PILLAR="{name: pillar, reference: pillar, pose: {translation: [1.8, 1.6, -0.05], rpy_deg: [0, 0, 65]}, reflectivity: 0.8}"
FLAT="{translation: [0, 0, 0]}"

scene single 8 "$FLAT" "$RISER"
scene three 8 "$FLAT" "$RISER" "$TANK" "$PILLAR"
scene clutter 40 "$FLAT" "$RISER" "$TANK" "$PILLAR"
scene buried 8 "$FLAT" \
  "{name: riser, reference: riser, pose: {translation: [-2.0, 1.0, -0.8], rpy_deg: [0, 0, 20]}, reflectivity: 0.8}" \
  "{name: tank, reference: tank, pose: {translation: [2.2, -1.0, -0.5]}, reflectivity: 0.8}" \
  "{name: pillar, reference: pillar, pose: {translation: [1.8, 1.6, -0.9], rpy_deg: [0, 0, 65]}, reflectivity: 0.8}"
# A 6° slope (the seabed pitched about y: height −x·tan 6°), structures tilted with it.
scene slope 8 "{rpy_deg: [0, 6, 0]}" \
  "{name: riser, reference: riser, pose: {translation: [-2.0, 1.0, 0.16], rpy_deg: [0, 6, 20]}, reflectivity: 0.8}" \
  "{name: tank, reference: tank, pose: {translation: [2.2, -1.0, -0.28], rpy_deg: [0, 6, 0]}, reflectivity: 0.8}" \
  "{name: pillar, reference: pillar, pose: {translation: [1.8, 1.6, -0.24], rpy_deg: [0, 6, 65]}, reflectivity: 0.8}"

# Marine growth (crude): 34 spheres of 3-8 cm radius scattered on the tops of the three
# structures of the "three" scene (tank top, pillar footing and column top, riser mudmat).
python3 - "$WORK" <<'PY'
import math, random, sys
work = sys.argv[1]
random.seed(7)
base = open(work + '/three.yaml').read()
lines = []
def add(x, y, z, r):
    lines.append("  - {name: growth%d, primitive: {type: sphere, radius: %.3f}, pose: {translation: [%.3f, %.3f, %.3f]}, reflectivity: 0.6}" % (len(lines), r, x, y, z))
for i in range(8):  # tank at (2.2, -1.0, -0.05), top at z = 1.0
    a = random.uniform(0, 2 * math.pi); d = random.uniform(0.05, 0.22); r = random.uniform(0.03, 0.07)
    add(2.2 + d * math.cos(a), -1.0 + d * math.sin(a), -0.05 + 1.0 + r * 0.3, r)
c, s = math.cos(math.radians(65)), math.sin(math.radians(65))
for i in range(14):  # pillar at (1.8, 1.6) yaw 65: footing top z = 0.4 outside the column
    while True:
        u, v = random.uniform(-0.95, 0.95), random.uniform(-0.95, 0.95)
        if max(abs(u), abs(v)) > 0.6: break
    r = random.uniform(0.03, 0.08)
    add(1.8 + c * u - s * v, 1.6 + s * u + c * v, -0.05 + 0.4 + r * 0.3, r)
for i in range(4):  # the column top, z = 2.5
    u, v = random.uniform(-0.25, 0.25), random.uniform(-0.25, 0.25); r = random.uniform(0.03, 0.06)
    add(1.8 + c * u - s * v, 1.6 + s * u + c * v, -0.05 + 2.5 + r * 0.3, r)
c, s = math.cos(math.radians(20)), math.sin(math.radians(20))
for i in range(8):  # riser at (-2, 1) yaw 20: mudmat top z = 0.1
    u, v = random.uniform(-0.45, 0.45), random.uniform(-0.45, 0.45); r = random.uniform(0.03, 0.06)
    add(-2 + c * u - s * v, 1 + s * u + c * v, -0.05 + 0.1 + r * 0.3, r)
open(work + '/growth.yaml', 'w').write(base.replace("trajectory:", "\n".join(lines) + "\ntrajectory:"))
PY

catalogue cat_exact 1.0
catalogue cat_small 0.9
catalogue cat_large 1.1
M="$ROOT/data/meshes"
catalogue cat_distractors 1.0 \
  "{name: bop_panel, mesh: $M/bop_panel.dae, symmetry: none}" \
  "{name: hot_stab, mesh: $M/hot_stab.dae, symmetry: none}" \
  "{name: sonobuoy, mesh: $M/sonobuoy.dae, symmetry: full}" \
  "{name: valve, mesh: $M/valve.dae, symmetry: none}" \
  "{name: sphere, reference: sphere, symmetry: full}"

run() {  # scene, catalogue, label
  local s=$1 c=$2 label=$3
  if [ ! -f "$WORK/$s.ply" ]; then
    rm -rf "$WORK/$s.ds"
    "$S3D" simulate "$WORK/$s.yaml" -o "$WORK/$s.ds" -q > /dev/null
    "$S3D" reconstruct "$WORK/$s.ds" -o "$WORK/$s.ply" --voxel-size 0.02 -q > /dev/null
  fi
  "$BENCH" "$WORK/$s.yaml" "$WORK/$s.ply" "$WORK/$c.yaml" --label "$label"
}

run single cat_exact "single structure (riser)"
run three cat_exact "three structures"
run clutter cat_distractors "three structures, 40 rocks, 5 distractor models"
run three cat_small "catalogue models 10 % small"
run three cat_large "catalogue models 10 % large"
run buried cat_exact "structures 40 % buried"
run slope cat_exact "6° slope, structures tilted with it"
run growth cat_exact "marine growth: 34 spheres of 3-8 cm on the tops"

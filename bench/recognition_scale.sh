#!/usr/bin/env bash
# Sizes off by ±10 % (issue 28 item 4, thesis sec. 6.7; docs/recognition.md "Scale"): structures
# built at 0.9, 0.95, 1.05 and 1.1 times their CAD model in small simulated scenes (12 x 10 m of
# seabed with relief and rocks, a downward-looking MB2250-like sonar 4 m up, four lines 2 m
# apart), carved (2 cm voxels) and recognised by the 2D method twice: with scale_range [0.9, 1.1]
# in the catalogue and without. Prints per structure the scale found, its error, the position
# and yaw errors and the time, for both runs.
# Usage: bench/recognition_scale.sh BUILD_DIR WORK_DIR [SCALES...]
set -euo pipefail
BUILD=${1:-build}
WORK=${2:-/tmp/sonar3d_recognition_scale}
shift 2 || true
SCALES=${*:-0.9 0.95 1.05 1.1}
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
MESHES=${MESHES:-$ROOT/../shared/data/meshes}
S3D="$BUILD/bin/sonar3d"
mkdir -p "$WORK"

# Family "ref": the project's reference riser, tank and pillar; family "mesh": two public CAD
# meshes (bop_panel, erov). Object poses as bench/recognition_scenes.sh and recognition_fields.py.
objects() {  # family scale
  local s=$2
  if [ "$1" = ref ]; then
    echo "  - {name: riser, reference: riser, scale: $s, pose: {translation: [-2.0, 1.0, -0.05], rpy_deg: [0, 0, 20]}, reflectivity: 0.8}"
    echo "  - {name: tank, reference: tank, scale: $s, pose: {translation: [2.2, -1.0, -0.05]}, reflectivity: 0.8}"
    echo "  - {name: pillar, reference: pillar, scale: $s, pose: {translation: [1.8, 1.6, -0.05], rpy_deg: [0, 0, 65]}, reflectivity: 0.8}"
  else
    echo "  - {name: bop_panel, mesh: $MESHES/bop_panel.dae, scale: $s, pose: {translation: [-2.5, 1.5, -0.03], rpy_deg: [0, 0, 25]}, reflectivity: 0.8}"
    echo "  - {name: erov, mesh: $MESHES/erov.dae, scale: $s, pose: {translation: [2.0, -1.0, -0.05], rpy_deg: [0, 0, -40]}, reflectivity: 0.8}"
  fi
}
catalogue() {  # family range-line
  if [ "$1" = ref ]; then
    echo "models:"
    echo "  - {name: riser, reference: riser, symmetry: none$2}"
    echo "  - {name: tank, reference: tank, symmetry: full$2}"
    echo "  - {name: pillar, reference: pillar, symmetry: \"180\"$2}"
  else
    echo "models:"
    echo "  - {name: bop_panel, mesh: $MESHES/bop_panel.dae, symmetry: none$2}"
    echo "  - {name: erov, mesh: $MESHES/erov.dae, symmetry: none$2}"
  fi
}

for fam in ref mesh; do
  catalogue $fam ", scale_range: [0.9, 1.1]" > "$WORK/cat_${fam}_range.yaml"
  catalogue $fam "" > "$WORK/cat_${fam}_fixed.yaml"
  for s in $SCALES; do
    name=${fam}_$s
    {
      echo "seed: 4"
      echo "sensor: {preset: mb2250, r_min: 1.0, r_max: 6.0, range_bins: 250, T_vehicle_sonar: {rpy_deg: [0, 90, 0]}}"
      echo "simulation: {elevation_step_deg: 0.1}"
      echo "objects:"
      echo "  - {name: seabed, primitive: {type: terrain, size: [12, 10], cell: 0.05, relief: 0.15, wavelength: 6, trenches: 0, rocks: 8, seed: 4}, pose: {translation: [0, 0, 0]}, reflectivity: 0.3}"
      objects $fam $s
      echo "trajectory: {type: lawnmower, x: [-4, 4], y: [-3, 3], z: 4.0, line_spacing: 2.0, spacing: 0.04, period: 0.1}"
    } > "$WORK/$name.yaml"
    [ -f "$WORK/$name/sonar.yaml" ] || "$S3D" simulate "$WORK/$name.yaml" -o "$WORK/$name" -q > /dev/null
    [ -f "$WORK/$name.ply" ] || "$S3D" reconstruct "$WORK/$name" -o "$WORK/$name.ply" --voxel-size 0.02 -q > /dev/null
    for run in range fixed; do
      "$S3D" recognize "$WORK/$name.ply" --catalogue "$WORK/cat_${fam}_$run.yaml" \
        -o "$WORK/${name}_$run.json" --overwrite -q > "$WORK/${name}_$run.log"
    done
  done
done

python3 - "$WORK" "$SCALES" <<'PY'
import json, math, sys
import yaml
work, scales = sys.argv[1], sys.argv[2].split()
SYM = {'riser': 360, 'tank': 0, 'pillar': 90, 'bop_panel': 360, 'erov': 360}
print('| model | true scale | run | found scale | scale error | position error (cm) | yaw error (deg) '
      '| confidence | registration (s) | scale search (s) |')
print('|---|---|---|---|---|---|---|---|---|---|')
for fam in ('ref', 'mesh'):
    for s in scales:
        name = '%s_%s' % (fam, s)
        scene = yaml.safe_load(open('%s/%s.yaml' % (work, name)))
        truth = {o['name']: o for o in scene['objects'] if o['name'] != 'seabed'}
        for run in ('range', 'fixed'):
            j = json.load(open('%s/%s_%s.json' % (work, name, run)))
            found = {}
            for p in j['placements']:
                found.setdefault(p['model'], p)
            for model, o in truth.items():
                p = found.get(model)
                if p is None:
                    print('| %s | %s | %s | missed | | | | | | |' % (model, s, run))
                    continue
                t = o['pose']['translation']
                d = math.dist(p['translation'][:2], t[:2]) * 100
                yaw_t = o['pose'].get('rpy_deg', [0, 0, 0])[2]
                per = SYM[model]
                e = abs((p['rpy_deg'][2] - yaw_t + per / 2) % per - per / 2) if per else 0.0
                sc = p.get('scale', 1.0)
                print('| %s | %s | %s | %.3f | %+.1f %% | %.1f | %.1f | %.2f | %.2f | %.2f |' % (
                    model, s, run, sc, (sc / float(s) - 1) * 100, d, e, p.get('confidence', float('nan')),
                    p['seconds_registration'], p.get('seconds_scale', 0.0)))
PY

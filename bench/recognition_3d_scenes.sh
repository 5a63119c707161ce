#!/usr/bin/env bash
# Measurements of the 3D recognition method (thesis sec. 6.3.1, docs/recognition.md): square
# patches of seabed (relief 15 cm, rocks) with one structure, a downward-looking MB2250-like sonar
# 4 m up on lines 1 m apart, carved at 2 cm (`sonar3d reconstruct`), then recognised by both
# methods and compared with the scene's truth by bench_recognition.
# Usage: bench/recognition_3d_scenes.sh BUILD_DIR WORK_DIR [SIZES...] (default sizes: 5 10 20 m)
set -euo pipefail
BUILD=${1:-build}
WORK=${2:-/tmp/sonar3d_recognition_3d}
shift 2 || true
SIZES=${*:-5 10 20}
S3D="$BUILD/bin/sonar3d"
BENCH="$BUILD/bench/bench_recognition"
mkdir -p "$WORK"

scene() {  # name, size m, object
  local name=$1 size=$2 object=$3
  local h
  h=$(python3 -c "print(max(1.0, $size / 2 - 0.5))")
  {
    echo "seed: 4"
    echo "sensor: {preset: mb2250, r_min: 1.0, r_max: 6.0, range_bins: 250, T_vehicle_sonar: {rpy_deg: [0, 90, 0]}}"
    echo "simulation: {elevation_step_deg: 0.1}"
    echo "objects:"
    echo "  - {name: seabed, primitive: {type: terrain, size: [$size, $size], cell: 0.05, relief: 0.15, wavelength: 6, trenches: 0, rocks: $((size * size / 12)), seed: 4}, pose: {translation: [0, 0, 0]}, reflectivity: 0.3}"
    echo "  - $object"
    echo "trajectory: {type: lawnmower, x: [-$h, $h], y: [-$h, $h], z: 4.0, line_spacing: 1.0, spacing: 0.04, period: 0.1}"
  } > "$WORK/$name.yaml"
}

{
  echo "models:"
  echo "  - {name: riser, reference: riser, symmetry: none}"
  echo "  - {name: tank, reference: tank, symmetry: full}"
  echo "  - {name: pillar, reference: pillar, symmetry: \"180\"}"
} > "$WORK/catalogue.yaml"

RISER="{name: riser, reference: riser, pose: {translation: [0.3, -0.2, -0.05], rpy_deg: [0, 0, 20]}, reflectivity: 0.8}"
TANK="{name: tank, reference: tank, pose: {translation: [0.3, -0.2, -0.05]}, reflectivity: 0.8}"
PILLAR="{name: pillar, reference: pillar, pose: {translation: [0.3, -0.2, -0.05], rpy_deg: [0, 0, 65]}, reflectivity: 0.8}"

run() {  # scene, method
  local s=$1 method=$2
  if [ ! -f "$WORK/$s.ply" ]; then
    rm -rf "$WORK/$s.ds"
    "$S3D" simulate "$WORK/$s.yaml" -o "$WORK/$s.ds" -q > /dev/null
    "$S3D" reconstruct "$WORK/$s.ds" -o "$WORK/$s.ply" --voxel-size 0.02 -q > /dev/null
  fi
  "$BENCH" "$WORK/$s.yaml" "$WORK/$s.ply" "$WORK/catalogue.yaml" --method "$method" --label "$s, $method"
}

for size in $SIZES; do
  scene "riser$size" "$size" "$RISER"
  for m in 3d 2d; do run "riser$size" $m; done
done
scene tank5 5 "$TANK"
scene pillar5 5 "$PILLAR"
for s in tank5 pillar5; do
  for m in 3d 2d; do run $s $m; done
done

#!/usr/bin/env bash
# Known structure poses on the field (docs/mapping.md "Measured: known structure poses", issue 26
# item 3): data/scenes/field.yaml simulated with its dead-reckoning error (or SCALE/HEADING
# overriding velocity_scale and heading_bias_deg), mapped as logged (pass 1), the structures
# recognised with data/catalogues/field.yaml, then mapped again with the scene's true poses of
# the riser, tank and pillar as known poses (as-built drawings) and the pass-1 placements.
# Prints both passes' navigation errors against the simulator's true navigation.
# Usage: bench/known_poses_field.sh BUILD_DIR WORK_DIR [map options, e.g. --method drift]
set -euo pipefail
SRC=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${1:-build}
WORK=${2:-/tmp/sonar3d_known_poses}
shift $(( $# >= 2 ? 2 : $# ))
S3D="$BUILD/bin/sonar3d"
ROI="--roi -27 -19 -1.2 27 19 3"
mkdir -p "$WORK"
sed -e "s/velocity_scale: 0.01/velocity_scale: ${SCALE:-0.01}/" \
    -e "s/heading_bias_deg: 0.2/heading_bias_deg: ${HEADING:-0.2}/" \
    "$SRC/data/scenes/field.yaml" > "$WORK/field.yaml"
cat > "$WORK/asbuilt.json" <<'JSON'
{"format": "sonar3d-placements", "version": 1, "placements": [
 {"model": "riser", "T_world_model": [[0.9396926207859084, -0.3420201433256687, 0, -12], [0.3420201433256687, 0.9396926207859084, 0, 6], [0, 0, 1, -0.1], [0, 0, 0, 1]]},
 {"model": "tank", "T_world_model": [[1, 0, 0, 4], [0, 1, 0, -8], [0, 0, 1, -0.1], [0, 0, 0, 1]]},
 {"model": "pillar", "T_world_model": [[0.42261826174069944, -0.9063077870366499, 0, 15], [0.9063077870366499, 0.42261826174069944, 0, 7], [0, 0, 1, -0.1], [0, 0, 0, 1]]}]}
JSON
rm -rf "$WORK/field" "$WORK/pass1" "$WORK/pass2"
/usr/bin/time -f "simulate: %e s, %M kB peak" "$S3D" simulate "$WORK/field.yaml" -o "$WORK/field" -q
/usr/bin/time -f "map (pass 1): %e s, %M kB peak" "$S3D" map "$WORK/field" -o "$WORK/pass1" $ROI "$@" \
  | grep -E "navigation error"
/usr/bin/time -f "recognize: %e s, %M kB peak" "$S3D" recognize "$WORK/pass1" \
  --catalogue "$SRC/data/catalogues/field.yaml" -o "$WORK/placements.json" -q
/usr/bin/time -f "map (pass 2): %e s, %M kB peak" "$S3D" map "$WORK/field" -o "$WORK/pass2" $ROI "$@" \
  --known-poses "$WORK/asbuilt.json" --placements "$WORK/placements.json" \
  | grep -E "known poses|used:|rejected:|navigation model|navigation error"

#!/usr/bin/env bash
# Recognition benchmark of unseen fields (issue 28; docs/recognition.md "Benchmark of unseen
# fields"). Six small fields (12 x 10 to 18 x 14 m) of public CAD meshes (../shared/data/meshes)
# and structures of our own design (bench/recognition_fields.py), with clutter that is not in the
# catalogues, burial, a slope, marine growth, and one clutter-only field; a downward-looking
# MB2250-like sonar 4 m up on lawnmower lines 2 m apart (as bench/recognition_scenes.sh).
# Each field is simulated and mapped (`sonar3d map`, as data/scenes/field.yaml; fields without
# navigation error also carved as one cloud, `sonar3d reconstruct`, which recognition then reads
# unless MAP_KIND=map), then recognised
# by both methods (`sonar3d recognize`, timed by /usr/bin/time -v, and bench_recognition against
# the scene's truth); datasets and maps are reused when present.
#
#   bench/recognition_fields.sh [all]  BUILD WORK [FIELDS...]  everything: data, recognition, table, calib
#   bench/recognition_fields.sh data   BUILD WORK [FIELDS...]  generate, simulate and map only
#   bench/recognition_fields.sh recog  BUILD WORK [FIELDS...]  recognition + bench (data must exist)
#   bench/recognition_fields.sh table  BUILD WORK              the summary table (Markdown)
#   bench/recognition_fields.sh calib  BUILD WORK              the labelled candidates: WORK/RUNS/calibration.csv
#
# Environment: RUNS (default runs: the recognition outputs' folder under WORK, e.g. runs_before),
# TIMEOUT (s per recognition run, default 300), METHODS (default "2d 3d"), MESHES (the public
# meshes, default ../shared/data/meshes beside the repository), RECOG_ARGS (extra flags for both
# methods of `sonar3d recognize`), BENCH_ARGS (extra flags for bench_recognition, e.g.
# --max-relief-proposals 4: its table's figures).
# The binaries are copied from BUILD to BIN (default WORK/bin) on the first run, so that a rebuild
# does not change them mid-run; another BIN (e.g. BIN=WORK/bin_after RUNS=runs_after) measures
# another build on the same datasets.
set -euo pipefail
MODE=all
case "${1:-}" in all|data|recog|table|calib) MODE=$1; shift ;; esac
BUILD=${1:-build}
WORK=${2:-/tmp/sonar3d_recognition_fields}
shift 2 || true
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
PY=/usr/bin/python3   # the Debian python3 with python3-numpy and python3-yaml
GEN="$ROOT/bench/recognition_fields.py"
RUNS=${RUNS:-runs}
TIMEOUT=${TIMEOUT:-300}
METHODS=${METHODS:-2d 3d}
MESHES=${MESHES:-$ROOT/../shared/data/meshes}
mkdir -p "$WORK/$RUNS"
WORK=$(cd "$WORK" && pwd)

if [ "$MODE" = table ]; then exec "$PY" "$GEN" table "$WORK" "$RUNS"; fi
if [ "$MODE" = calib ]; then exec "$PY" "$GEN" label "$WORK" "$RUNS" "$WORK/$RUNS/calibration.csv"; fi

BIN=${BIN:-$WORK/bin}
if [ ! -x "$BIN/sonar3d" ] || [ ! -x "$BIN/bench_recognition" ]; then
  mkdir -p "$BIN"
  cp "$BUILD/bin/sonar3d" "$BUILD/bench/bench_recognition" "$BIN/"
  git -C "$ROOT" rev-parse --short HEAD > "$BIN/COMMIT" 2>/dev/null || true
fi
S3D="$BIN/sonar3d"
BENCH="$BIN/bench_recognition"
FIELDS=$("$PY" "$GEN" generate "$WORK" --meshes "$MESHES")
[ $# -gt 0 ] && FIELDS="$*"
T="/usr/bin/time -v"

data() {  # field: simulate + map, each once
  local f=$1
  if [ ! -f "$WORK/$f.ds/frames.csv" ] || [ ! -f "$WORK/$f.ds/.complete" ]; then
    rm -rf "$WORK/$f.ds" "$WORK/${f}_map" "$WORK/${f}_map.ply" "$WORK/$f.ply" "$WORK/${f}_cloud.ply"
    echo "== $f: simulate" >&2
    $T -o "$WORK/$RUNS/$f.simulate.time.txt" nice -n 5 "$S3D" simulate "$WORK/$f.yaml" -o "$WORK/$f.ds" -q > /dev/null
    touch "$WORK/$f.ds/.complete"
  fi
  if [ ! -f "$WORK/${f}_map/merged.ply" ]; then
    rm -rf "$WORK/${f}_map" "$WORK/${f}_map.ply"
    echo "== $f: map" >&2
    local roi
    roi=$("$PY" -c "import json; f=[x for x in json.load(open('$WORK/fields.json'))['fields'] if x['name']=='$f'][0]; X,Y=f['size']; print(-X/2, -Y/2, -1.5, X/2, Y/2, 3.0)")
    # shellcheck disable=SC2086
    $T -o "$WORK/$RUNS/$f.map.time.txt" nice -n 5 "$S3D" map "$WORK/$f.ds" -o "$WORK/${f}_map" --roi $roi -q \
      > "$WORK/$RUNS/$f.map.txt"
  fi
  # Fields with perfect navigation are also carved as one cloud (no swath registration): the
  # recognition's own errors, without the map's (swath registration moved the swaths of
  # subsea_kit by up to 14 cm although the navigation was exact).
  if ! grep -q '^navigation_error' "$WORK/$f.yaml" && [ ! -f "$WORK/$f.ply" ]; then
    echo "== $f: reconstruct" >&2
    # The carving's whole configuration is written once into WORK and every cloud is carved
    # from it: the clouds keep the settings they were made with when reconstruct's defaults
    # change (issue 29 turned the ghost filters on; the 3D figures moved with it,
    # docs/recognition.md "After, recog3dfast").
    [ -f "$WORK/reconstruct.yaml" ] ||
      "$S3D" reconstruct --print-config --voxel-size 0.02 > "$WORK/reconstruct.yaml"
    $T -o "$WORK/$RUNS/$f.reconstruct.time.txt" nice -n 5 "$S3D" reconstruct "$WORK/$f.ds" \
      -o "$WORK/$f.ply" --config "$WORK/reconstruct.yaml" -q > /dev/null
  fi
  # What recognition reads: cut 0.5 m inside the seabed mesh's edge (the finite seabed ends in a
  # drop that no real seabed has; the 2D method placed BOP panels along it).
  local box
  box=$("$PY" -c "import json; f=[x for x in json.load(open('$WORK/fields.json'))['fields'] if x['name']=='$f'][0]; X,Y=f['size']; print(-X/2+0.5, -Y/2+0.5, X/2-0.5, Y/2-0.5)")
  # shellcheck disable=SC2086
  [ -f "$WORK/$f.ply" ] && [ ! -f "$WORK/${f}_cloud.ply" ] && "$PY" "$GEN" crop "$WORK/$f.ply" "$WORK/${f}_cloud.ply" $box >&2
  # shellcheck disable=SC2086
  [ ! -f "$WORK/${f}_map.ply" ] && "$PY" "$GEN" crop "$WORK/${f}_map/merged.ply" "$WORK/${f}_map.ply" $box >&2
  return 0
}

map_of() {  # what recognition reads: MAP_KIND=auto (default: the carved cloud for fields with
  # perfect navigation, the swath-registered map for the drift field) or map (always the map),
  # both cut to the seabed's interior
  if [ "${MAP_KIND:-auto}" = auto ] && [ -f "$WORK/${1}_cloud.ply" ]; then echo "$WORK/${1}_cloud.ply"; else echo "$WORK/${1}_map.ply"; fi
}

recog() {  # field, method
  local f=$1 m=$2 out="$WORK/$RUNS/$1.$2"
  echo "== $f: recognize --method $m" >&2
  rm -f "$out.json" "$out.ply"
  # shellcheck disable=SC2086
  $T -o "$out.time.txt" timeout "$TIMEOUT" nice -n 5 "$S3D" recognize "$(map_of "$f")" \
    --catalogue "$WORK/${f}_catalogue.yaml" -o "$out.json" --method "$m" -q ${RECOG_ARGS:-} \
    > "$out.txt" 2>&1 || echo "   (exit $?: see $out.txt, $out.time.txt)" >&2
  echo "== $f: bench_recognition --method $m" >&2
  $T -o "$out.bench.time.txt" timeout "$TIMEOUT" nice -n 5 "$BENCH" "$WORK/$f.yaml" "$(map_of "$f")" \
    "$WORK/${f}_catalogue.yaml" --method "$m" --label "$f, $m" ${BENCH_ARGS:-} > "$out.bench.txt" 2>&1 \
    || echo "   (exit $?: see $out.bench.txt)" >&2
}

for f in $FIELDS; do data "$f"; done
[ "$MODE" = data ] && exit 0
for f in $FIELDS; do
  for m in $METHODS; do recog "$f" "$m"; done
done
"$PY" "$GEN" table "$WORK" "$RUNS" | tee "$WORK/$RUNS/table.md"
"$PY" "$GEN" label "$WORK" "$RUNS" "$WORK/$RUNS/calibration.csv"

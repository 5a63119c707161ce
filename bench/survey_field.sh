#!/usr/bin/env bash
# `sonar3d survey` end to end on the issue-27 field (docs/survey.md): data/scenes/field.yaml cut to
# 40 x 30 m of survey lines (six East-West lines 6 m apart, x in [-20, 20], y in [-15, 15], the
# same seabed, structures, pipelines, sensor and dead-reckoning errors), simulated, then surveyed
# with data/catalogues/field.yaml: map (--method drift as docs/mapping.md) -> recognize (2d) ->
# world -> report. Prints the survey's stage table (wall time, peak memory, figures) and keeps
# WORK/survey/summary.json. With FULL=1 the whole data/scenes/field.yaml (54 x 38 m) instead.
# Usage: bench/survey_field.sh BUILD_DIR WORK_DIR
set -euo pipefail
SRC=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${1:-build}
WORK=${2:-/tmp/sonar3d_survey_field}
S3D="$BUILD/bin/sonar3d"
mkdir -p "$WORK"
if [ "${FULL:-0}" = 1 ]; then
  cp "$SRC/data/scenes/field.yaml" "$WORK/field.yaml"
  ROI="[-27, -19, -1.2, 27, 19, 3]"
else
  sed -e 's/^trajectory: .*$/trajectory: {type: lawnmower, x: [-20, 20], y: [-15, 15], z: 5.0, line_spacing: 6, spacing: 0.04, turn_radius: 3, period: 0.1}/' \
    "$SRC/data/scenes/field.yaml" > "$WORK/field.yaml"
  ROI="[-23, -18, -1.2, 23, 18, 3]"
fi
cat > "$WORK/survey.yaml" <<YAML
map: {region: $ROI, method: drift}
YAML
rm -rf "$WORK/field" "$WORK/survey"
/usr/bin/time -f "simulate: %e s, %M kB peak" "$S3D" simulate "$WORK/field.yaml" -o "$WORK/field" -q
/usr/bin/time -f "survey: %e s, %M kB peak" "$S3D" survey "$WORK/field" -o "$WORK/survey" \
  --catalogue "$SRC/data/catalogues/field.yaml" --config "$WORK/survey.yaml" -q

#!/usr/bin/env bash
# Relocalisation of one 36 m line against the field's world model (docs/mapping.md
# "Relocalisation", "Field"; issue 26 item 4: <= 5 cm, <= 5 s). Builds, once per WORK_DIR:
#   the field (data/scenes/field.yaml) simulated; its dataset with the simulator's TRUE navigation
#   mapped (map --method global --roi ...), the structures recognised (data/catalogues/field.yaml)
#   and turned into a world model (sonar3d world).
# Then, per line (LINES: diag, diag_a, diag_b, ew; default all four), a 36 m line simulated over
# the field with the field's dead-reckoning error, its logged navigation moved by a known rigid
# error (a turn about the line's middle and a shift: the unknown start of a new dive), relocalised
# against the world model. Prints per line the horizontal error against the simulator's true
# navigation (median / max, as logged and relocalised), the vertical median, the heading error,
# sigma, and the time: relocalize's own (inside: carving + registration) and the whole command's
# CPU user and wall time with the load average before the run.
# Usage: bench/relocalize_field.sh BUILD_DIR WORK_DIR [relocalize options, e.g. --threads 1]
set -euo pipefail
SRC=$(cd "$(dirname "$0")/.." && pwd)
BUILD=${1:-build}
WORK=${2:-/tmp/sonar3d_relocalize_field}
shift $(( $# >= 2 ? 2 : $# ))
S3D="$BUILD/bin/sonar3d"
ROI="--roi -27 -19 -1.2 27 19 3"
LINES=${LINES:-"diag diag_a diag_b ew"}
mkdir -p "$WORK"
WORK=$(cd "$WORK" && pwd)

if [ ! -f "$WORK/world/graph.json" ]; then
  rm -rf "$WORK/field" "$WORK/field_true" "$WORK/map_true" "$WORK/world" "$WORK/placements.json"
  /usr/bin/time -f "simulate field: %U s user, %e s wall, %M kB peak" \
    "$S3D" simulate "$SRC/data/scenes/field.yaml" -o "$WORK/field" -q
  # The dataset with the simulator's true navigation (frames shared by links).
  mkdir "$WORK/field_true"
  for f in "$WORK/field"/*; do
    [ "$(basename "$f")" = navigation.tum ] || ln -s "$f" "$WORK/field_true/"
  done
  cp "$WORK/field/truth/navigation.tum" "$WORK/field_true/navigation.tum"
  /usr/bin/time -f "map (true navigation): %U s user, %e s wall, %M kB peak" \
    "$S3D" map "$WORK/field_true" -o "$WORK/map_true" $ROI --method global -q
  /usr/bin/time -f "recognize: %U s user, %e s wall, %M kB peak" \
    "$S3D" recognize "$WORK/map_true" --catalogue "$SRC/data/catalogues/field.yaml" \
    -o "$WORK/placements.json" -q
  /usr/bin/time -f "world: %U s user, %e s wall, %M kB peak" \
    "$S3D" world "$WORK/map_true" --placements "$WORK/placements.json" \
    --catalogue "$SRC/data/catalogues/field.yaml" -o "$WORK/world" -q
fi

# name: start, end, heading (deg), then the rigid error: E, N (m), turn (deg) about the middle.
line_def() {
  case "$1" in
    diag)   echo "-15.6 -9 15.6 9 30 0 0 0" ;;
    diag_a) echo "-15.6 -9 15.6 9 30 0.5 -0.3 3" ;;
    diag_b) echo "-15.6 -9 15.6 9 30 -0.6 0.5 -4" ;;
    ew)     echo "-18 2 18 2 0 0.5 -0.3 3" ;;
    *) echo "unknown line '$1' (diag, diag_a, diag_b, ew)" >&2; exit 2 ;;
  esac
}

for name in $LINES; do
  read -r x0 y0 x1 y1 hdg de dn turn <<<"$(line_def "$name")"
  L="$WORK/line_$name"
  if [ ! -f "$L/navigation_logged.tum" ]; then
    rm -rf "$L" "$L.yaml"
    sed -e "s|^trajectory:.*|trajectory: {type: straight, start: [$x0, $y0, 5.0], end: [$x1, $y1, 5.0], spacing: 0.04, rpy_deg: [0, 0, $hdg], period: 0.1}|" \
      "$SRC/data/scenes/field.yaml" > "$L.yaml"
    "$S3D" simulate "$L.yaml" -o "$L" -q
    # The known rigid error on the logged (dead-reckoned) navigation: turned by `turn` about the
    # line's middle, then shifted by (de, dn).
    python3 - "$L/navigation.tum" "$L/navigation_logged.tum" "$de" "$dn" "$turn" \
      "$(echo "($x0 + $x1) / 2" | bc -l)" "$(echo "($y0 + $y1) / 2" | bc -l)" <<'PY'
import math, sys
src, dst, de, dn, turn, cx, cy = sys.argv[1], sys.argv[2], *map(float, sys.argv[3:])
a = math.radians(turn); c, s = math.cos(a), math.sin(a)
qz, qw = math.sin(a / 2), math.cos(a / 2)
out = []
for line in open(src):
    f = line.split()
    if not f or f[0].startswith('#'):
        out.append(line); continue
    t, x, y, z, qx1, qy1, qz1, qw1 = f[0], *map(float, f[1:8])
    x, y = x - cx, y - cy
    x, y = c * x - s * y + cx + de, s * x + c * y + cy + dn
    # q = q_turn * q_pose (the turn about z applied in the world)
    nx = qw * qx1 - qz * qy1
    ny = qw * qy1 + qz * qx1
    nz = qw * qz1 + qz * qw1
    nw = qw * qw1 - qz * qz1
    out.append(f"{t} {x:.6f} {y:.6f} {z:.6f} {nx:.9f} {ny:.9f} {nz:.9f} {nw:.9f}\n")
open(dst, 'w').writelines(out)
PY
    cp "$L/navigation_logged.tum" "$L/navigation.tum"
  fi
  rm -rf "$WORK/reloc_$name"
  load=$(cut -d' ' -f1-3 /proc/loadavg)
  /usr/bin/time -o "$WORK/time_$name" -f "%U %S %e %M" \
    "$S3D" relocalize "$L" --world "$WORK/world" -o "$WORK/reloc_$name" -q "$@" \
    > "$WORK/out_$name" || true
  read -r user sys wall peak < "$WORK/time_$name"
  python3 - "$L/truth/navigation.tum" "$L/navigation.tum" "$WORK/reloc_$name" "$name" \
    "$de $dn $turn" "$user" "$sys" "$wall" "$peak" "$load" <<'PY'
import json, math, os, sys
truth_f, logged_f, out, name, err, user, sys_s, wall, peak, load = sys.argv[1:]
def tum(f):
    r = []
    for line in open(f):
        v = line.split()
        if v and not v[0].startswith('#'):
            r.append(list(map(float, v[:8])))
    return r
def yaw(p):
    qx, qy, qz, qw = p[4:8]
    return math.atan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz))
def med(v):
    v = sorted(v); return v[len(v) // 2]
truth, logged = tum(truth_f), tum(logged_f)
j = json.load(open(os.path.join(out, 'relocalization.json')))
def stats(nav):
    h = [math.hypot(a[1] - b[1], a[2] - b[2]) for a, b in zip(nav, truth)]
    return med(h), max(h)
lm, lx = stats(logged)
line = f"{name} (error E N turn: {err}): as logged {lm:.3f} / {lx:.3f} m; "
if j['found']:
    nav = tum(os.path.join(out, 'navigation.tum'))
    assert len(nav) == len(truth)
    m, x = stats(nav)
    v = med([abs(a[3] - b[3]) for a, b in zip(nav, truth)])
    dy = med([abs(math.degrees(math.remainder(yaw(a) - yaw(b), 2 * math.pi)))
              for a, b in zip(nav, truth)])
    line += (f"relocalised {m:.3f} / {x:.3f} m, vertical median {v:.3f} m, heading {dy:.2f} deg, "
             f"sigma {j['sigma_horizontal_m']:.3f} m; ")
else:
    line += "NOT FOUND; "
s = j['seconds']
line += (f"inside {s['total']:.2f} s (carving {s['carving']:.2f} + registration "
         f"{s['registration']:.2f}); command {user} s user + {sys_s} s system, {wall} s wall, {int(peak) // 1024} MB; "
         f"load {load}")
print(line)
PY
done

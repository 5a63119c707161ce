#!/usr/bin/env bash
# Latency and rate of the ROS 1 node `sonar3d ros` (issue 25 item 4, docs/online.md).
#
# Simulates a sonar moving forward at 1 m/s, 2 m (P900) or 1 m (MB2250) above a seabed with a pipeline and a few
# reference shapes, looking forward and down, at the sensor's rate: P900-like (preset p900-130)
# at 15 Hz and MB2250-like (preset mb2250) at 40 Hz. Exports each as a ROS 1 bag, starts roscore
# on a free port of 127.0.0.1 and the node (2 cm voxels, --queue 8, cloud published at 1 Hz),
# plays the bag with Debian's `rosbag play -r R` (R = 1, then faster), and prints per run the
# node's own statistics (its JSON on exit): frames received / carved / dropped, per-frame latency
# from message arrival to the frame carved into the map and to the first cloud published with it
# (median, p95, max), the carving time per frame, and the load average at the time.
#
#   bench/ros_latency.sh BUILD_DIR WORK_DIR [p900|mb2250|both] [RATE_FACTORS...]
# e.g. bench/ros_latency.sh build /tmp/ros_bench both 1 2 3
# Environment: VOXEL (m, default 0.02), ROI ("xmin ymin zmin xmax ymax zmax", m; default the seabed
# prior -1 -8 -2.05 16 8 -0.5), RATE (cloud publishing rate, Hz, default 1), QUEUE (--queue, 8),
# CATALOGUE (a catalogue YAML: the node recognises its models every RECOG_PERIOD s, default 10,
# and the run prints the recognitions' count, time and skips), GRACE (s between the bag's end and
# the node's SIGINT, default 3).
set -euo pipefail
BUILD=$(realpath "${1:?build dir}")
WORK=${2:?work dir}
WHICH=${3:-both}
shift 3 || true
FACTORS=("$@")
[ ${#FACTORS[@]} -eq 0 ] && FACTORS=(1)
S="$BUILD/bin/sonar3d"
PY=/usr/bin/python3  # Debian's interpreter: it has the ROS 1 modules
VOXEL=${VOXEL:-0.02}
ROI=${ROI:--1 -8 -2.05 16 8 -0.5}
RATE=${RATE:-1}
QUEUE=${QUEUE:-8}
CATALOGUE=${CATALOGUE:-}
RECOG_PERIOD=${RECOG_PERIOD:-10}
GRACE=${GRACE:-3}
RECOG=()
TAG=""
if [ -n "$CATALOGUE" ]; then
  RECOG=(--catalogue "$(realpath "$CATALOGUE")" --recognition-period "$RECOG_PERIOD")
  TAG=".recog$RECOG_PERIOD"
fi
mkdir -p "$WORK"
WORK=$(realpath "$WORK")

PORT=$($PY -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
export ROS_MASTER_URI=http://127.0.0.1:$PORT ROS_IP=127.0.0.1 ROS_HOME=$WORK/ros_home \
  ROS_LOG_DIR=$WORK/ros_log
unset ROS_HOSTNAME
PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill -INT -- "-$p" 2>/dev/null || true; done
  sleep 1
  for p in "${PIDS[@]}"; do kill -KILL -- "-$p" 2>/dev/null || true; done
}
trap cleanup EXIT INT TERM
setsid roscore -p "$PORT" >"$WORK/roscore.log" 2>&1 &
PIDS+=($!)
for _ in $(seq 100); do
  $PY -c "import rosgraph,sys; sys.exit(0 if rosgraph.is_master_online() else 1)" && break
  sleep 0.2
done

scene() {  # name preset rate_hz altitude_m pitch_deg
  local name=$1 preset=$2 hz=$3 alt=$4 pitch=$5
  local period spacing
  period=$($PY -c "print(1/$hz)")
  spacing=$($PY -c "print(1.0/$hz)")  # 1 m/s
  cat >"$WORK/$name.yaml" <<EOF
# bench/ros_latency.sh: $preset at $hz Hz, 1 m/s, $alt m above the seabed, $pitch degrees down.
seed: 11
sensor:
  preset: $preset
  T_vehicle_sonar: {rpy_deg: [0, $pitch, 0]}
simulation: {elevation_step_deg: 0.05}
objects:
  - {name: seabed, primitive: {type: plane, size: [40, 40]}, pose: {translation: [0, 0, -2]}, reflectivity: 0.25}
  - {name: pipeline, primitive: {type: cylinder, radius: 0.2, height: 20}, pose: {translation: [6, 0, -1.8], rpy_deg: [0, 90, 0]}, reflectivity: 0.8}
  - {name: ball, primitive: {type: sphere, radius: 0.4}, pose: {translation: [5, 1.5, -1.6]}, reflectivity: 0.9}
  - {name: box, primitive: {type: box, size: [0.8, 0.6, 0.5]}, pose: {translation: [8, -1.5, -1.75]}, reflectivity: 0.7}
trajectory: {period: $period, type: straight, start: [0, 0, $(echo "$alt - 2" | bc -l)], end: [8, 0, $(echo "$alt - 2" | bc -l)], spacing: $spacing}
EOF
  if [ ! -f "$WORK/$name.bag" ]; then
    "$S" simulate "$WORK/$name.yaml" -o "$WORK/$name.ds" -q
    "$S" export rosbag "$WORK/$name.ds" -o "$WORK/$name.bag" --ros1 -q
  fi
}

run() {  # name factor
  local name=$1 f=$2
  local out="$WORK/$name.v$VOXEL.r$RATE.q$QUEUE.x$f$TAG.json"
  # shellcheck disable=SC2086
  # GNU time (which ignores SIGINT while it waits) gives the node's CPU time, all threads, at exit.
  setsid /usr/bin/time -f "%U %S" -o "$out.time" "$S" ros --quiet --voxel-size "$VOXEL" --roi $ROI --rate "$RATE" --queue "$QUEUE" "${RECOG[@]}" >"$out" 2>"$WORK/$name.v$VOXEL.r$RATE.q$QUEUE.x$f$TAG.log" &
  local node=$!
  PIDS+=("$node")
  rosbag play --wait-for-subscribers -q -r "$f" "$WORK/$name.bag" >/dev/null 2>&1
  sleep "$GRACE"  # the queue drains, the last cloud goes out
  local load
  load=$(cut -d' ' -f1-3 /proc/loadavg)
  kill -INT -- "-$node"
  wait "$node" || true
  load="$load; node CPU user+sys $(awk '{printf "%.2f s", $1 + $2}' "$out.time")"
  $PY - "$out" "$name" "$f" "$load" "$VOXEL" "$RATE" "$QUEUE" <<'EOF'
import json, sys
path, name, f, load, voxel, rate, queue = sys.argv[1:]
s = json.loads(open(path).read().strip().splitlines()[-1])
m = s['map']
c, p = s['latency_arrival_to_carved_ms'], s['latency_arrival_to_published_ms']
dropped = s['dropped_node_queue_full'] + s['frames_dropped_by_map']
left = s['queued']  # still waiting in the node's queue at SIGINT: not carved
print(f"{name} voxel {voxel} m, cloud at {rate} Hz, queue {queue}, bag x{f}: received {s['sonar_received']}, carved {m.get('frames_used', 0)}, dropped {dropped} "
      f"(queue full {s['dropped_node_queue_full']}), left in the queue at exit {left}; arrival->carved ms median {c['median']:.1f} "
      f"p95 {c['p95']:.1f} max {c['max']:.1f}; arrival->published median {p['median']:.0f} "
      f"p95 {p['p95']:.0f}; carve ms/frame median {m.get('push_ms', {}).get('median', 0):.1f} "
      f"p95 {m.get('push_ms', {}).get('p95', 0):.1f}; cloud() ms (last) {m.get('resolve_ms_last', 0):.0f}; "
      f"{s['cloud_points']} points; mounting {s['mounting']}; load {load}")
if 'recognition' in s:
    r = s['recognition']
    print(f"  recognition every {r['period_s']} s: started {r['started']}, finished {r['finished']}, "
          f"skipped (busy) {r['skipped_busy']}, failed {r['failed']}, map smaller than the "
          f"models {r['map_smaller_than_models']}; seconds median "
          f"{r['seconds']['median']:.2f} max {r['seconds']['max']:.2f}; last: {r['placements']} "
          f"placements in the map of {r['last_frames']} frames")
EOF
}

if [ "$WHICH" = p900 ] || [ "$WHICH" = both ]; then
  scene p900 p900-130 15 2 30
  for f in "${FACTORS[@]}"; do run p900 "$f"; done
fi
if [ "$WHICH" = mb2250 ] || [ "$WHICH" = both ]; then
  scene mb2250 mb2250 40 1 60  # its tank range: 0.25-1.4 m
  for f in "${FACTORS[@]}"; do run mb2250 "$f"; done
fi

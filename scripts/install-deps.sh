#!/usr/bin/env bash
# Installs everything sonar3d needs to build, test and benchmark, from Debian packages only.
# Non-interactive and idempotent: the only install path of the project (CI runs it too).
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config
  libeigen3-dev        # linear algebra, poses
  libtbb-dev           # the one threading backend
  libembree-dev        # ray tracing, closest-point queries
  libopenvdb-dev libboost-iostreams-dev  # sparse volumes (carving map); OpenVDB's CMake config needs Boost.Iostreams
  libassimp-dev        # CAD meshes, every format
  libopencv-core-dev libopencv-imgproc-dev libopencv-imgcodecs-dev  # PNG/TIFF IO, filters
  libgdal-dev          # GeoTIFF elevation maps
  libceres-dev         # robust least squares: swath adjustment
  libsqlite3-dev       # ROS 2 bags (sqlite3 storage)
  libbz2-dev liblz4-dev  # ROS 1 bag chunks (bz2, lz4)
  # Debian's ROS 1 (tests only: tests/test_rosbag_debian.py reads our bags with its `rosbag`
  # Python API and CLI, and imports bags written by it); python3-yaml reads sonar.yaml there.
  python3-rosbag python3-sensor-msgs python3-nav-msgs python3-geometry-msgs python3-tf2-msgs
  python3-yaml
  # Debian's ROS 1 for the node `sonar3d ros` (docs/online.md): roscpp, topic_tools'
  # ShapeShifter and the message headers it builds against; roscore and the Python client that
  # tests/test_ros_node.py runs it with (rosbag play comes with python3-rosbag).
  libroscpp-dev libtopic-tools-dev libstd-msgs-dev libsensor-msgs-dev libnav-msgs-dev
  libgeometry-msgs-dev libstd-srvs-dev libdiagnostic-msgs-dev
  libvisualization-msgs-dev  # --catalogue: recognised placements as MarkerArray
  ros-core python3-rospy python3-rosgraph python3-std-srvs python3-diagnostic-msgs
  python3-visualization-msgs
  libnanoflann-dev     # KD-tree (header only): core/point_index, the library's nearest-neighbour index
  zlib1g-dev           # NumPy .npz camera files (IDR/NeuS): deflated zip entries
  libyaml-cpp-dev nlohmann-json3-dev libcli11-dev libfmt-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  python3 python3-dev python3-numpy python3-pytest pybind11-dev  # the Python module and its tests
  python3-pip python3-setuptools python3-wheel python3-venv       # `pip install .` of the module
  libopenmpi-dev openmpi-bin  # planner sweeps over MPI ranks
  chromium                    # headless browser test of `sonar3d report`
  strace                      # the test that atomic writes fsync before renaming
  mkdocs                      # `make docs`: the documentation site (tests/docs_site.sh)
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} Debian packages present"
else
  echo "install-deps: installing ${missing[*]}"
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# Node.js for the report's web assets. The machine image ships Node 20 + npm; Debian's npm is the
# fallback (installing it over another Node would downgrade it).
if ! command -v npm >/dev/null 2>&1; then
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends nodejs npm
fi

# Web assets of `sonar3d report` (Plotly, three.js bundled into web/dist) and its browser test,
# from the npm registry, pinned by web/package-lock.json.
WEB_DIR="$(cd "$(dirname "$0")/.." && pwd)/web"
if [ ! -f "$WEB_DIR/dist/three-bundle.js" ] || [ ! -d "$WEB_DIR/node_modules" ] || \
   [ "$WEB_DIR/package-lock.json" -nt "$WEB_DIR/node_modules/.package-lock.json" ]; then
  echo "install-deps: npm ci in web/"
  (cd "$WEB_DIR" && npm ci --no-audit --no-fund)
fi

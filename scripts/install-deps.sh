#!/usr/bin/env bash
# Installs everything sonar3d needs to build, test and benchmark, from Debian packages only.
# Non-interactive and idempotent: the only install path of the project (CI runs it too).
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config
  libeigen3-dev        # linear algebra, poses
  libtbb-dev           # the one threading backend
  libembree-dev        # ray tracing, closest-point queries
  libopenvdb-dev       # sparse volumes (carving map)
  libassimp-dev        # CAD meshes, every format
  libopencv-core-dev libopencv-imgproc-dev libopencv-imgcodecs-dev  # PNG/TIFF IO, filters
  libyaml-cpp-dev nlohmann-json3-dev libcli11-dev libfmt-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  python3 python3-dev python3-numpy python3-pytest pybind11-dev  # the Python module and its tests
  libopenmpi-dev openmpi-bin  # planner sweeps over MPI ranks
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"

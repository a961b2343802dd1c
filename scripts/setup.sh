#!/usr/bin/env bash
# Installs the Debian packages the workspace needs (only those missing, so a second run is fast), then builds
# everything in Release into build/. Usage: scripts/setup.sh [--no-build]
set -euo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

PACKAGES=(
  build-essential cmake pkg-config clang-format
  ros-core-dev libnodeletlib-dev libnodeletlib-tools python3-rostest python3-geometry-msgs rosbash
  librosbag-dev python3-rosbag ros-std-srvs libdiagnostic-msgs-dev libroslz4-dev libbz2-dev
  libtf2-ros-dev libtf2-eigen-dev libtf2-geometry-msgs-dev ros-sensor-msgs libvisualization-msgs-dev
  libcv-bridge-dev libimage-transport-dev libopencv-dev libeigen3-dev
  libgtest-dev libbenchmark-dev libosmesa6-dev
  libassimp-dev libyaml-cpp-dev libfcl-dev libsqlite3-dev libbullet-dev libboost-program-options-dev
  python3-matplotlib python3-diagnostic-msgs python3-sensor-msgs
  qtbase5-dev libqt5charts5-dev nlohmann-json3-dev libssl-dev xvfb xauth python3-pil
  nftables strace
  # A training centre's records server (issue 41): PostgreSQL (the centre test starts a throw-away cluster) and libpq.
  postgresql libpq-dev
  # What the README's commands need as a new user runs them (issue 20): the Python message modules of every topic the
  # graph publishes (rostopic echo), tf_echo, and RViz (simulator.launch rviz:=true).
  python3-visualization-msgs python3-tf2-msgs python3-tf2-ros tf-tools rviz
)

missing=()
for package in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed" || missing+=("$package")
done
if ((${#missing[@]})); then
  echo "setup: installing ${#missing[@]} missing Debian packages: ${missing[*]}"
  SUDO=""
  if [[ $(id -u) -ne 0 ]]; then
    command -v sudo >/dev/null || { echo "setup: not root and no sudo; install as root: ${missing[*]}" >&2; exit 1; }
    SUDO=sudo
  fi
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

[[ ${1:-} == --no-build ]] && exit 0

BUILD="$ROOT/build"
# A pyenv python3 may come first on PATH and lacks catkin_pkg: catkin must use the system interpreter.
export PATH="/usr/bin:$PATH"
if [[ ! -f "$BUILD/CMakeCache.txt" ]]; then
  cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=Release \
    -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3 >"$ROOT/build.configure.log" 2>&1 \
    || { cat "$ROOT/build.configure.log"; echo "setup: cmake configure failed" >&2; exit 1; }
  mv "$ROOT/build.configure.log" "$BUILD/configure.log"
fi
cmake --build "$BUILD" -j"$(nproc)"

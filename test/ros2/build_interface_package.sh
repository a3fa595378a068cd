#!/bin/bash
# Builds msg/ros2/tinyline_msgs (or the package folder PKG_DIR, relative to
# SOURCE_DIR) the way a ROS 2 workspace would (ament_cmake, rosidl's C, C++
# and Python generators and type-description hashes), against the ROS 2 Jazzy
# wheels of the test venv, and installs it. The workspace's src/ holds a
# symlink to the package, as docs/ros2.md suggests.
#
#   build_interface_package.sh VENV SOURCE_DIR WORK_DIR [PKG_DIR]   -> WORK_DIR/install
set -euo pipefail
# Absolute paths: the package is configured from another folder.
venv=$(cd "$1" && pwd)
src=$(cd "$2" && pwd)
work=$3
pkg_dir=${4:-msg/ros2/tinyline_msgs}
pkg=$(basename "$pkg_dir")
export PATH="$venv/bin:$PATH"
export AMENT_PREFIX_PATH="$venv"
mkdir -p "$work/src"
ln -sfn "$src/$pkg_dir" "$work/src/$pkg"
cmake -S "$work/src/$pkg" -B "$work/build" -G Ninja \
  -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$venv" -DCMAKE_INSTALL_PREFIX="$work/install" \
  -DPython3_EXECUTABLE="$venv/bin/python" -DBUILD_TESTING=OFF \
  -DCMAKE_PROJECT_INCLUDE="$src/test/ros2/wheel_fixups.cmake" >"$work/configure.log" 2>&1 ||
  { tail -40 "$work/configure.log"; exit 1; }
cmake --build "$work/build" -j2 >"$work/build.log" 2>&1 || { grep -B2 -A10 -m3 "error" "$work/build.log"; exit 1; }
cmake --install "$work/build" >"$work/install.log" 2>&1 || { tail -20 "$work/install.log"; exit 1; }
echo "BUILT $work/install"

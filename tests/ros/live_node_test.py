#!/usr/bin/python3
"""The live node end to end, with a real ROS master (issue 15, done-when 4).

A simulated sequence is written as a VIODE-layout bag (with colour segmentation topics, which the
node reads when the options file says semantics.segmenter dataset, format color); `superdyna run` gives the offline ATE on
it; then rosmaster (python3-rosmaster), superdyna_ros and `rosbag play` run as they would on a
robot, this script subscribes to /superdyna/odometry with rospy, SIGINTs the node and checks:
  - odometry arrived for >= 95 % of the bag's frames;
  - its ATE (superdyna eval, SE(3)) is within 1.5x of the offline run's on the same frames, both
    taken from the last change of the world frame on (the inertial initialisation re-expresses
    the map in a gravity-aligned frame; odometry sent before it is in the provisional frame, and
    the node re-publishes only the path);
  - the node exits with 0 on SIGINT and prints its summary;
  - with segmentation topics, at most 5 % of the frames miss their segmentation image.
Run with Debian's /usr/bin/python3 (rospy, rosgraph). Exit 0 on success, 1 on a failed check.
"""
import argparse
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import time


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def run(command, **kwargs):
    print("+", " ".join(command), flush=True)
    return subprocess.run(command, check=True, **kwargs)


def ate_rmse(superdyna, ground_truth, estimate, report):
    run([superdyna, "eval", "--gt", ground_truth, "--est", estimate, "--json", report],
        stdout=subprocess.DEVNULL)
    with open(report) as f:
        return json.load(f)["ate_rmse"]


def read_tum(path):
    poses = []
    with open(path) as f:
        for line in f:
            if line.strip() and not line.startswith("#"):
                poses.append(line.split())
    return poses


def write_tum(path, poses):
    with open(path, "w") as f:
        for pose in poses:
            f.write(" ".join(pose) + "\n")


def frame_count(sequence):
    with open(os.path.join(sequence, "mav0", "cam0", "data.csv")) as f:
        return sum(1 for line in f if line.strip() and not line.startswith("#"))


class OdometryRecorder:
    """Every /superdyna/odometry message as a TUM row (stamp in s, position, quaternion xyzw)."""

    def __init__(self):
        import rospy
        from nav_msgs.msg import Odometry
        self.rows = []
        rospy.init_node("live_node_test", anonymous=True, disable_signals=True)
        self.subscriber = rospy.Subscriber("/superdyna/odometry", Odometry, self.received,
                                           queue_size=1000)

    def received(self, message):
        p = message.pose.pose.position
        q = message.pose.pose.orientation
        stamp = message.header.stamp.to_nsec() / 1e9
        self.rows.append([f"{stamp:.9f}"] + [repr(v) for v in (p.x, p.y, p.z, q.x, q.y, q.z, q.w)])

    def publishers(self):
        return self.subscriber.get_num_connections()


def wait_until(condition, timeout_s, what):
    end = time.time() + timeout_s
    while time.time() < end:
        if condition():
            return
        time.sleep(0.1)
    raise RuntimeError(f"timed out after {timeout_s} s waiting for {what}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--superdyna", required=True)
    parser.add_argument("--node", required=True)
    parser.add_argument("--config", required=True)
    parser.add_argument("--workdir", required=True)
    parser.add_argument("--duration", default="12")
    parser.add_argument("--rate", default="1.0", help="rosbag play rate")
    parser.add_argument("--node-param", action="append", default=[],
                        help="extra node parameter, _name:=value (repeatable)")
    parser.add_argument("--sequence", help="an existing sequence folder (with --bag) instead "
                        "of a simulated one")
    parser.add_argument("--bag", help="the --sequence folder written as a VIODE-layout bag")
    args = parser.parse_args()
    work = os.path.abspath(args.workdir)
    shutil.rmtree(work, ignore_errors=True)  # every run starts afresh
    os.makedirs(work)
    sequence, bag = os.path.join(work, "sequence"), os.path.join(work, "sequence.bag")
    if args.sequence:
        sequence, bag = os.path.abspath(args.sequence), os.path.abspath(args.bag)
    ground_truth = os.path.join(sequence, "mav0", "state_groundtruth_estimate0", "data.csv")
    if not args.sequence:
        run([args.superdyna, "simulate", "--out", sequence, "--scene", "street", "--dynamic",
             "high", "--duration", args.duration, "--seed", "5", "--semantic-color", "--rosbag",
             bag], stdout=subprocess.DEVNULL)
    offline = os.path.join(work, "offline.txt")
    run([args.superdyna, "run", "--dataset", "rosbag", "--path", bag, "--calibration", sequence,
         "--mode", "stereo-inertial", "--config", args.config, "--deterministic", "--output",
         offline], stdout=subprocess.DEVNULL)

    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}",
               ROS_HOME=os.path.join(work, "ros"), ROS_LOG_DIR=os.path.join(work, "ros", "log"))
    os.environ.update(env)
    master = subprocess.Popen(["rosmaster", "--core", "-p", str(port)], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    node_log_path = os.path.join(work, "node.log")
    node = None
    try:
        import rosgraph
        wait_until(lambda: rosgraph.is_master_online(), 20, "the ROS master")
        with open(node_log_path, "w") as node_log:
            node = subprocess.Popen(
                [args.node, f"_calibration:={sequence}", f"_config:={args.config}",
                 f"_output:={os.path.join(work, 'node_final.txt')}"] + args.node_param,
                env=env, stdout=node_log, stderr=subprocess.STDOUT)
        recorder = OdometryRecorder()
        wait_until(lambda: recorder.publishers() > 0, 30, "the node's /superdyna/odometry")
        run(["rosbag", "play", "-q", "-d", "1", "-r", args.rate, bag], env=env,
            stdout=subprocess.DEVNULL)
        frames = frame_count(sequence)
        # The node works through what it has queued; stop when nothing new came for 3 s.
        last, still_since = -1, time.time()
        while time.time() - still_since < 3.0:
            time.sleep(0.2)
            if len(recorder.rows) != last:
                last, still_since = len(recorder.rows), time.time()
        node.send_signal(signal.SIGINT)
        exit_code = node.wait(timeout=60)
    finally:
        if node is not None and node.poll() is None:
            node.kill()
        master.send_signal(signal.SIGINT)
        master.wait(timeout=30)

    with open(node_log_path) as f:
        node_output = f.read()
    print(node_output, end="")
    failures = []
    if exit_code != 0:
        failures.append(f"the node exited with {exit_code} on SIGINT")
    if "frames assembled" not in node_output:
        failures.append("the node printed no summary")
    missing = re.search(r"(\d+) segmentations did not arrive in time", node_output)
    if missing and int(missing.group(1)) > 0.05 * frame_count(sequence):
        failures.append(f"{missing.group(1)} frames without their segmentation image")

    received = recorder.rows
    live = os.path.join(work, "live_odometry.txt")
    write_tum(live, received)
    changes = [int(t) for t in re.findall(r"world frame changed at (\d+) ns", node_output)]
    since = changes[-1] / 1e9 if changes else 0.0
    live_final = [row for row in received if float(row[0]) >= since]
    offline_final = [row for row in read_tum(offline) if float(row[0]) >= since]
    write_tum(live + ".final_frame", live_final)
    write_tum(offline + ".final_frame", offline_final)
    live_ate = ate_rmse(args.superdyna, ground_truth, live + ".final_frame",
                        os.path.join(work, "live_eval.json"))
    offline_ate = ate_rmse(args.superdyna, ground_truth, offline + ".final_frame",
                           os.path.join(work, "offline_eval.json"))
    share = len(received) / frames
    print(f"odometry for {len(received)} of {frames} frames ({100 * share:.1f} %); world frame "
          f"final from {since:.3f} s ({len(live_final)} live, {len(offline_final)} offline "
          f"poses); ATE live {100 * live_ate:.2f} cm, offline {100 * offline_ate:.2f} cm "
          f"(ratio {live_ate / offline_ate:.2f})")
    if share < 0.95:
        failures.append(f"odometry for only {100 * share:.1f} % of the frames (< 95 %)")
    if live_ate > 1.5 * offline_ate:
        failures.append(f"live ATE {live_ate:.4f} m > 1.5 x offline {offline_ate:.4f} m")
    for failure in failures:
        print("FAIL:", failure)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

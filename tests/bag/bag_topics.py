#!/usr/bin/env python3
"""Topics of a ROS 1 bag as ROS's own Python reader (python3-rosbag) sees them, one per line:
name, type and message count separated by tabs, sorted by name; then the first IMU sample of each
sensor_msgs/Imu topic ("imu<TAB>topic<TAB>stamp_ns gx gy gz ax ay az") and the size of the first
message of each image topic ("image<TAB>topic<TAB>width height"). rosbag_reader_test compares
RosbagReader with it.

  bag_topics.py BAG
"""
import sys

import rosbag


def main():
    with rosbag.Bag(sys.argv[1]) as bag:
        topics = bag.get_type_and_topic_info().topics
        for name in sorted(topics):
            print(f"{name}\t{topics[name].msg_type}\t{topics[name].message_count}")
        for name in sorted(topics):
            kind = topics[name].msg_type
            if kind not in ("sensor_msgs/Imu", "sensor_msgs/Image"):
                continue
            for _, msg, _ in bag.read_messages(topics=[name]):
                stamp = msg.header.stamp.secs * 10**9 + msg.header.stamp.nsecs
                if kind == "sensor_msgs/Imu":
                    w, a = msg.angular_velocity, msg.linear_acceleration
                    print(f"imu\t{name}\t{stamp} {w.x!r} {w.y!r} {w.z!r} {a.x!r} {a.y!r} {a.z!r}")
                else:
                    print(f"image\t{name}\t{msg.width} {msg.height}")
                break
    return 0


if __name__ == "__main__":
    sys.exit(main())

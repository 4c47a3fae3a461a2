"""Reads an MCAP file of ROS 2 messages with mcap-ros2-support and prints, per topic, the
decoded messages as JSON lines (used by tests/ros2_mcap.rs).

Usage: python3 read_mcap_ros2.py FILE.mcap
"""
import json
import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def main(path):
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        profile = reader.get_header().profile
        print(json.dumps({"profile": profile}))
        for schema, channel, message, msg in reader.iter_decoded_messages():
            row = {
                "topic": channel.topic,
                "schema": schema.name,
                "log_time": message.log_time,
                "stamp": [msg.header.stamp.sec, msg.header.stamp.nanosec],
                "frame_id": msg.header.frame_id,
            }
            if schema.name == "sensor_msgs/msg/NavSatFix":
                row.update(
                    status=msg.status.status,
                    service=msg.status.service,
                    lat=msg.latitude,
                    lon=msg.longitude,
                    alt=msg.altitude,
                    covariance=list(msg.position_covariance),
                    covariance_type=msg.position_covariance_type,
                )
            elif schema.name == "geometry_msgs/msg/PoseWithCovarianceStamped":
                p = msg.pose.pose.position
                q = msg.pose.pose.orientation
                row.update(
                    position=[p.x, p.y, p.z],
                    orientation=[q.x, q.y, q.z, q.w],
                    covariance=list(msg.pose.covariance),
                )
            elif schema.name == "sensor_msgs/msg/Imu":
                q = msg.orientation
                row.update(
                    orientation=[q.x, q.y, q.z, q.w],
                    covariance=list(msg.orientation_covariance),
                    angular_velocity_covariance=list(msg.angular_velocity_covariance),
                )
            print(json.dumps(row))


if __name__ == "__main__":
    main(sys.argv[1])

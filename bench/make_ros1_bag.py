#!/usr/bin/env python3
"""Writes a synthetic robot recording as a ROS 1 bag (format 2.0, uncompressed or bz2 chunks, indexed), for the
import benchmarks (scripts/bench import): a 16 x 1800 lidar (sensor_msgs/PointCloud2: x, y, z, intensity, time as
float32) at 10 Hz, a 720-beam laser scan at 20 Hz, an IMU at 200 Hz, wheel odometry at 50 Hz and TF at 50 Hz.

    make_ros1_bag.py OUT.bag SECONDS [none|bz2]

The bytes are mostly point clouds, as in a real 3D-lidar recording. Deterministic (fixed seed).
"""
import bz2
import struct
import sys

import numpy as np

DEFS = {
    "std_msgs/Header": "uint32 seq\ntime stamp\nstring frame_id\n",
    "sensor_msgs/PointField": "uint8 INT8=1\nuint8 FLOAT32=7\nstring name\nuint32 offset\nuint8 datatype\nuint32 count\n",
    "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/Quaternion": "float64 x\nfloat64 y\nfloat64 z\nfloat64 w\n",
    "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/Pose": "Point position\nQuaternion orientation\n",
    "geometry_msgs/PoseWithCovariance": "Pose pose\nfloat64[36] covariance\n",
    "geometry_msgs/Twist": "Vector3 linear\nVector3 angular\n",
    "geometry_msgs/TwistWithCovariance": "Twist twist\nfloat64[36] covariance\n",
    "geometry_msgs/Transform": "Vector3 translation\nQuaternion rotation\n",
    "geometry_msgs/TransformStamped": "Header header\nstring child_frame_id\nTransform transform\n",
}
TOPICS = [
    ("/points", "sensor_msgs/PointCloud2",
     "Header header\nuint32 height\nuint32 width\nPointField[] fields\nbool is_bigendian\nuint32 point_step\n"
     "uint32 row_step\nuint8[] data\nbool is_dense\n", ["std_msgs/Header", "sensor_msgs/PointField"]),
    ("/scan", "sensor_msgs/LaserScan",
     "Header header\nfloat32 angle_min\nfloat32 angle_max\nfloat32 angle_increment\nfloat32 time_increment\n"
     "float32 scan_time\nfloat32 range_min\nfloat32 range_max\nfloat32[] ranges\nfloat32[] intensities\n",
     ["std_msgs/Header"]),
    ("/imu", "sensor_msgs/Imu",
     "Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n"
     "geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n"
     "geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n",
     ["std_msgs/Header", "geometry_msgs/Quaternion", "geometry_msgs/Vector3"]),
    ("/odom", "nav_msgs/Odometry",
     "Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n"
     "geometry_msgs/TwistWithCovariance twist\n",
     ["std_msgs/Header", "geometry_msgs/PoseWithCovariance", "geometry_msgs/Pose", "geometry_msgs/Point",
      "geometry_msgs/Quaternion", "geometry_msgs/TwistWithCovariance", "geometry_msgs/Twist",
      "geometry_msgs/Vector3"]),
    ("/tf", "tf2_msgs/TFMessage", "geometry_msgs/TransformStamped[] transforms\n",
     ["geometry_msgs/TransformStamped", "std_msgs/Header", "geometry_msgs/Transform", "geometry_msgs/Vector3",
      "geometry_msgs/Quaternion"]),
]


def full_definition(text, deps):
    out = text
    for d in deps:
        out += "\n" + "=" * 80 + "\nMSG: " + d + "\n" + DEFS[d]
    return out


def field(name, value):
    b = name.encode() + b"=" + value
    return struct.pack("<I", len(b)) + b


def record(header_fields, data):
    h = b"".join(header_fields)
    return struct.pack("<I", len(h)) + h + struct.pack("<I", len(data)) + data


def rstring(s):
    b = s.encode()
    return struct.pack("<I", len(b)) + b


def stamp(t):
    """(sec, nsec) of a time in seconds, the same way everywhere (message times and the index must agree)."""
    ns = int(round(t * 1e9))
    return ns // 1000000000, ns % 1000000000


def header(seq, t, frame):
    return struct.pack("<III", seq, *stamp(t)) + rstring(frame)


def main():
    out, seconds = sys.argv[1], float(sys.argv[2])
    compression = sys.argv[3] if len(sys.argv) > 3 else "none"
    rng = np.random.default_rng(1)
    t0 = 1700000000.0
    conns = []
    for i, (topic, typ, text, deps) in enumerate(TOPICS):
        definition = full_definition(text, deps).encode()
        conns.append(record([field("op", b"\x07"), field("conn", struct.pack("<I", i)), field("topic", topic.encode())],
                            b"".join([field("topic", topic.encode()), field("type", typ.encode()),
                                      field("md5sum", b"*"), field("message_definition", definition)])))
    # A fixed cloud (the rotation of the lidar changes little of the bytes' statistics), refreshed per sweep index.
    rings, cols = 16, 1800
    pts = rng.normal(0, 10, size=(rings * cols, 5)).astype("<f4")
    cloud_fields = b"".join(rstring(n) + struct.pack("<IBI", 4 * k, 7, 1)
                            for k, n in enumerate(["x", "y", "z", "intensity", "time"]))
    events = []  # (time, conn, payload)
    for k in range(int(seconds * 10)):
        t = t0 + k / 10
        pts[:, 0] += 0.001
        data = pts.tobytes()
        body = (header(k, t, "lidar") + struct.pack("<II", rings, cols) + struct.pack("<I", 5) + cloud_fields +
                struct.pack("<BII", 0, 20, 20 * cols) + struct.pack("<I", len(data)) + data + b"\x01")
        events.append((t + 0.02, 0, body))
    ranges = rng.uniform(0.5, 30, 720).astype("<f4").tobytes()
    for k in range(int(seconds * 20)):
        t = t0 + k / 20
        body = (header(k, t, "laser") + struct.pack("<7f", -3.14, 3.14, 0.00873, 0, 0.05, 0.1, 30) +
                struct.pack("<I", 720) + ranges + struct.pack("<I", 0))
        events.append((t + 0.01, 1, body))
    for k in range(int(seconds * 200)):
        t = t0 + k / 200
        body = header(k, t, "imu") + struct.pack("<4d9d3d9d3d9d", *([0, 0, 0, 1] + [0] * 9 + [0, 0, 0.1] + [0] * 9 +
                                                                      [0, 0, 9.81] + [0] * 9))
        events.append((t + 0.001, 2, body))
    for k in range(int(seconds * 50)):
        t = t0 + k / 50
        body = (header(k, t, "odom") + rstring("base_link") + struct.pack("<7d", k * 0.01, 0, 0, 0, 0, 0, 1) +
                struct.pack("<36d", *[0] * 36) + struct.pack("<6d", 0.5, 0, 0, 0, 0, 0.1) + struct.pack("<36d", *[0] * 36))
        events.append((t + 0.002, 3, body))
        tf = (struct.pack("<I", 1) + header(k, t, "odom") + rstring("base_link") +
              struct.pack("<7d", k * 0.01, 0, 0, 0, 0, 0, 1))
        events.append((t + 0.002, 4, tf))
    events.sort(key=lambda e: e[0])

    with open(out, "wb") as f:
        f.write(b"#ROSBAG V2.0\n")
        bag_header_at = f.tell()
        f.write(record([field("op", b"\x03"), field("index_pos", struct.pack("<Q", 0)),
                        field("conn_count", struct.pack("<I", len(conns))), field("chunk_count", struct.pack("<I", 0))],
                       b" " * 4000))
        chunk_infos = []
        chunk, chunk_start, chunk_end, counts, written = [], None, None, {}, set()
        index = {}  # connection -> [(sec, nsec, offset of the message record in the chunk)]
        size = 0

        def flush():
            nonlocal chunk, chunk_start, chunk_end, counts, size, index
            if not chunk:
                return
            raw = b"".join(chunk)
            data = bz2.compress(raw, 9) if compression == "bz2" else raw
            pos = f.tell()
            f.write(record([field("op", b"\x05"), field("compression", compression.encode()),
                            field("size", struct.pack("<I", len(raw)))], data))
            # The index data records after the chunk, one per connection (readers that seek need them).
            for c, entries in sorted(index.items()):
                f.write(record([field("op", b"\x04"), field("ver", struct.pack("<I", 1)),
                                field("conn", struct.pack("<I", c)), field("count", struct.pack("<I", len(entries)))],
                               b"".join(struct.pack("<III", *e) for e in entries)))
            chunk_infos.append((pos, chunk_start, chunk_end, dict(counts)))
            chunk, chunk_start, chunk_end, counts, size, index = [], None, None, {}, 0, {}

        offset = 0  # bytes of the open chunk so far
        for t, c, body in events:
            if not chunk:
                offset = 0
            if c not in written:
                chunk.append(conns[c])
                offset += len(conns[c])
                written.add(c)
            sec, nsec = stamp(t)
            index.setdefault(c, []).append((sec, nsec, offset))
            chunk.append(record([field("op", b"\x02"), field("conn", struct.pack("<I", c)),
                                 field("time", struct.pack("<II", sec, nsec))], body))
            offset += len(chunk[-1])
            size += len(body) + 60
            chunk_start = t if chunk_start is None else chunk_start
            chunk_end = t
            counts[c] = counts.get(c, 0) + 1
            if size > 4 << 20:
                flush()
        flush()
        index_pos = f.tell()
        for c in conns:
            f.write(c)
        for pos, start, end, cnt in chunk_infos:
            data = b"".join(struct.pack("<II", c, n) for c, n in cnt.items())
            f.write(record([field("op", b"\x06"), field("ver", struct.pack("<I", 1)),
                            field("chunk_pos", struct.pack("<Q", pos)),
                            field("start_time", struct.pack("<II", *stamp(start))),
                            field("end_time", struct.pack("<II", *stamp(end))),
                            field("count", struct.pack("<I", len(cnt)))], data))
        f.seek(bag_header_at)
        f.write(record([field("op", b"\x03"), field("index_pos", struct.pack("<Q", index_pos)),
                        field("conn_count", struct.pack("<I", len(conns))),
                        field("chunk_count", struct.pack("<I", len(chunk_infos)))], b" " * 4000))


if __name__ == "__main__":
    main()

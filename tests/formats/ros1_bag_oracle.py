#!/usr/bin/env python3
"""An independent reader of ROS 1 bags (format 2.0; uncompressed, bz2 or lz4 chunks), with Python's standard library (and
Debian's python3-lz4),
written from the format's wiki page (wiki.ros.org/Bags/Format/2.0) to check `driftlab import` against. Prints, per
topic, the message count and what the first and last messages say: record time, header seq, stamp and frame, and
for LaserScan, Odometry and TFMessage the values a person would look at."""
import bz2
import json
import struct
import sys


def fields_of(header):
    fields, i = {}, 0
    while i < len(header):
        (n,) = struct.unpack_from("<I", header, i)
        key, value = header[i + 4 : i + 4 + n].split(b"=", 1)
        fields[key.decode()] = value
        i += 4 + n
    return fields


def records(buf, pos=0):
    while pos + 4 <= len(buf):
        (hl,) = struct.unpack_from("<I", buf, pos)
        header = buf[pos + 4 : pos + 4 + hl]
        (dl,) = struct.unpack_from("<I", buf, pos + 4 + hl)
        data = buf[pos + 8 + hl : pos + 8 + hl + dl]
        pos += 8 + hl + dl
        yield fields_of(header), data


def string(data, i):
    (n,) = struct.unpack_from("<I", data, i)
    return data[i + 4 : i + 4 + n].decode(), i + 4 + n


def header(data, i=0):
    seq, sec, nsec = struct.unpack_from("<III", data, i)
    frame, i = string(data, i + 12)
    return {"seq": seq, "stamp_us": sec * 1000000 + nsec // 1000, "frame_id": frame}, i


def describe(msg_type, data, time_ns):
    out = {"record_us": time_ns // 1000}
    if msg_type == "tf2_msgs/TFMessage":
        (n,) = struct.unpack_from("<I", data, 0)
        out["transforms"] = n
        if n:
            h, i = header(data, 4)
            child, i = string(data, i)
            out["first"] = {"stamp_us": h["stamp_us"], "frame_id": h["frame_id"], "child": child,
                            "xyz": struct.unpack_from("<3d", data, i)}
        return out
    h, i = header(data)
    out.update(h)
    if msg_type == "sensor_msgs/LaserScan":
        angle_min, angle_max, inc, tinc, scan_time, rmin, rmax, n = struct.unpack_from("<7fI", data, i)
        ranges = struct.unpack_from("<%df" % n, data, i + 32)
        out.update(angle_min=angle_min, angle_increment=inc, range_max=rmax, nranges=n, ranges=ranges[:5])
    elif msg_type == "nav_msgs/Odometry":
        child, i = string(data, i)
        out.update(child=child, xyz=struct.unpack_from("<3d", data, i), q_xyzw=struct.unpack_from("<4d", data, i + 24))
    return out


def main(path):
    buf = open(path, "rb").read()
    assert buf.startswith(b"#ROSBAG V2.0\n")
    conns, topics = {}, {}

    def handle(fields, data):
        op = fields["op"][0]
        if op == 7:
            conn = struct.unpack("<I", fields["conn"])[0]
            conns[conn] = (fields["topic"].decode(), fields_of(data)["type"].decode())
        elif op == 2:
            topic, msg_type = conns[struct.unpack("<I", fields["conn"])[0]]
            sec, nsec = struct.unpack("<II", fields["time"])
            t = topics.setdefault(topic, {"type": msg_type, "count": 0})
            t["count"] += 1
            d = describe(msg_type, data, sec * 1000000000 + nsec)
            t.setdefault("first", d)
            t["last"] = d

    for fields, data in records(buf, 13):
        op = fields["op"][0]
        if op == 5:
            kind = fields["compression"].decode()
            if kind == "lz4":
                import lz4.frame  # Debian's python3-lz4; roslz4 writes LZ4 frames

                chunk = lz4.frame.decompress(data)
            else:
                chunk = bz2.decompress(data) if kind == "bz2" else data
            for inner in records(chunk):
                handle(*inner)
        else:
            handle(fields, data)
    json.dump(topics, sys.stdout, indent=1)


if __name__ == "__main__":
    main(sys.argv[1])

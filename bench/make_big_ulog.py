#!/usr/bin/env python3
"""A long PX4 flight log for scripts/bench ulog: a real flight log's data section flown again and again.

    make_big_ulog.py SRC.ulg MEGABYTES OUT.ulg

The header and definitions are SRC's; its data section follows as many times as it takes to reach MEGABYTES, each
repeat's times ('D' messages' timestamp, logged strings' 'L' and 'C') shifted by the flight's span so they keep
rising. Subscriptions ('A') and other records are written once, with the first flight: the repeats add data only.
"""
import struct
import sys


def main():
    src, megabytes, out = sys.argv[1], float(sys.argv[2]), sys.argv[3]
    b = open(src, "rb").read()
    if b[:7] != b"ULog\x01\x12\x35":
        sys.exit(f"{src}: not a ULog file")
    pos, records, first_data = 16, [], None
    while pos + 3 <= len(b):
        size, kind = struct.unpack_from("<HB", b, pos)
        if pos + 3 + size > len(b):
            break
        if first_data is None and kind == ord("A"):
            first_data = len(records)
        records.append((kind, b[pos:pos + 3 + size]))
        pos += 3 + size
    if first_data is None:
        sys.exit(f"{src}: no data section")
    stamps = [struct.unpack_from("<Q", r, 5)[0] for k, r in records[first_data:] if k == ord("D") and len(r) >= 13]
    span = max(stamps) - min(stamps) + 1_000_000  # a second between flights
    header = b[:16] + b"".join(r for _, r in records[:first_data])
    flight = b"".join(r for _, r in records[first_data:])
    repeat = []  # the data again, its times shifted by a placeholder filled per repeat
    for kind, r in records[first_data:]:
        if kind == ord("D") and len(r) >= 13:
            repeat.append((r, 5))  # size, kind, msg_id, then the timestamp
        elif kind == ord("L") and len(r) >= 12:
            repeat.append((r, 4))  # level, then the timestamp
        elif kind == ord("C") and len(r) >= 14:
            repeat.append((r, 6))  # level, tag, then the timestamp
        elif kind in (ord("O"), ord("S")):
            repeat.append((r, None))
    target = int(megabytes * 1e6)
    with open(out, "wb") as f:
        f.write(header)
        f.write(flight)
        written, k = len(header) + len(flight), 1
        while written < target:
            chunk = bytearray()
            for r, at in repeat:
                if at is None:
                    chunk += r
                else:
                    t = struct.unpack_from("<Q", r, at)[0] + k * span
                    chunk += r[:at] + struct.pack("<Q", t) + r[at + 8:]
            f.write(chunk)
            written += len(chunk)
            k += 1


if __name__ == "__main__":
    main()

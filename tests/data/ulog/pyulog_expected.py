#!/usr/bin/env python3
"""What PX4's own reader, pyulog, finds in ULog files, in the form of ../shared/data/ulog/expected.json, for
tests/formats/ulog_test.cc: per file, the header's start and the last timestamp [us], every topic instance's message
count (`name`, or `name/multi_id` for a topic logged in several instances or in another than 0), the total, the
dropouts, the count of untagged logged strings, and the information fields sys_name, ver_hw, ver_sw, time_ref_utc.

    PYTHONPATH=PYULOG_CHECKOUT python3 pyulog_expected.py FILE.ulg ... > pyulog_more.json

pyulog_more.json in this folder was written so by PX4/pyulog at commit 3cf1779, from its test/ folder's sample.ulg and
sample_px4_events.ulg.
"""
import json
import os
import sys

from pyulog import ULog


def expected(path):
    u = ULog(path)
    names = {}
    for d in u.data_list:
        names.setdefault(d.name, set()).add(d.multi_id)
    topics = {}
    for d in u.data_list:
        several = len(names[d.name]) > 1 or d.multi_id != 0
        topics[f"{d.name}/{d.multi_id}" if several else d.name] = len(d.data["timestamp"])
    info = {k: u.msg_info_dict[k] for k in ("ver_sw", "ver_hw", "sys_name", "time_ref_utc") if k in u.msg_info_dict}
    return {
        "start_us": int(u.start_timestamp),
        "last_us": int(u.last_timestamp),
        "messages": sum(topics.values()),
        "topics": dict(sorted(topics.items())),
        "dropouts": [{"timestamp_us": int(x.timestamp), "duration_ms": int(x.duration)} for x in u.dropouts],
        "logged_strings": len(u.logged_messages),
        "info": info,
    }


json.dump({os.path.basename(p): expected(p) for p in sys.argv[1:]}, sys.stdout, indent=1)
print()

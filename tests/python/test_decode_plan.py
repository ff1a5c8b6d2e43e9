"""Log.read's decode plans (python/read_channel.cc) against the reference decode (lcmtypes::walk, message by message,
through Log._read_reference): the same columns in the same order, with the same dtypes, shapes and values, on real
logs and on logs whose messages were cut short, given a trailing tail or another type's fingerprint."""
import os
import random
import struct

import numpy as np

from conftest import shared

import driftlab

SYNC = 0xEDA1DA01


def _events(path):
    """(channel, utime, data) of each event of an intact LCM log."""
    data = open(path, "rb").read()
    at = 0
    while at + 28 <= len(data):
        sync, _, utime, channel_len, data_len = struct.unpack_from(">IqqII", data, at)
        assert sync == SYNC, (path, at)
        start = at + 28 + channel_len
        yield data[at + 28 : start].decode(), utime, data[start : start + data_len]
        at = start + data_len


def _write(path, events):
    with open(path, "wb") as f:
        for n, (channel, utime, data) in enumerate(events):
            c = channel.encode()
            f.write(struct.pack(">IqqII", SYNC, n, utime, len(c), len(data)) + c + data)


def _damaged(events, seed):
    """The events with some messages of each channel damaged: the first one also cut short before it, every 5th
    cut short, every 9th with bytes after its end, every 13th with another fingerprint."""
    rng = random.Random(seed)
    seen = {}
    for channel, utime, data in events:
        k = seen[channel] = seen.get(channel, -1) + 1
        if len(data) <= 9:
            yield channel, utime, data
            continue
        if k == 0:
            yield channel, utime, data[: rng.randrange(8, len(data))]
        if k % 5 == 1:
            data = data[: rng.randrange(8, len(data))]
        elif k % 9 == 2:
            data = data + bytes(rng.randrange(256) for _ in range(rng.randrange(1, 40)))
        elif k % 13 == 3:
            data = data[:7] + bytes([data[7] ^ 1]) + data[8:]
        yield channel, utime, data


def _kind(a):
    if a.dtype != object:
        return a.dtype.str, a.ndim
    first = next((x for x in a if x is not None), None)
    return ("list" if isinstance(first, list) else "array" if isinstance(first, np.ndarray) else "str"), a.ndim


def _same_channel(fast, reference, where):
    assert list(fast) == list(reference), where
    for name, x in fast.items():
        y = reference[name]
        if x is None or y is None:
            assert x is None and y is None, (where, name)
            continue
        assert x.dtype == y.dtype and x.shape == y.shape, (where, name, x.dtype, y.dtype, x.shape, y.shape)
        if x.dtype != object:
            assert x.flags["C_CONTIGUOUS"], (where, name)
            assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), (where, name)
            continue
        for u, v in zip(x, y):
            assert type(u) is type(v), (where, name)
            if isinstance(u, np.ndarray):
                assert u.dtype == v.dtype and np.array_equal(u, v, equal_nan=u.dtype.kind == "f"), (where, name)
            else:
                assert u == v, (where, name)


def _compare(path):
    """Every channel of a driftlab type read both ways, in one pass and one by one; the kinds of columns met."""
    log = driftlab.open(path)
    known = [c for c, i in log.info().items() if i["type"] is not None]
    assert known, path
    reference = log._log._read_reference(None)
    fast = log.read_all()
    threads = log._log.read_many(None, 3)  # the channels shared between 3 passes, as on a machine with 3 cores
    assert list(fast) == list(reference) == list(threads) == known
    kinds = set()
    for c in known:
        _same_channel(fast[c], reference[c], (path, c))
        _same_channel(threads[c], reference[c], (path, c, "3 passes"))
        _same_channel(log.read(c), reference[c], (path, c, "read"))
        kinds |= {_kind(a) for a in fast[c].values() if a is not None}
        kinds |= {"nested" for name in fast[c] if name.count(".") >= 2}
    return kinds


def _damaged_copy(path, tmp_path, seed):
    log = driftlab.open(path)
    out = os.path.join(tmp_path, "damaged-%d.lcm" % seed)
    _write(out, _damaged(_events(log.lcm_path), seed))
    return out


def test_plans_equal_the_reference_on_the_sample_log_and_damaged_copies(test_data, tmp_path):
    path = os.path.join(test_data, "sample.lcm")
    kinds = _compare(path)
    for seed in range(3):
        damaged = _damaged_copy(path, str(tmp_path), seed)
        assert _compare(damaged) == kinds
        log = driftlab.open(damaged)
        assert any(len(log.read(c)["arrival"]) < i["count"] for c, i in log.info().items() if i["type"]), "none left out"
    # Scalars of 4 and 8 bytes (integers and floats), fixed-size arrays as 2-D, arrays of structs and of numbers of
    # varying length, strings, nested structs.
    for kind in [("<i4", 1), ("<i8", 1), ("<f4", 1), ("<f8", 1), ("<f8", 2), ("<f4", 2), ("list", 1), ("str", 1)]:
        assert kind in kinds, kind
    assert "nested" in kinds


def test_plans_equal_the_reference_on_a_log_damaged_between_events(test_data, tmp_path):
    """A log whose events do not follow each other (garbage between them, a length that overruns the next event, a
    tail cut short) is read past the damage as LogReader reads it, not by the passes over intact logs."""
    events = list(_events(os.path.join(test_data, "sample.lcm")))
    out = os.path.join(str(tmp_path), "garbage.lcm")
    _write(out, events)
    data = bytearray(open(out, "rb").read())
    third = len(data) // 3
    garbage = bytes(range(7, 107))
    data = data[:third] + garbage + data[third:]  # inside an event or between two: either way not intact
    at = data.index(struct.pack(">I", SYNC), 2 * third)
    struct.pack_into(">I", data, at + 24, struct.unpack_from(">I", data, at + 24)[0] + 5)  # overruns the next event
    with open(out, "wb") as f:
        f.write(bytes(data[:-10]))
    _compare(out)


def test_plans_equal_the_reference_on_bags_and_ulogs(tmp_path):
    kinds = set()
    for name in ["bags/nav2_turtlebot.mcap", "bags/tf_example.bag", "ulog/sample_log_small.ulg"]:
        source = shared(name)
        copy = os.path.join(str(tmp_path), os.path.basename(source))  # its conversion made beside the copy
        with open(source, "rb") as f, open(copy, "wb") as g:
            g.write(f.read())
        kinds |= _compare(copy)
        kinds |= _compare(_damaged_copy(copy, str(tmp_path), 7))
    # Scalars of 1 byte (int8, bool), byte arrays, and arrays of numbers whose length varies between messages.
    for kind in [("|i1", 1), ("|b1", 1), ("|u1", 2), ("array", 1), ("<i8", 2)]:
        assert kind in kinds, kind

"""driftlab.open and Log.read: a log's channels as NumPy arrays."""
import json
import os

import numpy as np
import pytest

import driftlab


def test_lcm_log_channels_and_counts_equal_info(test_data, cli):
    path = os.path.join(test_data, "sample.lcm")
    log = driftlab.open(path)
    expected = json.load(open(os.path.join(test_data, "sample.json")))
    assert log.channels == [c["name"] for c in expected["channels"]]
    info = log.info()
    for c in expected["channels"]:
        assert info[c["name"]]["count"] == c["count"]
        assert info[c["name"]]["type"] == c["type"]
        assert info[c["name"]]["first_arrival"] == c["first_utime"]
    assert log.time_unit == driftlab.TIME_UNIT == "us"


def test_read_gives_one_array_per_field_with_stamps_and_arrivals(test_data):
    log = driftlab.open(os.path.join(test_data, "sample.lcm"))
    gt = log.read("GROUND_TRUTH")
    n = log.info()["GROUND_TRUTH"]["count"]
    assert gt["stamp"].dtype == np.int64 and gt["arrival"].dtype == np.int64
    assert len(gt["stamp"]) == len(gt["arrival"]) == n
    assert gt["stamp"] is gt["header.utime"] or np.array_equal(gt["stamp"], gt["header.utime"])
    assert gt["arrival"][0] == log.info()["GROUND_TRUTH"]["first_arrival"]
    assert np.all(np.diff(gt["arrival"]) > 0)
    assert gt["header.seq"].dtype == np.int64 and list(gt["header.seq"][:3]) == [0, 1, 2]
    assert isinstance(gt["header.frame_id"][0], str)
    floats = [k for k, v in gt.items() if isinstance(v, np.ndarray) and v.dtype == np.float64]
    assert floats, gt.keys()
    for k in floats:
        assert gt[k].shape[0] == n and np.all(np.isfinite(gt[k])), k


def test_fixed_size_arrays_are_two_dimensional(test_data):
    log = driftlab.open(os.path.join(test_data, "sample.lcm"))
    for channel, meta in log.info().items():
        if meta["type"] is None:
            continue
        data = log.read(channel)
        for name, a in data.items():
            if a is None:
                continue
            assert a.shape[0] == meta["count"], (channel, name)
            if a.dtype != object:
                assert a.flags["C_CONTIGUOUS"], (channel, name)


def test_nav2_bag_odometry_count_and_stamps_match_the_log(nav2_bag, cli):
    log = driftlab.open(nav2_bag)
    assert "/odom" in log.channels
    code, out, err = cli("info", nav2_bag, "--json")
    assert code == 0, err
    info = {c["name"]: c for c in json.loads(out)["channels"]}
    odom = log.read("/odom")
    assert len(odom["stamp"]) == info["/odom"]["count"] == log.info()["/odom"]["count"]
    assert len(odom["arrival"]) == info["/odom"]["count"]
    assert odom["arrival"][0] == info["/odom"]["first_utime"]
    assert odom["arrival"][-1] == info["/odom"]["last_utime"]
    # The stamps are the ROS headers' (simulation time here), not the arrivals; in order, at the odometry's rate.
    assert not np.array_equal(odom["stamp"], odom["arrival"])
    assert np.all(np.diff(odom["stamp"]) >= 0)
    assert odom["header.utime"] is odom["stamp"] or np.array_equal(odom["header.utime"], odom["stamp"])


def test_every_channel_of_the_nav2_bag_reads(nav2_bag):
    log = driftlab.open(nav2_bag)
    for channel, meta in log.info().items():
        if meta["type"] is None:
            continue
        data = log.read(channel)
        assert len(data["arrival"]) == meta["count"], channel


def test_unknown_channel_is_a_key_error(test_data):
    log = driftlab.open(os.path.join(test_data, "sample.lcm"))
    with pytest.raises(KeyError, match="NO_SUCH"):
        log.read("NO_SUCH")


def test_a_bad_file_raises_the_cli_message(test_data, cli):
    path = os.path.join(test_data, "not_a_log.txt")
    code, _, err = cli("diagnose", path)
    assert code == 2
    message = err.strip().removeprefix("driftlab: ")
    assert "\n" not in message
    with pytest.raises(driftlab.Error) as e:
        driftlab.open(path)
    assert str(e.value) == message
    assert isinstance(e.value, RuntimeError) and isinstance(e.value, ValueError)
    missing = os.path.join(test_data, "missing.lcm")
    code, _, err = cli("diagnose", missing)
    with pytest.raises(driftlab.Error) as e:
        driftlab.open(missing)
    assert str(e.value) == err.strip().removeprefix("driftlab: ") and missing in str(e.value)


def _same(a, b):
    """Two Log.read dicts hold the same arrays (object arrays element by element)."""
    assert a.keys() == b.keys()
    for k in a:
        x, y = a[k], b[k]
        if x is None or y is None:
            assert x is y, k
            continue
        assert x.dtype == y.dtype and x.shape == y.shape, k
        if x.dtype == object:
            for u, v in zip(x, y):
                assert (np.array_equal(u, v) if isinstance(u, np.ndarray) else u == v), k
        else:
            assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), k


@pytest.mark.parametrize("which", ["sample", "nav2"])
def test_one_pass_read_of_every_channel_equals_reads_one_by_one(which, test_data, nav2_bag):
    log = driftlab.open(os.path.join(test_data, "sample.lcm") if which == "sample" else nav2_bag)
    known = [c for c, i in log.info().items() if i["type"] is not None]
    everything = log.read_all()
    assert sorted(everything) == sorted(known) and known
    for c in known:
        _same(everything[c], log.read(c))
    two = log.read(known[:2])
    assert list(two) == known[:2]
    for c in known[:2]:
        _same(two[c], everything[c])

"""driftlab.diagnose, driftlab.eval and driftlab.import_ against the CLI's --json."""
import json
import os

import pytest

import driftlab
from conftest import shared


def test_diagnose_of_the_nav2_bag_equals_the_cli(nav2_bag, cli):
    code, out, err = cli("diagnose", nav2_bag, "--json")
    assert code == 0, err
    assert driftlab.diagnose(nav2_bag) == json.loads(out)


def test_diagnose_options_are_the_cli_options(test_data, cli):
    path = os.path.join(test_data, "sample.lcm")
    code, out, err = cli("diagnose", path, "--max-lag", "0.1", "--window", "0.5", "--json")
    assert code == 0, err
    assert driftlab.diagnose(path, max_lag=0.1, window=0.5) == json.loads(out)
    code, out, err = cli("diagnose", path, "-c", "IMU|SCAN", "--json")
    assert code == 0, err
    assert driftlab.diagnose(path, channels="IMU|SCAN") == json.loads(out)
    assert [c["name"] for c in json.loads(out)["channels"]] == ["IMU", "SCAN"]
    with pytest.raises(driftlab.Error, match="invalid channel regex"):
        driftlab.diagnose(path, channels="(")
    code, _, err = cli("diagnose", path, "--max-lag", "20")
    assert code == 2
    with pytest.raises(driftlab.Error, match="--max-lag"):
        driftlab.diagnose(path, max_lag=20)


def test_eval_on_log_channels_equals_the_cli(test_data, cli):
    log = os.path.join(test_data, "sample.lcm")
    code, out, err = cli("eval", "--gt", log + ":GROUND_TRUTH", "--est", log + ":ODOM", "--align", "sim3", "--json")
    assert code == 0, err
    ours = driftlab.eval(gt=log + ":GROUND_TRUTH", est=log + ":ODOM", align="sim3")
    assert ours == json.loads(out)
    assert ours["matched"] == 51


def test_eval_on_real_tum_trajectories_equals_the_cli(cli):
    gt = shared("evo/fr2_desk_groundtruth.txt")
    est = shared("evo/fr2_desk_ORB.txt")
    args = ["--align", "se3", "--max-dt", "0.02", "--delta", "1", "--delta-unit", "m", "--all-pairs"]
    code, out, err = cli("eval", "--gt", gt, "--est", est, *args, "--json")
    assert code == 0, err
    ours = driftlab.eval(gt=gt, est=est, align="se3", max_dt=0.02, delta=1, delta_unit="m", all_pairs=True)
    assert ours == json.loads(out)


def test_eval_errors_are_the_cli_messages(test_data, cli):
    log = os.path.join(test_data, "sample.lcm")
    for kwargs, args in [
        (dict(gt="/nonexistent.tum", est=log + ":ODOM"), ["--gt", "/nonexistent.tum", "--est", log + ":ODOM"]),
        (dict(gt=log + ":GROUND_TRUTH", est=log + ":ODOM", delta=1.5), ["--gt", log + ":GROUND_TRUTH", "--est",
                                                                         log + ":ODOM", "--delta", "1.5"]),
    ]:
        code, _, err = cli("eval", *args)
        assert code == 2
        with pytest.raises(driftlab.Error) as e:
            driftlab.eval(**kwargs)
        assert str(e.value) == err.strip().splitlines()[-1].removeprefix("driftlab: ")
    with pytest.raises(driftlab.Error, match="--align"):
        driftlab.eval(gt=log + ":GROUND_TRUTH", est=log + ":ODOM", align="bogus")


def test_import_writes_the_log_the_cli_writes(nav2_bag, cli, tmp_path):
    summary = driftlab.import_(nav2_bag, out=tmp_path / "py.lcm")
    code, out, err = cli("import", nav2_bag, "-o", str(tmp_path / "cli.lcm"))
    assert code == 0, err
    assert (tmp_path / "py.lcm").read_bytes() == (tmp_path / "cli.lcm").read_bytes()
    # "BAG (MCAP) -> OUT: 8,201 messages", then a line per topic
    assert out.splitlines()[0].endswith(": {:,} messages".format(summary["messages"]))
    assert "(" + summary["format"] + ")" in out.splitlines()[0]
    assert summary["problems"] == []
    odom = [t for t in summary["topics"] if t["channel"] == "/odom"][0]
    assert odom["driftlab_type"] == "driftlab.odometry_t"
    assert driftlab.open(tmp_path / "py.lcm").info()["/odom"]["count"] == odom["messages"]

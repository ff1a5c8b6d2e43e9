"""Fixtures of the driftlab module's tests: where the CLI, the test data and the shared real data are (set by
tests/CMakeLists.txt; PYTHONPATH there points at build/python)."""
import os
import subprocess

import pytest


def _env(name):
    value = os.environ.get(name)
    if not value:
        pytest.skip(name + " is not set (run through ctest)")
    return value


@pytest.fixture(scope="session")
def cli():
    """Runs `driftlab ARGS...` and returns (exit code, stdout, stderr)."""
    binary = os.path.join(_env("DRIFTLAB_BIN_DIR"), "driftlab")

    def run(*args):
        r = subprocess.run([binary, *args], capture_output=True, text=True)
        return r.returncode, r.stdout, r.stderr

    return run


@pytest.fixture(scope="session")
def test_data():
    return _env("DRIFTLAB_TEST_DATA")


@pytest.fixture(scope="session")
def source_dir():
    return _env("DRIFTLAB_SOURCE_DIR")


def shared(name):
    path = os.path.join(os.environ.get("DRIFTLAB_SHARED_DATA", ""), name)
    if not os.path.exists(path):
        pytest.skip("no shared data " + name + " (../shared/data beside the checkout)")
    return path


@pytest.fixture(scope="session")
def nav2_bag():
    """The shared nav2 recording (a ROS 2 MCAP bag of a TurtleBot driving in Gazebo)."""
    return shared("bags/nav2_turtlebot.mcap")

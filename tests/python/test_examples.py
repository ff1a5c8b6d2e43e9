"""The tutorial script docs/examples/which_stream_is_late.py on the nav2 bag."""
import os
import subprocess
import sys

import pytest


def test_which_stream_is_late_names_amcl_and_writes_its_plot(nav2_bag, source_dir, tmp_path):
    pytest.importorskip("matplotlib")
    script = os.path.join(source_dir, "docs", "examples", "which_stream_is_late.py")
    png = tmp_path / "late.png"
    r = subprocess.run([sys.executable, script, nav2_bag, str(png)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "the late stream: /amcl_pose" in r.stdout
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

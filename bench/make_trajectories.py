#!/usr/bin/python3
"""Writes a reference and an estimated trajectory of N poses as TUM files, for benchmarking `driftlab eval`.

usage: make_trajectories.py N OUT_DIR   ->  OUT_DIR/gtN.tum, OUT_DIR/estN.tum (100 Hz, stamps jittered by 1 ms)
"""
import sys

import numpy as np

n, out = int(sys.argv[1]), sys.argv[2]
rng = np.random.default_rng(1)
s = np.arange(n) * 0.01


def poses(stamps, noise):
    xyz = np.stack([5 * np.cos(0.02 * s), 3 * np.sin(0.03 * s), 0.5 * np.sin(0.01 * s)], axis=1)
    xyz += noise * rng.standard_normal((n, 3))
    yaw = 0.02 * s
    quat = np.stack([np.zeros(n), np.zeros(n), np.sin(yaw / 2), np.cos(yaw / 2)], axis=1)
    return np.column_stack([stamps, xyz, quat])


np.savetxt(f"{out}/gt{n}.tum", poses(1700000000.0 + s, 0.0), fmt="%.6f")
np.savetxt(f"{out}/est{n}.tum", poses(1700000000.0 + s + 0.001 * rng.standard_normal(n), 0.01), fmt="%.6f")

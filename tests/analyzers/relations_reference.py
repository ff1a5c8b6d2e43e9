#!/usr/bin/python3
"""An independent reference for `driftlab eval --relations`: the relation error of Kuemmerle et al. ("On measuring
the accuracy of SLAM algorithms", Autonomous Robots 27, 2009), written from the paper and the benchmark's
description of its metric evaluator with numpy and scipy, in 4x4 homogeneous matrices (driftlab uses quaternions).

For each relation (t1, t2, x, y, z, roll, pitch, yaw): the estimate's poses X1, X2 at t1 and t2 (the pose whose
stamp is nearest, when within --max-dt; with --odometry, a stamp without one takes the nearest estimate pose moved
by the odometry's motion between the two stamps, the odometry interpolated linearly and by slerp between its two
poses around a stamp when they are at most 1 s apart); D = inv(X1) X2; D* the relation as a matrix
(R = Rz(yaw) Ry(pitch) Rx(roll)); E = inv(D*) D. Translation error |trans(E)| in metres, rotation error the angle
of rot(E) in degrees. Statistics: mean, sample standard deviation (n - 1) and maximum of the errors and of their
squares.

usage: relations_reference.py EST.tum RELATIONS [--odometry ODOM.tum] [--max-dt S]
prints one JSON object with the keys of `driftlab eval --json`'s "relations".
"""
import argparse
import json
import sys

import numpy as np
from scipy.spatial.transform import Rotation, Slerp


def read_tum(path):
    data = np.loadtxt(path, comments="#", ndmin=2)
    order = np.argsort(data[:, 0], kind="stable")
    return data[order]


def matrix(xyz, rotation):
    m = np.eye(4)
    m[:3, :3] = rotation.as_matrix()
    m[:3, 3] = xyz
    return m


def pose_of_row(row):
    return matrix(row[1:4], Rotation.from_quat(row[4:8]))  # scipy's quaternions are (x, y, z, w), as TUM's


def nearest_index(stamps, t):
    k = int(np.searchsorted(stamps, t))
    candidates = [i for i in (k - 1, k) if 0 <= i < len(stamps)]
    return min(candidates, key=lambda i: (abs(stamps[i] - t), i))


def odometry_at(odom, t):
    stamps = odom[:, 0]
    k = int(np.searchsorted(stamps, t))
    if k < len(stamps) and stamps[k] == t:
        return pose_of_row(odom[k])
    if k == 0 or k == len(stamps) or stamps[k] - stamps[k - 1] > 1.0:
        return None
    a, b = odom[k - 1], odom[k]
    f = (t - a[0]) / (b[0] - a[0])
    xyz = a[1:4] + f * (b[1:4] - a[1:4])
    slerp = Slerp([0.0, 1.0], Rotation.from_quat([a[4:8], b[4:8]]))
    return matrix(xyz, slerp([f])[0])


def stats(values):
    v = np.asarray(values, dtype=float)
    return {"mean": float(np.mean(v)), "std": float(np.std(v, ddof=1)) if v.size > 1 else 0.0,
            "max": float(np.max(v))}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("est")
    ap.add_argument("relations")
    ap.add_argument("--odometry")
    ap.add_argument("--max-dt", type=float, default=1e-4)
    a = ap.parse_args()

    est = read_tum(a.est)
    odom = read_tum(a.odometry) if a.odometry else None
    relations = np.loadtxt(a.relations, comments="#", ndmin=2)

    def pose_at(t):
        k = nearest_index(est[:, 0], t)
        if abs(est[k, 0] - t) <= a.max_dt:
            return pose_of_row(est[k]), 0.0
        if odom is None:
            return None, 0.0
        o_from, o_to = odometry_at(odom, est[k, 0]), odometry_at(odom, t)
        if o_from is None or o_to is None:
            return None, 0.0
        return pose_of_row(est[k]) @ np.linalg.inv(o_from) @ o_to, abs(t - est[k, 0])

    trans, rot, bridged, longest = [], [], 0, 0.0
    for t1, t2, x, y, z, roll, pitch, yaw in relations:
        x1, b1 = pose_at(t1)
        x2, b2 = pose_at(t2) if x1 is not None else (None, 0.0)
        if x1 is None or x2 is None:
            continue
        d = np.linalg.inv(x1) @ x2
        d_star = matrix([x, y, z], Rotation.from_euler("xyz", [roll, pitch, yaw]))  # extrinsic x, y, z: Rz Ry Rx
        e = np.linalg.inv(d_star) @ d
        trans.append(float(np.linalg.norm(e[:3, 3])))
        rot.append(float(np.degrees(np.linalg.norm(Rotation.from_matrix(e[:3, :3]).as_rotvec()))))
        if max(b1, b2) > 0:
            bridged += 1
            longest = max(longest, b1, b2)

    trans, rot = np.array(trans), np.array(rot)
    json.dump({"relations": len(relations), "used": len(trans), "bridged": bridged, "max_bridge_s": longest,
               "trans_m": stats(trans), "trans_sq_m2": stats(trans ** 2), "rot_deg": stats(rot),
               "rot_sq_deg2": stats(rot ** 2)}, sys.stdout)


if __name__ == "__main__":
    main()

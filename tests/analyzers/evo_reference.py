#!/usr/bin/python3
"""An independent reference for `driftlab eval`, written from evo's documented semantics with numpy.

evo itself is not packaged for Debian and PyPI is out of reach here, so this script restates what evo_ape and
evo_rpe compute, in evo's own way (every pair of stamps compared with numpy.argmin, Umeyama by numpy's SVD,
errors from 4x4 SE(3) matrices), and serves two purposes: the test oracle that driftlab's numbers must equal to
1e-6, and the peer that scripts/bench times driftlab against.

usage: evo_reference.py REF.tum EST.tum [--align none|se3|sim3] [--max-dt S] [--offset S]
                        [--delta D] [--delta-unit frames|m] [--all-pairs]
prints one JSON object with the keys of `driftlab eval --json` that evo defines.
"""
import argparse
import json
import sys

import numpy as np


def read_tum(path):
    data = np.loadtxt(path, comments="#", ndmin=2)
    stamps = data[:, 0]
    xyz = data[:, 1:4]
    quat_wxyz = data[:, [7, 4, 5, 6]]
    return stamps, xyz, quat_wxyz


def quat_to_matrix(q):
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def se3(r, t):
    m = np.eye(4)
    m[:3, :3] = r
    m[:3, 3] = t
    return m


def se3_inv(m):
    r, t = m[:3, :3], m[:3, 3]
    return se3(r.T, -r.T @ t)


def angle_of(r):
    """Rotation angle [rad] via the quaternion of r (accurate near 0 and pi)."""
    tr = np.trace(r)
    # Shepperd: pick the largest of w, x, y, z to divide by.
    cands = [tr, r[0, 0], r[1, 1], r[2, 2]]
    k = int(np.argmax(cands))
    if k == 0:
        w = np.sqrt(1 + tr) / 2
        v = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / (4 * w)
    else:
        i = k - 1
        j, l = (i + 1) % 3, (i + 2) % 3
        s = np.sqrt(1 + r[i, i] - r[j, j] - r[l, l]) * 2
        v = np.zeros(3)
        v[i] = s / 4
        v[j] = (r[j, i] + r[i, j]) / s
        v[l] = (r[l, i] + r[i, l]) / s
        w = (r[l, j] - r[j, l]) / s
    return 2 * np.arctan2(np.linalg.norm(v), abs(w))


def associate(ref_t, est_t, max_dt, offset):
    """For each stamp of the shorter trajectory, numpy.argmin over all stamps of the longer one."""
    est_longer = len(est_t) > len(ref_t)
    long_t, short_t = (est_t, ref_t) if est_longer else (ref_t, est_t)
    shifted = long_t + (offset if est_longer else -offset)
    short_ids, long_ids = [], []
    for i, s in enumerate(short_t):
        diffs = np.abs(shifted - s)
        j = int(np.argmin(diffs))
        if diffs[j] <= max_dt:
            short_ids.append(i)
            long_ids.append(j)
    return (short_ids, long_ids) if est_longer else (long_ids, short_ids)


def umeyama(src, dst, with_scale):
    """Least-squares similarity transform mapping src (3xN) onto dst (3xN) (Umeyama 1991)."""
    n = src.shape[1]
    mu_s, mu_d = src.mean(axis=1), dst.mean(axis=1)
    var_s = np.mean(np.sum((src - mu_s[:, None]) ** 2, axis=0))
    cov = (dst - mu_d[:, None]) @ (src - mu_s[:, None]).T / n
    u, d, vt = np.linalg.svd(cov)
    s = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        s[2, 2] = -1
    r = u @ s @ vt
    c = np.trace(np.diag(d) @ s) / var_s if with_scale else 1.0
    t = mu_d - c * r @ mu_s
    return r, t, c


def stats(e):
    e = np.asarray(e, dtype=float)
    if e.size == 0:
        return {k: 0.0 for k in ("rmse", "mean", "median", "std", "min", "max")}
    return {"rmse": float(np.sqrt(np.mean(e ** 2))), "mean": float(np.mean(e)), "median": float(np.median(e)),
            "std": float(np.std(e)), "min": float(np.min(e)), "max": float(np.max(e))}


def pairs_by_index(n, delta, all_pairs):
    if all_pairs:
        return [(i, i + delta) for i in range(n) if i + delta < n]
    ids = list(range(0, n, delta))
    return list(zip(ids, ids[1:]))


def pairs_by_path(positions, delta):
    ids, path = [], 0.0
    for i in range(len(positions)):
        if i > 0:
            path += float(np.linalg.norm(positions[i] - positions[i - 1]))
        if path >= delta:
            ids.append(i)
            path = 0.0
    return list(zip(ids, ids[1:]))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("ref")
    ap.add_argument("est")
    ap.add_argument("--align", default="none", choices=["none", "se3", "sim3"])
    ap.add_argument("--max-dt", type=float, default=0.01)
    ap.add_argument("--offset", type=float, default=0.0)
    ap.add_argument("--delta", type=float, default=1)
    ap.add_argument("--delta-unit", default="frames", choices=["frames", "m"])
    ap.add_argument("--all-pairs", action="store_true")
    a = ap.parse_args()

    ref_t, ref_p, ref_q = read_tum(a.ref)
    est_t, est_p, est_q = read_tum(a.est)
    ri, ei = associate(ref_t, est_t, a.max_dt, a.offset)
    ref_p, ref_q, est_p, est_q = ref_p[ri], ref_q[ri], est_p[ei], est_q[ei]
    n = len(ri)

    r, t, c = np.eye(3), np.zeros(3), 1.0
    if a.align != "none":
        r, t, c = umeyama(est_p.T, ref_p.T, a.align == "sim3")
    ref_poses = [se3(quat_to_matrix(ref_q[i]), ref_p[i]) for i in range(n)]
    est_poses = [se3(r @ quat_to_matrix(est_q[i]), c * r @ est_p[i] + t) for i in range(n)]

    ape_t, ape_r = [], []
    for q, p in zip(ref_poses, est_poses):
        e = se3_inv(q) @ p
        ape_t.append(np.linalg.norm(e[:3, 3]))
        ape_r.append(np.degrees(angle_of(e[:3, :3])))

    if a.delta_unit == "frames":
        pairs = pairs_by_index(n, int(a.delta), a.all_pairs)
    else:
        pairs = pairs_by_path([pp[:3, 3] for pp in ref_poses], a.delta)
    rpe_t, rpe_r = [], []
    for i, j in pairs:
        q_rel = se3_inv(ref_poses[i]) @ ref_poses[j]
        p_rel = se3_inv(est_poses[i]) @ est_poses[j]
        e = se3_inv(q_rel) @ p_rel
        rpe_t.append(np.linalg.norm(e[:3, 3]))
        rpe_r.append(np.degrees(angle_of(e[:3, :3])))

    json.dump({
        "matched": n,
        "alignment": {"type": a.align, "rotation": r.tolist(), "translation": t.tolist(), "scale": float(c)},
        "ate": stats(ape_t),
        "ate_rot_deg": stats(ape_r),
        "rpe": {"delta": a.delta, "unit": "m" if a.delta_unit == "m" else "frames", "pairs": len(pairs),
                "trans": stats(rpe_t), "rot_deg": stats(rpe_r)},
    }, sys.stdout)


if __name__ == "__main__":
    main()

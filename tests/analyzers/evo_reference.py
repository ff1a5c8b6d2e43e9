#!/usr/bin/python3
"""An independent reference for `driftlab eval`, written from evo's semantics with numpy and scipy.

evo itself is not packaged for Debian and PyPI is out of reach here, so this script restates what evo_ape and
evo_rpe compute, in evo's own way (every pair of stamps compared with numpy.argmin, Umeyama by numpy's SVD,
errors from 4x4 SE(3) matrices, angles by scipy's Rotation), and serves two purposes: the test oracle that
driftlab's numbers must equal to 1e-6, and the peer that scripts/bench times driftlab against. It must itself equal
what evo computed on real trajectories: `--expected ../shared/data/evo/expected.json` runs evo's 81 cases and
fails on any difference (a test runs it).

--align origin is evo's --align_origin: the estimate moved by ref_0 inv(est_0), its first associated pose onto the
reference's, as evo's PosePath3D.align_origin does with 4x4 matrices.

RPE pairs as evo chooses them (evo.core.filters): from the estimate's poses unless --pairs-from-reference; frames:
(0, d), (d, 2d), ... or, with --all-pairs, every (i, i + d); metres: consecutive pairs where the path travelled
since the previous pair's end reaches d (the first pair starting where it first does), or with --all-pairs, from
each pose the later pose whose path distance is closest to d, kept within --delta-tol * d; degrees and radians:
consecutive pairs where the rotation angles between consecutive poses add up to d (the first pair starting at
pose 0), or with --all-pairs every later pose whose direct rotation angle is within --delta-tol * d of d.

usage: evo_reference.py REF.tum EST.tum [--align none|se3|sim3|origin] [--max-dt S] [--offset S] [--delta D]
                        [--delta-unit frames|m|deg|rad] [--all-pairs] [--pairs-from-reference] [--delta-tol R]
       evo_reference.py --expected EXPECTED.json
prints one JSON object with the keys of `driftlab eval --json` that evo defines.
"""
import argparse
import functools
import json
import sys

import numpy as np
from scipy.spatial.transform import Rotation


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
        return None  # no errors, no statistics (as driftlab's JSON says)
    return {"rmse": float(np.sqrt(np.mean(e ** 2))), "mean": float(np.mean(e)), "median": float(np.median(e)),
            "std": float(np.std(e)), "min": float(np.min(e)), "max": float(np.max(e))}


def pairs_by_index(n, delta, all_pairs):
    if all_pairs:
        return [(i, i + delta) for i in range(n) if i + delta < n]
    ids = list(range(0, n, delta))
    return list(zip(ids, ids[1:]))


def pairs_by_path(positions, delta, tol, all_pairs):
    steps = np.linalg.norm(positions[1:] - positions[:-1], axis=1)
    if all_pairs:
        travelled = np.concatenate(([0.0], np.cumsum(steps)))
        pairs = []
        for i in range(len(positions) - 1):
            miss = np.abs(travelled[i + 1:] - travelled[i] - delta)
            j = int(np.argmin(miss))
            if miss[j] <= tol:
                pairs.append((i, i + 1 + j))
        return pairs
    ids, path = [], 0.0
    for i in range(len(positions)):
        if i > 0:
            path += float(np.linalg.norm(positions[i] - positions[i - 1]))
        if path >= delta:
            ids.append(i)
            path = 0.0
    return list(zip(ids, ids[1:]))


def pairs_by_angle(rotations, delta, tol, all_pairs):
    """rotations: a scipy Rotation of n poses; delta and tol in radians."""
    n = len(rotations)
    if all_pairs:
        pairs = []
        for i in range(n - 1):
            angles = np.linalg.norm((rotations[i].inv() * rotations[i + 1:]).as_rotvec(), axis=1)
            for j in np.flatnonzero((delta - tol <= angles) & (angles <= delta + tol)):
                pairs.append((i, i + 1 + int(j)))
        return pairs
    steps = np.linalg.norm((rotations[:-1].inv() * rotations[1:]).as_rotvec(), axis=1)
    pairs, start, angle = [], 0, 0.0
    for k, step in enumerate(steps):
        angle += step
        if angle >= delta:
            pairs.append((start, k + 1))
            start, angle = k + 1, 0.0
    return pairs


@functools.lru_cache(maxsize=4)
def matched(ref_path, est_path, max_dt, offset):
    """The associated positions and quaternions, once per pair of files (--expected runs 27 cases on each)."""
    ref_t, ref_p, ref_q = read_tum(ref_path)
    est_t, est_p, est_q = read_tum(est_path)
    ri, ei = associate(ref_t, est_t, max_dt, offset)
    return ref_p[ri], ref_q[ri], est_p[ei], est_q[ei]


def evaluate(ref_path, est_path, align="none", max_dt=0.01, offset=0.0, delta=1, delta_unit="frames",
             all_pairs=False, pairs_from_reference=False, delta_tol=0.1):
    ref_p, ref_q, est_p, est_q = matched(ref_path, est_path, max_dt, offset)
    n = len(ref_p)

    r, t, c = np.eye(3), np.zeros(3), 1.0
    if align == "origin":
        # evo's align_origin (PosePath3D.align_origin): to_ref_origin = ref.poses_se3[0] @ se3_inverse(est.poses_se3[0]),
        # left-multiplied onto every pose of the (associated) estimate.
        to_ref_origin = se3(quat_to_matrix(ref_q[0]), ref_p[0]) @ np.linalg.inv(se3(quat_to_matrix(est_q[0]), est_p[0]))
        r, t = to_ref_origin[:3, :3], to_ref_origin[:3, 3]
    elif align != "none":
        r, t, c = umeyama(est_p.T, ref_p.T, align == "sim3")
    ref_poses = [se3(quat_to_matrix(ref_q[i]), ref_p[i]) for i in range(n)]
    est_poses = [se3(r @ quat_to_matrix(est_q[i]), c * r @ est_p[i] + t) for i in range(n)]

    # Errors of many poses at once: stacked rotations (n x 3 x 3) and translations (n x 3).
    ref_r = np.array([pp[:3, :3] for pp in ref_poses]).reshape(-1, 3, 3)
    ref_t = np.array([pp[:3, 3] for pp in ref_poses]).reshape(-1, 3)
    est_r = np.array([pp[:3, :3] for pp in est_poses]).reshape(-1, 3, 3)
    est_t = np.array([pp[:3, 3] for pp in est_poses]).reshape(-1, 3)
    tr = lambda m: np.transpose(m, (0, 2, 1))

    def angles_deg(r):
        return np.degrees(Rotation.from_matrix(r).magnitude()) if len(r) else np.array([])

    # APE: inv(Q) P.
    ape_t = np.linalg.norm(est_t - ref_t, axis=1)
    ape_r = angles_deg(tr(ref_r) @ est_r)

    chosen = ref_poses if pairs_from_reference else est_poses
    if delta_unit == "frames":
        pairs = pairs_by_index(n, int(delta), all_pairs)
    elif delta_unit == "m":
        pairs = pairs_by_path(np.array([pp[:3, 3] for pp in chosen]), delta, delta * delta_tol, all_pairs)
    else:
        to_rad = np.pi / 180 if delta_unit == "deg" else 1.0
        rotations = Rotation.from_matrix(np.array([pp[:3, :3] for pp in chosen]))
        pairs = pairs_by_angle(rotations, delta * to_rad, delta * delta_tol * to_rad, all_pairs)
    # RPE: inv(inv(Q_i) Q_j) inv(P_i) P_j.
    i = np.array([p[0] for p in pairs], dtype=int)
    j = np.array([p[1] for p in pairs], dtype=int)
    q_rel_r = tr(ref_r[i]) @ ref_r[j]
    q_rel_t = (tr(ref_r[i]) @ (ref_t[j] - ref_t[i])[:, :, None])[:, :, 0]
    p_rel_r = tr(est_r[i]) @ est_r[j]
    p_rel_t = (tr(est_r[i]) @ (est_t[j] - est_t[i])[:, :, None])[:, :, 0]
    e_t = (tr(q_rel_r) @ (p_rel_t - q_rel_t)[:, :, None])[:, :, 0]
    rpe_t = np.linalg.norm(e_t, axis=1)
    rpe_r = angles_deg(tr(q_rel_r) @ p_rel_r)

    return {
        "matched": n,
        "alignment": {"type": align, "rotation": r.tolist(), "translation": t.tolist(), "scale": float(c)},
        "ate": stats(ape_t),
        "ate_rot_deg": stats(ape_r),
        "rpe": {"delta": delta, "unit": delta_unit, "all_pairs": all_pairs,
                "pairs_from_reference": pairs_from_reference, "pairs": len(pairs),
                "trans": stats(rpe_t), "rot_deg": stats(rpe_r)},
    }


def check_expected(path):
    """Runs every case evo computed (expected.json beside the trajectories) and reports the differences."""
    import os
    if not os.path.exists(path):
        # The shared real data is missing: skip (ctest's SKIP_RETURN_CODE), except under CI, which always has it.
        print(f"{path} is missing")
        return 1 if os.environ.get("CI") == "true" else 77
    folder = os.path.dirname(os.path.abspath(path))
    cases = json.load(open(path))["cases"]
    bad = 0
    for k, case in enumerate(cases):
        got = evaluate(os.path.join(folder, case["gt"]), os.path.join(folder, case["est"]),
                       align=case["align"] if case["metric"] == "ape" else "none", max_dt=case["max_dt"],
                       delta=case.get("delta", 1), delta_unit=case.get("delta_unit", "frames"),
                       all_pairs=case.get("all_pairs", False),
                       pairs_from_reference=case.get("pairs_from_reference", False),
                       delta_tol=case.get("rel_delta_tol", 0.1))
        if case["metric"] == "ape":
            counts = [("matched", got["matched"], case["matched"])]
            groups = [("trans", got["ate"], case["trans"]), ("rot_deg", got["ate_rot_deg"], case["rot_deg"])]
        else:
            counts = [("pairs", got["rpe"]["pairs"], case["pairs"])]
            groups = [("trans", got["rpe"]["trans"], case["trans"]), ("rot_deg", got["rpe"]["rot_deg"], case["rot_deg"])]
        problems = [f"{name} {ours} != {want}" for name, ours, want in counts if ours != want]
        for name, ours, want in groups:
            for key, value in want.items():
                if abs(ours[key] - value) > 1e-6 * max(abs(value), 1e-12):
                    problems.append(f"{name}.{key} {ours[key]!r} != {value!r}")
        if problems:
            bad += 1
            print(f"case {k} ({case['est']}, {case['metric']}, {case.get('delta')} {case.get('delta_unit')}, "
                  f"all_pairs {case.get('all_pairs')}, from reference {case.get('pairs_from_reference')}): "
                  + "; ".join(problems))
    print(f"{len(cases) - bad} of {len(cases)} cases equal evo's numbers")
    return 1 if bad else 0


def main():
    if len(sys.argv) == 3 and sys.argv[1] == "--expected":
        sys.exit(check_expected(sys.argv[2]))
    ap = argparse.ArgumentParser()
    ap.add_argument("ref")
    ap.add_argument("est")
    ap.add_argument("--align", default="none", choices=["none", "se3", "sim3", "origin"])
    ap.add_argument("--max-dt", type=float, default=0.01)
    ap.add_argument("--offset", type=float, default=0.0)
    ap.add_argument("--delta", type=float, default=1)
    ap.add_argument("--delta-unit", default="frames", choices=["frames", "m", "deg", "rad"])
    ap.add_argument("--all-pairs", action="store_true")
    ap.add_argument("--pairs-from-reference", action="store_true")
    ap.add_argument("--delta-tol", type=float, default=0.1)
    a = ap.parse_args()
    json.dump(evaluate(a.ref, a.est, a.align, a.max_dt, a.offset, a.delta, a.delta_unit, a.all_pairs,
                       a.pairs_from_reference, a.delta_tol), sys.stdout)


if __name__ == "__main__":
    main()

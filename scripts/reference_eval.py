#!/usr/bin/env python3
"""Independent reference computation of ATE and RPE with numpy, for checking `superdyna eval`.

Written separately from the C++ code, straight from the definitions:
  - association: pairs (est, gt) with |t_est + offset - t_gt| <= max_diff, one to one, greedily by
    smallest time difference (TUM RGB-D benchmark's associate.py rule);
  - alignment: Umeyama (1991) closed form, with or without scale;
  - ATE: per-pose position error after alignment; RMSE, mean, median, population std, min, max;
  - RPE: for each i, j is the first index with ground-truth path length(j) - length(i) >= delta;
    E = (G_i^-1 G_j)^-1 (P_i^-1 P_j); translation ||t_E|| / delta [m/m], rotation angle / delta
    [deg/m]; estimate positions scaled by the Sim(3) scale first.
Reads TUM-format files only. Prints a JSON object with the same keys as `superdyna eval --json`.
"""
import argparse
import json
import math
import sys

import numpy as np


def read_tum(path):
    rows = []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if not parts or parts[0].startswith("#"):
                continue
            try:
                rows.append([float(x) for x in parts])
            except ValueError:
                if rows:
                    raise
    data = np.array(rows)
    return data[:, 0], data[:, 1:4], data[:, 4:8]  # times, positions, quaternions xyzw


def quat_to_matrix(q):
    x, y, z, w = q / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def associate(t_gt, t_est, max_diff, offset):
    candidates = []
    for i, te in enumerate(t_est):
        lo = np.searchsorted(t_gt, te + offset - max_diff, side="left")
        hi = np.searchsorted(t_gt, te + offset + max_diff, side="right")
        for j in range(lo, hi):
            d = abs(te + offset - t_gt[j])
            if d <= max_diff:
                candidates.append((d, i, j))
    candidates.sort()
    used_est, used_gt, pairs = set(), set(), []
    for d, i, j in candidates:
        if i in used_est or j in used_gt:
            continue
        used_est.add(i)
        used_gt.add(j)
        pairs.append((i, j))
    pairs.sort(key=lambda p: p[1])
    return pairs


def umeyama(src, dst, with_scale):
    """Returns s, R, t minimising sum ||dst - (s R src + t)||^2; src, dst are 3xN."""
    mu_s, mu_d = src.mean(axis=1, keepdims=True), dst.mean(axis=1, keepdims=True)
    xs, xd = src - mu_s, dst - mu_d
    n = src.shape[1]
    cov = xd @ xs.T / n
    U, D, Vt = np.linalg.svd(cov)
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[2, 2] = -1
    R = U @ S @ Vt
    s = (D * np.diag(S)).sum() / (xs ** 2).sum() * n if with_scale else 1.0
    t = mu_d - s * R @ mu_s
    return s, R, t.ravel()


def stats(values):
    v = np.asarray(values)
    return {"rmse": math.sqrt(float(np.mean(v ** 2))), "mean": float(np.mean(v)),
            "median": float(np.median(v)), "std": float(np.std(v)), "min": float(v.min()),
            "max": float(v.max())}


def pose(R, t):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def rotation_angle_deg(R):
    # atan2 of sin and cos of the angle: accurate for small angles, unlike acos of the trace.
    sin_angle = np.linalg.norm([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2.0
    cos_angle = (np.trace(R) - 1.0) / 2.0
    return math.degrees(math.atan2(sin_angle, cos_angle))


def rpe(G, P, delta):
    """G, P: lists of 4x4 ground-truth and (scaled) estimate poses; distance-based pairs."""
    gt_pos = np.array([T[:3, 3] for T in G])
    length = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(gt_pos, axis=0), axis=1))])
    trans, rot = [], []
    for i in range(len(G)):
        later = np.nonzero(length[i + 1:] - length[i] >= delta)[0]
        if len(later) == 0:
            break
        j = i + 1 + later[0]
        E = np.linalg.inv(np.linalg.inv(G[i]) @ G[j]) @ (np.linalg.inv(P[i]) @ P[j])
        trans.append(np.linalg.norm(E[:3, 3]) / delta)
        rot.append(rotation_angle_deg(E[:3, :3]) / delta)
    return trans, rot


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--gt", required=True)
    ap.add_argument("--est", required=True)
    ap.add_argument("--align", choices=["none", "se3", "sim3"], default="se3")
    ap.add_argument("--max-diff", type=float, default=0.01)
    ap.add_argument("--offset", type=float, default=0.0)
    ap.add_argument("--rpe-delta", type=float, default=1.0)
    args = ap.parse_args()

    t_gt, p_gt, q_gt = read_tum(args.gt)
    t_est, p_est, q_est = read_tum(args.est)
    pairs = associate(t_gt, t_est, args.max_diff, args.offset)
    ie = [i for i, _ in pairs]
    ig = [j for _, j in pairs]
    src, dst = p_est[ie].T, p_gt[ig].T
    if args.align == "none":
        s, R, t = 1.0, np.eye(3), np.zeros(3)
    else:
        s, R, t = umeyama(src, dst, args.align == "sim3")
    aligned = s * (R @ src) + t[:, None]
    ate = stats(np.linalg.norm(dst - aligned, axis=0))
    G = [pose(quat_to_matrix(q_gt[j]), p_gt[j]) for j in ig]
    P = [pose(quat_to_matrix(q_est[i]), s * p_est[i]) for i in ie]
    trans, rot = rpe(G, P, args.rpe_delta)
    out = {"pairs": len(pairs), "scale": s, "ate_rmse": ate["rmse"], "ate_mean": ate["mean"],
           "ate_median": ate["median"], "ate_std": ate["std"], "ate_min": ate["min"],
           "ate_max": ate["max"], "rpe_trans": stats(trans)["rmse"],
           "rpe_trans_mean": stats(trans)["mean"], "rpe_rot": stats(rot)["rmse"],
           "rpe_rot_mean": stats(rot)["mean"], "rpe_pairs": len(trans)}
    json.dump(out, sys.stdout, indent=2)
    print()


if __name__ == "__main__":
    main()

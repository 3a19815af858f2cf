#!/usr/bin/env python3
"""OpenCV's StereoSGBM beside camplace's matcher on one rectified grey pair.

Both disparity maps are scored against the true disparity over the pixels where the truth
is finite: bad-1 and bad-2 (share of those pixels whose estimate is missing or more than
1 or 2 px off), completeness (share with an estimate) and the mean absolute error where
both exist. SGBM is timed over --runs runs (median); camplace's time is passed in.
Requirements: scripts/requirements-peers.txt.
"""
import argparse
import statistics
import time

import cv2
import numpy as np


def read_pfm(path):
    """A one-channel PFM (`Pf`) as a float32 array, top row first."""
    with open(path, "rb") as f:
        if f.readline().strip() != b"Pf":
            raise SystemExit(f"{path}: expected a one-channel PFM (Pf)")
        width, height = (int(v) for v in f.readline().split())
        scale = float(f.readline())
        order = "<" if scale < 0 else ">"
        data = np.frombuffer(f.read(width * height * 4), dtype=order + "f4")
    if data.size != width * height:
        raise SystemExit(f"{path}: expected {width}x{height} floats, the file ends early")
    return np.flipud(data.reshape(height, width)).astype(np.float32)


def sgbm(left, right, min_disp, max_disp, block=5):
    """SGBM's disparity (NaN where it has none), with the usual smoothness penalties."""
    count = int(np.ceil((max_disp - min_disp) / 16.0)) * 16
    matcher = cv2.StereoSGBM_create(
        minDisparity=int(np.floor(min_disp)),
        numDisparities=max(16, count),
        blockSize=block,
        P1=8 * block * block,
        P2=32 * block * block,
        uniquenessRatio=10,
        disp12MaxDiff=1,
        speckleWindowSize=100,
        speckleRange=2,
        mode=cv2.STEREO_SGBM_MODE_SGBM,
    )
    raw = matcher.compute(left, right).astype(np.float32) / 16.0
    raw[raw < matcher.getMinDisparity()] = np.nan
    return raw


def score(estimate, truth):
    valid = np.isfinite(truth)
    n = max(int(valid.sum()), 1)
    have = np.isfinite(estimate) & valid
    err = np.full(truth.shape, np.inf, dtype=np.float32)
    err[have] = np.abs(estimate[have] - truth[have])
    return {
        "bad1": float(((err > 1.0) & valid).sum() / n),
        "bad2": float(((err > 2.0) & valid).sum() / n),
        "complete": float(have.sum() / n),
        "mae": float(err[have].mean()) if have.any() else float("nan"),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--left", required=True)
    ap.add_argument("--right", required=True)
    ap.add_argument("--truth", required=True)
    ap.add_argument("--min-disp", type=float, default=0.0)
    ap.add_argument("--max-disp", type=float, required=True)
    ap.add_argument("--ours", help="camplace's disparity.pfm of the same pair")
    ap.add_argument("--ours-ms", type=float, help="camplace's median time, ms")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--runs", type=int, default=5)
    a = ap.parse_args()
    cv2.setNumThreads(a.threads)
    left = cv2.imread(a.left, cv2.IMREAD_GRAYSCALE)
    right = cv2.imread(a.right, cv2.IMREAD_GRAYSCALE)
    if left is None or right is None:
        raise SystemExit(f"{a.left if left is None else a.right}: expected a readable image")
    times = []
    for _ in range(a.runs):
        start = time.perf_counter()
        estimate = sgbm(left, right, a.min_disp, a.max_disp)
        times.append(1e3 * (time.perf_counter() - start))
    truth = read_pfm(a.truth)
    rows = [("opencv-sgbm", statistics.median(times), score(estimate, truth))]
    if a.ours:
        rows.append(("camplace", a.ours_ms, score(read_pfm(a.ours), truth)))
    print(f"{'matcher':<12} {'ms':>8} {'bad1':>7} {'bad2':>7} {'complete':>9} {'mae':>7}")
    for name, ms, r in rows:
        shown = f"{ms:8.2f}" if ms is not None else f"{'-':>8}"
        print(f"{name:<12} {shown} {r['bad1']:>7.3f} {r['bad2']:>7.3f} {r['complete']:>9.3f} {r['mae']:>7.3f}")


if __name__ == "__main__":
    main()

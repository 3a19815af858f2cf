"""Our hand-eye calibration beside OpenCV's, on the same rendered images and robot poses.

For each seed and setup (eye-to-hand, eye-in-hand) it renders a hand-eye calibration with
`camplace render --board B --hand-eye N [--eye-in-hand] --pose-format matrix --pose-unit mm`
(the robot's error 0.1 mm / 0.02° per axis, the cell's camera noise), runs
`camplace calibrate --hand-eye` with the true rig.json, and runs OpenCV on the same files:

- the board's pose per view: cv2.findChessboardCorners + cornerSubPix in the left image,
  put into the board order of docs/formats.md (calibrate_opencv.py's to_board_order), then
  cv2.solvePnP with the left camera's K and distortion from rig.json;
- cv2.calibrateRobotWorldHandEye with SHAH and LI, and cv2.calibrateHandEye with TSAI, PARK
  and DANIILIDIS (eye-to-hand by passing the inverted flange poses, as OpenCV's docs say).

Errors against hand_eye.json's truth: eye-to-hand of T_robot_world (OpenCV's T_base_camera
taken to the world by the true rig's left camera pose), eye-in-hand of T_flange_rig;
translation (mm, norm) and rotation (deg). Then the mean over the seeds per method.

  python scripts/peers-handeye.py --camplace target/release/camplace --out out/peers-handeye \
      [--seeds 1 2 3 4 5] [--poses 15] [--board 9x6@25] [--setups eye-to-hand eye-in-hand]
"""

import argparse
import json
import math
import os
import re
import subprocess
import sys

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from calibrate_opencv import board_points, detect, load_rig, parse_board, transform  # noqa: E402

PLACEMENT = "r=605,alpha=32,baseline=81,vergence=3.5"
ROBOT_WORLD = {"SHAH": cv2.CALIB_ROBOT_WORLD_HAND_EYE_SHAH, "LI": cv2.CALIB_ROBOT_WORLD_HAND_EYE_LI}
HAND_EYE = {"TSAI": cv2.CALIB_HAND_EYE_TSAI, "PARK": cv2.CALIB_HAND_EYE_PARK,
            "DANIILIDIS": cv2.CALIB_HAND_EYE_DANIILIDIS}


def read_poses(path):
    """Flange poses (base <- flange, 4x4, mm) of a `format matrix mm` pose file."""
    poses = []
    with open(path) as f:
        for line in f:
            line = line.split("#")[0].strip()
            if not line:
                continue
            if line.startswith("format"):
                if line.split()[1:] != ["matrix", "mm"]:
                    raise SystemExit(f"{path}: expected `format matrix mm`, got {line!r}")
                continue
            poses.append(np.array([float(v) for v in line.split()], float).reshape(4, 4))
    return poses


def read_matrix(text, key):
    """A 4x4 matrix `KEY = [[...], ...]` of a [robot] table."""
    m = re.search(rf"^{key} = (\[\[.*\]\])$", text, re.M)
    if not m:
        raise SystemExit(f"no {key} in:\n{text}")
    return np.array(json.loads(m.group(1)), float)


def errors(found, truth):
    d = np.linalg.inv(truth) @ found
    cos = (np.trace(d[:3, :3]) - 1) / 2
    return float(np.linalg.norm(d[:3, 3])), math.degrees(math.acos(max(-1.0, min(1.0, cos))))


def inverse(T):
    return np.linalg.inv(T)


def opencv_methods(root, setup, cols, rows, square, rig, poses):
    """{method: T} with T the eye-to-hand T_base_camera or the eye-in-hand T_flange_camera."""
    obj = board_points(cols, rows, square).astype(np.float64)
    left = rig["left"]
    cam_board, flanges = [], []
    frames = sorted(os.listdir(os.path.join(root, "frames")))
    for k, frame in enumerate(frames):
        corners, _ = detect(os.path.join(root, "frames", frame, "left.png"), cols, rows)
        if corners is None:
            continue
        ok, rvec, tvec = cv2.solvePnP(obj, corners.astype(np.float64), left["K"], left["dist"])
        if not ok:
            continue
        cam_board.append(transform(cv2.Rodrigues(rvec)[0], tvec))
        flanges.append(poses[k])
    split = lambda Ts: ([T[:3, :3] for T in Ts], [T[:3, 3].reshape(3, 1) for T in Ts])  # noqa: E731
    out = {}
    # AX = ZB with A = camera <- board ("world2cam") and B = flange <- base ("base2gripper")
    # eye-in-hand; eye-to-hand the board rides on the flange, so B = base <- flange.
    R_a, t_a = split(cam_board)
    B = [inverse(F) for F in flanges] if setup == "eye-in-hand" else flanges
    R_b, t_b = split(B)
    for name, method in ROBOT_WORLD.items():
        _, _, R_z, t_z = cv2.calibrateRobotWorldHandEye(R_a, t_a, R_b, t_b, method=method)
        Z = transform(R_z, t_z)  # camera <- flange (eye-in-hand) or camera <- base (eye-to-hand)
        out[name] = inverse(Z)
    # calibrateHandEye: gripper poses in the base and the target in the camera; eye-to-hand
    # the inverted flange poses give camera -> base.
    G = flanges if setup == "eye-in-hand" else [inverse(F) for F in flanges]
    R_g, t_g = split(G)
    for name, method in HAND_EYE.items():
        R, t = cv2.calibrateHandEye(R_g, t_g, R_a, t_a, method=method)
        out[name] = transform(R, t)
    return out, len(cam_board)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--camplace", default="target/release/camplace")
    p.add_argument("--out", default="out/peers-handeye")
    p.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    p.add_argument("--poses", type=int, default=15)
    p.add_argument("--board", default="9x6@25")
    p.add_argument("--setups", nargs="+", default=["eye-to-hand", "eye-in-hand"])
    a = p.parse_args()
    cols, rows, square = parse_board(a.board)
    methods = ["ours", *ROBOT_WORLD, *HAND_EYE]
    for setup in a.setups:
        what = "T_robot_world" if setup == "eye-to-hand" else "T_flange_rig"
        print(f"== {setup}: error of {what}, {a.poses} poses, mm / deg")
        print(f"{'seed':>4} " + " ".join(f"{m:>17}" for m in methods))
        table = {m: [] for m in methods}
        for seed in a.seeds:
            root = os.path.join(a.out, f"{setup}-{seed}")
            render = [a.camplace, "render", "--board", a.board, "--hand-eye", str(a.poses), "--placement", PLACEMENT,
                      "--seed", str(seed), "--pose-format", "matrix", "--pose-unit", "mm", "--out", root]
            if setup == "eye-in-hand":
                render.append("--eye-in-hand")
            subprocess.run(render, check=True, stdout=subprocess.DEVNULL)
            robot = os.path.join(root, "robot.toml")
            calibrate = [a.camplace, "calibrate", "--images", root, "--board", a.board, "--hand-eye",
                         "--robot-poses", os.path.join(root, "robot_poses.txt"),
                         "--rig", os.path.join(root, "rig.json"), "--out", robot]
            if setup == "eye-in-hand":
                calibrate.append("--eye-in-hand")
            subprocess.run(calibrate, check=True, stdout=subprocess.DEVNULL)
            with open(robot) as f:
                ours_text = f.read()
            with open(os.path.join(root, "hand_eye.json")) as f:
                truth = json.load(f)
            rig = load_rig(os.path.join(root, "rig.json"))
            poses = read_poses(os.path.join(root, "robot_poses.txt"))
            cv, used = opencv_methods(root, setup, cols, rows, square, rig, poses)
            T_world_left = rig["left"]["T_world_camera"]
            if setup == "eye-to-hand":
                want = np.array(truth["T_robot_world"], float)
                found = {"ours": read_matrix(ours_text, "T_robot_world")}
                found.update({m: T @ inverse(T_world_left) for m, T in cv.items()})
            else:
                want = np.array(truth["T_flange_rig"], float)
                found = {"ours": read_matrix(ours_text, "T_flange_rig")}
                found.update(cv)
            row = []
            for m in methods:
                t, r = errors(found[m], want)
                table[m].append((t, r))
                row.append(f"{t:8.3f} {r:8.4f}")
            print(f"{seed:>4} " + " ".join(row) + f"   (OpenCV found the board in {used} of {len(poses)})")
        means = {m: (np.mean([v[0] for v in table[m]]), np.mean([v[1] for v in table[m]])) for m in methods}
        worst = {m: (max(v[0] for v in table[m]), max(v[1] for v in table[m])) for m in methods}
        print("mean " + " ".join(f"{means[m][0]:8.3f} {means[m][1]:8.4f}" for m in methods))
        print("worst" + " ".join(f"{worst[m][0]:8.3f} {worst[m][1]:8.4f}" for m in methods))
        best_t = min(means[m][0] for m in methods if m != "ours")
        best_r = min(means[m][1] for m in methods if m != "ours")
        verdict_t = "no larger" if means["ours"][0] <= best_t else "LARGER"
        verdict_r = "no larger" if means["ours"][1] <= best_r else "LARGER"
        print(f"ours against OpenCV's best mean: translation {means['ours'][0]:.3f} vs {best_t:.3f} mm ({verdict_t}), "
              f"rotation {means['ours'][1]:.4f} vs {best_r:.4f} deg ({verdict_r})")


if __name__ == "__main__":
    main()

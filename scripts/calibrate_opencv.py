"""Side-by-side check of our stereo calibration against OpenCV's, on the same board images.

Reads a folder of chessboard images as `camplace render --board` or `camplace capture` write
it (frames/NNNN/left.png + right.png, table/left.png + right.png, and, from `render`, the true
rig.json), calibrates the stereo pair with OpenCV, and scores it (and, when given, our
rig.json) against the true rig:

  python scripts/calibrate_opencv.py DIR --board 9x6@25 [--ours ours.json] \
      [--camplace target/debug/camplace] [--board-in-world X,Y,Z,YAW] [--runs 3] \
      [--per-camera] [--json]

OpenCV's recipe: cv2.findChessboardCorners + cv2.cornerSubPix (11 x 11 window) on every
image, corners put into the board convention of docs/formats.md from the image alone
(handedness, then the colour of the square between corners 0 and cols + 1); then
cv2.calibrateCamera per camera on every view where that camera saw the whole board, then
cv2.stereoCalibrate on the views both saw, either with the intrinsics fixed
(CALIB_FIX_INTRINSIC) or refined jointly (CALIB_USE_INTRINSIC_GUESS), each with k3 free and
with CALIB_FIX_K3. The world frame comes from cv2.solvePnP of the table view in the left
camera, the board lying where --board-in-world says (default: centred on the world origin,
axes along the world's, as `camplace calibrate` assumes); the right camera follows from the
stereo pose.

With --camplace BIN the script runs `BIN calibrate --images DIR --board B --out OURS` itself
(OURS = --ours, default DIR/ours.json), timing the whole call and reading its solve time
("in S s") and reprojection RMS from its output.

Scores, per camera: fx, fy relative error (%); cx, cy error (px); dist = the largest
difference between the true and the estimated distortion over every 16th pixel, in pixels
(the true undistorted ray of the pixel, distorted by both models, scaled by the true fx, fy);
pos = camera centre error (mm); rot = angle of R_est^T R_true (deg); then the baseline's
relative error (%), the reprojection RMS (px; OpenCV: stereoCalibrate's, over views both
cameras saw; ours: camplace's own figure, over all its views) and the calibration time (s;
detection is timed apart). The table shows the worse of the two cameras; --per-camera adds
both.

Real images have no true rig: without one (no DIR/rig.json and no --truth) every
calibration is scored by what its own images can tell, all on OpenCV's corners of the views
both cameras saw (frames/ only: table/ of real images may repeat a frame), the same for
every rig:

  rms px       the calibration's own reprojection RMS (OpenCV: stereoCalibrate's; ours:
               camplace's, over its corners and all its views);
  pnp rms px   each camera alone: per-view solvePnP with the rig's K and distortion, RMS of
               the reprojection over both cameras (how well the lens model fits);
  epi rms/max  the rectified epipolar error: every corner's ray in each camera turned into
               the rectified frame both cameras share (x along the baseline, z the mean of
               the optical axes made square to it, focal length the mean of the four), and the
               difference of the two rows, px; zero for a perfect rig, whatever the board;
  xfer rms/max the transfer error: the board's pose from one camera's corners alone
               (solvePnP), carried to the other camera through the rig's pose between them
               and projected with its K and distortion, against the corners it found, px;
               both ways pooled.
"""
import argparse
import json
import math
import os
import re
import statistics
import subprocess
import time

import cv2
import numpy as np

SUBPIX_WIN = (5, 5)  # half-size: an 11 x 11 window, well inside a ~35 px square
SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)
CALIB_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 200, 1e-12)
CAMERAS = ("left", "right")


# ---------------------------------------------------------------- board and geometry

def parse_board(text):
    m = re.fullmatch(r"(\d+)x(\d+)@([0-9.]+)", text)
    if not m:
        raise SystemExit(f"--board wants COLSxROWS@SQUARE_MM, got {text!r}")
    return int(m.group(1)), int(m.group(2)), float(m.group(3))


def board_points(cols, rows, square):
    """Corner row * cols + col at (col * square, row * square, 0) in the board's frame."""
    r, c = np.mgrid[0:rows, 0:cols]
    return np.stack([c.ravel() * square, r.ravel() * square, np.zeros(rows * cols)], 1).astype(np.float32)


def table_board_in_world(cols, rows, square, spec=None):
    """T_world_board of the table view: from X,Y,Z,YAW (first corner, turn about z), or centred."""
    if spec is None:
        x, y, z, yaw = -(cols - 1) * square / 2, -(rows - 1) * square / 2, 0.0, 0.0
    else:
        x, y, z, yaw = (float(v) for v in spec.split(","))
    c, s = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
    return np.array([[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, z], [0, 0, 0, 1]], float)


def transform(R, t):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, np.ravel(t)
    return T


def apply(T, pts):
    return pts @ T[:3, :3].T + T[:3, 3]


def rotation_deg(Ra, Rb):
    cos = (np.trace(Ra.T @ Rb) - 1) / 2
    return math.degrees(math.acos(max(-1.0, min(1.0, cos))))


# ---------------------------------------------------------------- detection

def list_views(root):
    """View names in order: frames/NNNN..., then table."""
    frames = sorted(os.listdir(os.path.join(root, "frames"))) if os.path.isdir(os.path.join(root, "frames")) else []
    views = [f"frames/{f}" for f in frames]
    if os.path.isdir(os.path.join(root, "table")):
        views.append("table")
    return views


def square_means(grey, grid):
    """Mean grey level at the centre of every square between the inner corners, (rows-1, cols-1)."""
    centres = (grid[:-1, :-1] + grid[:-1, 1:] + grid[1:, :-1] + grid[1:, 1:]) / 4
    h, w = grey.shape
    out = np.empty(centres.shape[:2])
    for i in range(centres.shape[0]):
        for j in range(centres.shape[1]):
            x, y = np.round(centres[i, j]).astype(int)
            out[i, j] = grey[max(y - 1, 0):min(y + 2, h), max(x - 1, 0):min(x + 2, w)].mean()
    return out


def to_board_order(corners, grey, cols, rows):
    """OpenCV's corners (rows of `cols`, from either end) in our order, from the image alone.

    Handedness first: x -> y must turn anticlockwise on screen (negative cross product in
    image coordinates, since z = x × y faces the camera); else the rows are read the other
    way. Then the half turn: the square between corners 0 and cols + 1 must be black, i.e.
    the squares whose row + col is even darker than the others.
    """
    grid = corners.reshape(rows, cols, 2).astype(np.float64)
    dx, dy = grid[0, -1] - grid[0, 0], grid[-1, 0] - grid[0, 0]
    if dx[0] * dy[1] - dx[1] * dy[0] > 0:
        grid = grid[::-1]
    means = square_means(grey, grid)
    even = (np.add.outer(np.arange(rows - 1), np.arange(cols - 1)) % 2) == 0
    if means[even].mean() > means[~even].mean():
        grid = grid[::-1, ::-1]
    return grid.reshape(-1, 1, 2).astype(np.float32)


def detect(path, cols, rows):
    """Our-order corners of the whole board in one image, or None when OpenCV did not find it."""
    grey = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    if grey is None:
        raise SystemExit(f"cannot read image {path}")
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH + cv2.CALIB_CB_NORMALIZE_IMAGE
    found, corners = cv2.findChessboardCorners(grey, (cols, rows), flags=flags)
    if not found:
        return None, grey.shape[::-1]
    corners = cv2.cornerSubPix(grey, corners, SUBPIX_WIN, (-1, -1), SUBPIX_CRITERIA)
    return to_board_order(corners, grey, cols, rows), grey.shape[::-1]


def detect_all(root, views, cols, rows):
    """{view: {"left": corners or None, "right": ...}}, the image size, and the time taken."""
    t0 = time.perf_counter()
    found, size = {}, None
    for view in views:
        found[view] = {}
        for cam in CAMERAS:
            found[view][cam], size = detect(os.path.join(root, view, f"{cam}.png"), cols, rows)
    return found, size, time.perf_counter() - t0


# ---------------------------------------------------------------- OpenCV calibration

def calibrate_mono(obj, found, cam, size, flags):
    views = [v for v in found if found[v][cam] is not None]
    rms, K, dist, _, _ = cv2.calibrateCamera(
        [obj] * len(views), [found[v][cam] for v in views], size, None, None,
        flags=flags, criteria=CALIB_CRITERIA)
    return {"K": K, "dist": dist.ravel()[:5], "rms": rms, "views": len(views)}


def calibrate_stereo(obj, found, mono, size, flags):
    views = [v for v in found if all(found[v][c] is not None for c in CAMERAS)]
    left, right = mono["left"], mono["right"]
    rms, K1, d1, K2, d2, R, T, _, _ = cv2.stereoCalibrate(
        [obj] * len(views), [found[v]["left"] for v in views], [found[v]["right"] for v in views],
        left["K"].copy(), left["dist"].copy(), right["K"].copy(), right["dist"].copy(), size,
        flags=flags, criteria=CALIB_CRITERIA)
    return {"left": {"K": K1, "dist": d1.ravel()[:5]}, "right": {"K": K2, "dist": d2.ravel()[:5]},
            "T_right_left": transform(R, T), "rms": rms, "views": len(views)}


def place_in_world(obj, table_corners, T_world_board, stereo):
    """T_world_camera of both cameras from the table view in the left camera."""
    left = stereo["left"]
    ok, rvec, tvec = cv2.solvePnP(apply(T_world_board, obj.astype(np.float64)), table_corners.astype(np.float64),
                                  left["K"], left["dist"])
    if not ok:
        raise SystemExit("solvePnP failed on the table view")
    T_left_world = transform(cv2.Rodrigues(rvec)[0], tvec)
    T_world_left = np.linalg.inv(T_left_world)
    return T_world_left, T_world_left @ np.linalg.inv(stereo["T_right_left"])


def opencv_rig(obj, found, size, T_world_board, dist_flags, joint):
    """One OpenCV calibration: mono per camera, stereo, world frame; returns rig-like dict + extras."""
    mono = {cam: calibrate_mono(obj, found, cam, size, dist_flags) for cam in CAMERAS}
    stereo_flags = dist_flags | (cv2.CALIB_USE_INTRINSIC_GUESS if joint else cv2.CALIB_FIX_INTRINSIC)
    stereo = calibrate_stereo(obj, found, mono, size, stereo_flags)
    if found.get("table", {}).get("left") is None:
        raise SystemExit("OpenCV did not find the whole board in table/left.png: no world frame")
    T_world_left, T_world_right = place_in_world(obj, found["table"]["left"], T_world_board, stereo)
    rig = {cam: {"K": stereo[cam]["K"], "dist": stereo[cam]["dist"]} for cam in CAMERAS}
    rig["left"]["T_world_camera"], rig["right"]["T_world_camera"] = T_world_left, T_world_right
    return rig, {"rms": stereo["rms"], "stereo_views": stereo["views"],
                 "mono_rms": {c: mono[c]["rms"] for c in CAMERAS}, "mono_views": {c: mono[c]["views"] for c in CAMERAS}}


def timed_median(fn, runs):
    times, out = [], None
    for _ in range(max(runs, 1)):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return out, statistics.median(times)


# ---------------------------------------------------------------- ours

def load_rig(path):
    with open(path) as f:
        raw = json.load(f)
    return {cam: {"K": np.array(raw[cam]["K"], float), "dist": np.array(raw[cam]["dist"], float)[:5],
                  "T_world_camera": np.array(raw[cam]["T_world_camera"], float)} for cam in CAMERAS}


def run_camplace(binary, root, board, out, board_in_world, runs):
    """Run `camplace calibrate` `runs` times; median wall time and solve time, and its RMS."""
    cmd = [binary, "calibrate", "--images", root, "--board", board, "--out", out]
    if board_in_world:
        cmd += ["--board-in-world", board_in_world]
    walls, solves, text = [], [], ""
    for _ in range(max(runs, 1)):
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        walls.append(time.perf_counter() - t0)
        text = proc.stdout + proc.stderr
        if proc.returncode != 0:
            raise SystemExit(f"{' '.join(cmd)} failed:\n{text}")
        m = re.search(r"calibrated from (\d+) views in ([0-9.]+) s: reprojection RMS ([0-9.]+) px", text)
        if not m:
            raise SystemExit(f"no 'calibrated from N views in S s: reprojection RMS R px' in:\n{text}")
        solves.append(float(m.group(2)))
    return {"views": int(m.group(1)), "solve_s": statistics.median(solves), "wall_s": statistics.median(walls),
            "rms": float(m.group(3)), "log": text}


def pnp_rms(rig, obj, found):
    """Fallback RMS for a rig.json without its log: per-view solvePnP on OpenCV's corners."""
    sq = []
    for views in found.values():
        for cam in CAMERAS:
            pts = views[cam]
            if pts is None:
                continue
            _, rvec, tvec = cv2.solvePnP(obj, pts, rig[cam]["K"], rig[cam]["dist"])
            proj, _ = cv2.projectPoints(obj, rvec, tvec, rig[cam]["K"], rig[cam]["dist"])
            sq.append(((proj - pts) ** 2).sum(-1).ravel())
    return float(np.sqrt(np.concatenate(sq).mean()))


# ---------------------------------------------------------------- scores

def distort(xy, d):
    k1, k2, p1, p2, k3 = d
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2 ** 2 + k3 * r2 ** 3
    return np.stack([x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
                     y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y], 1)


def undistort(xy_d, d, iterations=50):
    """Fixed-point inverse of distort (OpenCV's undistortPoints scheme)."""
    k1, k2, p1, p2, k3 = d
    xy = xy_d.copy()
    for _ in range(iterations):
        x, y = xy[:, 0], xy[:, 1]
        r2 = x * x + y * y
        radial = 1 + k1 * r2 + k2 * r2 ** 2 + k3 * r2 ** 3
        delta = np.stack([2 * p1 * x * y + p2 * (r2 + 2 * x * x), p1 * (r2 + 2 * y * y) + 2 * p2 * x * y], 1)
        xy = (xy_d - delta) / radial[:, None]
    return xy


def distortion_difference(true_cam, est, width, height, step=16):
    """Max over every `step`-th pixel of |distort_true - distort_est| at its true ray, in px."""
    K = true_cam["K"]
    u, v = np.meshgrid(np.arange(0, width, step), np.arange(0, height, step))
    xy_d = np.stack([(u.ravel() - K[0, 2]) / K[0, 0], (v.ravel() - K[1, 2]) / K[1, 1]], 1)
    xy = undistort(xy_d, true_cam["dist"])
    diff = (distort(xy, true_cam["dist"]) - distort(xy, est["dist"])) * [K[0, 0], K[1, 1]]
    return float(np.hypot(diff[:, 0], diff[:, 1]).max())


def camera_errors(true_cam, est, width, height):
    Kt, Ke = true_cam["K"], est["K"]
    Tt, Te = true_cam["T_world_camera"], est["T_world_camera"]
    return {
        "fx_pct": 100 * abs(Ke[0, 0] - Kt[0, 0]) / Kt[0, 0],
        "fy_pct": 100 * abs(Ke[1, 1] - Kt[1, 1]) / Kt[1, 1],
        "cx_px": abs(Ke[0, 2] - Kt[0, 2]),
        "cy_px": abs(Ke[1, 2] - Kt[1, 2]),
        "dist_px": distortion_difference(true_cam, est, width, height),
        "pos_mm": float(np.linalg.norm(Te[:3, 3] - Tt[:3, 3])),
        "rot_deg": rotation_deg(Te[:3, :3], Tt[:3, :3]),
    }


def rig_errors(truth, est, width, height):
    cams = {cam: camera_errors(truth[cam], est[cam], width, height) for cam in CAMERAS}
    base = lambda rig: np.linalg.norm(rig["left"]["T_world_camera"][:3, 3] - rig["right"]["T_world_camera"][:3, 3])
    worse = {k: max(cams["left"][k], cams["right"][k]) for k in cams["left"]}
    worse["baseline_pct"] = 100 * abs(base(est) - base(truth)) / base(truth)
    return {"worse": worse, **cams}


# ---------------------------------------------------------------- scores without a truth

def board_pairs(found):
    """The frames both cameras saw the whole board in; not table/, which may repeat a frame."""
    return [v for name, v in found.items() if name != "table" and v["left"] is not None and v["right"] is not None]


def rays_world(cam, pts):
    """World-frame rays (unnormalised) of image points through a rig camera's model."""
    K = cam["K"]
    xy_d = np.stack([(pts[:, 0] - K[0, 2]) / K[0, 0], (pts[:, 1] - K[1, 2]) / K[1, 1]], 1)
    xy = undistort(xy_d, cam["dist"])
    rays = np.concatenate([xy, np.ones((len(xy), 1))], 1)
    return rays @ cam["T_world_camera"][:3, :3].T


def rectified_frame(rig):
    """Rows: the rectified axes in the world (x along the baseline), and its focal length."""
    Tl, Tr = rig["left"]["T_world_camera"], rig["right"]["T_world_camera"]
    x = Tr[:3, 3] - Tl[:3, 3]
    x /= np.linalg.norm(x)
    z = Tl[:3, 2] + Tr[:3, 2]
    z -= x * (z @ x)
    z /= np.linalg.norm(z)
    f = np.mean([rig[c]["K"][i, i] for c in CAMERAS for i in (0, 1)])
    return np.stack([x, np.cross(z, x), z]), f


def epipolar_errors(rig, found):
    """|row_left - row_right| in the rectified frame for every corner both cameras saw, px."""
    R, f = rectified_frame(rig)
    errs = []
    for views in board_pairs(found):
        rows = []
        for cam in CAMERAS:
            d = rays_world(rig[cam], views[cam].reshape(-1, 2).astype(np.float64)) @ R.T
            rows.append(f * d[:, 1] / d[:, 2])
        errs.append(np.abs(rows[0] - rows[1]))
    return np.concatenate(errs)


def transfer_errors(rig, obj, found):
    """The board's pose from one camera alone, seen through the other: distance to its corners, px."""
    T_cam_world = {c: np.linalg.inv(rig[c]["T_world_camera"]) for c in CAMERAS}
    errs = []
    for views in board_pairs(found):
        for src, dst in (("left", "right"), ("right", "left")):
            _, rvec, tvec = cv2.solvePnP(obj.astype(np.float64), views[src].astype(np.float64),
                                         rig[src]["K"], rig[src]["dist"])
            T_dst_board = T_cam_world[dst] @ rig[src]["T_world_camera"] @ transform(cv2.Rodrigues(rvec)[0], tvec)
            p = apply(T_dst_board, obj.astype(np.float64))
            proj, _ = cv2.projectPoints(p, np.zeros(3), np.zeros(3), rig[dst]["K"], rig[dst]["dist"])
            errs.append(np.linalg.norm(proj.reshape(-1, 2) - views[dst].reshape(-1, 2), axis=1))
    return np.concatenate(errs)


def self_scores(rig, rms, obj, found):
    rms_of = lambda e: float(np.sqrt(np.mean(e ** 2)))
    epi, xfer = epipolar_errors(rig, found), transfer_errors(rig, obj, found)
    return {"rms": rms, "pnp_rms": pnp_rms(rig, obj, found), "epi_rms": rms_of(epi), "epi_max": float(epi.max()),
            "xfer_rms": rms_of(xfer), "xfer_max": float(xfer.max()), "corners": int(len(epi))}


SELF_COLUMNS = [("rms px", "rms"), ("pnp rms", "pnp_rms"), ("epi rms", "epi_rms"), ("epi max", "epi_max"),
                ("xfer rms", "xfer_rms"), ("xfer max", "xfer_max")]


# ---------------------------------------------------------------- report

COLUMNS = [("fx%", "fx_pct", 4), ("fy%", "fy_pct", 4), ("cx px", "cx_px", 3), ("cy px", "cy_px", 3),
           ("dist px", "dist_px", 3), ("pos mm", "pos_mm", 3), ("rot deg", "rot_deg", 4),
           ("base%", "baseline_pct", 4), ("rms px", "rms", 4), ("calib s", "calib_s", 3)]


def print_table(rows, per_camera):
    print(f"{'method':<28}" + "".join(f"{h:>9}" for h, _, _ in COLUMNS))
    for name, r in rows.items():
        vals = {**r["errors"]["worse"], "rms": r["rms"], "calib_s": r["calib_s"]}
        print(f"{name:<28}" + "".join(f"{vals.get(k, float('nan')):>9.{p}f}" for _, k, p in COLUMNS))
        if per_camera:
            for cam in CAMERAS:
                e = r["errors"][cam]
                print(f"{'  ' + cam:<28}" + "".join(f"{e[k]:>9.{p}f}" if k in e else f"{'':>9}" for _, k, p in COLUMNS))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dir", help="board images folder (frames/NNNN/, table/, rig.json = truth)")
    ap.add_argument("--board", required=True, help="COLSxROWS@SQUARE_MM, e.g. 9x6@25")
    ap.add_argument("--board-in-world", help="X,Y,Z,YAW of the table view's board (default: centred on the origin)")
    ap.add_argument("--truth", help="true rig.json (default: DIR/rig.json)")
    ap.add_argument("--ours", help="our calibrated rig.json (with --camplace: where to write it; default DIR/ours.json)")
    ap.add_argument("--camplace", help="camplace binary: run `calibrate` on DIR and time it")
    ap.add_argument("--runs", type=int, default=3, help="time each calibration as the median of this many runs")
    ap.add_argument("--threads", type=int, help="cv2.setNumThreads (default: OpenCV's)")
    ap.add_argument("--per-camera", action="store_true", help="also print the left and right camera rows")
    ap.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    args = ap.parse_args()

    if args.threads is not None:
        cv2.setNumThreads(args.threads)
    cols, rows, square = parse_board(args.board)
    obj = board_points(cols, rows, square)
    T_world_board = table_board_in_world(cols, rows, square, args.board_in_world)
    views = list_views(args.dir)
    found, (width, height), detect_s = detect_all(args.dir, views, cols, rows)
    missed = [f"{v}/{c}.png" for v in views for c in CAMERAS if found[v][c] is None]

    truth_path = args.truth or os.path.join(args.dir, "rig.json")
    truth = load_rig(truth_path) if os.path.exists(truth_path) else None

    results = {}
    variants = [("OpenCV free k3, fix-intr", 0, False), ("OpenCV free k3, joint", 0, True),
                ("OpenCV FIX_K3, fix-intr", cv2.CALIB_FIX_K3, False), ("OpenCV FIX_K3, joint", cv2.CALIB_FIX_K3, True)]
    for name, dist_flags, joint in variants:
        (rig, extra), secs = timed_median(lambda: opencv_rig(obj, found, (width, height), T_world_board, dist_flags, joint), args.runs)
        results[name] = {"rig": rig, "rms": extra["rms"], "calib_s": secs, **extra}

    ours_path = args.ours or (os.path.join(args.dir, "ours.json") if args.camplace else None)
    camplace = None
    if args.camplace:
        camplace = run_camplace(args.camplace, args.dir, args.board, ours_path, args.board_in_world, args.runs)
    if ours_path:
        rig = load_rig(ours_path)
        rms = camplace["rms"] if camplace else pnp_rms(rig, obj, found)
        results["ours"] = {"rig": rig, "rms": rms, "calib_s": camplace["solve_s"] if camplace else float("nan")}

    if truth is None:
        # Real images: each rig scored by its own images (see the top of this file).
        scores = {name: self_scores(r["rig"], r["rms"], obj, found) for name, r in results.items()}
        if args.json:
            print(json.dumps({"missed": missed, "scores": scores}, default=float))
            return
        print(f"{args.dir}: no true rig, scored on OpenCV's corners of the {next(iter(scores.values()))['corners']} "
              f"corner pairs both cameras saw; not found: {', '.join(missed) or 'none'}")
        print(f"{'method':<28}" + "".join(f"{h:>10}" for h, _ in SELF_COLUMNS))
        for name, sc in scores.items():
            print(f"{name:<28}" + "".join(f"{sc[k]:>10.4f}" for _, k in SELF_COLUMNS))
        return
    for r in results.values():
        r["errors"] = rig_errors(truth, r["rig"], width, height)

    if args.json:
        print(json.dumps({"detect_s": detect_s, "missed": missed, "camplace": camplace and {k: v for k, v in camplace.items() if k != "log"},
                          "rows": {n: {k: v for k, v in r.items() if k != "rig"} for n, r in results.items()}}, default=float))
        return
    print(f"{args.dir}: {len(views)} views; OpenCV detection {detect_s:.3f} s for {2 * len(views)} images; "
          f"not found: {', '.join(missed) or 'none'}")
    first = next(iter(results.values()))
    print(f"OpenCV views: left {first['mono_views']['left']}, right {first['mono_views']['right']}, "
          f"both {first['stereo_views']}")
    print_table(results, args.per_camera)
    if camplace:
        print(f"ours: `camplace calibrate` {camplace['wall_s']:.3f} s wall (detection + solve + I/O), "
              f"solve {camplace['solve_s']:.3f} s, {camplace['views']} views")
    elif ours_path:
        print("ours: rms from per-view solvePnP on OpenCV's corners (no camplace log); no time")


if __name__ == "__main__":
    main()

"""The module's slots against the command line's on the same rendered pair: each slot's
state, askew flag and frame as `camplace estimate` writes them to poses.jsonl. Needs the
camplace binary (CAMPLACE_BIN, default target/debug/camplace)."""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

import camplace

ROOT = pathlib.Path(__file__).resolve().parents[2]
BIN = os.environ.get("CAMPLACE_BIN", str(ROOT / "target" / "debug" / "camplace"))
PLACEMENT = "r=605,alpha=32,baseline=81,vergence=3.5"
SEED = 4


def cli(*args):
    subprocess.run([BIN, *args], check=True, stdout=subprocess.DEVNULL)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """Two rendered frames with their background, a model, and `camplace estimate`'s lines."""
    root = tmp_path_factory.mktemp("slots")
    ds, model = root / "ds", root / "tray.model"
    cli("render", "--dataset", "--count", "2", "--placement", PLACEMENT, "--seed", str(SEED), "--out", str(ds))
    cli("model", "--placement", PLACEMENT, "--seed", str(SEED), "--verify-scenes", "4", "--out", str(model))
    cli("estimate", "--dataset", str(ds), "--model", str(model))
    lines = [json.loads(l) for l in (ds / "poses.jsonl").read_text().splitlines()]
    return ds, model, {l["frame"]: l for l in lines}


def test_the_slots_are_the_command_lines(dataset):
    ds, model, lines = dataset
    est = camplace.Estimator(None, str(model), rig=str(ds / "rig.json"))
    bg = ds / "background"
    est.set_background(camplace.read_image(str(bg / "left.png")), camplace.read_image(str(bg / "right.png")))
    judged = 0
    for name, line in sorted(lines.items()):
        f = ds / "frames" / name
        out = est.process(camplace.read_image(str(f / "left.png")), camplace.read_image(str(f / "right.png")))
        if not line["found"]:
            assert out["slots"] == []
            continue
        assert len(out["slots"]) == len(line["slots"]) == 8
        for got, want in zip(out["slots"], line["slots"]):
            assert got["state"] == want["state"]
            assert got["askew"] == want["askew"]
            assert got["frame"].shape == (4, 4)
            np.testing.assert_allclose(got["frame"], np.array(want["T_world_slot"]), rtol=0, atol=1e-9)
            judged += 1
    assert judged > 0, "no frame gave a pose to judge slots under"

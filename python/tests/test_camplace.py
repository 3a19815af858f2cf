"""The camplace module against the command line on the same rendered pair: the same pose,
the frame read in place (its address reaches the estimator), and bad input raising
camplace.Error. Needs the camplace binary (CAMPLACE_BIN, default target/debug/camplace)."""

import inspect
import json
import os
import pathlib
import pydoc
import subprocess

import numpy as np
import pytest

import camplace

ROOT = pathlib.Path(__file__).resolve().parents[2]
BIN = os.environ.get("CAMPLACE_BIN", str(ROOT / "target" / "debug" / "camplace"))
PLACEMENT = "r=605,alpha=32,baseline=81,vergence=3.5"
SEED = 3


def cli(*args):
    subprocess.run([BIN, *args], check=True, stdout=subprocess.DEVNULL)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """One rendered frame with its background, a model, and `camplace estimate`'s poses."""
    root = tmp_path_factory.mktemp("camplace")
    ds, model = root / "ds", root / "tray.model"
    cli("render", "--dataset", "--count", "1", "--placement", PLACEMENT, "--seed", str(SEED), "--out", str(ds))
    cli("model", "--placement", PLACEMENT, "--seed", str(SEED), "--verify-scenes", "4", "--out", str(model))
    cli("estimate", "--dataset", str(ds), "--model", str(model))
    line = (ds / "poses.jsonl").read_text().splitlines()[0]
    return ds, model, json.loads(line)


def estimator(ds, model):
    est = camplace.Estimator(None, str(model), rig=str(ds / "rig.json"))
    bg = ds / "background"
    est.set_background(camplace.read_image(str(bg / "left.png")), camplace.read_image(str(bg / "right.png")))
    return est


def frame(ds):
    f = ds / "frames" / "0000"
    return camplace.read_image(str(f / "left.png")), camplace.read_image(str(f / "right.png"))


def test_a_rendered_pair_gives_the_pose_estimate_gives(dataset):
    ds, model, line = dataset
    left, right = frame(ds)
    out = estimator(ds, model).process(left, right)
    assert out["found"] == line["found"]
    assert out["verdict"] == line["verdict"]
    assert out["inliers"] == line["inliers"]
    assert out["pose"].shape == (4, 4)
    np.testing.assert_allclose(out["pose"], np.array(line["T_world_tray"]), rtol=0, atol=1e-9)
    assert abs(out["score"] - line["score"]) < 1e-6
    assert set(out["timings_ms"]) >= {"rectify", "disparity", "ransac", "icp", "verify", "total"}


def test_the_frame_is_read_in_place_contiguous_or_strided(dataset):
    ds, model, _ = dataset
    left, right = frame(ds)
    est = estimator(ds, model)
    first = est.process(left, right)
    assert est.last_left_address == left.ctypes.data
    # The same pixels as a crop of a wider array: rows 640 + 96 bytes apart, not contiguous.
    h, w = left.shape
    wide = np.full((h, w + 96), 255, dtype=np.uint8)
    wide[:, 32 : 32 + w] = left
    crop = wide[:, 32 : 32 + w]
    assert not crop.flags["C_CONTIGUOUS"] and crop.strides == (w + 96, 1)
    again = est.process(crop, right)
    assert est.last_left_address == crop.ctypes.data
    np.testing.assert_array_equal(again["pose"], first["pose"])
    assert again["score"] == first["score"]


def test_render_gives_the_pixels_and_truth_render_writes(dataset):
    ds, _, line = dataset
    scene = camplace.render(placement=PLACEMENT, seed=SEED, scenario=0)
    left, right = frame(ds)
    np.testing.assert_array_equal(scene["left"], left)
    np.testing.assert_array_equal(scene["right"], right)
    truth = json.loads((ds / "frames" / "0000" / "truth.json").read_text())
    np.testing.assert_allclose(scene["T_world_tray"], np.array(truth["T_world_tray"]), rtol=0, atol=1e-12)
    assert scene["depth_left"].dtype == np.float32 and scene["depth_left"].shape == left.shape
    empty = camplace.render(placement=PLACEMENT, seed=SEED, scenario=None)
    np.testing.assert_array_equal(empty["left"], camplace.read_image(str(ds / "background" / "left.png")))
    assert empty["T_world_tray"] is None


def test_evaluate_gives_the_success_figures():
    summary = camplace.evaluate(placement=PLACEMENT, scenarios=2, seed=SEED)
    assert summary["scored"] == 2 and summary["frames"] == 2
    assert summary["success_rate"] == summary["successes"] / 2
    low, high = summary["success_interval"]
    assert 0 <= low <= summary["success_rate"] <= high <= 1


def test_bad_input_raises_with_one_line(dataset, tmp_path):
    ds, model, _ = dataset
    est = estimator(ds, model)
    left, right = frame(ds)
    cases = [
        (lambda: est.process(left.astype(np.float32), right), "left: expected a 2-D uint8 numpy array"),
        (lambda: est.process(left[:, ::2], right), "expected rows of adjacent pixels"),
        (lambda: est.process(left[:100], right), "expected 640 x 480 pixels"),
        (lambda: est.process([left, left], [right, right]), "expected 1 left and 1 right images"),
        (lambda: camplace.Estimator(None, str(tmp_path / "missing.model")), "missing.model"),
        (lambda: camplace.Estimator(None, str(model), method="two-shot"), "method"),
        (lambda: camplace.render(placement="r=abc"), "placement"),
        (lambda: camplace.read_image(str(tmp_path / "none.png")), "none.png"),
    ]
    for call, words in cases:
        with pytest.raises(camplace.Error) as e:
            call()
        assert words in str(e.value) and "\n" not in str(e.value), str(e.value)
    assert issubclass(camplace.Error, ValueError)



def test_arguments_of_the_wrong_type_raise_camplace_error_naming_them(dataset):
    ds, model, _ = dataset
    est = estimator(ds, model)
    cases = [
        (lambda: camplace.Estimator(123, str(model)), "cell: expected a path"),
        (lambda: camplace.Estimator(None, 5), "model: expected a path"),
        (lambda: camplace.Estimator(None, str(model), rig=1.5), "rig: expected a path"),
        (lambda: camplace.Estimator(None, str(model), placement=605), "placement: expected a str"),
        (lambda: camplace.Estimator(None, str(model), method=12), "method: expected a str"),
        (lambda: camplace.Estimator(None, str(model), tray=["a"]), "tray: expected a str"),
        (lambda: camplace.render(seed=-1), "seed: expected a whole number from 0"),
        (lambda: camplace.render(seed=2**64), "seed: expected a whole number from 0"),
        (lambda: camplace.render(scenario="0"), "scenario: expected a whole number from 0"),
        (lambda: camplace.render(method=None), "method: expected a str"),
        (lambda: camplace.evaluate(scenarios=-2), "scenarios: expected a whole number from 0"),
        (lambda: camplace.evaluate(scenarios=1.5), "scenarios: expected a whole number from 0"),
        (lambda: camplace.evaluate(placement=object()), "placement: expected a str"),
        (lambda: camplace.read_image(None), "path: expected a path"),
        (lambda: camplace.read_image(7), "path: expected a path"),
        (lambda: est.process(1, None), "left: expected a 2-D uint8 numpy array"),
        (lambda: est.set_background("a", "b"), "left: expected a 2-D uint8 numpy array"),
    ]
    for call, words in cases:
        with pytest.raises(camplace.Error) as e:
            call()
        assert words in str(e.value) and "\n" not in str(e.value), str(e.value)

def test_help_documents_every_call():
    for name in ["Estimator", "render", "evaluate", "read_image"]:
        assert getattr(camplace, name).__doc__, name
    for name in ["process", "set_background"]:
        assert getattr(camplace.Estimator, name).__doc__, name
    assert "process(left, right)" in camplace.__doc__
    # Every default reads as written (a default pyo3 cannot show would read "Ellipsis").
    text = pydoc.render_doc(camplace, renderer=pydoc.plaintext)
    assert "Ellipsis" not in text
    assert str(inspect.signature(camplace.render)).startswith("(cell=None, placement=None, seed=None, scenario=0,")

"""scripts/photo_set: evaluate.py's and like_family.py's metrics on arrays whose answers
are known, and the
committed photo-like scenes (tests/data/photo_set) and photos (tests/data/photos) hold the
files and boxes their JSON promises. Needs neither Mitsuba nor a matedit binary."""

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

PIL = pytest.importorskip("PIL.Image")

ROOT = Path(__file__).resolve().parents[2]
SCENES = sorted(p.parent for p in (ROOT / "tests/data/photo_set").glob("*/meta.json"))


def load_script(name):
    spec = importlib.util.spec_from_file_location(name, ROOT / f"scripts/photo_set/{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


evaluate = load_script("evaluate")
like_family = load_script("like_family")
make_set = load_script("make_set")


def test_lab_and_the_family_threshold():
    lab = like_family.lab
    assert lab(np.ones(3)) == pytest.approx([100, 0, 0], abs=1e-9)
    assert lab(np.zeros(3)) == pytest.approx([0, 0, 0], abs=1e-9)
    grey = lab(np.full(3, 0.18))
    assert grey[0] == pytest.approx(49.5, abs=0.1) and abs(grey[1]) < 1e-9
    far = lambda a, b: np.linalg.norm(lab(np.array(a)) - lab(np.array(b)))
    # what the family must tell apart, and what it must not
    assert far([0.03] * 3, [0.18] * 3) > like_family.FAMILY_DELTA_E  # black plastic as grey
    assert far([1.0, 0.78, 0.34], [0.9, 0.85, 0.7]) > like_family.FAMILY_DELTA_E  # gold as cream
    assert far([0.55, 0.04, 0.03], [0.5, 0.05, 0.04]) < like_family.FAMILY_DELTA_E  # a red a shade off
    assert like_family.disc(4).sum() == 12


def test_psnr_counts_only_the_masked_pixels():
    a = np.zeros((2, 2, 3))
    b = np.zeros((2, 2, 3))
    b[0, 0] = 0.1  # masked: mse = 0.01 -> 20 dB
    b[1, 1] = 1.0  # outside the mask: ignored
    mask = np.array([[True, False], [False, False]])
    assert evaluate.psnr(a, b, mask) == pytest.approx(20.0)
    # half the masked pixels off by 0.1 in every channel: mse = 0.005 -> 10 log10(200)
    mask[0, 1] = True
    assert evaluate.psnr(a, b, mask) == pytest.approx(10 * math.log10(200))
    assert evaluate.psnr(a, a, mask) == math.inf


def test_iou():
    a = np.array([[1, 1, 0, 0]], bool)
    b = np.array([[0, 1, 1, 0]], bool)
    assert evaluate.iou(a, b) == pytest.approx(1 / 3)
    assert evaluate.iou(a, a) == 1.0
    assert evaluate.iou(a, ~a) == 0.0
    assert evaluate.iou(np.zeros(4, bool), np.zeros(4, bool)) == 1.0


def test_summary_takes_median_worst_and_mean_and_counts_refusals():
    results = [
        {"own_psnr": 30.0, "own_status": "ok", "nomask_status": "refused"},
        {"own_psnr": 20.0, "own_status": "ok", "nomask_iou": 0.5, "nomask_status": "ok"},
        {"own_psnr": 46.0, "own_status": "ok", "nomask_iou": 0.9, "nomask_status": "ok"},
        {"own_status": "error"},
    ]
    s = evaluate.summary(results, evaluate.FIGURES)
    assert s["own_psnr"] == {"median": 30.0, "worst": 20.0, "mean": 32.0, "n": 3}
    assert s["nomask_iou"]["worst"] == 0.5
    assert (s["own_errors"], s["nomask_refused"]) == (1, 1)


def test_white_balance_greys_the_white_sphere_and_draws_its_error_from_the_seed():
    white = np.array([0.9, 0.6, 0.3])  # a white sphere under a sunset
    exact = make_set.white_balance(white, [7, 1], 0.0)
    balanced = white * exact
    assert np.allclose(balanced, balanced[0]), balanced
    # a grey surface keeps its luminance
    assert make_set.luminance(exact) == pytest.approx(1.0)
    off = make_set.white_balance(white, [7, 1], 0.05)
    assert np.array_equal(off, make_set.white_balance(white, [7, 1], 0.05))
    assert not np.allclose(off, make_set.white_balance(white, [7, 2], 0.05))
    assert 0 < np.abs(np.log(off / exact)).max() < 0.3
    # a grey card: the white sphere at 0.5 after the balance
    e = make_set.grey_card_exposure(white, exact)
    assert make_set.luminance(white * exact * e) == pytest.approx(0.5)


def test_camera_frame_is_right_up_and_back_as_the_layer_takes_them():
    assert np.allclose(make_set.camera_frame([0, 0, 4], [0, 0, 0]), np.eye(3))
    # from +x looking at the origin: right is -z, up is y, back is +x
    frame = make_set.camera_frame([5, 0, 0], [0, 0, 0])
    assert np.allclose(frame, [[0, 0, -1], [0, 1, 0], [1, 0, 0]])
    frame = make_set.camera_frame([1, 2, 3], [0, 0.3, 0])
    assert np.allclose(frame @ frame.T, np.eye(3)) and np.linalg.det(frame) == pytest.approx(1)


def test_layer_light_keeps_a_uniform_light_and_puts_a_lamp_where_the_camera_sees_it():
    frame = make_set.camera_frame([1, 2, 3], [0, 0, 0])
    out = make_set.layer_light(np.ones((64, 128, 3)), 37.0, frame, [2, 1, 0.5], size=(8, 16))
    assert out.shape == (8, 16, 3)
    # each texel takes the samples that land in it, about 32 x 32 here
    assert np.allclose(out, [2, 1, 0.5], rtol=0.06)
    # a lamp on the horizon at Mitsuba's u = 0.5 points down the map's own +z
    lamp = np.zeros((64, 128, 3))
    lamp[32, 64] = 1000
    def brightest(yaw):
        out = make_set.layer_light(lamp, yaw, np.eye(3), [1, 1, 1], size=(8, 16))
        return np.unravel_index(out[..., 0].argmax(), out.shape[:2])
    # unturned, towards the camera at +z: theta 90, phi 90 degrees (docs/CONVENTIONS.md)
    assert brightest(0.0) == (4, 4)
    # turned by -90 degrees about y it comes from -x: phi 180
    assert brightest(-90.0) == (4, 8)
    # the lamp's power is kept
    out = make_set.layer_light(lamp, 0.0, np.eye(3), [1, 1, 1], size=(8, 16))
    omega = np.sin((np.arange(8) + 0.5) / 8 * np.pi) * (np.pi / 8) * (2 * np.pi / 16)
    src_omega = np.sin(32.5 / 64 * np.pi) * (np.pi / 64) * (2 * np.pi / 128)
    assert (out[..., 0] * omega[:, None]).sum() == pytest.approx(1000 * src_omega, rel=1e-4)


def test_texel_directions_cover_each_texel_in_turn():
    d = make_set.texel_directions((4, 8), 3, np.random.default_rng(1))
    assert d.shape == (4 * 8 * 9, 3)
    assert np.allclose(np.linalg.norm(d, axis=1), 1)
    # each run of 9 lies in its texel: theta = (r + 0.5) / 4 pi, phi = (c + 0.5) / 8 2 pi at the centres
    rows = np.minimum((np.arccos(d[:, 1]) / np.pi * 4).astype(int), 3)
    cols = np.minimum((np.mod(np.arctan2(d[:, 2], d[:, 0]), 2 * np.pi) / (2 * np.pi) * 8).astype(int), 7)
    texel = np.repeat(np.arange(32), 9)
    assert np.array_equal(rows * 8 + cols, texel)


def test_committed_scenes_have_what_meta_promises():
    assert len(SCENES) == 6
    for scene in SCENES:
        meta = json.loads((scene / "meta.json").read_text())
        width, height = meta["size"]
        for name in ("photo.png", "mask.png", "edit_true.png"):
            assert PIL.open(scene / name).size == (width, height), (scene, name)
        side = min(width, height)
        for name in ("swatch.png", "swatch_mask.png"):
            assert PIL.open(scene / name).size == (side, side), (scene, name)
        mask = np.asarray(PIL.open(scene / "mask.png")) > 127
        assert set(np.unique(np.asarray(PIL.open(scene / "mask.png")))) <= {0, 255}
        assert mask.sum() == meta["object_pixels"]
        ys, xs = np.nonzero(mask)
        assert meta["box"] == [xs.min(), ys.min(), xs.max() + 1, ys.max() + 1]
        assert meta["material"] != meta["edit_material"] and meta["envmap"] != meta["swatch_envmap"]


def test_splits_are_disjoint():
    spec = importlib.util.spec_from_file_location("make_set", ROOT / "scripts/photo_set/make_set.py")
    make_set = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make_set)  # imports NumPy and Pillow only; Mitsuba when run
    assert not set(make_set.TEST_ENVMAPS) & set(make_set.TUNE_ENVMAPS)
    assert {s["split"] for s in map(lambda p: json.loads((p / "meta.json").read_text()), SCENES)} == {"test"}


def test_photos_have_boxes_and_masks_inside_them():
    folder = ROOT / "tests/data/photos"
    boxes = json.loads((folder / "boxes.json").read_text())
    assert len(boxes) >= 3
    for name, entry in boxes.items():
        width, height = PIL.open(folder / name).size
        x0, y0, x1, y1 = entry["box"]
        assert 0 <= x0 < x1 <= width and 0 <= y0 < y1 <= height, name
        mask = np.asarray(PIL.open(folder / (Path(name).stem + "_mask.png"))) > 127
        assert mask.shape == (height, width)
        ys, xs = np.nonzero(mask)
        # the box holds the mask, a few pixels of slack at most
        assert x0 <= xs.min() <= x0 + 4 and x1 - 4 <= xs.max() + 1 <= x1, name
        assert y0 <= ys.min() <= y0 + 4 and y1 - 4 <= ys.max() + 1 <= y1, name

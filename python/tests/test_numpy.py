"""The NumPy functions against the library's command line, batches against one-by-one
calls, and every kind of invalid input."""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

import matedit

ROOT = pathlib.Path(__file__).resolve().parents[2]


def cli():
    """The `matedit` binary that `cargo test` or `cargo build` left, if any."""
    for kind in ("release", "debug"):
        p = ROOT / "target" / kind / "matedit"
        if p.exists():
            return p
    return None


def scene(n=16, seed=0):
    rng = np.random.default_rng(seed)
    normals = matedit.sphere(n)
    env = (rng.random((8, 16, 3)) * 2).astype(np.float32)
    return normals, env, matedit.preset("clay")


def write_npy(path, a):
    np.save(path, a)
    return str(path)


def test_presets_and_helpers():
    names = matedit.presets()
    assert len(names) >= 95 and "gold-metallic-paint" in names
    c = matedit.preset("gold-metallic-paint")
    assert c.shape == (108,) and c.dtype == np.float64
    s = matedit.sphere(8)
    assert s.shape == (8, 8, 3) and s.dtype == np.float32
    assert np.all(s[0, 0] == 0)  # background in the corner
    assert np.allclose(np.linalg.norm(s[4, 4]), 1, atol=1e-6)
    assert matedit.sky(4, 8).shape == (4, 8, 3)


@pytest.mark.skipif(cli() is None, reason="no matedit binary: run cargo build first")
def test_render_and_backward_equal_the_command_line(tmp_path):
    normals, env, ctrl = scene()
    env_path = write_npy(tmp_path / "env.npy", env)
    (tmp_path / "m.json").write_text(json.dumps({"ctrl": ctrl.tolist()}))
    out = tmp_path / "img.npy"
    subprocess.run(
        [cli(), "render", "-o", out, "--sphere", "16", "--env", env_path, "--env-size", "full",
         "--material", tmp_path / "m.json", "--device", "cpu"],
        check=True, capture_output=True,
    )
    img = matedit.render(normals, env, ctrl, device="cpu")
    np.testing.assert_array_equal(img, np.load(out))

    up = np.random.default_rng(1).standard_normal(img.shape).astype(np.float32)
    up_path = write_npy(tmp_path / "up.npy", up)
    gdir = tmp_path / "g"
    subprocess.run(
        [cli(), "grad", "-o", gdir, "--sphere", "16", "--env", env_path, "--env-size", "full",
         "--material", tmp_path / "m.json", "--device", "cpu", "--upstream", up_path],
        check=True, capture_output=True,
    )
    d_env, d_normals, d_ctrl = matedit.backward(normals, env, ctrl, up, device="cpu")
    np.testing.assert_array_equal(d_env, np.load(gdir / "d_env.npy"))
    np.testing.assert_array_equal(d_normals, np.load(gdir / "d_normals.npy"))
    cli_ctrl = np.array(json.loads((gdir / "d_material.json").read_text())["ctrl"], np.float32)
    np.testing.assert_array_equal(d_ctrl, cli_ctrl)


def test_devices_agree():
    normals, env, ctrl = scene(12)
    ref = matedit.render(normals, env, ctrl, device="reference")
    fast = matedit.render(normals, env, ctrl, device="cpu")
    assert np.abs(fast - ref).max() <= 1e-5 * ref.max()


def test_batched_equals_one_by_one():
    normals, env, _ = scene()
    ctrls = np.stack([matedit.preset(n) for n in ("clay", "gold", "pink-fabric")])
    envs = np.stack([env, env * 0.5, env[::-1].copy()])
    batch = matedit.render(normals, envs, ctrls)
    assert batch.shape == (3, 16, 16, 3)
    up = np.ones((3, 16, 16, 3), np.float32)
    bg = matedit.backward(normals, envs, ctrls, up)
    for i in range(3):
        np.testing.assert_array_equal(batch[i], matedit.render(normals, envs[i], ctrls[i]))
        one = matedit.backward(normals, envs[i], ctrls[i], up[i])
        for b, o in zip(bg, one):
            np.testing.assert_array_equal(b[i], o)


def test_only_the_wanted_gradients():
    normals, env, ctrl = scene()
    env[::3] = 0.0  # black texels: left out without d_env on the fast CPU path
    up = np.random.default_rng(1).standard_normal((16, 16, 3)).astype(np.float32)
    for device in ("cpu", "reference"):
        full = matedit.backward(normals, env, ctrl, up, device=device)
        for wanted in (["ctrl"], ["normals"], ("env",), "env", ["env", "ctrl"], []):
            got = matedit.backward(normals, env, ctrl, up, device=device, wanted=wanted)
            names = [wanted] if isinstance(wanted, str) else list(wanted)
            for name, g, f in zip(("env", "normals", "ctrl"), got, full):
                assert g.shape == f.shape
                if name in names:
                    np.testing.assert_allclose(g, f, rtol=1e-5, atol=1e-5 * np.abs(f).max())
                else:
                    assert not g.any(), (device, wanted, name)
    with pytest.raises(ValueError, match="wanted: unknown gradient 'light'"):
        matedit.backward(normals, env, ctrl, up, wanted=["light"])


def test_non_contiguous_inputs_are_read_right():
    normals, env, ctrl = scene()
    wide = np.zeros((16, 32, 3), np.float32)
    wide[:, ::2] = normals
    strided = wide[:, ::2]
    assert not strided.flags.c_contiguous
    np.testing.assert_array_equal(
        matedit.render(strided, env, ctrl), matedit.render(normals, env, ctrl)
    )


def test_renderer_keeps_its_device():
    r = matedit.Renderer("cpu")
    assert r.describe().startswith("cpu")
    normals, env, ctrl = scene()
    np.testing.assert_array_equal(r.render(normals, env, ctrl), matedit.render(normals, env, ctrl, device="cpu"))


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda n, e, c: (n.astype(np.float64), e, c), "normals: dtype float64"),
        (lambda n, e, c: (n, e.astype(np.float16), c), "env: dtype float16"),
        (lambda n, e, c: (n, e, c.astype(np.int32)), "ctrl: dtype int32"),
        (lambda n, e, c: (n[..., :2], e, c), "normals: shape"),
        (lambda n, e, c: (n, e, c[:100]), "ctrl: shape"),
        (lambda n, e, c: (n, e[:0], c), "env: shape"),
        (lambda n, e, c: (np.where(n == n, np.float32("nan"), n), e, c), "NaN"),
        (lambda n, e, c: (n, -e, c), "env: texel"),
        (lambda n, e, c: (n, e, np.where(np.arange(108) == 6, -1.0, c)), "exponents must be >= 0"),
        (lambda n, e, c: (n, e, np.where(np.arange(108) == 0, 100.0, c)), "scales must be within"),
        (lambda n, e, c: (np.stack([n, n]), np.stack([e, e, e]), c), "batch of"),
    ],
)
def test_invalid_inputs_raise_value_errors(change, message):
    n, e, c = change(*scene())
    with pytest.raises(ValueError, match=message) as info:
        matedit.render(n, e, c)
    assert "\n" not in str(info.value)


def test_invalid_options_and_files(tmp_path):
    normals, env, ctrl = scene()
    with pytest.raises(ValueError, match="convention"):
        matedit.render(normals, env, ctrl, convention="polar")
    with pytest.raises(ValueError, match="device"):
        matedit.render(normals, env, ctrl, device="tpu")
    with pytest.raises(ValueError, match="field of view"):
        matedit.render(normals, env, ctrl, fov=180.0)
    with pytest.raises(ValueError, match="upstream"):
        matedit.backward(normals, env, ctrl, np.ones((3, 3, 3), np.float32))
    with pytest.raises(ValueError, match="unknown preset"):
        matedit.preset("unobtainium")
    with pytest.raises(ValueError, match="missing.exr"):
        matedit.load_env(tmp_path / "missing.exr")
    bad = tmp_path / "bad.npy"
    bad.write_bytes(b"\x93NUMPY garbage")
    with pytest.raises(ValueError, match="bad.npy"):
        matedit.load_normals(bad)


def test_files_load(tmp_path):
    env = (np.random.default_rng(2).random((16, 32, 3)) - 0.1).astype(np.float32)
    p = write_npy(tmp_path / "env.npy", env)
    small = matedit.load_env(p, size=(8, 16))
    assert small.shape == (8, 16, 3) and small.min() >= 0
    assert matedit.load_env(p, size=None).shape == (16, 32, 3)
    n = write_npy(tmp_path / "n.npy", matedit.sphere(8) * 2)
    np.testing.assert_allclose(matedit.load_normals(n), matedit.sphere(8), atol=1e-6)

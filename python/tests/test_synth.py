"""Dataset synthesis from Python: a whole run against the shards run as Ray tasks on a
local Ray instance with 2 workers (the same chunk files, bit for bit), a shard read back
with the standard tarfile module, and a bad spec failing before anything is written."""

import io
import json
import pathlib
import tarfile

import numpy as np
import pytest

import matedit

ray = pytest.importorskip("ray")
from matedit.ray import synth_ray  # noqa: E402


def write_spec(root: pathlib.Path, **changes) -> pathlib.Path:
    env = np.linspace(0.1, 3.0, 16 * 32 * 3, dtype=np.float32).reshape(16, 32, 3)
    np.save(root / "sky.npy", env)
    spec = {
        "count": 12,
        "seed": 11,
        "image_size": 16,
        "env_size": "8x16",
        "chunk_size": 4,
        "normals": [{"sphere": 16}, {"bumpy": 16}],
        "envs": ["sky.npy"],
        "materials": [{"preset": "gold"}, {"random": "merl"}],
    }
    spec.update(changes)
    path = root / "spec.json"
    path.write_text(json.dumps(spec))
    return path


def data_files(d: pathlib.Path) -> dict:
    return {p.name: p.read_bytes() for p in sorted(d.glob("chunk-*"))}


@pytest.fixture(scope="module")
def local_ray():
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


def test_ray_shards_write_the_whole_runs_bytes(tmp_path, local_ray):
    spec = write_spec(tmp_path)
    whole = matedit.synth(spec, tmp_path / "whole", device="cpu")
    assert whole["samples"] == 12 and whole["chunks_written"] == 3
    assert whole["chunks_present"] == 3

    out = synth_ray(spec, tmp_path / "ray", num_shards=3, device="cpu")
    assert out["complete"] and out["samples"] == 12 and out["missing"] == []
    assert sorted(s["shard"] for s in out["shards"]) == ["0/3", "1/3", "2/3"]
    a, b = data_files(tmp_path / "whole"), data_files(tmp_path / "ray")
    assert sorted(a) == [f"chunk-00000{i}.{e}" for i in range(3) for e in ("json", "tar")]
    assert a == b

    # run again: every chunk is complete and skipped
    again = synth_ray(spec, tmp_path / "ray", num_shards=3, device="cpu")
    assert again["samples"] == 0 and sum(s["chunks_skipped"] for s in again["shards"]) == 3
    assert data_files(tmp_path / "ray") == a

    # a shard as a data loader sees it: groups of members sharing a key
    manifest = json.loads((tmp_path / "ray" / "manifest.json").read_text())
    assert manifest["complete"] and manifest["count"] == 12
    with tarfile.open(tmp_path / "ray" / manifest["chunks"][1]["file"]) as t:
        names = t.getnames()
        assert names[:6] == [f"00000004.{m}" for m in manifest["members"]]
        mask = np.load(io.BytesIO(t.extractfile("00000004.mask.npy").read()))
        image = np.load(io.BytesIO(t.extractfile("00000004.image.npy").read()))
        normals = np.load(io.BytesIO(t.extractfile("00000004.normals.npy").read()))
        env = np.load(io.BytesIO(t.extractfile("00000004.env.npy").read()))
        ctrl = np.array(json.loads(t.extractfile("00000004.material.json").read())["ctrl"])
        params = json.loads(t.extractfile("00000004.params.json").read())
    assert image.shape == (16, 16, 3) and env.shape == (8, 16, 3) and ctrl.shape == (108,)
    assert params["index"] == 4 and params["seed"] == 11
    assert mask.shape == (16, 16) and np.array_equal(mask == 1, np.any(normals != 0, axis=-1))
    # the image is a render of the recorded inputs
    again = matedit.render(normals, env, ctrl, device="cpu")
    assert np.array_equal(again, image)


def test_a_bad_spec_writes_nothing(tmp_path):
    spec = write_spec(tmp_path, envs=["missing.exr"])
    with pytest.raises(ValueError, match=r"spec.json: envs\[0\]: .*missing.exr: no such file"):
        synth_ray(spec, tmp_path / "ds", num_shards=3)
    with pytest.raises(ValueError, match="shard 4/3"):
        matedit.synth(write_spec(tmp_path), tmp_path / "ds", shard=(4, 3))
    assert not (tmp_path / "ds").exists()
